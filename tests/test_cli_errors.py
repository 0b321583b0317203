"""Bad input on every command: names list ``random`` and ``procedural`` where accepted, with
"did you mean"; an env a command cannot drive says so; misspelt options get the closest;
``evaluate`` warns about a policy trained in another env; folders in the Minari path that
are not datasets break nothing, and ``export`` refuses to write there."""

from __future__ import annotations

import re
import shutil
import warnings
from pathlib import Path
from typing import Any

import gymnasium as gym
import minari
import numpy as np
import pytest
from minari.data_collector import EpisodeBuffer

from slide_gym import TABLE_NAMES
from slide_gym.cli import main
from slide_gym.cli.args import one_line_warnings
from slide_gym.datasets.lerobot import export_lerobot
from slide_gym.datasets.store import load, local_dataset_ids

SLIDE, GRASP, GOAL = "SlideGym/TopSlide-v0", "SlideGym/TopSlideGrasp-v0", "SlideGym/TopSlideGoal-v0"
DATASET = "test/robust-v0"


def _one_line(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """``slide-gym argv`` exits 2 with one line on stderr (a ValueError); that line."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    command = " ".join(argv[:2]) if argv[0] == "bench" else argv[0]
    assert err.startswith(f"slide-gym {command}: error: ") and err.count("\n") == 1, err
    return err


def _usage_error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """``slide-gym argv`` is an argparse usage error (exit 2); its one error line."""
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err  # one line, no usage block
    line, hint = lines[0].rsplit(" (see ", 1)
    assert re.fullmatch(r"slide-gym [a-z -]+ --help\)", hint), hint
    return line


def _refuse(*args: object, **kwargs: object) -> Any:
    raise AssertionError("work started although the input was bad")


COLLECT = ["collect", "--env", SLIDE, "--episodes", "1", "--dataset-id", "t/x-v0"]
RP = ("random", "procedural")


@pytest.mark.parametrize(
    ("argv", "near", "listed"),
    [
        ([*COLLECT, "--object", "procedurl"], "procedural", RP),
        ([*COLLECT, "--table", "rando"], "random", ("random",)),
        (["run", "--object", "rando"], "random", RP),
        (["run", "--table", "randon"], "random", ("random",)),
        (["evaluate", "regions", "--episodes", "1", "--object", "procedurl"], "procedural", RP),
        (["bench", "execute", "--objects", "L,procedurl"], "procedural", ("procedural",)),
    ],
)
def test_name_lists_hold_every_accepted_name(
    argv: list[str],
    near: str,
    listed: tuple[str, ...],
    monkeypatch: pytest.MonkeyPatch,
    minari_root: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setattr("slide_gym.cli.commands._run_episode", _refuse)
    monkeypatch.setattr("slide_gym.jobs.run_cases", _refuse)
    if argv[0] == "bench":
        argv = [*argv, "--out", str(minari_root / "bench.jsonl")]
    err = _one_line(argv, capsys)
    assert f"did you mean {near!r}?" in err
    names = err.split("valid names: ")[1]
    assert all(n in names.split(" (or")[0].split(", ") for n in listed)


def test_env_and_reset_errors_name_random_and_procedural() -> None:
    with pytest.raises(ValueError, match=r"did you mean 'procedural'\? valid names: .*random"):
        gym.make(SLIDE, object="procedurl")
    env = gym.make(SLIDE)
    try:
        with pytest.raises(ValueError, match=r"unknown table 'rndom'; did you mean 'random'"):
            env.reset(seed=0, options={"table": "rndom"})
    finally:
        env.close()


def test_run_draws_a_random_table_as_the_env_does(monkeypatch: pytest.MonkeyPatch) -> None:
    """``run --table random``: the episode's table and plate are the env's draw for the seed,
    and the expert is told both (the plate is no catalog shape it could recognise)."""
    from agents import episode

    seen: dict[str, Any] = {}

    def reset_only(env: gym.Env, agent: Any, *, seed: int, **_: Any) -> Any:
        seen["info"] = env.reset(seed=seed)[1]
        seen["known"] = [o.name for o in agent.library.objects]
        seen["tables"] = [t.name for t in agent.library.tables]
        return seen["info"]

    monkeypatch.setattr(episode, "play_episode", reset_only)
    for seed in (3, 4):
        episode.run_episode("procedural", "random", seed=seed, env_id=SLIDE)
        plain = gym.make(SLIDE, object="procedural", table="random")
        try:
            _, expected = plain.reset(seed=seed)
        finally:
            plain.close()
        info = seen["info"]
        assert info["table"] == expected["table"] and info["table"] in TABLE_NAMES
        assert info["object"] == expected["object"] == f"procedural-{seed}"
        assert seen["known"][0] == info["object"] and seen["tables"][0] == info["table"]
        np.testing.assert_array_equal(info["object_pose_2d"], expected["object_pose_2d"])


def test_run_accepts_random_scenes_on_the_command_line(monkeypatch, capsys) -> None:
    got: dict[str, Any] = {}

    def fake(obj: str, table: str, **kwargs: Any) -> Any:
        got.update(object=obj, table=table)
        raise KeyboardInterrupt  # stop here: the arguments got through

    monkeypatch.setattr("slide_gym.cli.commands._run_episode", lambda: fake)
    assert main(["run", "--object", "random", "--table", "random"]) == 130
    assert got == {"object": "random", "table": "random"}


@pytest.mark.parametrize(
    "argv",
    [
        ["run"],
        ["collect", "--episodes", "1", "--dataset-id", "t/x-v0"],
        ["evaluate", "regions", "--episodes", "1"],
        ["bench", "execute"],
    ],
)
def test_an_env_the_command_cannot_drive_says_so(argv: list[str], capsys) -> None:
    line = _usage_error([*argv, "--env", GOAL], capsys)
    command = " ".join(argv[:2]) if argv[0] == "bench" else argv[0]
    assert f"slide-gym {command} cannot drive {GOAL}" in line and "goal-conditioned" in line
    assert "did you mean" not in line and SLIDE in line


@pytest.mark.parametrize(
    ("argv", "hint"),
    [
        (["run", "--objct", "L"], "did you mean --object?"),
        (["collect", "--episodes", "1", "--dataset-id", "t/x-v0", "--splt=seen"], "--split"),
        (["bench", "plan", "--trails", "3"], "did you mean --trials?"),
        (["run", "--objct", "L", "--tabel", "round"], "--object for --objct, --table for --tabel"),
    ],
)
def test_a_misspelt_option_gets_the_closest(argv: list[str], hint: str, capsys) -> None:
    line = _usage_error(argv, capsys)
    command = " ".join(argv[:2]) if argv[0] == "bench" else argv[0]
    assert line.startswith(f"slide-gym {command}: error: unrecognized arguments: ")
    assert hint in line


def test_an_unlike_option_gets_no_guess(capsys) -> None:
    line = _usage_error(["run", "--zzzzzz"], capsys)
    assert line == "slide-gym run: error: unrecognized arguments: --zzzzzz"


class _Policy:
    """A policy with SB3's ``predict`` and a card naming the env it was trained in."""

    card = {"env_id": GRASP, "env_kwargs": {"object": "square"}}

    def predict(self, obs: dict, **_: Any) -> tuple[np.ndarray, None]:
        return np.zeros(8, dtype=np.float32), None


def test_evaluate_warns_when_the_policy_comes_from_another_env(capsys) -> None:
    from agents.evaluate import evaluate

    with pytest.warns(UserWarning, match=f"trained in {GRASP}, not {SLIDE}"):
        result = evaluate(_Policy(), SLIDE, episodes=1, max_steps=2)
    assert result["env_kwargs"] == {"object": "square"}
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)  # the same env: no warning
        evaluate(_Policy(), GRASP, episodes=1, max_steps=2)
    with one_line_warnings("evaluate"):
        warnings.warn("the policy was trained in A,\n not B", stacklevel=1)
    assert capsys.readouterr().err == (
        "slide-gym evaluate: warning: the policy was trained in A, not B\n"
    )
    with one_line_warnings("evaluate"):  # gymnasium colours its own warnings
        warnings.warn("\x1b[33mWARN: out of date\x1b[0m", DeprecationWarning, stacklevel=1)
    assert capsys.readouterr().err == "slide-gym evaluate: warning: WARN: out of date\n"


# ---------------------------------------------------------------- the Minari folder
def _buffer(env: gym.Env, steps: int, seed: int) -> EpisodeBuffer:
    obs, _ = env.reset(seed=seed)
    observations = {k: [v] for k, v in obs.items()}
    actions = []
    for _ in range(steps):
        action = np.zeros(env.action_space.shape, dtype=np.float32)
        obs, *_ = env.step(action)
        actions.append(action)
        for k, v in obs.items():
            observations[k].append(v)
    return EpisodeBuffer(
        id=None,
        seed=seed,
        options=None,
        observations={k: np.stack(v) for k, v in observations.items()},
        actions=np.stack(actions),
        rewards=np.zeros(steps),
        terminations=np.zeros(steps, dtype=bool),
        truncations=np.arange(steps) == steps - 1,
        infos={"is_success": np.zeros(steps + 1, dtype=bool)},
    )


@pytest.fixture(scope="module")
def cluttered(minari_root: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 2-episode dataset of idle steps, with a LeRobot export, a half-written dataset and
    a stray file in the Minari folder beside it."""
    env = gym.make(SLIDE)
    try:
        buffers = [_buffer(env, 4, seed) for seed in (0, 1)]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # no author or permalink to give
            dataset = minari.create_dataset_from_buffers(
                dataset_id=DATASET,
                buffer=buffers,
                env=env.spec,
                algorithm_name="idle",
            )
    finally:
        env.close()
    export = tmp_path_factory.mktemp("export") / "lerobot"
    export_lerobot(dataset, export, task="idle", fps=20.0)
    shutil.move(export, minari_root / "lerobot-export")  # as written by an older version
    (minari_root / "test" / "half-v0" / "data").mkdir(parents=True)
    (minari_root / "notes.txt").write_text("not a dataset")
    return minari_root


def test_folders_that_are_not_datasets_break_no_command(
    cluttered: Path, tmp_path: Path, capsys
) -> None:
    assert local_dataset_ids() == [DATASET]
    assert load(DATASET).total_episodes == 2
    model = tmp_path / "bc.zip"
    assert main(["train-bc", DATASET, "--out", str(model), "--steps", "2"]) == 0
    assert main(["replay", DATASET, "--episodes", "1"]) == 0  # idle steps replay exactly
    capsys.readouterr()
    from agents.evaluate import evaluate

    assert evaluate(model, SLIDE, episodes=1, max_steps=2)["episodes"] == 1
    # a new dataset can still be written beside them
    env = gym.make(SLIDE)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)
            minari.create_dataset_from_buffers(
                dataset_id="test/second-v0",
                buffer=[_buffer(env, 2, 5)],
                env=env.spec,
                algorithm_name="idle",
            )
    finally:
        env.close()
    assert local_dataset_ids() == [DATASET, "test/second-v0"]


@pytest.mark.parametrize("inside", ["exports/square", "", "test/new"])
def test_export_refuses_the_minari_folder(cluttered: Path, inside: str, capsys) -> None:
    out = cluttered / inside
    err = _one_line(["export", DATASET, "--out", str(out)], capsys)
    assert "inside the Minari datasets folder" in err and "MINARI_DATASETS_PATH" in err
    assert not (cluttered / "exports").exists() and not (cluttered / "test" / "new").exists()


@pytest.mark.parametrize(
    ("option", "needle"),
    [
        ("stop_overhng=0.03", "unknown expert parameters ['stop_overhng']; allowed: "),
        ("stop_overhang=-1", "ExpertParams.stop_overhang must be a finite positive number"),
        ("stop_overhang", "--expert-param takes NAME=NUMBER"),
    ],
)
def test_collect_expert_params_are_checked_before_any_work(
    option: str,
    needle: str,
    monkeypatch: pytest.MonkeyPatch,
    minari_root: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setattr("slide_gym.jobs.run_cases", _refuse)
    assert needle in _one_line([*COLLECT, "--expert-param", option], capsys)


@pytest.mark.parametrize(
    "argv",
    [
        ["bench", "execute", "--trials", "1"],
        [*COLLECT],
        ["evaluate", "random", "--env", SLIDE, "--episodes", "1"],
        ["run", "--object", "square"],
    ],
)
@pytest.mark.parametrize(
    ("option", "needle"),
    [
        ("anchor=1", "unknown physics settings ['anchor']; allowed: solver_iterations, "),
        ("friction_anchor=2", "friction_anchor must be True or False, got 2.0"),
        ("solver_residual_threshold=0", "solver_residual_threshold must be in (0, 0.01], got 0"),
        ("timestep=0.001", "physics cannot set timestep"),
        ("friction_anchor", "--physics takes NAME=NUMBER"),
    ],
)
def test_physics_settings_are_checked_before_any_work(
    argv: list[str],
    option: str,
    needle: str,
    monkeypatch: pytest.MonkeyPatch,
    minari_root: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setattr("slide_gym.jobs.run_cases", _refuse)
    monkeypatch.setattr("agents.evaluate.evaluate", _refuse)
    monkeypatch.setattr("agents.episode.run_episode", _refuse)
    assert needle in _one_line([*argv, "--physics", option], capsys)
