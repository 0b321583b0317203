"""Engine settings: plate and table collision shapes, and the free-mode switch.

Near the object the world steps at ``PhysicsParams.timestep`` with ``solver_iterations``;
while the robot is farther than ``near_distance`` from it, steps are ``free_step_factor``
times longer with ``free_solver_iterations``. The control period never changes.
"""

from __future__ import annotations

import numpy as np
import pytest

from slide_gym.bench.env import arm_speeds
from slide_gym.envs.top_slide import TopSlideEnv
from slide_gym.sim import PhysicsParams, Simulation, pb, physics_overrides

FAR = (0.75, 0.2, 0.0)
"""A square plate's start pose on the square table, more than 10 cm from the robot."""
UNDER = (0.6, 0.0, 0.0)
"""A start pose under the hand: :data:`LOWER` brings the fingers within 10 cm of it."""
LOWER = np.array([0, 1, 0, -1, 0, 0, 0, -1], dtype=np.float32)
"""Shoulder forward, elbow open, hand open: the hand goes down toward the table."""


def _lowered_env(steps: int = 3) -> TopSlideEnv:
    env = TopSlideEnv(object="square", table="square")
    env.reset(seed=0, options={"object_pose": UNDER})
    for _ in range(steps):
        env.step(LOWER)
    return env


def _engine(sim: Simulation) -> tuple[float, int]:
    p = sim.client.getPhysicsEngineParameters()
    return p["fixedTimeStep"], p["numSolverIterations"]


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("solver_iterations", 0),
        ("free_solver_iterations", 2.5),
        ("free_step_factor", 0),
        ("free_step_factor", True),
        ("near_distance", -0.1),
        ("prism_margin", float("nan")),
        ("friction_anchor", 1),
        ("solver_residual_threshold", 0.0),
        ("solver_residual_threshold", float("nan")),
        ("solver_residual_threshold", 0.5),
        ("solver_residual_threshold", "1e-4"),
    ],
)
def test_bad_physics_settings_are_rejected(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=field):
        PhysicsParams(**{field: value})


def test_physics_from_a_dict_takes_json_and_cli_values() -> None:
    """``--physics`` passes floats and ``gym.make`` JSON: 0/1 flags and whole floats count."""
    assert physics_overrides({"friction_anchor": 1.0, "solver_iterations": 50.0}) == {
        "friction_anchor": True,
        "solver_iterations": 50,
    }
    assert physics_overrides(None) is None
    with pytest.raises(ValueError, match="unknown physics settings \\['anchor'\\]; allowed: "):
        physics_overrides({"anchor": 1})
    with pytest.raises(ValueError, match="physics_hz sets it"):
        physics_overrides({"timestep": 0.001})
    with pytest.raises(ValueError, match="friction_anchor must be True or False, got 2"):
        physics_overrides({"friction_anchor": 2})
    with pytest.raises(ValueError, match="unknown physics settings"):
        TopSlideEnv(physics={"anchor": True})


def test_friction_anchor_is_set_on_every_robot_link_only_when_asked(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    calls: list[tuple[int, int]] = []
    change = pb.changeDynamics

    def recording(body: int, link: int, **kwargs: object) -> None:
        if "frictionAnchor" in kwargs:
            calls.append((body, link))
        change(body, link, **kwargs)

    monkeypatch.setattr(pb, "changeDynamics", recording)
    env = TopSlideEnv()
    env.reset(seed=0)
    env.close()
    assert calls == []
    env = TopSlideEnv(physics={"friction_anchor": True})
    env.reset(seed=0)
    robot = env.sim.bodies["robot"]
    links = env.sim.client.getNumJoints(robot)
    assert env.sim.settings.friction_anchor
    assert calls == [(robot, link) for link in range(-1, links)]
    env.close()


def test_the_solver_residual_threshold_reaches_the_engine(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """PyBullet does not report the threshold back, so the calls that set it are recorded;
    a looser threshold then gives another pressed world than the default's."""
    thresholds: list[float] = []
    client_set = pb.setPhysicsEngineParameter

    def recording(**kwargs: object) -> None:
        if "solverResidualThreshold" in kwargs:
            thresholds.append(float(kwargs["solverResidualThreshold"]))  # type: ignore[arg-type]
        client_set(**kwargs)

    monkeypatch.setattr(pb, "setPhysicsEngineParameter", recording)
    states = []
    for physics in (None, {"solver_residual_threshold": 1e-2}):
        env = TopSlideEnv(object="square", table="square", physics=physics)
        try:
            env.reset(seed=0, options={"object_pose": UNDER})
            for _ in range(30):
                obs, *_ = env.step(LOWER)
            states.append(np.concatenate([obs["arm_qpos"], obs["finger_qpos"]]))
        finally:
            env.close()
    assert thresholds and set(thresholds) == {1e-7, 1e-2}
    assert not np.array_equal(states[0], states[1])


def test_the_free_robot_takes_longer_cheaper_steps_and_the_near_one_full_ones() -> None:
    env = TopSlideEnv(object="square", table="square")
    try:
        s = env.sim.settings
        env.reset(seed=0, options={"object_pose": FAR})
        assert env.sim.adapt(env.n_substeps) == s.free_step_factor == 2
        assert env.sim.physics.timestep == pytest.approx(2 * s.timestep)
        assert _engine(env.sim) == (pytest.approx(2 * s.timestep), s.free_solver_iterations)
        assert env.dt == pytest.approx(0.05)  # the control period is the same

    finally:
        env.close()
    env = _lowered_env()
    try:
        s = env.sim.settings
        assert env.sim.adapt(env.n_substeps) == 1
        assert env.sim.physics is s
        assert _engine(env.sim) == (pytest.approx(s.timestep), s.solver_iterations)
        assert env.dt == pytest.approx(0.05)
    finally:
        env.close()


def test_an_odd_substep_count_keeps_the_base_steps() -> None:
    """physics_hz = 13 x control_hz: 13 substeps cannot be paired; free mode only cuts the
    solver iterations."""
    env = TopSlideEnv(object="square", table="square", physics_hz=260.0)
    try:
        env.reset(seed=0, options={"object_pose": FAR})
        s = env.sim.settings
        assert env.sim.adapt(env.n_substeps) == 1 and env.sim.physics is s
        assert _engine(env.sim) == (pytest.approx(s.timestep), s.free_solver_iterations)
    finally:
        env.close()


def test_free_mode_off_is_the_plain_world() -> None:
    plain = PhysicsParams(free_step_factor=1, free_solver_iterations=100)
    sim = Simulation(physics=plain)
    try:
        assert sim.adapt(12) == 1 and _engine(sim) == (pytest.approx(1 / 240), 100)
    finally:
        sim.close()


def test_episodes_across_both_modes_replay_exactly() -> None:
    """The switch depends on the state only: a seed and actions replay bit for bit."""
    actions = np.random.default_rng(0).uniform(-1, 1, (60, 8)).astype(np.float32)
    actions[:20] = LOWER
    runs = []
    for _ in range(2):
        env = TopSlideEnv(object="square", table="square")
        obs, _ = env.reset(seed=0, options={"object_pose": UNDER})
        steps = []
        for a in actions:
            obs, *_ = env.step(a)
            steps.append(env.sim.physics.timestep)
        runs.append((obs["arm_qpos"].copy(), obs["object_pose"].copy(), steps))
        env.close()
    assert len(set(runs[0][2])) == 2, "the episode should visit both modes"
    assert np.array_equal(runs[0][0], runs[1][0]) and np.array_equal(runs[0][1], runs[1][1])
    assert runs[0][2] == runs[1][2]


def test_prisms_collide_at_their_real_size() -> None:
    """A sphere rests on the table top itself, not on a 1 mm margin above it."""
    import pybullet as pb

    from slide_gym.geometry import get_table
    from slide_gym.task import add_table_body

    sim = Simulation()
    try:
        add_table_body(sim, get_table("square"))
        c = sim.client
        shape = c.createCollisionShape(pb.GEOM_SPHERE, radius=0.01)
        ball = c.createMultiBody(0.05, shape, basePosition=[0.6, 0.0, 0.02])
        for _ in range(240):
            sim.step()
        gap = c.getBasePositionAndOrientation(ball)[0][2] - 0.01
        assert abs(gap) < 2.5 * sim.settings.prism_margin
    finally:
        sim.close()


@pytest.mark.parametrize("seed", [5, 7])
def test_random_actions_never_send_the_arm_flying(seed: int) -> None:
    """With a random hand command the fingers close on nothing; pressed together by the
    tendon they once made the arm diverge (these seeds: joint speeds pinned at 20 rad/s;
    now only the fingertips collide with each other, see ``WamT42.load``)."""
    (fastest,) = arm_speeds(episodes=1, steps=300, seed=seed)["fastest_per_episode"]
    assert fastest < 8.0
