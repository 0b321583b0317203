"""The lift-off first brings the arm's rigid-finger fingertip over the measured (bent) one."""

from __future__ import annotations

import numpy as np

from agents.expert import UNLOAD_MARGIN, SlideGraspExpert
from agents.params import ExpertParams
from slide_gym.robot.kinematics import fingertip_chain
from slide_gym.robot.model import READY_ARM_Q


def _expert() -> SlideGraspExpert:
    expert = SlideGraspExpert.__new__(SlideGraspExpert)  # only what _unload_line reads
    expert.tip, expert.params = fingertip_chain(), ExpertParams()
    expert.rng = np.random.default_rng(0)
    return expert


def test_unload_line_ends_over_the_measured_fingertip():
    expert, q = _expert(), np.asarray(READY_ARM_Q, dtype=float)
    cmd = expert.tip.forward(q)[:3, 3]
    bend = np.array([0.015, -0.01, 0.02])  # the real tip: ahead of and above the command's
    line = expert._unload_line(q, {"fingertip_pose": np.r_[cmd + bend, 1.0, 0, 0, 0]})
    assert line is not None and np.allclose(line[0], q)
    end = expert.tip.forward(line[-1])[:3, 3]
    assert np.allclose(end[:2], cmd[:2] + bend[:2], atol=1e-3)
    assert abs(end[2] - (cmd[2] + 0.5 * bend[2] + UNLOAD_MARGIN)) < 1e-3


def test_no_unload_line_for_a_finger_that_is_not_bent_down():
    expert, q = _expert(), np.asarray(READY_ARM_Q, dtype=float)
    cmd = expert.tip.forward(q)[:3, 3]
    below = np.r_[cmd + [0.01, 0.0, -0.005], 1.0, 0, 0, 0]  # the real tip under the command's
    assert expert._unload_line(q, {"fingertip_pose": below}) is None
    far = np.r_[cmd + [0.2, 0.0, 0.02], 1.0, 0, 0, 0]  # beyond any tracker correction
    assert expert._unload_line(q, {"fingertip_pose": far}) is None
