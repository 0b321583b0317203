"""A scripted agent for demos, tests and ``slide-gym bench env``: press the fingertip on the
object, drag it over the nearest table edge, let go. A resolved-rate controller on the NumPy
kinematics, no planner.

It is not the paper's planner (that drives :class:`agents.PlannerAgent`); it shows the physics
and the environment working end to end, and gives tests a contact-rich rollout.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
from shapely.geometry import Point

from slide_gym.envs.top_slide import TopSlideEnv
from slide_gym.geometry import quat_yaw, transform_points
from slide_gym.robot.kinematics import robot_chain

PITCH = np.deg2rad(60.0)
"""Angle between the finger axis (Z_F) and the table during the press."""


class ScriptedSlider:
    """Phases: hover above a contact point, press ``press_depth`` into the top, slide, lift.

    ``act(observation)`` returns an action for :class:`TopSlideEnv`; the controller keeps its
    own copy of the joint targets, integrated exactly as the environment does.
    """

    def __init__(
        self, env: Any, press_depth: float = 0.012, speed: float = 0.04, gain: float = 4.0
    ):
        self.env = env.unwrapped
        self.chain = robot_chain()
        self.press_depth, self.speed, self.gain = press_depth, speed, gain
        self.dt = self.env.dt
        self.q_target: np.ndarray | None = None
        self.phase = "hover"
        self.phase_steps = 0

    def _plan(self, obs: dict[str, np.ndarray]) -> None:
        task = self.env.task
        obj, table = task.object, task.table
        pose = obs["object_pose"]
        x, y, yaw = float(pose[0]), float(pose[1]), quat_yaw(pose[3:])
        cloud = obj.top_surface_points(0.01)[:, :2]
        contact_local = cloud[np.argmin(np.linalg.norm(cloud, axis=1))]
        self.contact = transform_points(contact_local[None], x, y, yaw)[0]
        boundary = table.polygon.exterior
        nearest = boundary.interpolate(boundary.project(Point(x, y)))
        to_edge = np.array([nearest.x - x, nearest.y - y])
        dist = float(np.linalg.norm(to_edge))
        self.direction = to_edge / max(dist, 1e-9)
        corners = transform_points(np.asarray(obj.polygon.exterior.coords), x, y, yaw)
        reach = float(np.max((corners - [x, y]) @ self.direction))  # object extent to the edge
        # overhang u* plus a margin, while the centroid stays at least 1 cm on the table
        self.slide_length = min(dist - reach + task.params.u_star + 0.015, dist - 0.01)
        self.top = table.height + obj.thickness
        radial = self.contact / max(np.linalg.norm(self.contact), 1e-9)
        z_axis = np.r_[np.cos(PITCH) * radial, -np.sin(PITCH)]
        x_axis = np.r_[radial[1], -radial[0], 0.0]  # so that finger B (on -Y_F) is above A
        self.rotation = np.column_stack([x_axis, np.cross(z_axis, x_axis), z_axis])

    def _target_position(self) -> np.ndarray:
        c = np.r_[self.contact, self.top]
        k = self.phase_steps
        if self.phase == "hover":  # come in from above, clear of the object
            return c + [0, 0, 0.04 + max(0.0, 0.06 - k * self.speed * self.dt)]
        if self.phase == "press":
            return c + [0, 0, 0.04 - min(k * self.speed * self.dt, 0.04 + self.press_depth)]
        slid = np.r_[self.direction * self.slide_length, -self.press_depth]
        if self.phase == "slide":
            frac = min(k * self.speed * self.dt / self.slide_length, 1.0)
            return c + np.r_[slid[:2] * frac, slid[2]]
        return c + slid + [0, 0, min(k * self.speed * self.dt, 0.06) + self.press_depth]

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        if self.q_target is None:
            self.q_target = np.asarray(obs["arm_qpos"], dtype=float).copy()
            self._plan(obs)
        t, jac = self.chain.jacobian(self.q_target)
        p_err = self._target_position() - t[:3, 3]
        r = t[:3, :3]
        r_err = 0.5 * sum(np.cross(r[:, i], self.rotation[:, i]) for i in range(3))
        twist = np.r_[self.gain * p_err, self.gain * r_err] * self.dt
        damping = 1e-3
        dq = jac.T @ np.linalg.solve(jac @ jac.T + damping * np.eye(6), twist)
        action = np.zeros(8, dtype=np.float32)
        action[:7] = np.clip(dq / self.env.max_joint_step, -1.0, 1.0)
        action[7] = -1.0
        self.q_target = np.clip(
            self.q_target + self.env.max_joint_step * action[:7],
            self.env.observation_space["arm_qpos"].low + 0.2,
            self.env.observation_space["arm_qpos"].high - 0.2,
        )
        self._advance(np.linalg.norm(p_err))
        return action

    def _advance(self, err: float) -> None:
        self.phase_steps += 1
        done = {
            "hover": err < 0.005 and self.phase_steps > 10,
            "press": self.phase_steps * self.speed * self.dt >= 0.04 + self.press_depth + 0.01,
            "slide": self.phase_steps * self.speed * self.dt >= self.slide_length + 0.01,
            "lift": False,
        }[self.phase]
        if done:
            order = ["hover", "press", "slide", "lift"]
            self.phase = order[order.index(self.phase) + 1]
            self.phase_steps = 0


def run_demo(
    object_name: str, table_name: str, seed: int = 0, out: Path | None = None, max_steps: int = 300
) -> dict[str, Any]:
    """Run one scripted slide in ``SlideGym/TopSlide-v0``, optionally saving a GIF."""
    import imageio.v3 as iio

    env = TopSlideEnv(
        object=object_name, table=table_name, render_mode="rgb_array" if out else None
    )
    wall = time.perf_counter()
    obs, info = env.reset(seed=seed)
    start = info["object_pose_2d"]
    policy = ScriptedSlider(env)
    frames = [env.render()] if out else []
    steps = 0
    try:
        for steps in range(1, max_steps + 1):
            obs, _, terminated, truncated, info = env.step(policy.act(obs))
            if out and steps % 2 == 0:
                frames.append(env.render())
            if terminated or truncated:
                break
    finally:
        env.close()
    if out:
        out.parent.mkdir(parents=True, exist_ok=True)
        iio.imwrite(out, np.stack(frames), duration=1000 * 2 * policy.dt, loop=0)
    return {
        "object": object_name,
        "table": table_name,
        "seed": seed,
        "success": info["is_success"],
        "steps": steps,
        "sim_time_s": steps * policy.dt,
        "wall_time_s": time.perf_counter() - wall,
        "object_start_pose": list(start),
        "object_final_pose": list(info["object_pose_2d"]),
        "overhang_m": info["overhang_m"],
        "video": str(out) if out else None,
    }
