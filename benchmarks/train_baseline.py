"""Learning baseline for the slide task: SAC + HER on ``SlideGym/TopSlideGoal-v0`` (default) or
PPO on ``SlideGym/TopSlideDense-v0``, for a fixed budget of env steps.

Every ``--eval-every`` steps (and before training) the deterministic policy plays
``--eval-episodes`` fixed-seed episodes; one row per evaluation is appended to
``OUT/progress.csv`` and the learning curve is redrawn to ``OUT/learning_curve.png``. The model
(and SAC's replay buffer) are saved at each evaluation, so ``--resume`` continues a run that was
stopped. Needs the ``rl`` extra (stable-baselines3, a CPU torch).

    OMP_NUM_THREADS=1 python benchmarks/train_baseline.py --steps 100000 --out runs/sac_her
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")  # 20x slower on this 2-core machine otherwise

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import slide_gym  # noqa: E402, F401 - registers the envs

ENVS = {"sac-her": "SlideGym/TopSlideGoal-v0", "ppo": "SlideGym/TopSlideDense-v0"}
COLUMNS = (
    "steps",
    "train_wall_s",
    "success_rate",
    "graspable_rate",
    "fell_off_rate",
    "mean_return",
    "mean_length",
)
EVAL_SEED = 10_000
"""Evaluation episodes use reset seeds EVAL_SEED, EVAL_SEED + 1, ...: the same every time."""


def make_model(algo: str, env: gym.Env, budget: int, seed: int) -> Any:
    """A fresh SAC + HER or PPO model (hyperparameters sized for one CPU core)."""
    from stable_baselines3 import PPO, SAC, HerReplayBuffer

    if algo == "ppo":
        return PPO("MultiInputPolicy", env, n_steps=2048, batch_size=128, seed=seed, device="cpu")
    return SAC(  # panda-gym's rl-zoo settings (gamma, lr, tau), with a smaller net and batch
        "MultiInputPolicy",
        env,
        replay_buffer_class=HerReplayBuffer,
        replay_buffer_kwargs={"n_sampled_goal": 4, "goal_selection_strategy": "future"},
        buffer_size=max(budget, 1000),
        learning_starts=1000,
        batch_size=256,
        gamma=0.95,
        learning_rate=1e-3,
        tau=0.05,
        policy_kwargs={"net_arch": [256, 256]},
        seed=seed,
        device="cpu",
    )


def evaluate(model: Any, env: gym.Env, episodes: int) -> dict[str, float]:
    """Success (``is_success``), graspable-at-the-end and fall-off rates, mean return and
    length of ``episodes`` deterministic fixed-seed episodes."""
    rows = []
    for k in range(episodes):
        obs, info = env.reset(seed=EVAL_SEED + k)
        total, steps, done = 0.0, 0, False
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, info = env.step(action)
            total, steps, done = total + float(reward), steps + 1, terminated or truncated
        rows.append((info["is_success"], info["graspable"], info["fell_off"], total, steps))
    success, graspable, fell, returns, lengths = (np.mean(c) for c in zip(*rows, strict=True))
    return {
        "success_rate": float(success),
        "graspable_rate": float(graspable),
        "fell_off_rate": float(fell),
        "mean_return": float(returns),
        "mean_length": float(lengths),
    }


def plot(csv_path: Path, png_path: Path, title: str) -> None:
    """Success rate (and graspable-at-the-end rate) against env steps."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with csv_path.open() as f:
        rows = list(csv.DictReader(f))
    steps = [int(r["steps"]) for r in rows]
    fig, ax = plt.subplots(figsize=(6, 3.5), dpi=120)
    ax.plot(steps, [float(r["success_rate"]) for r in rows], "o-", label="success (is_success)")
    ax.plot(steps, [float(r["graspable_rate"]) for r in rows], "s--", label="graspable at the end")
    ax.set(xlabel="env steps", ylabel="rate", ylim=(-0.03, 1.03), title=title)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left")
    fig.tight_layout()
    fig.savefig(png_path)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--algo", choices=tuple(ENVS), default="sac-her")
    ap.add_argument("--steps", type=int, default=100_000, help="training budget (env steps)")
    ap.add_argument("--eval-every", type=int, default=5000, help="env steps between evaluations")
    ap.add_argument("--eval-episodes", type=int, default=10)
    ap.add_argument(
        "--max-episode-steps", type=int, default=None, help="time limit (default: the registered)"
    )
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("runs/baseline"))
    ap.add_argument("--resume", action="store_true", help="continue the run saved in --out")
    args = ap.parse_args(argv)
    if args.steps < 1 or args.eval_every < 1 or args.eval_episodes < 1:
        ap.error("--steps, --eval-every and --eval-episodes must be positive")

    import torch
    from stable_baselines3 import PPO, SAC

    torch.set_num_threads(1)
    env_id = ENVS[args.algo]
    limit = {} if args.max_episode_steps is None else {"max_episode_steps": args.max_episode_steps}
    env, eval_env = gym.make(env_id, **limit), gym.make(env_id, **limit)
    out: Path = args.out
    csv_path, model_path = out / "progress.csv", out / "model.zip"
    buffer_path = out / "replay_buffer.pkl"
    if csv_path.exists() and not args.resume:
        ap.error(f"{csv_path} exists: pass --resume to continue it, or another --out")
    out.mkdir(parents=True, exist_ok=True)

    done_wall = 0.0
    if args.resume and model_path.exists():
        cls = SAC if args.algo == "sac-her" else PPO
        model = cls.load(model_path, env=env, device="cpu")
        if args.algo == "sac-her" and buffer_path.exists():
            model.load_replay_buffer(buffer_path)
        with csv_path.open() as f:
            last = list(csv.DictReader(f))[-1]
        done_wall = float(last["train_wall_s"])
        print(f"resuming at {model.num_timesteps} steps", flush=True)
    else:
        model = make_model(args.algo, env, args.steps, args.seed)
        with csv_path.open("w", newline="") as f:
            csv.writer(f).writerow(COLUMNS)

    title = f"{args.algo} on {env_id}"

    def record(wall: float) -> None:
        row = {"steps": model.num_timesteps, "train_wall_s": round(wall, 1)}
        row.update(evaluate(model, eval_env, args.eval_episodes))
        with csv_path.open("a", newline="") as f:
            csv.writer(f).writerow([row[c] for c in COLUMNS])
        plot(csv_path, out / "learning_curve.png", title)
        print(", ".join(f"{k} {v:.3g}" for k, v in row.items()), flush=True)

    if model.num_timesteps == 0:
        record(0.0)
    while model.num_timesteps < args.steps:
        chunk = min(args.eval_every, args.steps - model.num_timesteps)
        start, t0 = model.num_timesteps, time.perf_counter()
        model.learn(chunk, reset_num_timesteps=False)
        dt = time.perf_counter() - t0
        done_wall += dt
        n = model.num_timesteps - start
        print(f"trained {n} steps at {n / dt:.1f} steps/s", flush=True)
        model.save(model_path)
        if args.algo == "sac-her":
            model.save_replay_buffer(buffer_path)
        record(done_wall)
    env.close()
    eval_env.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
