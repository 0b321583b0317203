"""Named splits: the seed ranges and object sets never overlap, every user of a seed range
takes it from ``slide_gym.splits``, and ``--split`` selects what it says."""

from __future__ import annotations

import itertools
import json
from typing import Any

import gymnasium as gym
import pytest

from slide_gym import OBJECT_NAMES
from slide_gym.cli import main
from slide_gym.datasets.config import CollectConfig
from slide_gym.splits import (
    DAGGER_SEED,
    SEED_RANGES,
    SPLITS,
    TEST_SEED,
    TRAIN_SEED,
    VALIDATION_SEED,
    get_split,
)

ENV_ID = "SlideGym/TopSlide-v0"


def test_seed_ranges_are_disjoint_and_start_at_the_constants() -> None:
    for (a, ra), (b, rb) in itertools.combinations(SEED_RANGES.items(), 2):
        assert not set(ra) & set(rb), (a, b)
    starts = {name: r.start for name, r in SEED_RANGES.items()}
    assert starts == {
        "train": TRAIN_SEED,
        "test": TEST_SEED,
        "validation": VALIDATION_SEED,
        "dagger": DAGGER_SEED,
    }
    assert (TRAIN_SEED, TEST_SEED, VALIDATION_SEED, DAGGER_SEED) == (0, 10_000, 20_000, 40_000)


def test_every_user_of_a_seed_range_takes_it_from_splits() -> None:
    import agents.evaluate
    import agents.learned.dagger
    from agents.learned.train import TrainConfig

    assert agents.evaluate.TEST_SEED is TEST_SEED
    assert agents.learned.dagger.DAGGER_SEED is DAGGER_SEED
    assert TrainConfig().val_seed == VALIDATION_SEED
    assert CollectConfig(ENV_ID).seed == TRAIN_SEED


def test_splits_never_overlap() -> None:
    seen, train, test = (SPLITS[n] for n in ("seen", "procedural-train", "procedural-test"))
    assert set(seen.objects()) == set(OBJECT_NAMES)
    plates_train, plates_test = set(train.objects()), set(test.objects())
    assert len(plates_train) == len(plates_test) == 10_000
    assert not plates_train & plates_test
    assert not set(OBJECT_NAMES) & (plates_train | plates_test)
    # the test plates and seen's test poses come from the test range, which no trainer uses
    assert test.collect_seeds == test.evaluate_seeds == seen.evaluate_seeds == SEED_RANGES["test"]
    assert train.collect_seeds == train.evaluate_seeds == seen.collect_seeds == SEED_RANGES["train"]


def test_a_split_env_draws_the_split_objects() -> None:
    """The env's own draw: the plate of a procedural-test seed is in procedural-test, a seen
    episode draws a catalog object."""
    test, seen = SPLITS["procedural-test"], SPLITS["seen"]
    env = gym.make(ENV_ID, object=test.object)
    try:
        seed = test.evaluate_seeds[3]
        _, info = env.reset(seed=seed)
        assert info["object"] == f"procedural-{seed}" and info["object"] in test.objects()
        assert info["object"] not in SPLITS["procedural-train"].objects()
        _, info = env.reset(seed=seen.evaluate_seeds[0], options={"object": seen.object})
        assert info["object"] in seen.objects()
    finally:
        env.close()


def test_first_seed_keeps_every_episode_in_the_range() -> None:
    split = get_split("procedural-train")
    assert split.first_seed("collect", 5) == 0
    assert split.first_seed("evaluate", 10, 9990) == 9990
    with pytest.raises(ValueError, match=r"reset seeds 0-9999, but --seed 9999 .* 9999-10000"):
        split.first_seed("collect", 2, 9999)
    with pytest.raises(ValueError, match="did you mean 'procedural-test'"):
        get_split("procedural-tests")


def test_collect_config_keeps_the_split() -> None:
    config = CollectConfig(ENV_ID, object="procedural", seed=10_000, split="procedural-test")
    assert config.to_json()["split"] == "procedural-test"
    assert "split" not in CollectConfig(ENV_ID).to_json()  # older datasets keep their identity
    with pytest.raises(ValueError, match="collects object 'procedural', not 'square'"):
        CollectConfig(ENV_ID, seed=10_000, split="procedural-test")
    with pytest.raises(ValueError, match="reset seeds 10000-19999"):
        CollectConfig(ENV_ID, object="procedural", seed=3, split="procedural-test")


@pytest.mark.parametrize(
    ("argv", "object_", "seed"),
    [
        (["--split", "procedural-test"], "procedural", 10_000),
        (["--split", "procedural-train", "--seed", "7"], "procedural", 7),
        (["--split", "seen"], "random", 0),
        ([], "square", 0),
    ],
)
def test_collect_split_selects_objects_and_seeds(
    argv: list[str], object_: str, seed: int, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    got: dict[str, Any] = {}

    def fake_collect(config: CollectConfig, episodes: int, dataset_id: str, **_: Any) -> dict:
        got.update(config=config, episodes=episodes)
        return {"episodes_run": episodes, "expert_success_rate": 1.0, "failures": {}}

    monkeypatch.setattr("slide_gym.datasets.collect.collect", fake_collect)
    args = ["collect", "--env", ENV_ID, "--episodes", "3", "--dataset-id", "t/x-v0", *argv]
    assert main(args) == 0
    config = got["config"]
    assert (config.object, config.seed, got["episodes"]) == (object_, seed, 3)
    assert config.split == (argv[1] if argv else None)


@pytest.mark.parametrize(
    ("argv", "object_", "seed"),
    [
        (["--split", "procedural-test"], "procedural", TEST_SEED),
        (["--split", "procedural-train"], "procedural", TRAIN_SEED),
        (["--split", "seen"], "random", TEST_SEED),
        ([], None, TEST_SEED),
    ],
)
def test_evaluate_split_selects_objects_and_seeds(
    argv: list[str], object_: str | None, seed: int, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    got: dict[str, Any] = {}

    def fake_evaluate(agent: str, env_id: str, **kwargs: Any) -> dict:
        got.update(kwargs)
        return {"env_kwargs": kwargs["env_kwargs"], "seed": kwargs["seed"]}

    monkeypatch.setattr("agents.evaluate.evaluate", fake_evaluate)
    assert main(["evaluate", "regions", "--episodes", "2", "--json", *argv]) == 0
    assert got["seed"] == seed and got["env_kwargs"].get("object") == object_
    out = json.loads(capsys.readouterr().out)
    assert out.get("split") == (argv[1] if argv else None)


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        (["--split", "seen", "--object", "L"], "--split seen sets the object"),
        (["--split", "procedural-test", "--seed", "5"], "reset seeds 10000-19999"),
        (["--split", "procedural-train", "--seed", "9999"], "runs seeds 9999-10000"),
    ],
)
def test_split_conflicts_are_one_line_errors(argv: list[str], match: str, capsys) -> None:
    args = ["collect", "--env", ENV_ID, "--episodes", "2", "--dataset-id", "t/x-v0", *argv]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith("slide-gym collect: error: ") and match in err
    assert err.count("\n") == 1


def test_collect_never_runs_a_seed_past_its_split(minari_root, monkeypatch) -> None:
    """``--only-success`` runs further seeds, but not into the next range."""
    from slide_gym.datasets import collect as collect_module

    asked: list[int] = []

    def fail_all(fn: Any, cases: list[dict], *args: Any, **kwargs: Any) -> list[dict]:
        asked.extend(c["seed"] for c in cases)
        return [{"case": c, "success": False, "steps": 1, "return": 0.0} for c in cases]

    monkeypatch.setattr(collect_module, "run_cases", fail_all)
    config = CollectConfig(
        ENV_ID, object="procedural", seed=9_990, only_success=True, split="procedural-train"
    )
    with pytest.raises(ValueError, match="no episode to keep"):
        collect_module.collect(config, 5, "test/split-edge-v0")
    assert max(asked) == 9_999
    with pytest.raises(ValueError, match="runs seeds 9990-10009"):
        collect_module.collect(config, 20, "test/split-edge-v0")
