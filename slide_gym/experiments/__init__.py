"""The paper's experiments (``slide-gym experiment``): named, resumable runs of planning
queries, one JSON line per query, stamped with the code version."""

from __future__ import annotations

from slide_gym.experiments.run import results_file, run_experiment, run_experiments
from slide_gym.experiments.specs import EXPERIMENTS, LATER, experiment_cases

__all__ = [
    "EXPERIMENTS",
    "LATER",
    "experiment_cases",
    "results_file",
    "run_experiment",
    "run_experiments",
]
