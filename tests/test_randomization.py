"""Domain randomisation: drawn from the reset seed, applied to the world, validated, recorded."""

from __future__ import annotations

import json
import re

import gymnasium as gym
import numpy as np
import pytest

import slide_gym  # noqa: F401 - registers the environments
from slide_gym.cli import main
from slide_gym.datasets.collect import collect
from slide_gym.datasets.config import CollectConfig
from slide_gym.datasets.store import dataset_metadata, load, read_episodes
from slide_gym.envs.randomization import DEFAULT_RANGES, KEYS, PARAMETERS, parse
from slide_gym.envs.top_slide import TopSlideEnv
from slide_gym.geometry import get_object
from slide_gym.robot.model import PAD_FRICTION, HandParams
from slide_gym.task import TaskParams

ENV_ID = "SlideGym/TopSlide-v0"


def _env(randomization=None, **kwargs) -> TopSlideEnv:
    return TopSlideEnv(object="E", table="square", randomization=randomization, **kwargs)


def _rollout(env: TopSlideEnv, seed: int, options=None, steps: int = 15) -> list[dict]:
    """The reset observation and those of ``steps`` seeded random actions."""
    obs, _ = env.reset(seed=seed, options=options)
    rng = np.random.default_rng(0)
    out = [obs]
    for _ in range(steps):
        out.append(env.step(rng.uniform(-1, 1, 8).astype(np.float32))[0])
    return out


def _same(a: list[dict], b: list[dict]) -> bool:
    return all(np.array_equal(x[k], y[k]) for x, y in zip(a, b, strict=True) for k in x)


def _world(env: TopSlideEnv) -> dict[str, float]:
    """What the built world holds for each key (PyBullet multiplies friction coefficients)."""
    c, sim, robot = env.sim.client, env.sim, env.robot
    plate = c.getDynamicsInfo(sim.body("object"), -1)[1]
    links = robot.finger_a_links + robot.finger_b_links
    pads = {c.getDynamicsInfo(robot.body, i)[1] for i in links}
    assert len(pads) == 1
    obj = env.task.object
    return {
        "plate_table_friction": plate * c.getDynamicsInfo(sim.body("table"), -1)[1],
        "pad_friction": plate * pads.pop(),
        "plate_density": c.getDynamicsInfo(sim.body("object"), -1)[0] / (obj.area * obj.thickness),
        "plate_thickness": obj.thickness,
        "table_height": env.task.table.height,
        "finger_stiffness": robot.hand.k_proximal,
    }


def test_a_randomised_reset_reproduces_from_its_seed() -> None:
    a, b = _env("default"), _env("default")
    first, again = _rollout(a, 7), _rollout(b, 7)
    assert _same(first, again)
    drawn = a.randomization_values
    assert drawn == b.randomization_values and set(drawn) == set(KEYS)
    for key, (lo, hi) in DEFAULT_RANGES.items():
        assert lo <= drawn[key] <= hi
    world = _world(a)
    for key in KEYS:
        assert world[key] == pytest.approx(drawn[key], rel=1e-6), key
    assert first[0]["table_height"][0] == pytest.approx(drawn["table_height"])
    assert first[0]["object_pose"][2] == pytest.approx(drawn["table_height"], abs=1e-4)
    _, info = a.reset()  # no seed: the generator goes on, and the draw with it
    assert info["randomization"] != drawn
    a.close()
    b.close()


def test_different_seeds_draw_different_values_and_keep_the_scene() -> None:
    env, plain = _env("default"), _env()
    _, one = env.reset(seed=1)
    _, two = env.reset(seed=2)
    assert all(one["randomization"][k] != two["randomization"][k] for k in KEYS)
    _, plain_info = plain.reset(seed=2)  # randomisation has its own generator
    assert plain_info["object_pose_2d"] == pytest.approx(two["object_pose_2d"], abs=1e-3)
    np.testing.assert_array_equal(plain.start_pose, env.start_pose)
    env.close()
    plain.close()


def test_none_is_the_fixed_world_and_an_episode_option_does_not_leak() -> None:
    env, fresh = _env(), _env()
    _rollout(env, 3, {"randomization": {"table_height": -0.08, "pad_friction": 2.0}}, 3)
    assert env.randomization_values == {"table_height": -0.08, "pad_friction": 2.0}
    after, clean = _rollout(env, 3), _rollout(fresh, 3)
    assert _same(after, clean)
    _, info = env.reset(seed=3)
    assert info["randomization"] == {}
    e = get_object("E")
    p = TaskParams()
    assert _world(env) == pytest.approx(
        {
            "plate_table_friction": p.object_friction * p.table_friction,
            "pad_friction": p.object_friction * PAD_FRICTION,
            "plate_density": e.density,
            "plate_thickness": e.thickness,
            "table_height": 0.0,
            "finger_stiffness": HandParams().k_proximal,
        },
        rel=1e-6,
    )
    env.close()
    fresh.close()


def test_episode_options_replace_the_envs_ranges_for_one_episode() -> None:
    env = _env("default")
    _, base = env.reset(seed=4)
    _, info = env.reset(seed=4, options={"randomization": {"pad_friction": 0.9}})
    assert info["randomization"]["pad_friction"] == 0.9
    others = {k: v for k, v in info["randomization"].items() if k != "pad_friction"}
    assert others == {k: v for k, v in base["randomization"].items() if k != "pad_friction"}
    _, info = env.reset(seed=4, options={"randomization": {"table_height": [-0.1, -0.09]}})
    assert -0.1 <= info["randomization"]["table_height"] <= -0.09
    _, info = env.reset(seed=4)
    assert info["randomization"] == base["randomization"]
    # the drawn values as exact options start the same episode in an env without ranges
    plain = _env()
    replayed = _rollout(plain, 4, {"randomization": base["randomization"]})
    assert _same(_rollout(env, 4), replayed)
    env.close()
    plain.close()


def test_observations_stay_in_the_space_at_the_bounds() -> None:
    for height in (-0.1, 0.05):
        env = _env({"table_height": height, "plate_thickness": 0.0003})
        obs = _rollout(env, 0, steps=5)
        assert all(env.observation_space.contains(o) for o in obs)
        env.close()


def test_set_state_works_in_a_randomised_episode() -> None:
    env = _env("default")
    observations = _rollout(env, 2, steps=10)
    state = env.get_state()
    other = _env("default")
    other.reset(seed=2)
    other.set_state(state)
    restored = other.observation()
    assert all(np.array_equal(restored[k], observations[-1][k]) for k in restored)
    env.close()
    other.close()


def test_goal_env_takes_randomization() -> None:
    env = gym.make("SlideGym/TopSlideGoal-v0", object="L", randomization="default")
    _, info = env.reset(seed=0)
    assert set(info["randomization"]) == set(KEYS)
    env.close()


BAD = [
    ("defualt", "randomization must be None, 'default' or a dict"),
    ({"pad_fricton": (0.8, 1.0)}, "unknown randomization key 'pad_fricton'; did you mean"),
    ({"pad_friction": (1.2, 0.8)}, r"\['pad_friction'\]: low 1.2 is above high 0.8"),
    ({"table_height": (-0.3, 0.0)}, r"outside the allowed \[-0.1, 0.05\] m"),
    ({"plate_thickness": 3.0}, r"outside the allowed \[0.0003, 0.05\] m"),
    ({"plate_density": 0.0}, r"outside the allowed \[100, 10000\] kg/m\^3"),
    ({"finger_stiffness": "stiff"}, "must be a number or a \\(low, high\\) pair"),
    ({"plate_table_friction": (0.1, 0.2, 0.3)}, "pair of numbers"),
    ({"plate_table_friction": True}, "pair of numbers"),
    ({"plate_table_friction": float("nan")}, "must be finite"),
]


@pytest.mark.parametrize(("spec", "match"), BAD)
def test_bad_randomization_is_a_value_error(spec, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        _env(spec)
    if isinstance(spec, dict):
        env = _env()
        with pytest.raises(ValueError, match="reset option randomization"):
            env.reset(seed=0, options={"randomization": spec})
        env.close()


@pytest.mark.parametrize("command", ["collect", "evaluate"])
@pytest.mark.parametrize(
    ("text", "match"),
    [
        ('{"pad_friction": [1.2, 0.8]}', "low 1.2 is above high 0.8"),
        ('{"table_hight": 0}', "did you mean 'table_height'"),
        ("{not json", "--randomization must be None, 'default' or a dict"),
    ],
)
def test_cli_bad_randomization_exits_2(command, text, match, capsys, minari_root) -> None:
    extra = ["--dataset-id", "test/bad-v0"] if command == "collect" else ["regions"]
    argv = [command, *extra, "--env", ENV_ID, "--episodes", "1", "--randomization", text]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"slide-gym {command}: error: ") and err.count("\n") == 1
    assert re.search(match, err), err
    assert not (minari_root / ".slide_gym" / "test" / "bad-v0").exists()


def test_every_default_range_lies_within_its_bounds() -> None:
    assert parse("default") == DEFAULT_RANGES and tuple(DEFAULT_RANGES) == KEYS
    for p in PARAMETERS:
        assert p.bounds[0] <= p.default[0] < p.default[1] <= p.bounds[1], p.name


@pytest.mark.slow
def test_a_collection_stores_its_randomization(minari_root) -> None:
    ranges = {"pad_friction": [0.9, 1.1], "table_height": -0.02}
    config = CollectConfig(env_id=ENV_ID, time_budget=60.0, randomization=ranges)
    assert config.randomization == {"pad_friction": [0.9, 1.1], "table_height": [-0.02, -0.02]}
    assert CollectConfig.from_json(json.loads(json.dumps(config.to_json()))) == config
    assert "randomization" not in CollectConfig(env_id=ENV_ID).to_json()
    collect(config, 1, "test/randomised-v0", workers=1)
    dataset = load("test/randomised-v0")
    meta = dataset_metadata(dataset)
    assert meta["randomization"] == config.randomization
    assert meta["env_kwargs"]["randomization"] == config.randomization
    (episode,) = read_episodes(dataset)
    drawn = episode.options["randomization"]
    assert 0.9 <= drawn["pad_friction"] <= 1.1 and drawn["table_height"] == -0.02
    env = dataset.recover_environment()
    _, info = env.reset(seed=episode.seed, options=episode.options)
    assert info["randomization"] == pytest.approx(drawn)
    env.close()
    assert main(["replay", "test/randomised-v0"]) == 0
