"""Pinhole camera shared by the ray-caster and by code that needs to know what is visible.

Conventions (used by :mod:`lfd_envs.render.raycast` too, so a point projected here lands on
the pixel that the renderer draws it in):

* World is z-up, metres; the table top is the plane z = 0.
* Images are indexed ``image[row, col]``; row 0 is the top of the image.
* Pixel ``(row, col)`` covers the continuous square ``[col, col+1) x [row, row+1)`` in
  pixel coordinates ``(u, v)`` and its ray passes through the centre ``(col+0.5, row+0.5)``.
  ``Camera.project`` returns ``(u, v)``, so ``image[int(v), int(u)]`` is the pixel a point
  falls into.
* ``fov_y_deg`` is the vertical field of view; the horizontal one follows from the aspect ratio.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from lfd_envs.core.errors import check_int_range

__all__ = ["Camera"]


def _vec3(name: str, value: Any) -> tuple[float, float, float]:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"Camera.{name} must be 3 finite numbers, got {value!r}") from None
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"Camera.{name} must be 3 finite numbers, got {value!r}")
    return (float(arr[0]), float(arr[1]), float(arr[2]))


@dataclass(frozen=True)
class Camera:
    """A pinhole camera looking from ``position`` towards ``look_at``.

    Args:
        position: Camera centre in world coordinates (metres).
        look_at: Point the optical axis passes through.
        up: Approximate up direction; only its component orthogonal to the view direction
            is used. Must not be parallel to the view direction.
        fov_y_deg: Vertical field of view in degrees, in (0, 180).

    Example:
        >>> cam = Camera(position=(0.0, -0.8, 0.8), look_at=(0.0, 0.0, 0.0))
        >>> uv = cam.project([[0.0, 0.0, 0.0]], width=32, height=32)  # centre of the image
    """

    position: tuple[float, float, float]
    look_at: tuple[float, float, float] = (0.0, 0.0, 0.0)
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    fov_y_deg: float = 45.0

    def __post_init__(self) -> None:
        pos = _vec3("position", self.position)
        target = _vec3("look_at", self.look_at)
        up = _vec3("up", self.up)
        object.__setattr__(self, "position", pos)
        object.__setattr__(self, "look_at", target)
        object.__setattr__(self, "up", up)
        try:
            fov = float(self.fov_y_deg)
        except (TypeError, ValueError):
            raise ValueError(f"Camera.fov_y_deg must be a number in (0, 180), got {self.fov_y_deg!r}") from None
        if not (math.isfinite(fov) and 0.0 < fov < 180.0):
            raise ValueError(f"Camera.fov_y_deg must be a number in (0, 180), got {self.fov_y_deg!r}")
        object.__setattr__(self, "fov_y_deg", fov)
        forward = np.subtract(target, pos)
        if np.linalg.norm(forward) < 1e-9:
            raise ValueError("Camera.look_at must differ from Camera.position")
        forward = forward / np.linalg.norm(forward)
        right = np.cross(forward, np.asarray(up))
        if np.linalg.norm(right) < 1e-6 * max(1.0, float(np.linalg.norm(up))):
            raise ValueError(
                f"Camera.up {up} is zero or parallel to the view direction {tuple(forward.round(4))}; "
                "choose another up vector (e.g. (0, 1, 0) for a camera looking straight down)"
            )

    # ------------------------------------------------------------------ geometry
    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return unit ``(forward, right, up)`` vectors (float64) of the camera frame.

        ``right`` points to increasing image columns, ``up`` to decreasing image rows.
        """
        forward = np.subtract(self.look_at, self.position)
        forward = forward / np.linalg.norm(forward)
        right = np.cross(forward, np.asarray(self.up))
        right = right / np.linalg.norm(right)
        true_up = np.cross(right, forward)
        return forward, right, true_up

    def tan_half_fov(self, width: int, height: int) -> tuple[float, float]:
        """Return ``(tan(fov_x/2), tan(fov_y/2))`` for an image of ``width`` x ``height``."""
        width, height = _check_size(width, height)
        ty = math.tan(math.radians(self.fov_y_deg) * 0.5)
        return ty * width / height, ty

    def project(
        self,
        points: Any,
        width: int,
        height: int,
        return_depth: bool = False,
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """Project world points to continuous pixel coordinates ``(u, v)`` = (column, row).

        Args:
            points: Array-like of shape ``(..., 3)``.
            width: Image width in pixels.
            height: Image height in pixels.
            return_depth: Also return the depth along the optical axis (metres).

        Returns:
            ``uv`` of shape ``(..., 2)`` (float64). Points behind the camera get ``nan``.
            ``image[int(v), int(u)]`` is the pixel containing the point when
            ``0 <= u < width`` and ``0 <= v < height``. With ``return_depth``, a tuple
            ``(uv, depth)`` where ``depth`` has shape ``(...)``.
        """
        width, height = _check_size(width, height)
        pts = np.asarray(points, dtype=np.float64)
        if pts.ndim == 0 or pts.shape[-1] != 3:
            raise ValueError(f"points must have shape (..., 3), got {pts.shape}")
        forward, right, up = self.basis()
        tx, ty = self.tan_half_fov(width, height)
        rel = pts - np.asarray(self.position)
        z = rel @ forward
        with np.errstate(divide="ignore", invalid="ignore"):
            x = (rel @ right) / (z * tx)
            y = (rel @ up) / (z * ty)
        u = (x + 1.0) * 0.5 * width
        v = (1.0 - y) * 0.5 * height
        uv = np.stack([u, v], axis=-1)
        uv[z <= 1e-9] = np.nan
        if return_depth:
            return uv, z
        return uv

    def pixel(self, point: Any, width: int, height: int) -> tuple[int, int] | None:
        """Return the ``(row, col)`` of the pixel containing ``point``, or ``None`` if off-image."""
        uv = self.project(np.asarray(point, dtype=np.float64).reshape(3), width, height)
        if not np.all(np.isfinite(uv)):
            return None
        col, row = int(math.floor(uv[0])), int(math.floor(uv[1]))
        if 0 <= row < height and 0 <= col < width:
            return row, col
        return None

    def is_visible(self, points: Any, width: int, height: int) -> np.ndarray:
        """Boolean mask ``(...)``: whether each point projects inside the image (ignores occlusion)."""
        uv = self.project(points, width, height)
        with np.errstate(invalid="ignore"):
            return (
                np.isfinite(uv).all(axis=-1)
                & (uv[..., 0] >= 0)
                & (uv[..., 0] < width)
                & (uv[..., 1] >= 0)
                & (uv[..., 1] < height)
            )


def _check_size(width: Any, height: Any) -> tuple[int, int]:
    return check_int_range("width", width, 1), check_int_range("height", height, 1)
