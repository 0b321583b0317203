"""Learning from the expert's demonstrations: the rows of the documentation's "Learning" table.

Each row collects its dataset (``slide-gym collect``, resumable), trains its policy
(``slide-gym train-dp`` / ``train-bc`` / ``dagger``, resumable) into ``MODELS/ROW``, and
evaluates it on 100 test episodes (reset seeds from 10000; a diffusion policy's checkpoint
was chosen on validation seeds from 20000). Rows are appended to ``OUT/rows.jsonl`` as they
finish (with the code version, the demonstrations, the training time on one core and the
command); ``report`` writes ``OUT/learning.md`` and ``OUT/learning_curves.png`` from them.

    OMP_NUM_THREADS=1 python benchmarks/learning.py list
    OMP_NUM_THREADS=1 python benchmarks/learning.py run dp-square-slide --models models
    OMP_NUM_THREADS=1 python benchmarks/learning.py report
    OMP_NUM_THREADS=1 python benchmarks/learning.py fit models/dp-square-slide \
        --dataset slide-gym/square-slide-v1

Datasets live in Minari's folder (``MINARI_DATASETS_PATH``). One row's training takes up to
an hour on one core; run rows side by side on separate cores.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")

from slide_gym.splits import TEST_SEED  # noqa: E402 - after the thread setting

SLIDE, GRASP = "SlideGym/TopSlide-v0", "SlideGym/TopSlideGrasp-v0"
SQUARE = {"object": "square", "table": "square"}
CATALOG = {"object": "random", "table": "random"}
PROCEDURAL = {"object": "procedural", "table": "random"}
"""Generated plates: the plate of each reset seed, so the test seeds' plates are unseen."""
EE = {"control_mode": "ee_delta"}
"""Fingertip-pose increments instead of joint increments (the env's ``control_mode``)."""
ANCHOR = {"physics": {"friction_anchor": True}}
"""PyBullet's friction anchors on the robot's links (the env's ``physics``): demonstrations
collected, policies validated and tested in that physics."""
EPISODES = 100
OUT = Path("docs/results/learning")


@dataclass(frozen=True)
class Row:
    """One line of the table: a method trained on one dataset, tested in one scene."""

    name: str
    method: str  # "random", "expert", "bc", "dp", "dp-dart", "dp-dagger"
    env_id: str
    scene: dict[str, Any]
    dataset: str | None = None  # the Minari id
    collect: dict[str, Any] = field(default_factory=dict)  # CollectConfig fields, episodes
    train: list[str] = field(default_factory=list)  # extra train-dp / dagger arguments
    base: str | None = None  # dagger: the row whose policy it starts from; dp: whose it tests
    action_horizon: int | None = None  # actions executed per chunk (None: the policy's)
    samples: int | None = None  # chunks drawn per decision, the medoid executed (None: 1)


SQUARE_SLIDE = {"episodes": 200, "only_success": True}


VAL10 = ["--val-episodes", "10"]


def _grasp_skill_row(suffix: str, version: str, train: list[str]) -> Row:
    """A grasping skill trained on square-grasp demonstrations ``version`` after the wide
    sliding policy (``train-dp --after``)."""
    return Row(
        f"dp-ee-square-grasp-after-slide{suffix}",
        "dp",
        GRASP,
        {**SQUARE, **EE},
        f"slide-gym/square-grasp-ee-{version}",
        SQUARE_SLIDE,
        ["--after", "{models}/dp-ee-square-slide-wide", *train],
    )


HORIZON_ROWS = {"dp-ee-square-slide-10k": 2, "dp-ee-catalog-slide": 2}
"""Rows whose trained policy is also tested at another action horizon (chosen on validation
seeds with ``horizon``): row ``NAME-hK``."""


def _ee_square_dagger(
    name: str, version: int, episodes: int, base: str, workers: int = 1, extra: tuple = ()
) -> Row:
    """One DAgger round of ``episodes`` rollouts on the square slide in fingertip steps, from
    row ``base``'s policy, into dataset ``square-slide-ee-dagger-v{version}`` (``extra``:
    further ``dagger`` arguments)."""
    return Row(
        name,
        "dp-dagger",
        SLIDE,
        {**SQUARE, **EE},
        f"slide-gym/square-slide-ee-dagger-v{version}",
        {},
        ["--rounds", "1", "--episodes", str(episodes), "--workers", str(workers), *extra],
        base=base,
    )


STOP_DAGGER = ["--beta", "0"]
"""DAgger on the square slide that stops at 3.5 cm: the learner executes every chunk."""


def _stop_dagger(
    name: str,
    dataset: str,
    extra: tuple = (),
    rounds: int = 1,
    base: str = "dp-ee-square-slide-stop",
    physics: dict[str, Any] | None = None,
    env_id: str = SLIDE,
    workers: int = 1,
    max_steps: int = 600,
) -> Row:
    """DAgger rounds (100 rollouts each) from ``base`` into ``dataset``; ``physics``: the
    base's scene physics (e.g. :data:`ANCHOR`), which its dataset's rollouts run in too.
    Rollouts are cut at ``max_steps`` (the square slide's 200 demonstrations take 111-429
    steps, median 236; the square grasp's 503 on average)."""
    return Row(
        name,
        "dp-dagger",
        env_id,
        {**SQUARE, **EE, **(physics or {})},
        f"slide-gym/{dataset}",
        {},
        ["--rounds", str(rounds), "--episodes", "100", "--workers", str(workers)]
        + [*STOP_DAGGER, "--max-steps", str(max_steps), *extra],
        base=base,
    )


def _ee_square_seeds(
    name: str,
    train: list[str],
    dataset: str = "slide-gym/square-slide-ee-v1",
    collect: dict[str, Any] | None = None,
    physics: dict[str, Any] | None = None,
) -> list[Row]:
    """Diffusion-policy rows on the square slide demonstrations in fingertip steps
    (``dataset``, collected with ``collect``), trained with ``train`` at training seeds 0
    (row ``name``), 1 and 2 (``name-seed1``, ``-seed2``; a :data:`SEED_GROUPS` entry);
    ``physics``: the scene's physics settings (e.g. :data:`ANCHOR`), if any."""
    return [
        Row(
            name + (f"-seed{s}" if s else ""),
            "dp",
            SLIDE,
            {**SQUARE, **EE, **(physics or {})},
            dataset,
            collect or SQUARE_SLIDE,
            train + (["--seed", str(s)] if s else []),
        )
        for s in (0, 1, 2)
    ]


GPU_B256 = ["--device", "cuda", "--batch-size", "256", "--iterations", "6000"]
GPU_B256 += ["--snapshot-every", "6000", "--val-episodes", "0"]
"""Trained on a GPU (an H200 lent for a few minutes, six runs side by side): batches of 256,
as many iterations as fitted; no simulator there, so ``run`` validates the snapshot here."""
CPU_B256 = ["--batch-size", "256", "--val-every", "5000"]
"""Batches of 256 on one core (0.22 s per iteration on an AMD EPYC core with the other core
training too: 10000 iterations in 37-39 minutes, 20000 in 79), validated every 5000."""
NEAR_POSTURE_SEEDS = (
    "docs/results/learning/near-posture-seeds-square-grasp-ee-stop-anchor-nearest-v1.json"
)
"""The seeds of the nearest-side square grasps whose grasp lies within 1 rad of the expert's
grasp posture (`python benchmarks/grasp_branches.py
slide-gym/square-grasp-ee-stop-anchor-nearest-v1 --near-posture 1.0 --write-seeds FILE`); the
other 48 grasp on far IK branches, after transfers that rise a median 0.20 m (0.11 m)."""
ANCHOR_SEEDS = [("", []), ("-seed1", ["--seed", "1"]), ("-seed2", ["--seed", "2"])]
"""The anchored batch-256 bases' training seeds (row suffix, ``train-dp`` options); their
DAgger rows and controls train at the base's seed."""
GRASP_DEMO_EXPERT = {
    "press_speed": 0.02,
    "press_hold_s": 0.3,
    "slide_speed": 0.05,
    "settle_s": 0.3,
    "grasp_speed": 0.04,
    "close_s": 0.8,
    "lift_speed": 0.05,
    "slide_settle_s": 0.3,
    "stop_overhang": 0.035,
}
"""The expert settings that collected ``square-grasp-ee-stop-anchor-v1`` (its speeds and holds
from before the quicker defaults of ``acbcfdf`` and ``dd3943b``, and the stop), as
``CollectConfig.from_metadata`` reads them from that dataset; written out so that the row's
command names them and a fresh machine needs no copy of that dataset. A larger collection
with them changes only the number of demonstrations. ``square-slide-ee-stop-anchor-v1`` was
collected with the same settings."""
OFFSETS = ["--actions", "offsets"]
"""The chunks of the rows trained before per-step deltas became the default."""
ROWS = {
    r.name: r
    for r in [
        Row("random-square-slide", "random", SLIDE, SQUARE),
        Row("expert-square-slide", "expert", SLIDE, SQUARE),
        Row("bc-square-slide", "bc", SLIDE, SQUARE, "slide-gym/square-slide-v1", SQUARE_SLIDE),
        Row(
            "dp-square-slide",
            "dp",
            SLIDE,
            SQUARE,
            "slide-gym/square-slide-v1",
            SQUARE_SLIDE,
            OFFSETS,
        ),
        *(
            Row(
                f"dp-square-slide-seed{s}",
                "dp",
                SLIDE,
                SQUARE,
                "slide-gym/square-slide-v1",
                SQUARE_SLIDE,
                [*OFFSETS, "--seed", str(s)],
            )
            for s in (1, 2)
        ),
        Row(
            "dp-square-slide-nofeat",
            "dp",
            SLIDE,
            SQUARE,
            "slide-gym/square-slide-v1",
            SQUARE_SLIDE,
            [*OFFSETS, "--no-features"],
        ),
        Row(
            "dp-dart-square-slide",
            "dp-dart",
            SLIDE,
            SQUARE,
            "slide-gym/square-slide-dart-v1",
            {**SQUARE_SLIDE, "action_noise": 0.05},
            OFFSETS,
        ),
        Row(
            "dp-dagger-square-slide",
            "dp-dagger",
            SLIDE,
            SQUARE,
            "slide-gym/square-slide-dagger-v1",
            {},
            ["--rounds", "1", "--episodes", "40"],
            base="dp-square-slide",
        ),
        Row("expert-square-grasp", "expert", GRASP, SQUARE),
        Row("bc-square-grasp", "bc", GRASP, SQUARE, "slide-gym/square-grasp-v1", SQUARE_SLIDE),
        Row(
            "dp-square-grasp",
            "dp",
            GRASP,
            SQUARE,
            "slide-gym/square-grasp-v1",
            SQUARE_SLIDE,
            OFFSETS,
        ),
        Row(
            "dp-square-slide-10k",
            "dp",
            SLIDE,
            SQUARE,
            "slide-gym/square-slide-v1",
            SQUARE_SLIDE,
            ["--iterations", "10000"],
        ),
        Row(
            "dp-square-grasp-10k",
            "dp",
            GRASP,
            SQUARE,
            "slide-gym/square-grasp-v1",
            SQUARE_SLIDE,
            ["--iterations", "10000", "--val-every", "2500", *VAL10],
        ),
        Row(
            "dp-square-grasp-after-slide",
            "dp",
            GRASP,
            SQUARE,
            "slide-gym/square-grasp-v1",
            SQUARE_SLIDE,
            [
                "--after",
                "{models}/dp-square-slide-10k",
                *["--iterations", "10000", "--val-every", "2500", *VAL10],
            ],
        ),
        Row(
            "dp-square-grasp-v2-10k",
            "dp",
            GRASP,
            SQUARE,
            "slide-gym/square-grasp-v2",
            SQUARE_SLIDE,
            ["--iterations", "10000", "--val-every", "2500", *VAL10],
        ),
        Row(
            "dp-square-grasp-v2-after-slide",
            "dp",
            GRASP,
            SQUARE,
            "slide-gym/square-grasp-v2",
            SQUARE_SLIDE,
            [
                "--after",
                "{models}/dp-square-slide-10k",
                *["--iterations", "10000", "--val-every", "2500", *VAL10],
            ],
        ),
        Row(
            "dp-dagger-square-grasp-after-slide",
            "dp-dagger",
            GRASP,
            SQUARE,
            "slide-gym/square-grasp-dagger-v1",
            {},
            ["--rounds", "1", "--episodes", "40", "--workers", "2"],
            base="dp-square-grasp-after-slide",
        ),
        Row(
            "dp-dagger-square-grasp-v2-after-slide",
            "dp-dagger",
            GRASP,
            SQUARE,
            "slide-gym/square-grasp-dagger-v2",
            {},
            ["--rounds", "1", "--episodes", "20", "--workers", "2", "--max-steps", "700"],
            base="dp-square-grasp-v2-after-slide",
        ),
        Row("expert-catalog-slide", "expert", SLIDE, CATALOG),
        Row(
            "dp-catalog-slide",
            "dp",
            SLIDE,
            CATALOG,
            "slide-gym/catalog-slide-v1",
            {"episodes": 400, "only_success": True},
            OFFSETS,
        ),
        Row("expert-catalog-grasp", "expert", GRASP, CATALOG),
        Row(
            "dp-catalog-grasp",
            "dp",
            GRASP,
            CATALOG,
            "slide-gym/catalog-grasp-v1",
            SQUARE_SLIDE,
            ["--iterations", "10000", "--val-every", "2500", *VAL10],
        ),
        Row("expert-procedural-grasp", "expert", GRASP, PROCEDURAL),
        Row(
            "dp-catalog-grasp-procedural",
            "dp",
            GRASP,
            PROCEDURAL,
            "slide-gym/catalog-grasp-v1",
            base="dp-catalog-grasp",
        ),
        Row("expert-ee-square-slide", "expert", SLIDE, {**SQUARE, **EE}),
        Row(
            "bc-ee-square-slide",
            "bc",
            SLIDE,
            {**SQUARE, **EE},
            "slide-gym/square-slide-ee-v1",
            SQUARE_SLIDE,
        ),
        Row(
            "dp-ee-square-slide",
            "dp",
            SLIDE,
            {**SQUARE, **EE},
            "slide-gym/square-slide-ee-v1",
            SQUARE_SLIDE,
            OFFSETS,
        ),
        Row(
            "dp-ee-square-slide-deltas",
            "dp",
            SLIDE,
            {**SQUARE, **EE},
            "slide-gym/square-slide-ee-v1",
            SQUARE_SLIDE,
            ["--actions", "deltas", "--scaling", "standard"],
        ),
        Row(
            "dp-ee-square-slide-deltas-nofeat",
            "dp",
            SLIDE,
            {**SQUARE, **EE},
            "slide-gym/square-slide-ee-v1",
            SQUARE_SLIDE,
            ["--actions", "deltas", "--scaling", "standard", "--iterations", "10000"]
            + ["--no-features"],
        ),
        Row(
            "dp-dart-ee-square-slide",
            "dp-dart",
            SLIDE,
            {**SQUARE, **EE},
            "slide-gym/square-slide-ee-dart-v1",
            {**SQUARE_SLIDE, "action_noise": 0.1},
            ["--actions", "deltas", "--scaling", "standard", "--iterations", "10000"],
        ),
        Row("expert-ee-catalog-slide", "expert", SLIDE, {**CATALOG, **EE}),
        Row(
            "dp-ee-catalog-slide",
            "dp",
            SLIDE,
            {**CATALOG, **EE},
            "slide-gym/catalog-slide-ee-v1",
            {"episodes": 400, "only_success": True},
            ["--actions", "deltas", "--scaling", "standard", "--iterations", "10000"],
        ),
        Row(
            "dp-ee-catalog-slide-stop",
            "dp",
            SLIDE,
            {**CATALOG, **EE},
            "slide-gym/catalog-slide-ee-stop-v1",
            {"episodes": 400, "only_success": True, "expert_params": {"stop_overhang": 0.035}},
            ["--iterations", "10000"],
        ),
        Row(
            "dp-ee-square-slide-nofeat",
            "dp",
            SLIDE,
            {**SQUARE, **EE},
            "slide-gym/square-slide-ee-v1",
            SQUARE_SLIDE,
            [*OFFSETS, "--no-features"],
        ),
        _ee_square_dagger("dp-dagger-ee-square-slide", 1, 16, "dp-ee-square-slide", workers=2),
        *_ee_square_seeds("dp-ee-square-slide-10k", ["--iterations", "10000"]),
        *_ee_square_seeds(
            "dp-ee-square-slide-wide", ["--channels", "64", "128", "256", "--iterations", "10000"]
        ),
        Row(
            "dp-ee-square-slide-1000",
            "dp",
            SLIDE,
            {**SQUARE, **EE},
            "slide-gym/square-slide-ee-1000-v1",
            {"episodes": 1000, "only_success": True},
        ),
        Row(
            "dp-ee-square-slide-u3",
            "dp",
            SLIDE,
            {**SQUARE, **EE},
            "slide-gym/square-slide-ee-u3-v1",
            {**SQUARE_SLIDE, "planner_params": {"u_star": 0.03}},
            ["--iterations", "8000", "--val-every", "4000"],
        ),
        *_ee_square_seeds(
            "dp-ee-square-slide-stop",
            ["--iterations", "10000"],
            "slide-gym/square-slide-ee-stop-v1",
            {**SQUARE_SLIDE, "expert_params": {"stop_overhang": 0.035}},
        ),
        *_ee_square_seeds(
            "dp-ee-square-slide-stop-b256",
            GPU_B256,
            "slide-gym/square-slide-ee-stop-v1",
            {**SQUARE_SLIDE, "expert_params": {"stop_overhang": 0.035}},
        ),
        Row(
            "dp-ee-square-slide-b256",
            "dp",
            SLIDE,
            {**SQUARE, **EE},
            "slide-gym/square-slide-ee-v1",
            SQUARE_SLIDE,
            GPU_B256,
        ),
        *(
            Row(
                "dp-ee-catalog-slide-stop-b256" + (f"-seed{s}" if s else ""),
                "dp",
                SLIDE,
                {**CATALOG, **EE},
                "slide-gym/catalog-slide-ee-stop-v1",
                {"episodes": 400, "only_success": True, "expert_params": {"stop_overhang": 0.035}},
                GPU_B256 + (["--seed", str(s)] if s else []),
            )
            for s in (0, 1)
        ),
        *(
            Row(
                f"dp-ee-catalog-slide-stop-b256{suffix}-ft",
                "dp",
                SLIDE,
                {**CATALOG, **EE},
                "slide-gym/catalog-slide-ee-stop-v1",
                {"episodes": 400, "only_success": True, "expert_params": {"stop_overhang": 0.035}},
                ["--init", f"{{models}}/dp-ee-catalog-slide-stop-b256{suffix}"]
                + ["--batch-size", "256", "--iterations", "3000", "--val-every", "0", *seed],
            )
            for suffix, seed in (("", []), ("-seed1", ["--seed", "1"]))
        ),
        *_ee_square_seeds(
            "dp-ee-square-slide-stop-b256-10k",
            [*CPU_B256, "--iterations", "10000"],
            "slide-gym/square-slide-ee-stop-v1",
            {**SQUARE_SLIDE, "expert_params": {"stop_overhang": 0.035}},
        ),
        Row("expert-ee-square-slide-anchor", "expert", SLIDE, {**SQUARE, **EE, **ANCHOR}),
        *_ee_square_seeds(
            "dp-ee-square-slide-stop-anchor-b256-10k",
            [*CPU_B256, "--iterations", "10000"],
            "slide-gym/square-slide-ee-stop-anchor-v1",
            {**SQUARE_SLIDE, "expert_params": {"stop_overhang": 0.035}},
            ANCHOR,
        ),
        *(
            Row(
                "dp-ee-catalog-slide-stop-b256-20k" + suffix,
                "dp",
                SLIDE,
                {**CATALOG, **EE},
                "slide-gym/catalog-slide-ee-stop-v1",
                {"episodes": 400, "only_success": True, "expert_params": {"stop_overhang": 0.035}},
                [*CPU_B256, "--iterations", "20000", *seed],
            )
            for suffix, seed in (("", []), ("-seed1", ["--seed", "1"]))
        ),
        Row(
            "dp-ee-square-grasp-stop-anchor-b256-5k",
            "dp",
            GRASP,
            {**SQUARE, **EE, **ANCHOR},
            "slide-gym/square-grasp-ee-stop-anchor-v1",
            {**SQUARE_SLIDE, "expert_params": {"stop_overhang": 0.035}},
            ["--batch-size", "256", "--iterations", "5000", *VAL10],
        ),
        *(
            Row(  # the anchored square grasp, fine-tuned 5000 iterations at a time
                f"dp-ee-square-grasp-stop-anchor-b256-5k-{suffix}",
                "dp",
                GRASP,
                {**SQUARE, **EE, **ANCHOR},
                "slide-gym/square-grasp-ee-stop-anchor-v1",
                {**SQUARE_SLIDE, "expert_params": {"stop_overhang": 0.035}},
                ["--init", f"{{models}}/dp-ee-square-grasp-stop-anchor-b256-5k{base}"]
                + ["--batch-size", "256", "--iterations", "5000", *VAL10],
            )
            for suffix, base in (
                ("ft", ""),
                ("ft2", "-ft"),
                ("ft3", "-ft2"),
                ("ft4", "-ft3"),
                ("ft5", "-ft4"),
            )
        ),
        Row(  # one 15000-iteration schedule, against the three 5000s of -5k-ft2
            "dp-ee-square-grasp-stop-anchor-b256-15k",
            "dp",
            GRASP,
            {**SQUARE, **EE, **ANCHOR},
            "slide-gym/square-grasp-ee-stop-anchor-v1",
            {**SQUARE_SLIDE, "expert_params": {"stop_overhang": 0.035}},
            [*CPU_B256, "--iterations", "15000"],
        ),
        _stop_dagger(  # the past-stop gate on the 15k grasp: labels where the learner slid past
            # every demonstration's stop, i.e. all of its grasp, by the expert that collected
            # the demonstrations (its speeds and holds, from the dataset's metadata)
            "dp-dagger-past-stop-ee-square-grasp-stop-anchor-b256-15k",
            "square-grasp-ee-stop-anchor-dagger-past-stop-v1",
            ("--chunk-labels", "1", "--label-from-overhang", "0.035"),
            base="dp-ee-square-grasp-stop-anchor-b256-15k",
            physics=ANCHOR,
            env_id=GRASP,
            workers=2,
            max_steps=900,
        ),
        *(
            Row(  # five times the demonstrations of -15k, collected by the same expert
                "dp-ee-square-grasp-stop-anchor-1000-b256-15k" + suffix,
                "dp",
                GRASP,
                {**SQUARE, **EE, **ANCHOR},
                "slide-gym/square-grasp-ee-stop-anchor-1000-v1",
                {"episodes": 1000, "only_success": True, "expert_params": GRASP_DEMO_EXPERT},
                [*CPU_B256, "--iterations", "15000", *seed],
            )
            for suffix, seed in (("", []), ("-seed1", ["--seed", "1"]))
        ),
        *(
            Row(  # demonstrations that slide toward the side the plate lies on (not either)
                f"dp-ee-square-{task}-stop-anchor-nearest-b256-10k{suffix}",
                "dp",
                env_id,
                {**SQUARE, **EE, **ANCHOR},
                f"slide-gym/square-{task}-ee-stop-anchor-nearest-v1",
                {**SQUARE_SLIDE, "expert_params": {**GRASP_DEMO_EXPERT, "nearest_goal_edge": 1}},
                [*CPU_B256, "--iterations", "10000", *seed],
            )
            for task, env_id, suffix, seed in (
                ("grasp", GRASP, "", []),
                ("slide", SLIDE, "", []),
                ("slide", SLIDE, "-seed1", ["--seed", "1"]),
                ("slide", SLIDE, "-seed2", ["--seed", "2"]),
            )
        ),
        Row(  # the grasps of those on the grasp posture's IK branches only (152 of 200)
            "dp-ee-square-grasp-stop-anchor-nearest-near-posture-b256-10k",
            "dp",
            GRASP,
            {**SQUARE, **EE, **ANCHOR},
            "slide-gym/square-grasp-ee-stop-anchor-nearest-v1",
            {**SQUARE_SLIDE, "expert_params": {**GRASP_DEMO_EXPERT, "nearest_goal_edge": 1}},
            [*CPU_B256, "--iterations", "10000", "--episode-seeds", NEAR_POSTURE_SEEDS],
        ),
        *(
            Row(  # the nearest-side grasps with the hand moved along straight lines to them
                "dp-ee-square-grasp-stop-anchor-nearest-straight-b256-10k" + suffix,
                "dp",
                GRASP,
                {**SQUARE, **EE, **ANCHOR},
                "slide-gym/square-grasp-ee-stop-anchor-nearest-straight-v1",
                {
                    **SQUARE_SLIDE,
                    "expert_params": {
                        **GRASP_DEMO_EXPERT,
                        "nearest_goal_edge": 1,
                        "straight_transfer": 1,
                    },
                },
                [*CPU_B256, "--iterations", "10000", *seed],
            )
            for suffix, seed in ANCHOR_SEEDS
        ),
        Row(  # ... with DART in the free-space moves: noisy, and the expert's corrections
            "dp-dart-ee-square-grasp-stop-anchor-nearest-straight-b256-10k",
            "dp-dart",
            GRASP,
            {**SQUARE, **EE, **ANCHOR},
            "slide-gym/square-grasp-ee-stop-anchor-nearest-straight-dart-v1",
            {
                **SQUARE_SLIDE,
                "action_noise": 0.3,
                "noise_phases": ["approach", "transfer"],
                "expert_params": {
                    **GRASP_DEMO_EXPERT,
                    "nearest_goal_edge": 1,
                    "straight_transfer": 1,
                },
            },
            [*CPU_B256, "--iterations", "10000"],
        ),
        Row(  # ... with DART in the transfer only (the slide left clean), 5000 iterations
            "dp-dart-transfer-ee-square-grasp-stop-anchor-nearest-straight-b256-5k",
            "dp-dart",
            GRASP,
            {**SQUARE, **EE, **ANCHOR},
            "slide-gym/square-grasp-ee-stop-anchor-nearest-straight-dart-transfer-v1",
            {
                **SQUARE_SLIDE,
                "action_noise": 0.3,
                "noise_phases": ["transfer"],
                "expert_params": {
                    **GRASP_DEMO_EXPERT,
                    "nearest_goal_edge": 1,
                    "straight_transfer": 1,
                },
            },
            [*CPU_B256, "--iterations", "5000"],
        ),
        *(
            _stop_dagger(  # the past-stop gate on the straight-transfer grasp: its labels follow
                # the same one-mode straight transfer (the dataset's expert settings); "steps":
                # per-step labels re-timed to the learner, since chunk labels catch a lagging
                # learner up to the plan (18.6 % of them at the step limit, demonstrations 10 %)
                f"dp-dagger{kind}-past-stop-ee-square-grasp-stop-anchor-nearest-straight-b256-10k",
                f"square-grasp-ee-stop-anchor-nearest-straight-dagger{kind}-past-stop-v1",
                (*labels, "--label-from-overhang", "0.035"),
                base="dp-ee-square-grasp-stop-anchor-nearest-straight-b256-10k",
                physics=ANCHOR,
                env_id=GRASP,
                workers=2,
                max_steps=900,
            )
            for kind, labels in (("", ("--chunk-labels", "1")), ("-steps", ()))
        ),
        *(
            Row(  # ... and on random catalog scenes, against dp-ee-catalog-slide-stop-b256-10k;
                # -ft10k: 10000 more iterations from its weights (a fresh warm-up and decay)
                "dp-ee-catalog-slide-stop-nearest-b256-10k" + suffix,
                "dp",
                SLIDE,
                {**CATALOG, **EE},
                "slide-gym/catalog-slide-ee-stop-nearest-v1",
                {
                    "episodes": 400,
                    "only_success": True,
                    "expert_params": {**GRASP_DEMO_EXPERT, "nearest_goal_edge": 1},
                },
                init + [*CPU_B256, "--iterations", "10000"],
            )
            for suffix, init in (
                ("", []),
                ("-ft10k", ["--init", "{models}/dp-ee-catalog-slide-stop-nearest-b256-10k"]),
            )
        ),
        Row(
            "dp-ee-catalog-slide-stop-1000-b256-20k",
            "dp",
            SLIDE,
            {**CATALOG, **EE},
            "slide-gym/catalog-slide-ee-stop-1000-v1",
            {"episodes": 1000, "only_success": True, "expert_params": {"stop_overhang": 0.035}},
            [*CPU_B256, "--iterations", "20000"],
        ),
        Row(
            "dp-ee-square-slide-10k-ft",
            "dp",
            SLIDE,
            {**SQUARE, **EE},
            "slide-gym/square-slide-ee-v1",
            SQUARE_SLIDE,
            ["--init", "{models}/dp-ee-square-slide-10k"]
            + ["--iterations", "5000", "--val-every", "0"],
        ),
        _ee_square_dagger("dp-dagger2-ee-square-slide", 2, 20, "dp-ee-square-slide-10k"),
        _ee_square_dagger("dp-dagger3-ee-square-slide", 3, 20, "dp-ee-square-slide-10k"),
        _ee_square_dagger("dp-dagger4-ee-square-slide", 4, 100, "dp-ee-square-slide-10k"),
        _ee_square_dagger("dp-dagger5-ee-square-slide", 5, 100, "dp-ee-square-slide-10k"),
        _ee_square_dagger(
            "dp-dagger6-ee-square-slide",
            6,
            100,
            "dp-ee-square-slide-10k",
            extra=("--skip-phases", "release"),
        ),
        _stop_dagger(
            "dp-dagger-chunks-ee-square-slide-stop",
            "square-slide-ee-stop-dagger-chunks-v2",
            ("--chunk-labels", "4"),
        ),
        _stop_dagger("dp-dagger-steps-ee-square-slide-stop", "square-slide-ee-stop-dagger-v1"),
        _stop_dagger(  # the label expert slides a pressed plate straight on (agents.takeover)
            "dp-dagger-straight-ee-square-slide-stop",
            "square-slide-ee-stop-dagger-straight-v1",
            ("--chunk-labels", "4"),
        ),
        _stop_dagger(  # ... and tries that before a planned slide on
            "dp-dagger-straight-first-ee-square-slide-stop",
            "square-slide-ee-stop-dagger-straight-first-v1",
            ("--chunk-labels", "4", "--expert-param", "straight_slide_on=1"),
        ),
        _stop_dagger(  # ... and plans from a fingertip low beside the plate (raised only if needed)
            "dp-dagger-approach-ee-square-slide-stop",
            "square-slide-ee-stop-dagger-approach-v2",
            ("--chunk-labels", "4"),
        ),
        _stop_dagger(  # labels only past the demonstrations' stop, a chunk at every step
            "dp-dagger-past-stop-ee-square-slide-stop",
            "square-slide-ee-stop-dagger-past-stop-v1",
            ("--chunk-labels", "1", "--label-from-overhang", "0.035"),
        ),
        _stop_dagger(  # the same with another seed (learner noise, training)
            "dp-dagger-past-stop-ee-square-slide-stop-seed1",
            "square-slide-ee-stop-dagger-past-stop-seed1-v1",
            ("--chunk-labels", "1", "--label-from-overhang", "0.035", "--seed", "1"),
        ),
        _stop_dagger(
            "dp-dagger-past-stop-ee-square-slide-stop-seed2",
            "square-slide-ee-stop-dagger-past-stop-seed2-v1",
            ("--chunk-labels", "1", "--label-from-overhang", "0.035", "--seed", "2"),
        ),
        _stop_dagger(  # a second round: rollouts of the seed-1 round's policy, same gate
            "dp-dagger2-past-stop-ee-square-slide-stop-seed1",
            "square-slide-ee-stop-dagger2-past-stop-seed1-v1",
            ("--chunk-labels", "1", "--label-from-overhang", "0.035", "--seed", "1"),
            rounds=2,
        ),
        _stop_dagger(  # ... or from a fingertip that came down beside the plate
            "dp-dagger-off-demos-ee-square-slide-stop",
            "square-slide-ee-stop-dagger-off-demos-v1",
            ("--chunk-labels", "1", "--label-from-overhang", "0.035")
            + ("--label-from-miss", "0.015"),
        ),
        *(
            Row(  # the control of the anchored DAgger rows: as many iterations on the demos alone
                f"dp-ee-square-slide-stop-anchor-b256-10k{suffix}-ft",
                "dp",
                SLIDE,
                {**SQUARE, **EE, **ANCHOR},
                "slide-gym/square-slide-ee-stop-anchor-v1",
                {**SQUARE_SLIDE, "expert_params": {"stop_overhang": 0.035}},
                ["--init", f"{{models}}/dp-ee-square-slide-stop-anchor-b256-10k{suffix}"]
                + ["--batch-size", "256", "--iterations", "5000", "--val-every", "0", *seed],
            )
            for suffix, seed in ANCHOR_SEEDS
        ),
        *(
            _stop_dagger(  # the past-stop gate on each anchored batch-256 base (batch 256 too)
                f"dp-dagger-past-stop-ee-square-slide-stop-anchor-b256-10k{suffix}",
                f"square-slide-ee-stop-anchor-dagger-past-stop{suffix}-v1",
                ("--chunk-labels", "1", "--label-from-overhang", "0.035", *seed),
                base=f"dp-ee-square-slide-stop-anchor-b256-10k{suffix}",
                physics=ANCHOR,
            )
            for suffix, seed in ANCHOR_SEEDS
        ),
        Row(
            "dp-ee-catalog-slide-stop-b256-10k",
            "dp",
            SLIDE,
            {**CATALOG, **EE},
            "slide-gym/catalog-slide-ee-stop-v1",
            {"episodes": 400, "only_success": True, "expert_params": {"stop_overhang": 0.035}},
            [*CPU_B256, "--iterations", "10000"],
        ),
        Row(
            "dp-ee-square-slide-stop-ft",
            "dp",
            SLIDE,
            {**SQUARE, **EE},
            "slide-gym/square-slide-ee-stop-v1",
            {**SQUARE_SLIDE, "expert_params": {"stop_overhang": 0.035}},
            ["--init", "{models}/dp-ee-square-slide-stop", "--iterations", "5000"]
            + ["--val-every", "0"],
        ),
        Row("expert-ee-square-grasp", "expert", GRASP, {**SQUARE, **EE}),
        Row(
            "dp-ee-square-grasp-10k",
            "dp",
            GRASP,
            {**SQUARE, **EE},
            "slide-gym/square-grasp-ee-v1",
            SQUARE_SLIDE,
            ["--iterations", "10000", "--val-episodes", "10"],
        ),
        _grasp_skill_row("", "v1", ["--iterations", "5000", "--val-every", "2500", *VAL10]),
        _grasp_skill_row("-v2", "v2", ["--iterations", "10000", "--val-every", "2500", *VAL10]),
        _grasp_skill_row(
            "-axes", "v2", ["--tip-axes", "--iterations", "10000", "--val-every", "2500", *VAL10]
        ),
        _grasp_skill_row(
            "-v3", "v3", ["--tip-axes", "--iterations", "5000", "--val-every", "2500", *VAL10]
        ),
        _grasp_skill_row(
            "-offsets",
            "v3",
            ["--tip-axes", "--actions", "offsets", "--iterations", "5000", "--val-every", "0"],
        ),
        Row(
            "bc-ee-square-grasp",
            "bc",
            GRASP,
            {**SQUARE, **EE},
            "slide-gym/square-grasp-ee-v1",
            SQUARE_SLIDE,
        ),
        Row(
            "dp-ee-square-grasp",
            "dp",
            GRASP,
            {**SQUARE, **EE},
            "slide-gym/square-grasp-ee-v1",
            SQUARE_SLIDE,
            [*OFFSETS, "--iterations", "15000"],
        ),
        Row(
            "dp-ee-square-grasp-deltas",
            "dp",
            GRASP,
            {**SQUARE, **EE},
            "slide-gym/square-grasp-ee-v1",
            SQUARE_SLIDE,
            [
                "--actions",
                "deltas",
                "--scaling",
                "standard",
                "--iterations",
                "15000",
                "--val-episodes",
                "10",
            ],
        ),
    ]
}


ROWS.update(
    {
        f"{name}-h{k}": replace(ROWS[name], name=f"{name}-h{k}", base=name, action_horizon=k)
        for name, k in HORIZON_ROWS.items()
    }
)
SEED_GROUPS = {
    name: [name, f"{name}-seed1", f"{name}-seed2"]
    for name in ROWS
    if f"{name}-seed1" in ROWS and f"{name}-seed2" in ROWS
}
"""Rows that differ only in the training seed (0, 1, 2; rows ``name``, ``name-seed1``,
``name-seed2``): ``report`` gives their mean and spread once all have run."""


def command(row: Row, models: Path) -> str:
    """The ``slide-gym`` commands that make the row (what the table cites)."""
    out = models / row.name
    scene = _scene_options(row.scene)
    test = f"--episodes {EPISODES} --seed {TEST_SEED}"
    if row.action_horizon is not None:
        test += f" --action-horizon {row.action_horizon}"
    if row.samples is not None:
        test += f" --samples {row.samples}"
    if row.method in ("random", "expert"):
        agent = "regions" if row.method == "expert" else "random"
        return f"slide-gym evaluate {agent} --env {row.env_id} {scene} {test}"
    trained = _trained(row)
    c = trained.collect
    noise = f" --action-noise {c['action_noise']}" if c.get("action_noise") else ""
    noise += f" --noise-phases {','.join(c['noise_phases'])}" if c.get("noise_phases") else ""
    noise += "".join(f" --planner-param {k}={v}" for k, v in c.get("planner_params", {}).items())
    noise += "".join(f" --expert-param {k}={v}" for k, v in c.get("expert_params", {}).items())
    collect = (
        f"slide-gym collect --env {row.env_id} {_scene_options(trained.scene)} "
        f"--episodes {c.get('episodes')} "
        f"--only-success{noise} --dataset-id {row.dataset}"
    )
    if row.method == "bc":
        train = f"slide-gym train-bc {row.dataset} --out {out}.zip --steps 5000"
        return f"{collect}; {train}; slide-gym evaluate {out}.zip --env {row.env_id} {scene} {test}"
    if row.method == "dp-dagger":
        base = models / str(row.base)
        train = (
            f"slide-gym dagger --env {row.env_id} --policy {base} {' '.join(row.train)} "
            f"--out {out} --dataset-id {row.dataset}"
        )
        policy = f"{out}/round-{_rounds(row)}/policy"
        return f"{train}; slide-gym evaluate {policy} --env {row.env_id} {test}"
    if row.base is not None:
        out = models / row.base
    args = " ".join(a.format(models=models) for a in trained.train)
    train = f"slide-gym train-dp {row.dataset} --out {out} {args}".rstrip()
    if "--snapshot-every" in trained.train:
        train += f"; slide-gym choose-checkpoint {out}"
    return f"{collect}; {train}; slide-gym evaluate {out} --env {row.env_id} {scene} {test}"


def _trained(row: Row) -> Row:
    """The row whose data and training make ``row``'s policy: its ``base`` for a diffusion
    policy tested elsewhere, else itself."""
    return ROWS[row.base] if row.method == "dp" and row.base else row


def _scene_options(scene: dict[str, Any]) -> str:
    """The ``--object``, ``--table`` (and ``--control-mode``, ``--physics``) options of a
    scene."""
    options = f"--object {scene['object']} --table {scene['table']}"
    if "control_mode" in scene:
        options += f" --control-mode {scene['control_mode']}"
    for name, value in scene.get("physics", {}).items():
        options += f" --physics {name}={int(value) if isinstance(value, bool) else value}"
    return options


def _rounds(row: Row) -> int:
    """The DAgger rounds a row runs (its policy is the last round's)."""
    return int(row.train[row.train.index("--rounds") + 1]) if "--rounds" in row.train else 2


def _collect(row: Row, workers: int = 1) -> None:
    from slide_gym.datasets.collect import collect
    from slide_gym.datasets.config import CollectConfig

    c = dict(row.collect)
    episodes = c.pop("episodes")
    config = CollectConfig(env_id=row.env_id, **row.scene, **c)
    collect(config, episodes, str(row.dataset), workers=workers)


def _cli(*args: str) -> None:
    from slide_gym.cli import main

    code = main(list(args))
    if code != 0:
        raise SystemExit(f"slide-gym {' '.join(args)} exited with {code}")


def run(row: Row, models: Path, out: Path, workers: int = 1) -> dict[str, Any]:
    """Collect the row's demonstrations (``workers`` episodes at a time) unless its dataset is
    complete, train unless its policy is, test it, and append the record to ``rows.jsonl``."""
    from agents.evaluate import evaluate
    from slide_gym.version import code_version

    start = time.perf_counter()
    agent: Any
    training: dict[str, Any] = {}
    if row.method in ("random", "expert"):
        agent = "random" if row.method == "random" else "regions"
    else:
        if row.method != "dp-dagger":
            _collect(_trained(row), workers)
        path = models / (row.base if row.method == "dp" and row.base else row.name)
        if row.method == "bc":
            zip_path = path.with_suffix(".zip")
            if not zip_path.exists():
                _cli("train-bc", str(row.dataset), "--out", str(zip_path), "--steps", "5000")
            agent = zip_path
            training = json.loads(zip_path.with_suffix(".json").read_text())["training"]
        elif row.method == "dp-dagger":
            base = models / str(row.base)
            _cli(
                "dagger",
                "--env",
                row.env_id,
                "--policy",
                str(base),
                *row.train,
                "--out",
                str(path),
                "--dataset-id",
                str(row.dataset),
            )
            agent = path / f"round-{_rounds(row)}" / "policy"
            training = json.loads((agent / "policy.json").read_text())
            base_card = json.loads((base / "policy.json").read_text())
            training["base_train_time_s"] = base_card["checkpoint"]["train_time_s"]
        else:
            if not (path / "policy.json").exists() or _unfinished(path):
                resume = ["--resume"] if (path / "checkpoint.pt").exists() else []
                args = [a.format(models=models) for a in _trained(row).train]
                _cli("train-dp", str(row.dataset), "--out", str(path), *args, *resume)
            if "--snapshot-every" in row.train:  # trained without validation (a GPU run)
                _cli("choose-checkpoint", str(path))
            agent = path
            training = json.loads((path / "policy.json").read_text())
    env_kwargs = dict(row.scene)
    result = evaluate(
        agent,
        row.env_id,
        episodes=EPISODES,
        seed=TEST_SEED,
        env_kwargs=env_kwargs,
        progress=True,
        action_horizon=row.action_horizon,
        samples=row.samples,
    )
    record = {
        "row": row.name,
        "method": row.method,
        "env_id": row.env_id,
        "scene": row.scene,
        "dataset": row.dataset,
        "action_horizon": row.action_horizon,
        **({"samples": row.samples} if row.samples is not None else {}),
        "training": training,
        "episodes": result["episodes"],
        "successes": result["successes"],
        "success_rate": result["success_rate"],
        "ci95": result["ci95"],
        "mean_length": result["mean_length"],
        "ended": result["ended"],
        "test_seeds": [TEST_SEED, TEST_SEED + EPISODES - 1],
        "eval_wall_s": result["wall_time_s"],
        "wall_s": time.perf_counter() - start,
        "command": command(row, Path("models")),  # as `run --models models` writes it
        "code_version": code_version(),
    }
    out.mkdir(parents=True, exist_ok=True)
    with (out / "rows.jsonl").open("a") as f:
        f.write(json.dumps(record) + "\n")
    if row.method in ("dp", "dp-dart") and row.base is None and (agent / "progress.csv").exists():
        (out / "curves").mkdir(exist_ok=True)
        shutil.copy(agent / "progress.csv", out / "curves" / f"{row.name}.csv")
    return record


def horizons(
    row: Row, models: Path, out: Path, choices: list[int], episodes: int
) -> list[dict[str, Any]]:
    """The row's trained policy on ``episodes`` validation episodes (seeds from
    :data:`~slide_gym.splits.VALIDATION_SEED`, never the test seeds) at each action horizon
    in ``choices``: how the horizon of a row such as ``...-h4`` was chosen. Appended to
    ``OUT/horizons.jsonl``."""
    from agents.evaluate import evaluate
    from slide_gym.splits import VALIDATION_SEED
    from slide_gym.version import code_version

    path = models / (row.base or row.name)
    results = []
    for k in choices:
        r = evaluate(
            str(path),
            row.env_id,
            episodes=episodes,
            seed=VALIDATION_SEED,
            env_kwargs=dict(row.scene),
            action_horizon=k,
        )
        record = {
            "policy": path.name,
            "action_horizon": k,
            "episodes": r["episodes"],
            "successes": r["successes"],
            "ci95": r["ci95"],
            "mean_length": r["mean_length"],
            "seeds": [VALIDATION_SEED, VALIDATION_SEED + episodes - 1],
            "code_version": code_version(),
        }
        out.mkdir(parents=True, exist_ok=True)
        with (out / "horizons.jsonl").open("a") as f:
            f.write(json.dumps(record) + "\n")
        print(json.dumps(record))
        results.append(record)
    return results


def _unfinished(path: Path) -> bool:
    """True if the run in ``path`` has not reached its last iteration (its progress rows)."""
    from agents.learned.train import read_progress

    card = json.loads((path / "policy.json").read_text())
    rows = read_progress(path / "progress.csv")
    return not rows or int(rows[-1]["iteration"]) < card["training"]["iterations"]


def latest_rows(out: Path) -> dict[str, dict[str, Any]]:
    """The last row written for each name."""
    rows: dict[str, dict[str, Any]] = {}
    path = out / "rows.jsonl"
    if path.exists():
        for line in path.read_text().splitlines():
            if line.strip():
                row = json.loads(line)
                rows[row["row"]] = row
    return rows


def report(out: Path) -> Path:
    rows = latest_rows(out)
    lines = [
        "| row | env | scene | demonstrations | training (1 core or GPU) | success (95 % CI) "
        "| mean length | failures |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name in ROWS:
        if name not in rows:
            continue
        r = rows[name]
        t = r.get("training") or {}
        demos = t.get("demonstrations", {})
        if r["method"] == "bc":
            demos = {"episodes": t.get("episodes"), "frames": t.get("frames")}
        n_demo = f"{demos['episodes']} ({demos['frames']} steps)" if demos else "-"
        seconds = (t.get("checkpoint") or {}).get("train_time_s") or t.get("train_time_s")
        if r["method"] == "dp-dagger" and seconds is not None:
            seconds += t.get("base_train_time_s", 0.0)
        iters = (t.get("checkpoint") or {}).get("iteration") or t.get("steps")
        train = f"{seconds / 60:.0f} min, {iters} it" if seconds else "-"
        batch = (t.get("training") or {}).get("batch_size", 64)
        if seconds and batch != 64:
            train += f" of {batch}"
        if t.get("device") == "cuda":
            train += " (GPU)"
        lo, hi = r["ci95"]
        mode = ", fingertip steps" if r["scene"].get("control_mode") == "ee_delta" else ""
        if r["scene"].get("physics", {}).get("friction_anchor"):
            mode += ", friction anchors"
        lines.append(
            f"| {name} | {r['env_id'].split('/')[1]} | {r['scene']['object']} on "
            f"{r['scene']['table']}{mode} | {n_demo} | {train} | "
            f"**{100 * r['success_rate']:.0f} %** ({100 * lo:.0f}-{100 * hi:.0f}) | "
            f"{r['mean_length']:.0f} | {_failures(r)} |"
        )
    spread = _seed_spread(rows)
    if spread:
        lines += ["", "Training seeds 0, 1 and 2 (the same data and test episodes):", "", *spread]
    lines += [
        "",
        "Commands that make each row with today's code (and the code version that made it):",
        "",
    ]
    lines += [
        f"- `{name}` ({rows[name]['code_version']}): `{command(row, Path('models'))}`"
        for name, row in ROWS.items()
        if name in rows
    ]
    md = out / "learning.md"
    md.write_text("\n".join(lines) + "\n")
    _plot_curves(out)
    return md


def _failures(row: dict[str, Any]) -> str:
    """How the row's failed test episodes ended (``-`` for rows run before it was kept)."""
    from agents.evaluate import failure_summary

    if "ended" not in row:
        return "-"
    return failure_summary(row["ended"]).removeprefix("; failures: ") or "none"


def _seed_spread(rows: dict[str, dict[str, Any]]) -> list[str]:
    """A line per complete seed group: the success rates, their mean and sample deviation."""
    import numpy as np

    lines = []
    for group, names in SEED_GROUPS.items():
        if all(n in rows for n in names):
            rates = np.array([100 * rows[n]["success_rate"] for n in names])
            each = ", ".join(f"{r:.0f} %" for r in rates)
            lines.append(
                f"- {group}: {each}; mean **{rates.mean():.0f} %**, "
                f"standard deviation {rates.std(ddof=1):.1f} points"
            )
    return lines


def _plot_curves(out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import csv

    import matplotlib.pyplot as plt

    curves = sorted((out / "curves").glob("*.csv")) if (out / "curves").exists() else []
    if not curves:
        return
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 4.6))
    colours = plt.get_cmap("tab20").colors
    for k, path in enumerate(curves):
        style = {"color": colours[k % 20], "linestyle": ("-", "--", ":")[k // 20 % 3]}
        rows = list(csv.DictReader(path.open()))
        it = [int(r["iteration"]) for r in rows]
        ax1.plot(it, [float(r["loss"]) for r in rows], label=path.stem, **style)
        val = [r for r in rows if r["val_success_rate"]]
        ax2.plot(
            [int(r["iteration"]) for r in val],
            [100 * float(r["val_success_rate"]) for r in val],
            marker="o",
            **style,
        )
    ax1.set_yscale("log")
    ax1.set_xlabel("iteration")
    ax1.set_ylabel("noise-prediction loss")
    ax2.set_xlabel("iteration")
    ax2.set_ylabel("validation success (%, 10-20 episodes)")
    ax2.set_ylim(0, 100)
    fig.legend(loc="center right", fontsize=7)
    fig.tight_layout(rect=(0, 0, 0.76, 1))
    fig.savefig(out / "learning_curves.png", dpi=110)
    plt.close(fig)


def fit(
    policy_dir: Path, dataset_id: str, windows: int = 128, at_start: bool = False
) -> dict[str, Any]:
    """How well a policy reproduces its demonstrations: ``windows`` training windows (seeded),
    the executed part of a sampled chunk against the labels (mean absolute error per action
    entry, in action units), with 10, 50 and 100 DDIM steps. A grasping skill (``train-dp
    --after``) is fitted on what follows each slide, as it was trained. ``at_start``: the
    first window of each episode instead (a skill's hand-off), up to ``windows`` of them; the
    answer then also counts the windows whose executed chunk moves joint 2 the other way
    than the labels do (with 10 DDIM steps)."""
    import minari
    import numpy as np
    import torch

    from agents.learned import DiffusionPolicy
    from agents.learned.data import ChunkSampler, chunk_to_actions, load_demonstrations

    policy = DiffusionPolicy.load(policy_dir)
    cfg = policy.config
    demos = load_demonstrations(
        minari.load_dataset(dataset_id),
        with_features=cfg.with_features,
        tip_axes=cfg.tip_axes,
        after_slide="after" in policy.card,
    )
    mine = ChunkSampler(demos, cfg.obs_horizon, cfg.pred_horizon, cfg.actions)
    plain = ChunkSampler(demos, cfg.obs_horizon, cfg.pred_horizon, "deltas")
    if at_start:
        if mine.dropped:
            raise ValueError("--at-start needs a dataset without dropped labels")
        idx = demos.starts[:windows]
    else:
        idx = np.random.default_rng(0).integers(0, len(mine), windows)
    obs = torch.from_numpy(mine.inputs[mine.obs_rows[idx]])
    first, count = cfg.obs_horizon - 1, cfg.action_horizon
    want = plain.chunks[idx][:, first : first + count]
    out: dict[str, Any] = {"policy": str(policy_dir), "label_mean_abs": float(np.abs(want).mean())}
    for steps in (10, 50, 100):
        chunks = policy.model.sample(obs, torch.Generator().manual_seed(0), steps=steps).numpy()
        got = np.stack([chunk_to_actions(c, first, count, cfg.actions) for c in chunks])
        out[f"error_{steps}_steps"] = float(np.abs(got - want).mean())
        if at_start and steps == 10:
            turn = np.sign(got[:, :, 1].sum(1)) != np.sign(want[:, :, 1].sum(1))
            out["windows"], out["joint2_reversed_10_steps"] = len(idx), int(turn.sum())
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    sub.add_parser("list", help="the rows and their commands")
    p = sub.add_parser("run", help="make rows (collect, train, evaluate)")
    p.add_argument("rows", nargs="+", choices=sorted(ROWS), metavar="ROW")
    p.add_argument("--models", type=Path, default=Path("models"))
    p.add_argument("--out", type=Path, default=OUT)
    p.add_argument("--workers", type=int, default=1, help="parallel episodes while collecting")
    p = sub.add_parser("horizon", help="a row's policy on validation seeds at action horizons")
    p.add_argument("row", choices=sorted(ROWS), metavar="ROW")
    p.add_argument("--horizons", type=int, nargs="+", default=[8, 4, 2], metavar="K")
    p.add_argument("--episodes", type=int, default=20, metavar="N")
    p.add_argument("--models", type=Path, default=Path("models"))
    p.add_argument("--out", type=Path, default=OUT)
    p = sub.add_parser("fit", help="a policy's action error on its training windows")
    p.add_argument("policies", nargs="+", type=Path, metavar="DIR")
    p.add_argument("--dataset", required=True, metavar="ID")
    p.add_argument("--windows", type=int, default=128, metavar="N")
    p.add_argument("--at-start", action="store_true", help="each episode's first window")
    p = sub.add_parser("report", help="learning.md and learning_curves.png from the rows")
    p.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    if args.cmd == "list":
        for row in ROWS.values():
            print(f"{row.name}: {command(row, Path('models'))}")
    elif args.cmd == "horizon":
        horizons(ROWS[args.row], args.models, args.out, args.horizons, args.episodes)
    elif args.cmd == "fit":
        for path in args.policies:
            print(json.dumps(fit(path, args.dataset, args.windows, args.at_start)))
    elif args.cmd == "run":
        for name in args.rows:
            record = run(ROWS[name], args.models, args.out, args.workers)
            print(json.dumps({k: record[k] for k in ("row", "success_rate", "ci95")}))
    else:
        print(report(args.out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
