"""Why an episode failed: one decision from the expert's account and the env's step infos.

:class:`Outcome` follows what the env's infos say of the plate over an episode;
:func:`failure_cause` turns it, the expert's last phase and its reason for giving up (if it
did) into the record's ``failure``, which is ``None`` exactly when the episode succeeded.
In order of precedence the causes are:

- ``the plate fell off the table in phase X`` (``after the expert gave up`` if it had: the
  row's ``gave_up`` says why);
- the expert's reason for giving up (``plan infeasible: ...``, ``planning budget used up
  ...``, ``not graspable after the slide ...``, ``no IK solution ...``);
- ``out of episode time in phase Y``, while the expert was still at work;
- once the expert was done, the plate's state. Grasp envs: ``held but clearance below 5 cm
  (peaked at 3.6 cm)``, ``held 5 cm up but not for 1 s (0.40 s at most, ...)``, ``slipped
  from the pinch`` or ``never held between both fingers`` (with ``caught in the hand`` when
  it hangs from the hand anyway, by one finger say). Slide envs: ``not left graspable
  ...``, ``left graspable but still touched by the robot``, ``left graspable but not at
  rest``.
"""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

GOALS = ("grasp", "slide")
CAUGHT_CLEARANCE = 0.005
"""m: a plate this far up, touching the hand but not both fingers, is caught in the hand (in
one finger's crook, say), not lying on the table."""


@dataclass
class Outcome:
    """The plate over one episode, from the env's infos (``None``: not known, e.g. a record
    written before these were kept).

    Attributes:
        goal: the env's, ``"grasp"`` (slide, grasp, lift) or ``"slide"``.
        fell_off, truncated: the episode ended so (truncated also when the expert gave up).
        clearance_m, max_clearance_m: the plate's lowest point above the table top, at the
            end and at most.
        pinched: it touches both fingers at the end; ``was_pinched``: at some step.
        max_pinched_clearance_m: the most clearance while it touched both fingers.
        max_held_s: the longest lift that held (``info["lift_held_s"]``).
        touching_table, touching_robot, graspable, overhang_m: at the end.
    """

    goal: str = "grasp"
    fell_off: bool = False
    truncated: bool = False
    clearance_m: float | None = None
    max_clearance_m: float | None = None
    pinched: bool | None = None
    was_pinched: bool = False
    max_pinched_clearance_m: float | None = None
    max_held_s: float = 0.0
    touching_table: bool | None = None
    touching_robot: bool | None = None
    graspable: bool | None = None
    overhang_m: float | None = None

    def __post_init__(self) -> None:
        if self.goal not in GOALS:
            raise ValueError(f"goal must be one of {', '.join(GOALS)}, got {self.goal!r}")

    def update(self, info: dict[str, Any], truncated: bool = False) -> None:
        """Take in one step's info (the reset's too) and whether the step truncated."""
        clearance = float(info["clearance_m"])
        self.clearance_m = clearance
        self.max_clearance_m = max(clearance, self.max_clearance_m or -float("inf"))
        self.pinched = bool(info["pinched"])
        if self.pinched:
            self.was_pinched = True
            peak = self.max_pinched_clearance_m
            self.max_pinched_clearance_m = clearance if peak is None else max(peak, clearance)
        self.max_held_s = max(self.max_held_s, float(info["lift_held_s"]))
        self.touching_table = bool(info["touching_table"])
        self.touching_robot = bool(info["touching_robot"])
        self.graspable = bool(info["graspable"])
        self.overhang_m = float(info["overhang_m"])
        self.fell_off = self.fell_off or bool(info["fell_off"])
        self.truncated = self.truncated or bool(truncated)


def failure_cause(
    success: bool,
    outcome: Outcome,
    phase: str,
    gave_up: str | None = None,
    *,
    lift_height: float = 0.05,
    hold_s: float = 1.0,
) -> str | None:
    """Why the episode failed (see the module docstring), ``None`` if it succeeded.

    ``phase``: the expert's last phase (``"done"`` once it finished, ``"failed"`` once it
    gave up); ``gave_up``: its reason, if it did; ``lift_height`` and ``hold_s``: the env's
    lift test (``TaskParams.lift_height``, ``lift_hold_s``)."""
    if success:
        return None
    if outcome.fell_off:
        if phase == "failed":
            return "the plate fell off the table after the expert gave up"
        return f"the plate fell off the table in phase {phase}"
    if gave_up:
        return gave_up
    if outcome.pinched is None:  # the plate's state was not kept: only the phase is known
        if outcome.truncated:
            return f"out of episode time in phase {phase}"
        return f"ended in phase {phase} without success"
    if outcome.truncated and phase != "done":
        return f"out of episode time in phase {phase}"
    if outcome.goal == "slide":
        return _slide_state(outcome)
    return _grasp_state(outcome, lift_height, hold_s)


def _cm(metres: float | None) -> str:
    return "-" if metres is None else f"{100 * metres:.1f} cm"


def _grasp_state(o: Outcome, lift_height: float, hold_s: float) -> str:
    need = f"{100 * lift_height:g} cm"
    if o.pinched:
        peak = o.max_pinched_clearance_m
        if peak is None or peak < lift_height:
            why = f"held but clearance below {need} (peaked at {_cm(peak)}"
        else:
            why = f"held {need} up but not for {hold_s:g} s ({o.max_held_s:.2f} s at most, "
            why += f"peak {_cm(peak)}"
        return why + (", the plate touching the table)" if o.touching_table else ")")
    why = "slipped from the pinch" if o.was_pinched else "never held between both fingers"
    if o.touching_robot and (o.clearance_m or 0.0) > CAUGHT_CLEARANCE:
        return f"{why} (caught in the hand, clearance {_cm(o.clearance_m)})"
    peak = o.max_pinched_clearance_m if o.was_pinched else o.max_clearance_m
    return f"{why} (clearance peaked at {_cm(peak)})"


def _slide_state(o: Outcome) -> str:
    if not o.graspable:
        return f"not left graspable (overhang {_cm(o.overhang_m)})"
    if o.touching_robot:
        return "left graspable but still touched by the robot"
    return "left graspable but not at rest"


def row_failure(row: dict[str, Any]) -> str | None:
    """The ``failure`` of a ``slide-gym run --json`` object; for one written before the
    record named every failure (no ``gave_up`` key: its ``failure`` is the expert's reason
    for giving up, if any), decided from what it kept."""
    if row.get("success"):
        return None
    if "gave_up" in row:
        return row.get("failure") or "failure not recorded"
    if "phase_reached" not in row:
        return "failure not recorded"
    goal = "grasp" if "Grasp" in str(row.get("env_id", "Grasp")) else "slide"
    ended = {"fell_off": bool(row.get("fell_off")), "truncated": bool(row.get("truncated"))}
    outcome = Outcome(goal, **ended)
    phase = str(row.get("phase_reached"))
    return failure_cause(False, outcome, phase, row.get("failure"))


def failure_kind(row: dict[str, Any]) -> str | None:
    """A failed episode's cause without its numbers, for counting (None for a success)."""
    failure = row_failure(row)
    if failure is None:
        return None
    failure = re.sub(r" after \d+ iterations.*| \(.*\)$", "", failure)
    return re.sub(r"\d+(\.\d+)?", "N", failure)


def failure_counts(rows: Sequence[dict[str, Any]]) -> dict[str, int]:
    """Failed rows counted by :func:`failure_kind`, the most frequent first."""
    kinds = Counter(k for k in map(failure_kind, rows) if k is not None)
    return dict(kinds.most_common())
