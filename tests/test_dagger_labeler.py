"""DAgger's label expert keeps one plan per rollout: it follows the executed actions and is
replaced only where the learner has left its plan."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import slide_gym  # noqa: F401 - registers the envs
from agents.learned.labeler import PlanLabeler
from slide_gym.datasets.config import CollectConfig

CONFIG = CollectConfig(
    env_id="SlideGym/TopSlide-v0", object="square", table="square", control_mode="ee_delta"
)


@pytest.fixture
def scene():
    env = gym.make(CONFIG.env_id, **CONFIG.env_kwargs())
    obs, _ = env.reset(seed=3)
    base = env.unwrapped
    labeler = PlanLabeler(CONFIG, 3, 60.0, base.task.object, base.task.table)
    yield env, obs, labeler
    labeler.close()
    env.close()


def test_the_expert_follows_the_executed_actions_and_keeps_its_plan(scene):
    env, obs, labeler = scene
    rng = np.random.default_rng(0)
    targets = []
    for t in range(24):
        label = labeler.label(obs, t, t % 8 == 0)
        assert label is not None and np.isfinite(label).all()
        learner = np.r_[rng.uniform(-0.5, 0.5, 6), -1.0].astype(np.float32)
        labeler.executed(learner)
        obs, *_ = env.step(learner)
        expert = labeler.agent.expert(0)
        # the expert's command is the environment's (to the 1e-6 rad its start read off the
        # observed arm), though the learner acted
        assert np.allclose(expert.q_cmd, env.unwrapped.control.target, atol=1e-5)
        targets.append(expert.target)
    assert labeler.queries == 1 and labeler.failures == 0  # one plan: the learner stayed near
    assert not np.allclose(targets[0], targets[-1])  # and the plan went on


def test_a_plate_moved_during_the_approach_gets_a_fresh_expert(scene):
    env, obs, labeler = scene
    labeler.label(obs, 0, True)
    expert = labeler.agent.expert(0)
    assert expert.phase == "approach"
    assert not expert.off_plan(obs, 0.03, 0.005)
    moved = {**obs, "object_pose": obs["object_pose"] + np.r_[0.01, 0, 0, 0, 0, 0, 0]}
    assert expert.off_plan(moved, 0.03, 0.005)
    labeler.label(moved, 1, False)  # not at a chunk boundary: the plan stays
    assert labeler.queries == 1
    labeler.label(moved, 8, True)
    assert labeler.queries == 2 and labeler.agent.expert(0) is not expert


def _labels_of_a_halted_learner(env, obs, labeler) -> list[np.ndarray]:
    """The expert acts until 10 steps into its slide, then the learner holds the arm still
    for 30 steps; the labels of those steps."""
    t, slid, labels = 0, 0, []
    while len(labels) < 30:
        label = labeler.label(obs, t, t == 0)  # one expert: the halt must not replace it
        assert label is not None
        expert = labeler.agent.expert(0)
        slid += expert.phase == "slide"
        if slid > 10:
            labels.append(label)
            action = np.r_[np.zeros(6), label[-1]].astype(np.float32)
        else:
            action = label
        labeler.executed(action)
        obs, *_ = env.step(action)
        t += 1
        assert t < 400, "the expert never slid"
    return labels


def test_labels_for_a_lagging_learner_keep_the_plans_pace(scene):
    env, obs, labeler = scene
    labels = _labels_of_a_halted_learner(env, obs, labeler)
    largest = np.abs(np.stack(labels)[:, :-1]).max(axis=1)
    # the slide's own pace is 5 cm/s: 0.25 of the 1 cm step (tracking corrections on top)
    assert largest.max() < 0.35 and np.median(largest) > 0.1  # it still says "go on"


def test_labels_on_the_plans_clock_catch_up_at_full_speed(scene):
    env, obs, labeler = scene
    labeler.retime = False
    labels = _labels_of_a_halted_learner(env, obs, labeler)
    assert np.abs(np.stack(labels)[-1][:-1]).max() > 0.99  # what re-timing prevents


def test_labels_of_a_skipped_phase_are_given_but_withheld(scene):
    env, obs, labeler = scene
    labeler.skip_phases = frozenset({"approach"})
    label = labeler.label(obs, 0, True)
    assert label is not None and labeler.agent.expert(0).phase == "approach"
    assert labeler.withheld
    labeler.skip_phases = frozenset({"release"})
    labeler.label(obs, 1, False)
    assert not labeler.withheld


def _branch(env):
    from slide_gym.datasets.recording import reset_options

    branch = gym.make(CONFIG.env_id, **CONFIG.env_kwargs()).unwrapped
    branch.reset(seed=3, options=reset_options(env, CONFIG))
    return branch


def test_a_chunk_label_is_what_the_expert_does_next_when_it_acts(scene):
    env, obs, labeler = scene
    branch = _branch(env)
    try:
        chunks, actions = {}, []
        for t in range(64):
            label = labeler.label(obs, t, t % 8 == 0)
            if t in (0, 24, 40):
                state = env.unwrapped.get_state()
                expert = labeler.agent.expert(0)
                before = (expert.q_cmd.copy(), expert.phase, len(expert.queue))
                chunks[t] = labeler.chunk(label, branch, state, 15)
                # the learner's env and the labelling expert are as they were
                assert np.array_equal(env.unwrapped.get_state(), state)
                assert labeler.agent.expert(0) is expert
                after = (expert.q_cmd, expert.phase, len(expert.queue))
                assert np.array_equal(before[0], after[0]) and before[1:] == after[1:]
            actions.append(label)  # the expert acts itself (no follow: nothing to re-time)
            obs, *_ = env.step(label)
        actions = np.stack(actions)
        for t, chunk in chunks.items():
            assert chunk is not None and chunk.shape == (15, 7)
            assert np.array_equal(chunk[0], actions[t])
            # the copy ran the same plan in a restored world (contact caches rebuilt)
            assert np.abs(chunk - actions[t : t + 15]).max() < 0.05
    finally:
        branch.close()
