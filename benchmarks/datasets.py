"""Dataset benchmarks for the documentation's "Datasets" page.

``throughput``: collect the same episodes with 1 and then 2 worker processes into a fresh
Minari folder each, and report successful demonstrations per minute (per worker) and the
speed-up. ``bc``: for the slide-only and the grasp env, collect an expert dataset, clone it
(``slide-gym train-bc``), and evaluate the clone and the expert on the same held-out seeds.

Results go to ``OUT/throughput.json`` and ``OUT/bc.json`` (+ ``OUT/bc.md``), a part at a time;
the datasets live in ``OUT/minari`` and collection resumes there, so a stopped ``bc`` run
continues (timings of a resumed collection are not comparable, so ``throughput`` always
starts afresh).

    OMP_NUM_THREADS=1 python benchmarks/datasets.py throughput --episodes 16
    OMP_NUM_THREADS=1 python benchmarks/datasets.py bc --episodes 100 --eval-episodes 50
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

ENVS = ("SlideGym/TopSlide-v0", "SlideGym/TopSlideGrasp-v0")


def _collect(root: Path, env_id: str, episodes: int, dataset_id: str, workers: int, **kw: Any):
    os.environ["MINARI_DATASETS_PATH"] = str(root)
    from slide_gym.datasets.collect import collect
    from slide_gym.datasets.config import CollectConfig

    config = CollectConfig(env_id=env_id, **kw)
    return collect(config, episodes, dataset_id, workers=workers)


def throughput(args: argparse.Namespace) -> dict[str, Any]:
    from slide_gym.version import code_version

    rows = []
    for workers in (1, 2):
        root = args.out / f"throughput-{workers}"
        shutil.rmtree(root, ignore_errors=True)
        start = time.perf_counter()
        summary = _collect(
            root,
            args.env,
            args.episodes,
            "bench/throughput-v0",
            workers,
            object=args.object,
            table=args.table,
        )
        wall = time.perf_counter() - start
        successes = round(summary["expert_success_rate"] * summary["episodes_run"])
        rows.append(
            {
                "workers": workers,
                "episodes": summary["episodes_run"],
                "successes": successes,
                "wall_s": wall,
                "successes_per_min": 60 * successes / wall,
                "successes_per_min_per_worker": 60 * successes / wall / workers,
                "bytes_per_step": summary["bytes_per_step"],
            }
        )
        shutil.rmtree(root, ignore_errors=True)
    result = {
        "env_id": args.env,
        "object": args.object,
        "table": args.table,
        "code_version": code_version(),
        "runs": rows,
        "speedup_1_to_2_workers": rows[0]["wall_s"] / rows[1]["wall_s"],
    }
    (args.out / "throughput.json").write_text(json.dumps(result, indent=2))
    return result


def bc(args: argparse.Namespace) -> list[dict[str, Any]]:
    from agents.bc import train_bc, write_model_card
    from agents.evaluate import evaluate
    from slide_gym.datasets.store import load
    from slide_gym.splits import TEST_SEED
    from slide_gym.version import code_version

    path = args.out / "bc.json"
    done = json.loads(path.read_text()) if path.exists() else []
    root = args.out / "minari"
    for env_id in ENVS:
        if any(r["env_id"] == env_id for r in done):
            continue
        name = env_id.split("/")[1].replace("-v0", "").lower()
        dataset_id = f"bench/{name}-{args.object}-{args.table}-v0"
        start = time.perf_counter()
        summary = _collect(
            root,
            env_id,
            args.episodes,
            dataset_id,
            args.workers,
            object=args.object,
            table=args.table,
            only_success=True,
        )
        collect_s = time.perf_counter() - start
        dataset = load(dataset_id)
        env = dataset.recover_environment()
        model_path = args.out / f"bc-{name}.zip"
        model, stats = train_bc(dataset, steps=args.steps, seed=0, env=env)
        model.save(model_path)
        env.close()
        kwargs = {"object": args.object, "table": args.table}
        write_model_card(model_path, env_id, kwargs, {"dataset_id": dataset_id, **stats})
        seeds = {"episodes": args.eval_episodes, "seed": TEST_SEED, "env_kwargs": kwargs}
        clone = evaluate(model_path, env_id, **seeds)
        expert = evaluate("regions", env_id, **seeds)
        row = {
            "env_id": env_id,
            "object": args.object,
            "table": args.table,
            "dataset_id": dataset_id,
            "dataset_episodes": summary["episodes"],
            "dataset_steps": summary["steps"],
            "expert_episodes_run": summary["episodes_run"],
            "collect_s": collect_s,
            "train_steps": stats["steps"],
            "train_s": stats["train_time_s"],
            "final_loss": stats["final_loss"],
            "bc_success": clone["success_rate"],
            "bc_ci95": clone["ci95"],
            "expert_success": expert["success_rate"],
            "expert_ci95": expert["ci95"],
            "eval_episodes": args.eval_episodes,
            "eval_seeds": f"{TEST_SEED}-{TEST_SEED + args.eval_episodes - 1}",
            "code_version": code_version(),
        }
        done.append(row)
        path.write_text(json.dumps(done, indent=2))
        print(json.dumps(row), file=sys.stderr)
    lines = [
        "| env | demos (steps) | BC training | BC success | expert success |",
        "|---|---|---|---|---|",
    ]
    for r in done:
        lo, hi = (100 * v for v in r["bc_ci95"])
        elo, ehi = (100 * v for v in r["expert_ci95"])
        lines.append(
            f"| `{r['env_id']}` | {r['dataset_episodes']} ({r['dataset_steps']}) | "
            f"{r['train_steps']} steps, {r['train_s']:.0f} s | "
            f"{100 * r['bc_success']:.0f} % ({lo:.0f}-{hi:.0f}) | "
            f"{100 * r['expert_success']:.0f} % ({elo:.0f}-{ehi:.0f}) |"
        )
    (args.out / "bc.md").write_text("\n".join(lines) + "\n")
    return done


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="what", required=True)
    for name in ("throughput", "bc"):
        p = sub.add_parser(name)
        p.add_argument("--out", type=Path, default=Path("runs/datasets"))
        p.add_argument("--object", default="square")
        p.add_argument("--table", default="square")
        p.add_argument("--episodes", type=int, default=16 if name == "throughput" else 100)
    sub.choices["throughput"].add_argument("--env", default="SlideGym/TopSlideGrasp-v0")
    p = sub.choices["bc"]
    p.add_argument("--steps", type=int, default=5000, help="BC gradient steps")
    p.add_argument("--eval-episodes", type=int, default=50)
    p.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    result = throughput(args) if args.what == "throughput" else bc(args)
    print(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
