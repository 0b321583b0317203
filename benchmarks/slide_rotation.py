"""How far the plate turns on its first slide against the turn Eq. 2 planned, from
``slide-gym bench execute`` result files.

Each file is one set (an outline at one thickness, density or planner setting). For every
episode the first slide's yaw error comes from the expert's ``slid:`` event; for episodes
without a replan the planned turn (Eq. 2's goal against the start) and the real one (the slid
pose against the start) are compared, with the least-squares slope of real on planned: 1 when
the plate turns with the fingertip, below 1 when it lags behind.

    OMP_NUM_THREADS=1 slide-gym bench execute --objects docs/examples/shim.json --trials 10 \
        --out shim.jsonl
    python benchmarks/slide_rotation.py shim.jsonl [more.jsonl ...]

``--press`` also presses a card outline of each thickness in :data:`PRESS_THICKNESSES` 1.6 cm
deep (the middle of the expert's band) and drags it 5 cm
(:func:`slide_gym.bench.drag.drag_plate`): how much of the press the plate carries, and how
far the fingertip sank into the table.
"""

from __future__ import annotations

import argparse
import gzip
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

FIRST_SLIDE = re.compile(r"^(?:slid|lifted off): .*error ([\d.]+) m ([\d.]+) rad")
LARGE_ERROR = 0.3
"""Yaw error (rad) counted as a large turn away from the plan."""


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def summarise(path: Path) -> dict[str, Any]:
    """The first-slide rotation figures of one ``bench execute`` result file."""
    text = gzip.decompress(path.read_bytes()).decode() if path.suffix == ".gz" else path.read_text()
    rows = [json.loads(line) for line in text.splitlines() if line.strip()]
    errors = []
    for row in rows:
        match = next((m for e in row.get("events", []) if (m := FIRST_SLIDE.match(e))), None)
        if match is not None:
            errors.append(float(match.group(2)))
    planned, real = [], []
    for row in rows:
        if row.get("replans") or row.get("object_slid_pose") is None:
            continue
        start = row["object_start_pose"][2]
        planned.append(_wrap(row["object_predicted_pose"][2] - start))
        real.append(_wrap(row["object_slid_pose"][2] - start))
    err = np.asarray(errors)
    p, r = np.asarray(planned), np.asarray(real)
    slope = float(np.dot(p, r) / np.dot(p, p)) if len(p) and np.dot(p, p) > 0 else math.nan
    return {
        "file": path.name,
        "object": rows[0]["object"] if rows else None,
        "episodes": len(rows),
        "lifted": sum(bool(row["success"]) for row in rows),
        "replanned": sum(int(row.get("replans", 0)) > 0 for row in rows),
        "slides": len(err),
        "yaw_error_median_rad": float(np.median(err)) if len(err) else math.nan,
        "yaw_error_p90_rad": float(np.percentile(err, 90)) if len(err) else math.nan,
        "large_errors": int((err > LARGE_ERROR).sum()),
        "planned_turn_median_rad": float(np.median(np.abs(p))) if len(p) else math.nan,
        "real_turn_median_rad": float(np.median(np.abs(r))) if len(r) else math.nan,
        "slope": slope,
    }


PRESS_THICKNESSES = (0.0005, 0.00076, 0.002, 0.004)
"""Plate thicknesses (m) of ``--press``."""


def press_shares(contact_erp: float | None = None) -> None:
    """Print the plate's share of the press at each of :data:`PRESS_THICKNESSES`, and how far
    the plate lagged behind the fingertip; ``contact_erp``: PyBullet's ``contactERP`` instead
    of the engine's default."""
    from slide_gym.bench.drag import drag_plate

    def configure(env: Any) -> None:
        if contact_erp is not None:
            env.unwrapped.sim.client.setPhysicsEngineParameter(contactERP=contact_erp)

    print("| thickness | press on the plate (median) | plate below the table top | lag |")
    print("|---|---|---|---|")
    for thickness in PRESS_THICKNESSES:
        r = drag_plate(thickness, 0.016, 0.0, length=0.05, configure=configure)
        print(
            f"| {thickness * 1000:.2f} mm | {r.press_force_n:.2f} N | {r.sink_m * 1000:.2f} mm "
            f"| {r.lag_m * 1000:.1f} mm |"
        )


def trace_contacts(obj: str, table: str, seed: int, every: int = 10) -> None:
    """Run one expert episode and print, every ``every`` steps of its press and slide, the
    normal force the robot puts on the table and on the plate, and where the table contact
    lies (its depth inside the plate's outline; negative: outside)."""
    import gymnasium as gym
    import shapely
    from gymnasium.utils import seeding

    from agents.episode import START_MARGIN, play_episode
    from agents.planner_agent import PlannerAgent
    from slide_gym.envs.scene import SceneChoice
    from slide_gym.geometry import transform_polygon
    from slide_gym.geometry.polygons import quat_yaw

    shape, table_shape = SceneChoice(obj, table).draw(
        seeding.np_random(seed)[0], seed, START_MARGIN
    )
    env = gym.make("SlideGym/TopSlideGrasp-v0", object=obj, table=table)
    agent = PlannerAgent("regions", 10.0, seed=seed, objects=[shape], tables=[table_shape])
    sim = env.unwrapped.sim
    rows: list[tuple[float, float, float | None]] = []

    def watch(action: Any, obs: dict, *_: Any) -> None:
        pose = np.asarray(obs["object_pose"], float)
        outline = transform_polygon(shape.polygon, pose[0], pose[1], quat_yaw(pose[3:7]))
        on_table = sim.contact_points("robot", "table")
        on_plate = sim.contact_points("robot", "object")
        depth = None
        if on_table:
            point = shapely.Point(on_table[0][5][:2])
            depth = outline.exterior.distance(point) * (1 if outline.contains(point) else -1)
        rows.append((sum(c[9] for c in on_table), sum(c[9] for c in on_plate), depth))

    try:
        record = play_episode(env, agent, seed=seed, on_step=watch).to_json_dict()
    finally:
        agent.close()
        env.close()
    phases = record["phase_steps"]
    names = [name for name, _ in phases]
    start, end = phases[names.index("press")][1], phases[names.index("lift_off")][1]
    print(f"{obj} on {table}, seed {seed}: events {record['events']}")
    print(
        "| step | phase | robot on the table | robot on the plate | table contact inside outline |"
    )
    print("|---|---|---|---|---|")
    for k in range(start, end, every):
        phase = [name for name, step in phases if step <= k][-1]
        table_n, plate_n, depth = rows[k]
        where = "-" if depth is None else f"{depth * 1000:.1f} mm"
        print(f"| {k} | {phase} | {table_n:.2f} N | {plate_n:.2f} N | {where} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("files", nargs="*", type=Path, help="bench execute JSONL files")
    parser.add_argument("--press", action="store_true", help="also press and drag card outlines")
    parser.add_argument("--contact-erp", type=float, help="--press with this contactERP")
    parser.add_argument(
        "--trace", nargs=3, metavar=("OBJECT", "TABLE", "SEED"), help="trace one episode's contacts"
    )
    args = parser.parse_args()
    if args.press:
        press_shares(args.contact_erp)
    if args.trace:
        trace_contacts(args.trace[0], args.trace[1], int(args.trace[2]))
    if not args.files:
        return
    print(
        "| set | lifted | replanned | first-slide yaw error: median / 90th pct | "
        f"> {LARGE_ERROR} rad | planned turn (median) | real turn (median) | real / planned |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for path in args.files:
        s = summarise(path)
        print(
            f"| {s['file']} | {s['lifted']}/{s['episodes']} | {s['replanned']} "
            f"| {s['yaw_error_median_rad']:.2f} / {s['yaw_error_p90_rad']:.2f} rad "
            f"| {s['large_errors']}/{s['slides']} | {s['planned_turn_median_rad']:.2f} rad "
            f"| {s['real_turn_median_rad']:.2f} rad | {s['slope']:.2f} |"
        )


if __name__ == "__main__":
    main()
