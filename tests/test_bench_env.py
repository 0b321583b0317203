"""``slide-gym bench env``: the random-action run and ``--against panda-gym`` (no timing
assertions: only that both run on the same protocol and the ratio is theirs over ours)."""

from __future__ import annotations

import pytest

from slide_gym.bench import env as bench_env
from slide_gym.cli import main


def test_random_actions_run_through_gym_make() -> None:
    out = bench_env._random_actions("square", "square", steps=30, seed=0, repeats=1, against=None)
    ours = out["random"]
    assert ours["env_id"] == "SlideGym/TopSlide-v0" and ours["control_dt"] == pytest.approx(0.05)
    assert ours["real_time_factor"] == pytest.approx(ours["env_steps_per_s"] * 0.05)
    assert "against" not in out and "rtf_ratio" not in out


def test_against_panda_gym_prints_the_ratio() -> None:
    pytest.importorskip("panda_gym")
    out = bench_env._random_actions(
        "square", "square", steps=30, seed=0, repeats=1, against="panda-gym"
    )
    theirs = out["against"]
    assert theirs["env_id"] == "PandaPush-v3" and theirs["control_dt"] == pytest.approx(0.04)
    assert theirs["physics_hz"] == pytest.approx(500.0) and theirs["solver_iterations"] == 50
    ratio = out["random"]["real_time_factor"] / theirs["real_time_factor"]
    assert out["rtf_ratio"] == pytest.approx(ratio)


def test_an_unknown_against_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["bench", "env", "--against", "mujoco"])
    assert exit_.value.code == 2
    assert "panda-gym" in capsys.readouterr().err


def test_bench_env_rejects_bad_random_steps() -> None:
    with pytest.raises(ValueError, match="random_steps"):
        bench_env.bench_env(random_steps=0)


def test_rgbd_reports_the_image_cost_per_step() -> None:
    out = bench_env.bench_env(
        steps=3, resets=1, repeats=1, random_steps=3, rgbd=True, image_size=(40, 36)
    )
    rgbd = out["rgbd"]
    assert rgbd["image_size"] == [40, 36] and rgbd["env_steps_per_s"] > 0
    assert rgbd["image_ms_per_step"] == pytest.approx(
        1e3 * (1 / rgbd["env_steps_per_s"] - 1 / out["env_steps_per_s"])
    )


def test_pointcloud_reports_the_points_cost_per_step() -> None:
    out = bench_env.bench_env(
        steps=3,
        resets=1,
        repeats=1,
        random_steps=3,
        pointcloud=True,
        image_size=(40, 36),
        num_points=64,
    )
    points = out["pointcloud"]
    assert points["image_size"] == [40, 36] and points["num_points"] == 64
    assert points["points_ms_per_step"] == pytest.approx(
        1e3 * (1 / points["env_steps_per_s"] - 1 / out["env_steps_per_s"])
    )
    assert "rgbd" not in out
