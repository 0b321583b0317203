"""Train a diffusion policy on a demonstration dataset: checkpoints, progress rows,
validation on held-out seeds, resume.

:func:`train_diffusion` writes into one folder:

- ``checkpoint.pt``: everything to continue (weights, EMA, optimiser, schedule, random
  streams), written every ``log_every`` iterations and on Ctrl-C;
- ``progress.csv``: per ``log_every`` iterations, the mean loss, learning rate and training
  seconds, and where validated, the success rate on validation seeds with its Wilson interval;
- ``policy.pt`` / ``policy.json``: the EMA weights of the checkpoint with the best validation
  success (the latest if none validated), and its card;
- ``learning_curve.png``: loss and validation success against iterations;
- ``snapshots/ITERATION/``: with ``snapshot_every``, the EMA weights every that many
  iterations (and where Ctrl-C stops the run) as a policy folder each, for choosing the
  checkpoint after training (:func:`choose_snapshot`) where the training machine cannot run
  the simulator.

``device="cuda"`` trains on a GPU; batches, diffusion noise and the minibatch draws come
from the same seeded CPU streams, and every saved policy holds CPU weights.

Validation episodes use reset seeds from :data:`slide_gym.splits.VALIDATION_SEED`, never the
test seeds of ``slide-gym evaluate`` (from 10000), so choosing the checkpoint does not peek
at the test. Ctrl-C finishes the iteration in progress, saves a checkpoint and raises
``KeyboardInterrupt``; ``resume=True`` continues from it, to the same weights as a run
that was never stopped.
"""

from __future__ import annotations

import copy
import csv
import json
import math
import shutil
import signal
import sys
import threading
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from agents.learned.data import ChunkSampler, load_demonstrations
from agents.learned.diffusion import EMA, DiffusionConfig, DiffusionModel
from agents.learned.policy import (
    CARD_FILE,
    FIRST_FILE,
    WEIGHTS_FILE,
    DiffusionPolicy,
    is_policy_dir,
    save_policy,
)
from slide_gym.splits import VALIDATION_SEED

CHECKPOINT_FILE = "checkpoint.pt"
PROGRESS_FILE = "progress.csv"
CURVE_FILE = "learning_curve.png"
SNAPSHOT_DIR = "snapshots"
DEVICES = ("cpu", "cuda")
PROGRESS_FIELDS = (
    "iteration",
    "loss",
    "lr",
    "train_time_s",
    "val_success_rate",
    "val_ci_low",
    "val_ci_high",
    "val_episodes",
    "val_mean_length",
)


@dataclass(frozen=True)
class TrainConfig:
    """The optimisation.

    Args:
        iterations: gradient steps in all (a resumed run continues to this many).
        batch_size: windows per step.
        learning_rate, weight_decay, warmup: AdamW, with a linear warm-up over ``warmup``
            steps and a cosine decay to 0 at ``iterations``.
        seed: weights, minibatches and diffusion noise.
        log_every: iterations per progress row (and per checkpoint).
        val_every: iterations per validation (0: never; the last iteration always validates
            when ``val_episodes`` > 0).
        val_episodes: validation episodes each time (reset seeds from ``val_seed``).
        val_seed: first validation reset seed.
    """

    iterations: int = 20_000
    batch_size: int = 64
    learning_rate: float = 1e-3
    weight_decay: float = 1e-6
    warmup: int = 500
    seed: int = 0
    log_every: int = 500
    val_every: int = 5_000
    val_episodes: int = 20
    val_seed: int = VALIDATION_SEED

    def __post_init__(self) -> None:
        for name in ("iterations", "batch_size", "log_every"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be a positive integer, got {value!r}")
        for name in ("warmup", "seed", "val_every", "val_episodes", "val_seed"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
        if not (math.isfinite(self.learning_rate) and self.learning_rate > 0):
            raise ValueError(f"learning_rate must be positive, got {self.learning_rate!r}")


def _lr_factor(step: int, warmup: int, total: int) -> float:
    if step < warmup:
        return (step + 1) / warmup
    progress = (step - warmup) / max(1, total - warmup)
    return 0.5 * (1 + math.cos(math.pi * min(progress, 1.0)))


def hand_kind(labels: np.ndarray) -> str:
    """``"binary"`` if every labelled hand command (the last entry) is -1 or +1, else
    ``"continuous"`` (see :class:`DiffusionConfig`); unlabelled (NaN) steps are ignored."""
    hand = labels[:, -1][np.isfinite(labels[:, -1])]
    return "binary" if np.isin(hand, (-1.0, 1.0)).all() else "continuous"


def train_diffusion(
    dataset: Any,
    out: Path,
    *,
    config: DiffusionConfig | None = None,
    train: TrainConfig | None = None,
    env_id: str,
    env_kwargs: dict[str, Any],
    card: dict[str, Any] | None = None,
    resume: bool = False,
    progress: bool = True,
    init: Path | None = None,
    only_success: bool = True,
    first: Path | None = None,
    device: str = "cpu",
    snapshot_every: int = 0,
    episode_seeds: frozenset[int] | None = None,
) -> dict[str, Any]:
    """Train on Minari ``dataset`` into folder ``out`` (see the module docstring) and return
    the summary that ``policy.json`` also holds. ``env_id``/``env_kwargs``: the env the
    policy acts in (validation, and ``slide-gym evaluate DIR``); ``card``: extra entries
    for ``policy.json``. An ``out`` that already holds a checkpoint needs ``resume=True``
    (with the same configuration). ``init``: a ``policy.pt`` to start from (its weights,
    configuration and normalisation statistics; DAgger's warm start). ``only_success``: train
    on the episodes whose ``success`` flag is set and on DAgger rollouts (False: on every
    episode); see :func:`~agents.learned.data.load_demonstrations`. ``first``: a sliding
    skill's ``policy.pt``; the model learns only what follows a finished slide in each
    episode (``after_slide``) and the saved policy runs ``first`` until then (validation
    included). ``episode_seeds``: train only on the episodes reset with these seeds."""
    first_model = None
    if first is not None:
        from agents.learned.policy import load_model

        first_model = load_model(Path(first))
    init_model = None
    if init is not None:
        from agents.learned.policy import load_model

        init_model = load_model(Path(init))
        config = init_model.config
    config = config or DiffusionConfig()
    train = train or TrainConfig()
    out = Path(out)
    ckpt_path = out / CHECKPOINT_FILE
    if ckpt_path.exists() and not resume:
        raise ValueError(
            f"{str(out)!r} already holds a training run ({CHECKPOINT_FILE}); pass --resume to "
            "continue it, or choose another --out"
        )
    torch.set_num_threads(1)
    demos = load_demonstrations(
        dataset,
        with_features=config.with_features,
        tip_axes=config.tip_axes,
        only_success=only_success,
        after_slide=first_model is not None,
        targets=config.actions == "targets",
        episode_seeds=episode_seeds,
    )
    seed_list = None if episode_seeds is None else sorted(episode_seeds)
    if init_model is None:
        config = replace(config, hand=hand_kind(demos.labels))
    sampler = ChunkSampler(demos, config.obs_horizon, config.pred_horizon, config.actions)
    torch.manual_seed(train.seed)
    model = DiffusionModel(config, demos.inputs.shape[1], demos.labels.shape[1])
    if init_model is not None:
        if (init_model.input_dim, init_model.action_dim) != (model.input_dim, model.action_dim):
            raise ValueError(
                f"init {str(init)!r} has inputs/actions {init_model.input_dim}/"
                f"{init_model.action_dim}, the dataset {model.input_dim}/{model.action_dim}"
            )
        model.load_state_dict(init_model.state_dict())
    else:
        stats = (*demos.input_stats(), *sampler.chunk_stats())
        model.set_stats(*(torch.from_numpy(a) for a in stats))
    model.to(device)
    ema = EMA(model)
    optimizer = torch.optim.AdamW(
        model.parameters(), lr=train.learning_rate, weight_decay=train.weight_decay
    )
    schedule = torch.optim.lr_scheduler.LambdaLR(
        optimizer, lambda s: _lr_factor(s, train.warmup, train.iterations)
    )
    rng = np.random.default_rng(train.seed)
    noise = torch.Generator().manual_seed(train.seed)
    start, train_time, best = 0, 0.0, -1.0
    if resume and ckpt_path.exists():
        blob = torch.load(ckpt_path, map_location=device, weights_only=False)
        saved = (blob["config"], blob["train"], blob.get("only_success", True), blob.get("first"))
        saved += (blob.get("episode_seeds"),)
        first_key = None if first is None else str(first)
        if saved != (config.to_json(), _train_json(train), only_success, first_key, seed_list):
            raise ValueError(
                f"{str(out)!r} was trained with another configuration ({saved}); resume with "
                "the same options, or choose another --out"
            )
        model.load_state_dict(blob["model"])
        ema.load_state_dict(blob["ema"])
        optimizer.load_state_dict(blob["optimizer"])
        schedule.load_state_dict(blob["schedule"])
        rng.bit_generator.state = blob["rng"]
        noise.set_state(blob["noise"])
        start, train_time, best = blob["iteration"], blob["train_time_s"], blob["best"]
        _truncate_progress(out / PROGRESS_FILE, start)
    out.mkdir(parents=True, exist_ok=True)
    summary: dict[str, Any] = {
        **(card or {}),
        "env_id": env_id,
        "env_kwargs": dict(env_kwargs),
        "config": config.to_json(),
        "training": _train_json(train),
        "demonstrations": {
            "episodes": demos.episodes,
            "frames": demos.frames,
            "windows": len(sampler),
            "dropped_windows": sampler.dropped,
            "skipped_episodes": demos.skipped,
            "only_success": bool(only_success),
            "seeds": [min(demos.seeds), max(demos.seeds)],
            "after_slide": first_model is not None,
            **({"episode_seeds": len(seed_list)} if seed_list is not None else {}),
        },
        "parameters": sum(p.numel() for p in model.parameters()),
        "device": device,
    }

    def checkpoint(iteration: int) -> None:
        blob = {
            "config": config.to_json(),
            "train": _train_json(train),
            "only_success": bool(only_success),
            "first": None if first is None else str(first),
            "episode_seeds": seed_list,
            "input_dim": model.input_dim,
            "action_dim": model.action_dim,
            "model": model.state_dict(),
            "ema": ema.state_dict(),
            "optimizer": optimizer.state_dict(),
            "schedule": schedule.state_dict(),
            "rng": rng.bit_generator.state,
            "noise": noise.get_state(),
            "iteration": iteration,
            "train_time_s": train_time,
            "best": best,
        }
        tmp = ckpt_path.with_suffix(".tmp")
        torch.save(blob, tmp)
        tmp.replace(ckpt_path)

    def choose(iteration: int, val: dict[str, Any] | None) -> None:
        nonlocal best
        rate = -1.0 if val is None else float(val["success_rate"])
        if rate >= best or not (out / "policy.pt").exists():
            best = max(best, rate)
            chosen = {"iteration": iteration, "train_time_s": round(train_time, 1)}
            if val is not None:
                chosen |= {k: val[k] for k in ("success_rate", "ci95", "episodes", "seeds")}
                chosen["seeds"] = [val["seeds"][0], val["seeds"][-1]]
            save_policy(_on_cpu(ema.model), out, {**summary, "checkpoint": chosen}, first_model)

    def snapshot(iteration: int) -> None:
        chosen = {"iteration": iteration, "train_time_s": round(train_time, 1)}
        folder = out / SNAPSHOT_DIR / str(iteration)
        save_policy(_on_cpu(ema.model), folder, {**summary, "checkpoint": chosen}, first_model)

    bar = _progress_bar(train.iterations, start, progress)
    losses: list[float] = []
    model.train()
    iteration = start
    interrupted = _InterruptFlag()
    try:
        while iteration < train.iterations and not interrupted:
            tick = time.perf_counter()
            obs, actions = sampler.batch(rng, train.batch_size)
            loss = model.loss(
                torch.from_numpy(obs).to(device), torch.from_numpy(actions).to(device), noise
            )
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            schedule.step()
            ema.update(model)
            iteration += 1
            train_time += time.perf_counter() - tick
            losses.append(float(loss.detach()))
            bar.update(1)
            if iteration % train.log_every == 0 or iteration == train.iterations:
                last = iteration == train.iterations
                validate = train.val_episodes > 0 and (
                    last or (train.val_every and iteration % train.val_every == 0)
                )
                val = (
                    _validate(_on_cpu(ema.model), env_id, env_kwargs, train, first_model)
                    if validate
                    else None
                )
                row = _progress_row(iteration, losses, schedule, train_time, val)
                bar.set_postfix(loss=f"{row['loss']:.4f}", val=row["val_success_rate"])
                _append_progress(out / PROGRESS_FILE, row)
                losses = []
                if validate or last:
                    choose(iteration, val)
                if snapshot_every and (iteration % snapshot_every == 0 or last):
                    snapshot(iteration)
                checkpoint(iteration)
    finally:
        interrupted.restore()
        bar.close()
    if interrupted:
        checkpoint(iteration)
        if snapshot_every and iteration > start:
            snapshot(iteration)
        print(f"\ninterrupted: checkpoint at iteration {iteration} saved", file=sys.stderr)
        raise KeyboardInterrupt
    plot_learning_curve(out / PROGRESS_FILE, out / CURVE_FILE)
    return json.loads((out / "policy.json").read_text())


def choose_snapshot(
    out: Path, *, episodes: int = 20, seed: int = VALIDATION_SEED, progress: bool = False
) -> dict[str, Any]:
    """Validate every snapshot of the run in ``out`` (``snapshots/ITERATION``, written with
    ``snapshot_every``) on ``episodes`` episodes from reset seed ``seed``, record each in
    ``progress.csv`` (and the learning curve), and make the best one ``out``'s policy (the
    later one on a tie, as during training); return its card. A snapshot already validated
    with these episodes is not run again, so an interrupted choice resumes."""
    from agents.evaluate import evaluate

    out = Path(out)
    folders = sorted(
        (p for p in (out / SNAPSHOT_DIR).glob("*") if p.name.isdigit() and is_policy_dir(p)),
        key=lambda p: int(p.name),
    )
    if not folders:
        raise ValueError(
            f"{str(out)!r} holds no snapshots ({SNAPSHOT_DIR}/ITERATION/{WEIGHTS_FILE}); train "
            "with --snapshot-every N"
        )
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes must be a positive integer, got {episodes!r}")
    rows = {int(r["iteration"]): r for r in read_progress(out / PROGRESS_FILE)}
    best: tuple[float, int] | None = None
    for folder in folders:
        iteration = int(folder.name)
        row = rows.setdefault(
            iteration, {k: "" for k in PROGRESS_FIELDS} | {"iteration": iteration}
        )
        if str(row.get("val_episodes", "")) != str(episodes):
            policy = DiffusionPolicy.load(folder, seed=_card_seed(folder))
            val = evaluate(
                policy,
                policy.card["env_id"],
                episodes=episodes,
                seed=seed,
                env_kwargs=policy.card.get("env_kwargs"),
                progress=progress,
            )
            row |= _val_fields(val)
            _write_progress(out / PROGRESS_FILE, rows)
        rate = float(row["val_success_rate"])
        if best is None or rate >= best[0]:
            best = (rate, iteration)
    assert best is not None
    rate, iteration = best
    folder = out / SNAPSHOT_DIR / str(iteration)
    row = rows[iteration]
    card = json.loads((folder / CARD_FILE).read_text())
    low, high = float(row["val_ci_low"]), float(row["val_ci_high"])
    card["checkpoint"] |= {
        "success_rate": rate,
        "ci95": [low, high],
        "episodes": int(row["val_episodes"]),
        "seeds": [seed, seed + int(row["val_episodes"]) - 1],
    }
    for name in (WEIGHTS_FILE, FIRST_FILE):
        if (folder / name).is_file():
            shutil.copyfile(folder / name, out / name)
    (out / CARD_FILE).write_text(json.dumps(card, indent=2) + "\n")
    plot_learning_curve(out / PROGRESS_FILE, out / CURVE_FILE)
    return card


def _card_seed(folder: Path) -> int:
    card = json.loads((folder / CARD_FILE).read_text())
    return int(card.get("training", {}).get("seed", 0))


def _write_progress(path: Path, rows: dict[int, dict[str, Any]]) -> None:
    tmp = path.with_suffix(".tmp")
    with tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, PROGRESS_FIELDS, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows[k] for k in sorted(rows))
    tmp.replace(path)


class _InterruptFlag:
    """Ctrl-C (SIGINT) sets this flag instead of raising, so the iteration in progress
    finishes and the checkpoint is exact; a second Ctrl-C raises at once. Only in the main
    thread (elsewhere signals cannot be caught and the flag stays unset)."""

    def __init__(self) -> None:
        self.set = False
        self._previous: Any = None
        if threading.current_thread() is threading.main_thread():
            self._previous = signal.signal(signal.SIGINT, self._handle)

    def _handle(self, signum: int, frame: Any) -> None:
        if self.set:
            raise KeyboardInterrupt
        self.set = True

    def __bool__(self) -> bool:
        return self.set

    def restore(self) -> None:
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None


def check_device(device: str) -> str:
    """``device`` if torch can train there: ``"cpu"``, or ``"cuda"`` where a GPU is visible."""
    if device not in DEVICES:
        raise ValueError(f"device must be one of {', '.join(DEVICES)}, got {device!r}")
    if device == "cuda" and not torch.cuda.is_available():
        raise ValueError(
            "device 'cuda': torch sees no GPU here (torch.cuda.is_available() is False); "
            "train with device 'cpu'"
        )
    return device


def _on_cpu(model: DiffusionModel) -> DiffusionModel:
    """``model`` itself if it is on the CPU, else a CPU copy (what policies are saved as)."""
    if next(model.parameters()).device.type == "cpu":
        return model
    return copy.deepcopy(model).cpu()


def _train_json(train: TrainConfig) -> dict[str, Any]:
    return asdict(train)


def _validate(
    model: DiffusionModel,
    env_id: str,
    env_kwargs: dict[str, Any],
    train: TrainConfig,
    first: DiffusionModel | None = None,
) -> dict[str, Any]:
    from agents.evaluate import evaluate

    model.eval()
    policy = DiffusionPolicy(model, seed=train.seed, first=first)
    return evaluate(
        policy, env_id, episodes=train.val_episodes, seed=train.val_seed, env_kwargs=env_kwargs
    )


def _progress_row(
    iteration: int, losses: list[float], schedule: Any, train_time: float, val: Any
) -> dict[str, Any]:
    row: dict[str, Any] = {
        "iteration": iteration,
        "loss": float(np.mean(losses)) if losses else math.nan,
        "lr": schedule.get_last_lr()[0],
        "train_time_s": round(train_time, 2),
    }
    if val is not None:
        row |= _val_fields(val)
    return {k: row.get(k, "") for k in PROGRESS_FIELDS}


def _val_fields(val: dict[str, Any]) -> dict[str, Any]:
    """The progress columns of a validation result."""
    return {
        "val_success_rate": val["success_rate"],
        "val_ci_low": val["ci95"][0],
        "val_ci_high": val["ci95"][1],
        "val_episodes": val["episodes"],
        "val_mean_length": val["mean_length"],
    }


def _append_progress(path: Path, row: dict[str, Any]) -> None:
    new = not path.exists()
    with path.open("a", newline="") as f:
        writer = csv.DictWriter(f, PROGRESS_FIELDS)
        if new:
            writer.writeheader()
        writer.writerow(row)


def read_progress(path: Path) -> list[dict[str, str]]:
    """The rows of a ``progress.csv`` ([] if there is none)."""
    if not path.exists():
        return []
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def _truncate_progress(path: Path, iteration: int) -> None:
    """Drop rows written after the checkpoint a resumed run continues from."""
    rows = [r for r in read_progress(path) if int(r["iteration"]) <= iteration]
    tmp = path.with_suffix(".tmp")
    with tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, PROGRESS_FIELDS)
        writer.writeheader()
        writer.writerows(rows)
    tmp.replace(path)


def plot_learning_curve(progress: Path, out: Path) -> Path | None:
    """Loss (log scale) and validation success (with Wilson bands) against iterations."""
    rows = read_progress(progress)
    if not rows:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    it = np.array([int(r["iteration"]) for r in rows])
    loss = np.array([float(r["loss"]) for r in rows])
    val = [r for r in rows if r["val_success_rate"] != ""]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 3.4))
    ax1.plot(it, loss)
    ax1.set_yscale("log")
    ax1.set_xlabel("iteration")
    ax1.set_ylabel("noise-prediction loss")
    if val:
        vi = np.array([int(r["iteration"]) for r in val])
        rate = np.array([float(r["val_success_rate"]) for r in val])
        lo = np.array([float(r["val_ci_low"]) for r in val])
        hi = np.array([float(r["val_ci_high"]) for r in val])
        ax2.plot(vi, 100 * rate, marker="o")
        ax2.fill_between(vi, 100 * lo, 100 * hi, alpha=0.25)
    ax2.set_ylim(0, 100)
    ax2.set_xlabel("iteration")
    ax2.set_ylabel("validation success (%)")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def _progress_bar(total: int, start: int, enabled: bool) -> Any:
    from tqdm import tqdm

    return tqdm(total=total, initial=start, desc="train-dp", disable=not enabled, file=sys.stderr)
