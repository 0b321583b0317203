"""Cameras of the environment: the fixed scene camera and the wrist camera on the hand.

Both render headless with PyBullet's TinyRenderer. :func:`render_rgbd` returns an RGB image
(H, W, 3) uint8 and, if asked, a depth image (H, W, 1) float32 in metres: the distance along
the camera's optical axis (the z-buffer linearised), ``FAR`` where nothing is in view.
:meth:`TopSlideEnv.render` and the ``"rgbd"`` observation share this code.
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


def render_rgbd(
    client: Any,
    view: Any,
    width: int,
    height: int,
    fov: float,
    depth: bool = True,
    shadow: bool = False,
    near: float = NEAR,
) -> tuple[np.ndarray, np.ndarray | None]:
    """RGB (height, width, 3) uint8 and, if ``depth``, depth (height, width, 1) float32 in
    metres from the TinyRenderer (headless); ``shadow`` about doubles the cost."""
    proj = client.computeProjectionMatrixFOV(fov, width / height, near, FAR)
    _, _, rgba, zbuf, _ = client.getCameraImage(
        width,
        height,
        view,
        proj,
        renderer=pb.ER_TINY_RENDERER,
        shadow=int(shadow),
        flags=pb.ER_NO_SEGMENTATION_MASK,
    )
    rgb = np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3].copy()
    if not depth:
        return rgb, None
    z = np.asarray(zbuf, dtype=np.float64).reshape(height, width, 1)
    metres = FAR * near / (FAR - (FAR - near) * z)
    return rgb, np.clip(metres, near, FAR).astype(np.float32)


def image_size(width: int | None, height: int | None, default: tuple[int, int]) -> tuple[int, int]:
    """(width, height): each given one checked (:func:`check_size`), else its default."""
    w = default[0] if width is None else check_size("render_width", width)
    h = default[1] if height is None else check_size("render_height", height)
    return w, h


def render_frame(client: Any, camera: Camera, width: int, height: int) -> np.ndarray:
    """The scene camera's picture for :meth:`TopSlideEnv.render`: RGB with shadows."""
    rgb, _ = render_rgbd(
        client,
        camera.view(client),
        width,
        height,
        camera.fov,
        depth=False,
        shadow=True,
        near=RENDER_NEAR,
    )
    return rgb
