"""The ``"pointcloud"`` observation and the cameras' models: shapes, dtypes, world frame and
labels on a known scene, intrinsics and extrinsics against the rendered images, and seeded,
deterministic sampling."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import shapely

import slide_gym  # noqa: F401 - registers the environments
from slide_gym.envs.cameras import CameraModel, capture
from slide_gym.envs.observation import POINT_KEYS
from slide_gym.envs.pointcloud import (
    SEGMENT_NAMES,
    farthest_point_indices,
    fuse,
    sample_indices,
    voxel_representatives,
)
from slide_gym.envs.top_slide import TopSlideEnv

W, H = 64, 48
"""Small, non-square cameras: a swapped width and height shows."""
PLATE, TABLE, ROBOT = range(3)
TOL = 1e-3
"""Metres a point may lie off its surface (the depth buffer is good to about 0.01 mm)."""


@pytest.fixture
def make_env() -> Iterator[Callable[..., TopSlideEnv]]:
    made: list[TopSlideEnv] = []

    def make(**kwargs: Any) -> TopSlideEnv:
        kwargs = {"render_width": W, "render_height": H, **kwargs}
        made.append(TopSlideEnv(**kwargs))
        return made[-1]

    yield make
    for env in made:
        env.close()


def _plate_distances(env: TopSlideEnv, xy: np.ndarray) -> np.ndarray:
    """Horizontal distance (m) of world points ``xy`` from the plate's footprint."""
    x, y, yaw = env._state.object_pose  # noqa: SLF001 - the plate as it rests now
    rot = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
    local = (xy - (x, y)) @ rot  # world -> plate frame
    return shapely.distance(env.task.object.polygon, shapely.points(local))


def _check_on_surfaces(env: TopSlideEnv, xyz: np.ndarray, labels: np.ndarray) -> None:
    """Table points on the slab, at the top where not on its sides; plate points over the
    footprint, between the table top and the plate's top face."""
    top = env.task.table.height
    plate_top = top + env.task.object.thickness
    table = xyz[labels == TABLE]
    assert np.all(table[:, 2] <= top + TOL)
    assert np.all(table[:, 2] >= top - env.task.table.slab_thickness - TOL)
    on_top = np.abs(table[:, 2] - top) < TOL
    assert on_top.mean() > 0.8  # most of what the cameras see of the table is its top
    plate = xyz[labels == PLATE]
    assert len(plate) > 0
    assert np.all(_plate_distances(env, plate[:, :2]) < TOL)
    assert np.all((plate[:, 2] > top - TOL) & (plate[:, 2] < plate_top + TOL))
    assert np.any(np.abs(plate[:, 2] - plate_top) < TOL)  # the top face is seen


def test_pointcloud_entries_have_their_shapes_dtypes_and_labels(make_env) -> None:
    env = make_env(object="A", obs_mode="pointcloud", num_points=300)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    xyz, rgb, seg = (obs[k] for k in POINT_KEYS)
    assert xyz.shape == (300, 3) and xyz.dtype == np.float32
    assert rgb.shape == (300, 3) and rgb.dtype == np.uint8 and rgb.std() > 5
    assert seg.shape == (300,) and seg.dtype == np.uint8
    assert set(np.unique(seg)) == set(range(len(SEGMENT_NAMES)))
    assert len(np.unique(xyz, axis=0)) == 300  # farthest-point sampling never repeats
    for key in ("arm_qpos", "object_pose", "table_outline"):  # the state part stays
        assert obs[key].dtype == np.float32
    _check_on_surfaces(env, xyz, seg)
    # The plate is blue, the table brown: the colours travel with the points.
    assert rgb[seg == PLATE, 2].mean() > rgb[seg == PLATE, 0].mean()
    assert rgb[seg == TABLE, 0].mean() > rgb[seg == TABLE, 2].mean()


def test_fused_cloud_lies_on_the_table_and_the_plate_in_the_world_frame(make_env) -> None:
    """Every pixel of both cameras, on two scenes (the wrist camera looks down from 0.26 m,
    the scene camera at 30 degrees from 1.35 m)."""
    for obj, seed in (("A", 0), ("square", 3)):
        env = make_env(object=obj, obs_mode="pointcloud")
        env.reset(seed=seed)
        models = env.cameras
        xyz, _, labels = fuse(env.sim.client, models.values(), env.sim.bodies)
        _check_on_surfaces(env, xyz, labels)
        top = np.abs(xyz[labels == TABLE, 2] - env.task.table.height)
        assert np.percentile(top[top < TOL], 99) < 1e-4
        # Robot points: the wrist camera sees the fingers around its view, within 0.5 m.
        wrist = models["wrist"].world_from_camera[:3, 3]
        robot = xyz[labels == ROBOT]
        assert len(robot) and np.linalg.norm(robot - wrist, axis=1).min() < 0.1


def test_intrinsics_and_extrinsics_project_a_known_point_to_its_pixel_and_back(
    make_env,
) -> None:
    env = make_env(object="square", obs_mode="rgbd")
    env.reset(seed=3)
    # Put the plate where the wrist camera's optical axis (camera +z) meets the table.
    pose = env.cameras["wrist"].world_from_camera
    reach = (env.task.table.height - pose[2, 3]) / pose[2, 2]
    x, y, _ = pose[:3, 3] + reach * pose[:3, 2]
    env.reset(seed=3, options={"object_pose": (x, y, 0.3)})
    x, y, _ = env._state.object_pose  # noqa: SLF001 - where it came to rest
    centre = np.array([x, y, env.task.table.height + env.task.object.thickness])
    for name, model in env.cameras.items():
        assert (model.width, model.height, model.near, model.far) == (W, H, 0.01, 10.0)
        k = model.intrinsics
        f = 0.5 * H / math.tan(math.radians(model.fov) / 2)
        np.testing.assert_allclose(k, [[f, 0, W / 2], [0, f, H / 2 - 1], [0, 0, 1]])
        pose = model.world_from_camera
        np.testing.assert_allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3), atol=1e-6)
        assert np.linalg.det(pose[:3, :3]) == pytest.approx(1.0, abs=1e-6)
        (u, v), depth = (a[0] for a in model.project(centre))
        col, row = round(u), round(v)
        assert 0 <= col < W and 0 <= row < H, name
        if name == "wrist":  # near the optical axis (4 mm above the table): near (cx, cy)
            np.testing.assert_allclose((u, v), k[:2, 2], atol=0.3)
        _, metres, seg = capture(env.sim.client, model, segmentation=True)
        assert seg[row, col] == env.sim.bodies["object"], name
        # Back: the pixel's depth puts its point on the plate's top face, within the pixel's
        # footprint there (a pixel's width over the sine of the 30 degree view, at most).
        back = model.unproject(metres)[row * W + col]
        assert back[2] == pytest.approx(centre[2], abs=TOL)
        assert _plate_distances(env, back[None, :2])[0] < TOL
        assert np.linalg.norm(back - centre) < 2.0 * depth / f, name
        np.testing.assert_allclose(model.project(back)[0], [[col, row]], atol=1e-6)
    scene = env.cameras["scene"].world_from_camera
    target = np.asarray(env.camera.target)
    assert np.linalg.norm(scene[:3, 3] - target) == pytest.approx(env.camera.distance)
    axis = (target - scene[:3, 3]) / env.camera.distance  # the optical axis is camera +z
    np.testing.assert_allclose(scene[:3, 2], axis, atol=1e-6)


def test_rgbd_depth_with_the_cameras_gives_the_table_height() -> None:
    env = gym.make("SlideGym/TopSlide-v0", obs_mode="rgbd", render_width=W, render_height=H)
    try:
        obs, _ = env.reset(seed=0)
        model = env.unwrapped.cameras["wrist"]
        points = model.unproject(obs["wrist_depth"])
        # The wrist camera looks down at the table: most of its pixels are the table top.
        height = env.unwrapped.task.table.height
        assert np.mean(np.abs(points[:, 2] - height) < TOL) > 0.6
        assert isinstance(model, CameraModel)
    finally:
        env.close()


def test_a_seed_replays_the_cloud_and_the_wrist_camera_moves(make_env) -> None:
    envs = [make_env(obs_mode="pointcloud", num_points=128) for _ in range(2)]
    action = np.zeros(8, dtype=np.float32)
    action[0] = 1.0  # the base joint turns: the hand and its camera swing
    runs = []
    for env in envs:
        frames = [env.reset(seed=5)[0]]
        poses = [env.cameras["wrist"].world_from_camera]
        for _ in range(3):
            frames.append(env.step(action)[0])
            poses.append(env.cameras["wrist"].world_from_camera)
        runs.append(frames)
    for a, b in zip(*runs, strict=True):
        for key in POINT_KEYS:
            np.testing.assert_array_equal(a[key], b[key])
    assert np.linalg.norm(poses[-1][:3, 3] - poses[0][:3, 3]) > 0.01
    again = envs[0].reset(seed=6)[0]["pointcloud_xyz"]
    assert not np.array_equal(again, runs[0][0]["pointcloud_xyz"])


def test_sampling_is_seeded_spread_out_and_pads_small_clouds() -> None:
    rng = np.random.default_rng(0)
    points = rng.uniform(-0.5, 0.5, (4000, 3)).astype(np.float32)
    labels = rng.integers(0, 3, 4000).astype(np.uint8)
    draws = [sample_indices(points, labels, 200, np.random.default_rng(s)) for s in (1, 1, 2)]
    np.testing.assert_array_equal(draws[0], draws[1])
    assert not np.array_equal(draws[0], draws[2]) and len(set(draws[0])) == 200

    def spacing(idx: np.ndarray) -> float:
        p = points[idx]
        d = np.linalg.norm(p[:, None] - p[None], axis=-1)
        return float(d[np.triu_indices(len(p), 1)].min())

    assert spacing(draws[0]) > 3 * spacing(rng.choice(4000, 200, replace=False))
    # Farthest-point sampling by hand on a line: 0, then the far end, then the middle.
    line = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 0, 0], [0.4, 0, 0]], dtype=np.float32)
    np.testing.assert_array_equal(farthest_point_indices(line, 3, 0), [0, 1, 2])
    # One point per voxel and label: two bodies in one voxel stay apart.
    keep = voxel_representatives(line[[2, 3, 3]], np.array([0, 0, 1]), 0.2)
    np.testing.assert_array_equal(keep, [0, 2])
    few = sample_indices(points[:5], labels[:5], 8, np.random.default_rng(3))
    np.testing.assert_array_equal(few[:5], np.arange(5))
    assert len(few) == 8 and set(few[5:]) <= set(range(5))


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"obs_mode": "pointcloud", "num_points": 0}, "num_points"),
        ({"obs_mode": "pointcloud", "num_points": 2.5}, "num_points"),
        ({"obs_mode": "rgbd", "num_points": 100}, "obs_mode='pointcloud'"),
        ({"obs_mode": "points"}, "pointcloud"),
    ],
)
def test_bad_pointcloud_arguments_are_value_errors(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        TopSlideEnv(**kwargs)


def test_cameras_need_a_reset_and_the_state_mode_has_none(make_env) -> None:
    env = make_env(obs_mode="pointcloud")
    with pytest.raises(RuntimeError, match="reset"):
        _ = env.cameras
    state = make_env()
    state.reset(seed=0)
    assert state.cameras == {}
