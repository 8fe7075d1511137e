"""What to draw: plain dataclasses, independent of the particle engine.

Every layer describes the same kind of object in all ``W`` worlds of a batch. Positions are
given either as numpy arrays shaped ``(W, N, 3)`` or as a flat ``wp.array`` of ``wp.vec3`` with
``W * N`` entries (world-major, the particle engine's layout). Arrays without the leading world
axis (``(N, 3)``) describe static scenery drawn identically in every world.

Colours are RGB triples in ``[0, 1]``; a colour whose largest value exceeds 1 is read as
0-255 (so ``(255, 0, 0)`` and ``(1.0, 0.0, 0.0)`` are the same red).

Layers:

* :class:`TriangleMeshLayer` - cloth (two-sided: ``front_color`` where the ray hits the side
  the winding normal points to, ``back_color`` on the other side).
* :class:`SphereLayer` - pickers, particles, any spheres.
* :class:`CapsuleChainLayer` - rope: capsules between consecutive particles.
* :class:`BoxLayer` - oriented boxes: table, plank, pin block, rigid boxes.

Layers are validated on construction (what does not depend on the number of worlds) and again
by :meth:`lfd_envs.render.Renderer.render` (world count, lengths, finite values); bad input
raises ``ValueError`` with the offending layer field named.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Union

import numpy as np
import warp as wp

__all__ = [
    "TriangleMeshLayer",
    "SphereLayer",
    "CapsuleChainLayer",
    "BoxLayer",
    "Layer",
    "grid_triangles",
    "PICKER_COLOR",
    "CLOTH_FRONT_COLOR",
    "CLOTH_BACK_COLOR",
    "ROPE_COLOR",
]

#: Default colours (RGB in [0, 1]).
PICKER_COLOR = (1.0, 1.0, 1.0)
CLOTH_FRONT_COLOR = (0.85, 0.33, 0.22)
CLOTH_BACK_COLOR = (0.22, 0.48, 0.85)
ROPE_COLOR = (0.85, 0.72, 0.25)
BOX_COLOR = (0.55, 0.42, 0.30)

ArrayOrWarp = Union[np.ndarray, "wp.array", Any]


# ---------------------------------------------------------------------------- helpers
def as_color(name: str, value: Any, count: int | None = None) -> np.ndarray:
    """Normalise a colour or a per-item colour array to float32 ``(count, 3)`` in [0, 1].

    ``count=None`` requires a single colour and returns shape ``(3,)``.
    """
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an RGB colour (3 numbers) or an (N, 3) array, got {value!r}") from None
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    if arr.size and arr.max() > 1.0:
        arr = arr / 255.0
    if arr.size and (arr.min() < 0.0 or arr.max() > 1.0):
        raise ValueError(f"{name} must lie in [0, 1] (or 0-255), got {value!r}")
    if count is None:
        if arr.shape != (3,):
            raise ValueError(f"{name} must be one RGB colour of shape (3,), got shape {arr.shape}")
        return arr.astype(np.float32)
    if arr.shape == (3,):
        return np.broadcast_to(arr.astype(np.float32), (count, 3)).copy()
    if arr.shape != (count, 3):
        raise ValueError(f"{name} must have shape (3,) or ({count}, 3), got {arr.shape}")
    return arr.astype(np.float32)


def is_warp_array(value: Any) -> bool:
    """True for a ``warp.array`` (any device)."""
    return isinstance(value, wp.array)


def _check_positions_static(name: str, value: Any) -> None:
    """Shape checks that do not need the world count."""
    if is_warp_array(value):
        if value.dtype != wp.vec3 or value.ndim not in (1, 2):
            raise ValueError(
                f"{name} as a warp array must be 1-D (or 2-D (W, N)) of wp.vec3, "
                f"got dtype {getattr(value.dtype, '__name__', value.dtype)} with ndim {value.ndim}"
            )
        if value.size == 0:
            raise ValueError(f"{name} must not be empty")
        return
    try:
        arr = np.asarray(value, dtype=np.float32)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array of shape (W, N, 3) or (N, 3)") from None
    if arr.ndim not in (2, 3) or arr.shape[-1] != 3 or arr.size == 0:
        raise ValueError(f"{name} must have shape (W, N, 3) or (N, 3) with N >= 1, got {arr.shape}")


def grid_triangles(rows: int, cols: int) -> np.ndarray:
    """Triangle indices ``(2*(rows-1)*(cols-1), 3)`` int32 for a row-major particle grid.

    Particle ``(r, c)`` has index ``r * cols + c``. With particles laid out so that ``c`` grows
    along +x and ``r`` along +y, the triangles wind counter-clockwise seen from +z, i.e. the
    *front* side faces up.
    """
    if rows < 2 or cols < 2:
        raise ValueError(f"a cloth grid needs at least 2x2 particles, got {rows}x{cols}")
    r, c = np.meshgrid(np.arange(rows - 1), np.arange(cols - 1), indexing="ij")
    i00 = (r * cols + c).ravel()
    i01 = i00 + 1
    i10 = i00 + cols
    i11 = i10 + 1
    tri = np.empty((i00.size * 2, 3), dtype=np.int32)
    tri[0::2] = np.stack([i00, i01, i11], axis=1)
    tri[1::2] = np.stack([i00, i11, i10], axis=1)
    return tri


# ---------------------------------------------------------------------------- layers
@dataclass
class TriangleMeshLayer:
    """A two-sided triangle mesh per world (cloth).

    Args:
        points: Vertex positions: numpy ``(W, Nv, 3)`` or flat ``wp.array(dtype=wp.vec3)`` of
            ``W * Nv`` entries (world-major). With ``offset_by_world=False``: one world's
            vertices, numpy ``(Nv, 3)`` or a ``wp.array`` of ``Nv`` entries.
        indices: ``(T, 3)`` int triangle indices, LOCAL to one world (0 <= i < Nv).
        front_color: Colour of the side the winding normal ``(b-a) x (c-a)`` points to.
        back_color: Colour of the other side.
        offset_by_world: ``True`` (default): ``points`` holds every world's vertices and world
            ``w`` uses vertices ``w*Nv ... w*Nv+Nv-1``. ``False``: one mesh shared by all worlds.

    The renderer keeps the BVH between calls and only refits it when the points move; it is
    rebuilt only when the topology (``indices``, ``Nv``, world count) changes.
    """

    points: ArrayOrWarp
    indices: Any
    front_color: Any = CLOTH_FRONT_COLOR
    back_color: Any = CLOTH_BACK_COLOR
    offset_by_world: bool = True

    def __post_init__(self) -> None:
        _check_positions_static("TriangleMeshLayer.points", self.points)
        try:
            idx = np.asarray(self.indices)
        except (TypeError, ValueError):
            raise ValueError("TriangleMeshLayer.indices must be an int array of shape (T, 3)") from None
        if idx.ndim != 2 or idx.shape[1] != 3 or idx.shape[0] < 1:
            raise ValueError(f"TriangleMeshLayer.indices must have shape (T, 3) with T >= 1, got {idx.shape}")
        if not np.issubdtype(idx.dtype, np.integer):
            if not np.all(np.isfinite(idx)) or not np.all(idx == np.round(idx)):
                raise ValueError("TriangleMeshLayer.indices must be integers")
        if idx.min() < 0:
            raise ValueError(f"TriangleMeshLayer.indices must be >= 0, got min {idx.min()}")
        self.indices = np.ascontiguousarray(idx, dtype=np.int32)
        self.front_color = as_color("TriangleMeshLayer.front_color", self.front_color)
        self.back_color = as_color("TriangleMeshLayer.back_color", self.back_color)
        if self.offset_by_world not in (True, False):
            raise ValueError(f"TriangleMeshLayer.offset_by_world must be a bool, got {self.offset_by_world!r}")


@dataclass
class SphereLayer:
    """Spheres, e.g. pickers (white) or particles.

    Args:
        centers: numpy ``(W, S, 3)`` or flat ``wp.array(dtype=wp.vec3)`` of ``W * S`` entries;
            numpy ``(S, 3)`` = the same spheres in every world.
        radii: One radius or ``(S,)`` radii (metres, > 0).
        colors: One colour or ``(S, 3)`` colours.
    """

    centers: ArrayOrWarp
    radii: Any = 0.015
    colors: Any = PICKER_COLOR

    def __post_init__(self) -> None:
        _check_positions_static("SphereLayer.centers", self.centers)
        _check_radii("SphereLayer.radii", self.radii)


@dataclass
class CapsuleChainLayer:
    """A chain of capsules through consecutive points per world (rope).

    Args:
        points: numpy ``(W, P, 3)`` or flat ``wp.array(dtype=wp.vec3)`` of ``W * P`` entries
            (P >= 1; a single point draws a sphere).
        radius: Capsule radius (metres, > 0), usually the particle radius.
        colors: One colour or ``(P, 3)`` per-point colours (segment ``i`` takes point ``i``'s
            colour) - handy for striped ropes that show twist and direction.
        closed: Also join the last point to the first.
    """

    points: ArrayOrWarp
    radius: float = 0.01
    colors: Any = ROPE_COLOR
    closed: bool = False

    def __post_init__(self) -> None:
        _check_positions_static("CapsuleChainLayer.points", self.points)
        _check_radii("CapsuleChainLayer.radius", self.radius, scalar_only=True)


@dataclass
class BoxLayer:
    """Oriented boxes (table, plank, pin block, rigid boxes).

    Args:
        centers: numpy ``(W, B, 3)`` (or ``(B, 3)`` = same in every world) or flat
            ``wp.array(dtype=wp.vec3)`` of ``W * B`` entries.
        half_extents: ``(B, 3)`` or ``(W, B, 3)`` half sizes along the box axes (> 0); ``(3,)``
            for all boxes; or a flat ``wp.array`` of vec3 with ``B`` or ``W * B`` entries.
        rotations: ``None`` (axis aligned), rotation matrices ``(W, B, 3, 3)`` / ``(B, 3, 3)``
            (columns are the box axes in world frame), or unit quaternions ``(W, B, 4)`` /
            ``(B, 4)`` in Warp's ``(x, y, z, w)`` order; or a flat ``wp.array`` of ``wp.mat33``
            or ``wp.quat`` with ``W * B`` entries (the particle engine's layout).

    Box data is small: warp inputs are copied to the host and the layer is re-packed only when
    its content changes (static boxes cost nothing per frame).
        colors: One colour or ``(B, 3)``.
    """

    centers: ArrayOrWarp
    half_extents: Any
    rotations: Any = None
    colors: Any = BOX_COLOR

    def __post_init__(self) -> None:
        _check_positions_static("BoxLayer.centers", self.centers)


Layer = Union[TriangleMeshLayer, SphereLayer, CapsuleChainLayer, BoxLayer]


def _check_radii(name: str, value: Any, scalar_only: bool = False) -> None:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive number{'' if scalar_only else ' or an (S,) array'}") from None
    if scalar_only and arr.ndim != 0:
        raise ValueError(f"{name} must be a single positive number, got shape {arr.shape}")
    if arr.ndim > 1 or arr.size == 0 or not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f"{name} must be finite and > 0 (a number or an (S,) array), got {value!r}")
