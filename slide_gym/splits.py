"""Named train/test splits: which objects and which reset seeds a result is measured on.

A reset seed fixes everything an episode draws: the start pose, the catalog object of
``object="random"`` and the plate of ``object="procedural"`` (the plate of seed ``s`` is
``procedural-s``, :mod:`slide_gym.geometry.procedural`). So the seed ranges below are the
splits: every command and trainer draws from its own range, and no two ranges overlap.

========== ================= =================================================
range      reset seeds       used by
========== ================= =================================================
train      0 - 9999          ``slide-gym collect`` (``--seed`` default 0)
test       10000 - 19999     ``slide-gym evaluate`` (``--seed`` default 10000)
validation 20000 - 29999     ``train-dp``'s choice of checkpoint
(unused)   30000 - 39999     reserved
dagger     40000 - 49999     DAgger's learner episodes (``slide-gym dagger``)
========== ================= =================================================

The named object splits (:data:`SPLITS`, ``--split NAME`` on ``collect`` and ``evaluate``):

================= ================================= ============= =============
split             objects (env ``object=``)         collect seeds evaluate seeds
================= ================================= ============= =============
seen              the catalog objects (``random``)  train         test
procedural-train  plates 0 - 9999 (``procedural``)  train         train
procedural-test   plates 10000 - 19999              test          test
================= ================================= ============= =============

``seen`` holds the catalog's objects (:data:`slide_gym.OBJECT_NAMES`), one drawn per episode:
its test episodes are new start poses of the same objects. The procedural splits hold
generated plates that no catalog object is, and no plate is in both: a policy trained on
``procedural-train`` meets only plates it never saw on ``procedural-test``. The table is
the command's ``--table`` (any table: the splits are about objects and seeds). Validation
and DAgger seeds are neither train nor test plates.
"""

from __future__ import annotations

from dataclasses import dataclass

from slide_gym.geometry import OBJECT_NAMES
from slide_gym.geometry.shape_json import closest
from slide_gym.task import PROCEDURAL, RANDOM

TRAIN_SEED = 0
"""First reset seed of collections (demonstrations, training episodes)."""
TEST_SEED = 10_000
"""First reset seed of the test episodes (``slide-gym evaluate``)."""
VALIDATION_SEED = 20_000
"""First reset seed of the episodes that choose a learned policy's checkpoint: not a test
seed, so the choice does not peek at the test."""
DAGGER_SEED = 40_000
"""First reset seed of DAgger's learner episodes."""
RANGE_SIZE = 10_000
"""Seeds per range."""

SEED_RANGES: dict[str, range] = {
    name: range(first, first + RANGE_SIZE)
    for name, first in (
        ("train", TRAIN_SEED),
        ("test", TEST_SEED),
        ("validation", VALIDATION_SEED),
        ("dagger", DAGGER_SEED),
    )
}
"""The reset seeds of each use (half-open ranges, pairwise disjoint)."""


@dataclass(frozen=True)
class Split:
    """A named set of objects and the reset seeds each command draws from.

    Args:
        name: what ``--split`` takes.
        object: the env's ``object`` argument (``"random"``: the catalog; ``"procedural"``:
            the plate of each reset seed).
        collect_seeds, evaluate_seeds: the reset seeds of ``collect`` and ``evaluate``.
        description: one line for help texts.
    """

    name: str
    object: str
    collect_seeds: range
    evaluate_seeds: range
    description: str

    def seeds(self, command: str) -> range:
        """The reset seeds of ``command`` (``"collect"`` or ``"evaluate"``)."""
        if command not in ("collect", "evaluate"):
            raise ValueError(f"command must be 'collect' or 'evaluate', got {command!r}")
        return self.collect_seeds if command == "collect" else self.evaluate_seeds

    def objects(self) -> tuple[str, ...]:
        """The names of this split's objects (``procedural-SEED`` for plates)."""
        if self.object == RANDOM:
            return OBJECT_NAMES
        seeds = sorted({*self.collect_seeds, *self.evaluate_seeds})
        return tuple(f"{PROCEDURAL}-{s}" for s in seeds)

    def first_seed(self, command: str, episodes: int, seed: int | None = None) -> int:
        """``seed`` (default: the first of the range) if ``episodes`` episodes from it stay
        in ``command``'s range; else a ValueError naming the range."""
        allowed = self.seeds(command)
        first = allowed.start if seed is None else seed
        last = first + max(int(episodes), 1) - 1
        if first not in allowed or last not in allowed:
            raise ValueError(
                f"--split {self.name}: {command} takes reset seeds {allowed.start}-"
                f"{allowed.stop - 1}, but --seed {first} with {episodes} episode(s) runs seeds "
                f"{first}-{last}"
            )
        return first


SPLITS: dict[str, Split] = {
    s.name: s
    for s in (
        Split(
            "seen",
            RANDOM,
            SEED_RANGES["train"],
            SEED_RANGES["test"],
            "the catalog objects, one drawn per episode; test: new start poses",
        ),
        Split(
            "procedural-train",
            PROCEDURAL,
            SEED_RANGES["train"],
            SEED_RANGES["train"],
            "generated plates of seeds 0-9999",
        ),
        Split(
            "procedural-test",
            PROCEDURAL,
            SEED_RANGES["test"],
            SEED_RANGES["test"],
            "generated plates of seeds 10000-19999, never trained on",
        ),
    )
}
"""The named splits, by name."""
SPLIT_NAMES: tuple[str, ...] = tuple(SPLITS)


def get_split(name: str) -> Split:
    """The split called ``name``; a ValueError with the closest name and all of them."""
    if name in SPLITS:
        return SPLITS[name]
    near = closest(name, SPLIT_NAMES)
    hint = f"did you mean {near!r}? " if near is not None else ""
    raise ValueError(f"unknown split {name!r}; {hint}valid names: {', '.join(SPLIT_NAMES)}")
