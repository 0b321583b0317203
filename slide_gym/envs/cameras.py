"""Cameras of the environment: the fixed scene camera and the wrist camera on the hand.

Both render headless with PyBullet's TinyRenderer. :class:`CameraModel` is one camera as it
is now (intrinsics K, pose in the world, size, clip planes); :func:`capture` returns what it
sees: RGB, metric depth along the optical axis (the z-buffer linearised, ``far`` where
nothing is in view) and optionally each pixel's body. :meth:`TopSlideEnv.render`, the
``"rgbd"`` and the ``"pointcloud"`` observations share this code.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from slide_gym.sim import MAX_IMAGE_SIDE, pb

NEAR, FAR = 0.01, 10.0
"""Clip planes of the observation cameras (m); depth images lie in [NEAR, FAR]."""
RENDER_NEAR = 0.05
"""Near clip plane of :meth:`TopSlideEnv.render` (m; its images are as before cameras)."""
RENDER_SIZE = (480, 360)
"""(width, height) of :meth:`TopSlideEnv.render` unless ``render_width``/``render_height``."""
OBS_IMAGE_SIZE = (128, 128)
"""(width, height) of the ``"rgbd"`` observation images unless given."""
WRIST_LINK = "t42_palm"
"""The hand link the wrist camera is fixed to (its z axis is the hand's approach axis)."""
WRIST_EYE = (0.06, 0.0, 0.0)
"""Wrist camera position in the palm frame (m): 6 cm off the palm's side."""
WRIST_TARGET = (0.0, 0.0, 0.3)
"""Point the wrist camera looks at, in the palm frame (m): 30 cm out between the fingers."""
WRIST_UP = (1.0, 0.0, 0.0)
"""The wrist image's up direction in the palm frame (away from the fingers)."""
WRIST_FOV = 60.0
"""Vertical field of view of the wrist camera (degrees)."""


@dataclass(frozen=True)
class Camera:
    """The scene camera: it looks at ``target`` (world, m) from ``distance`` (m) at ``yaw``
    and ``pitch`` (degrees, PyBullet's debug-camera convention), ``fov`` degrees vertically.
    The default is the view :meth:`TopSlideEnv.render` has always had."""

    target: tuple[float, float, float] = (0.45, 0.0, 0.15)
    distance: float = 1.35
    yaw: float = 60.0
    pitch: float = -30.0
    fov: float = 45.0

    def __post_init__(self) -> None:
        try:
            target = tuple(float(v) for v in np.asarray(self.target, dtype=float).reshape(-1))
        except (TypeError, ValueError):
            target = ()
        if len(target) != 3 or not all(math.isfinite(v) for v in target):
            raise ValueError(f"camera target must be 3 finite numbers, got {self.target!r}")
        object.__setattr__(self, "target", target)
        for name in ("distance", "yaw", "pitch", "fov"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
                raise ValueError(f"camera {name} must be a number, got {value!r}")
            if not math.isfinite(value):
                raise ValueError(f"camera {name} must be finite, got {value}")
            object.__setattr__(self, name, float(value))
        if not 0.0 < self.distance <= 100.0:
            raise ValueError(f"camera distance must be in (0, 100] m, got {self.distance}")
        if not 0.0 < self.fov < 180.0:
            raise ValueError(f"camera fov must be in (0, 180) degrees, got {self.fov}")

    @classmethod
    def of(cls, spec: Camera | Mapping[str, Any] | None) -> Camera:
        """A camera from ``None`` (the default), a :class:`Camera` or a dict of its fields."""
        if spec is None:
            return cls()
        if isinstance(spec, Camera):
            return spec
        if isinstance(spec, Mapping):
            fields = {f.name for f in dataclasses.fields(cls)}
            unknown = sorted(set(spec) - fields)
            if unknown:
                raise ValueError(f"unknown camera keys {unknown}; allowed: {', '.join(fields)}")
            return cls(**spec)
        raise ValueError(f"camera must be None, a Camera or a dict, got {spec!r}")

    def view(self, client: Any) -> Any:
        """PyBullet's view matrix of this camera."""
        return client.computeViewMatrixFromYawPitchRoll(
            list(self.target), self.distance, self.yaw, self.pitch, 0.0, 2
        )


def check_size(what: str, value: Any) -> int:
    """``value`` as a whole number of pixels in 1..MAX_IMAGE_SIDE, else a ValueError."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{what} must be a whole number of pixels, got {value!r}")
    if not 1 <= value <= MAX_IMAGE_SIDE:
        raise ValueError(f"{what} must be 1..{MAX_IMAGE_SIDE} pixels, got {value}")
    return int(value)


def wrist_view(client: Any, pos: Sequence[float], quat: Sequence[float]) -> Any:
    """View matrix of the wrist camera, given the world pose of :data:`WRIST_LINK`."""
    rot = np.asarray(client.getMatrixFromQuaternion(quat), dtype=float).reshape(3, 3)
    origin = np.asarray(pos, dtype=float)
    eye = origin + rot @ WRIST_EYE
    target = origin + rot @ WRIST_TARGET
    return client.computeViewMatrix(eye.tolist(), target.tolist(), (rot @ WRIST_UP).tolist())


@dataclass(frozen=True)
class CameraModel:
    """One camera as it is now: a pinhole model in OpenCV's convention (camera x right, y down,
    z forward; pixel ``[row, column]`` is seen along the ray through ``(u, v) = (column,
    row)``), built from PyBullet's ``view`` matrix (16 numbers, column-major).

    ``intrinsics`` is K (3 x 3, pixels) and ``world_from_camera`` the camera's pose in the world
    (4 x 4: ``p_world = R p_cam + t``); ``width``, ``height`` in pixels, ``fov`` vertical in
    degrees, ``near`` and ``far`` the clip planes (m)."""

    width: int
    height: int
    fov: float
    near: float
    far: float
    view: tuple[float, ...]

    @property
    def intrinsics(self) -> np.ndarray:
        # PyBullet's projection scales y by 1 / tan(fov / 2) and x by that over the aspect
        # ratio, so both focal lengths are height / (2 tan(fov / 2)) pixels. The TinyRenderer
        # samples each pixel at its corner in OpenGL's window (y up): pixel [j, i] at
        # x = i, y = height - 1 - j, which puts the principal point at (w / 2, h / 2 - 1).
        f = 0.5 * self.height / math.tan(math.radians(self.fov) / 2.0)
        cx, cy = self.width / 2.0, self.height / 2.0 - 1.0
        return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])

    @property
    def world_from_camera(self) -> np.ndarray:
        camera_from_world = np.asarray(self.view, dtype=float).reshape(4, 4).T  # OpenGL axes
        return np.linalg.inv(camera_from_world) @ np.diag([1.0, -1.0, -1.0, 1.0])

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates ``(n, 2)`` and depths ``(n,)`` (m along the optical axis) of
        world points ``(n, 3)``."""
        pose = self.world_from_camera
        cam = (np.asarray(points, dtype=float).reshape(-1, 3) - pose[:3, 3]) @ pose[:3, :3]
        uv = cam @ self.intrinsics.T
        return uv[:, :2] / uv[:, 2:], cam[:, 2]

    def unproject(self, depth: np.ndarray, where: np.ndarray | None = None) -> np.ndarray:
        """World points ``(n, 3)`` of a depth image ``(height, width)`` (m along the optical
        axis): of every pixel row by row, or of the pixels of the mask ``where`` in that
        order."""
        z = np.asarray(depth, dtype=float).reshape(self.height, self.width)
        mask = np.ones(z.shape, dtype=bool) if where is None else where
        rows, cols = np.nonzero(mask)
        z = z[mask]
        (f, _, cx), (_, _, cy), _ = self.intrinsics
        cam = np.stack([(cols - cx) / f * z, (rows - cy) / f * z, z], axis=-1)
        pose = self.world_from_camera
        return cam @ pose[:3, :3].T + pose[:3, 3]


def capture(
    client: Any, model: CameraModel, shadow: bool = False, segmentation: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """What ``model`` sees, from the TinyRenderer (headless): RGB ``(height, width, 3)`` uint8,
    depth ``(height, width)`` float64 in metres along the optical axis (``far`` where nothing
    is in view) and, if ``segmentation``, the PyBullet body id of each pixel (int32, -1 for
    none); ``shadow`` about doubles the cost."""
    width, height, near, far = model.width, model.height, model.near, model.far
    proj = client.computeProjectionMatrixFOV(model.fov, width / height, near, far)
    _, _, rgba, zbuf, seg = client.getCameraImage(
        width,
        height,
        model.view,
        proj,
        renderer=pb.ER_TINY_RENDERER,
        shadow=int(shadow),
        flags=0 if segmentation else pb.ER_NO_SEGMENTATION_MASK,
    )
    rgb = np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3].copy()
    # The depth buffer holds OpenGL window depth in [0, 1]; invert the perspective division.
    z = np.asarray(zbuf, dtype=np.float64).reshape(height, width)
    metres = far * near / (far - (far - near) * z)
    labels = np.asarray(seg, dtype=np.int32).reshape(height, width) if segmentation else None
    return rgb, metres, labels


def render_rgbd(client: Any, model: CameraModel) -> tuple[np.ndarray, np.ndarray]:
    """RGB ``(height, width, 3)`` uint8 and depth ``(height, width, 1)`` float32 in metres,
    clipped to ``[near, far]``: the ``"rgbd"`` observation's pair of images."""
    rgb, metres, _ = capture(client, model)
    depth = np.clip(metres, model.near, model.far).astype(np.float32)
    return rgb, depth[:, :, None]


def image_size(width: int | None, height: int | None, default: tuple[int, int]) -> tuple[int, int]:
    """(width, height): each given one checked (:func:`check_size`), else its default."""
    w = default[0] if width is None else check_size("render_width", width)
    h = default[1] if height is None else check_size("render_height", height)
    return w, h


def render_frame(client: Any, camera: Camera, width: int, height: int) -> np.ndarray:
    """The scene camera's picture for :meth:`TopSlideEnv.render`: RGB with shadows."""
    model = CameraModel(width, height, camera.fov, RENDER_NEAR, FAR, camera.view(client))
    return capture(client, model, shadow=True)[0]
