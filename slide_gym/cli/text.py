"""Plain-text summaries of ``demo``, ``plan`` and ``run`` (``--json`` prints everything at full
precision): poses in m and rad to 3 decimals, times in s to 2."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from slide_gym.cli.args import fmt_pose, or_na

if TYPE_CHECKING:  # agents builds on slide_gym: imported on use only
    from agents.record import EpisodeRecord


def demo_text(s: dict[str, Any]) -> str:
    """A few lines about one scripted slide (``agents.scripted.run_demo``'s summary)."""
    lines = [
        f"{'success' if s['success'] else 'failed'}: {s['object']} on {s['table']}, "
        f"seed {s['seed']}, overhang {or_na(s['overhang_m'], '.3f', ' m')}",
        f"  {s['steps']} steps, {or_na(s['sim_time_s'], '.2f', ' s')} simulated in "
        f"{or_na(s['wall_time_s'], '.2f', ' s')}",
        f"  start pose {fmt_pose(s['object_start_pose'])}",
        f"  final pose {fmt_pose(s['object_final_pose'])}",
    ]
    if s.get("video"):
        lines.append(f"  wrote {s['video']}")
    return "\n".join(lines)


def plan_text(out: dict[str, Any]) -> str:
    """A few lines about one planning query (``plan_once``'s report)."""
    lines = [
        f"{out['status']} ({out['planner']}, {out['planning_time_s']:.2f} s): "
        f"{out['object']} on {out['table']} from {fmt_pose(out['object_start_pose'])}"
    ]
    if out["status"] == "solved":
        lines.append(
            f"  goal pose {fmt_pose(out['object_goal_pose'])}, overhang "
            f"{or_na(out['overhang_m'], '.3f', ' m')}, {len(out['path'])} path configurations"
        )
    elif out.get("reason"):
        lines.append(f"  {out['reason']}")
    return "\n".join(lines)


def run_text(r: EpisodeRecord) -> str:
    """A few lines about one expert episode."""
    e = r.expert
    cm = None if e.slide_error_m is None else 100.0 * e.slide_error_m
    deg = None if e.slide_error_rad is None else math.degrees(e.slide_error_rad)
    lines = [
        f"{'lifted' if r.success else 'failed'}: {r.object} on {r.table}, seed {r.seed}, "
        f"{r.planner} planner, phase reached {r.phase_reached}",
        f"  planned {'yes' if e.planned else 'no'} ({e.replans} replans, "
        f"{or_na(e.planning_time_s, '.2f', ' s')} planning); {r.steps} steps, "
        f"{or_na(r.sim_time_s, '.2f', ' s')} simulated in {or_na(r.wall_time_s, '.2f', ' s')}",
        f"  slide error {or_na(cm, '.1f', ' cm')} / {or_na(deg, '.1f', ' deg')}, plate rose "
        f"{or_na(r.lift_height_m, '.3f', ' m')}, clearance {or_na(r.clearance_m, '.3f', ' m')} "
        f"(most {or_na(r.max_clearance_m, '.3f', ' m')}), final pose "
        f"{fmt_pose(r.object_final_pose)}",
    ]
    if r.failure:
        lines.append(f"  failure: {r.failure}")
    return "\n".join(lines)
