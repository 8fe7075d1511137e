"""Host side of the headless ray-caster: validates layers, packs them for the kernel, caches.

Typical use (one task, fixed camera, every step)::

    renderer = Renderer(32, 32, Camera(position=(0, -0.8, 0.9), look_at=(0, 0, 0)))
    images = renderer.render([cloth_layer, picker_layer], num_worlds=W)   # (W, 32, 32, 3) uint8

Caching: the cloth ``wp.Mesh`` (one mesh, triangles grouped by world) is built on the first call
and afterwards only refitted to the new vertex positions; it is rebuilt when the topology
changes (other ``indices``, vertex count or world count) and, to keep the BVH tight while the
cloth crumples, every ``rebuild_every`` calls (0 = never). Small geometry (spheres, capsules,
boxes) is packed on the host each call and uploaded in one copy per buffer.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np
import warp as wp

from .camera import Camera
from .raycast import SceneData, ViewData, render_kernel
from .scene import (
    BoxLayer,
    CapsuleChainLayer,
    SphereLayer,
    TriangleMeshLayer,
    as_color,
    is_warp_array,
)

__all__ = ["Renderer", "DEFAULT_CAMERA"]

#: A camera looking at the origin of the table from the front and above (about 50 degrees down).
DEFAULT_CAMERA = Camera(position=(0.0, -0.75, 0.9), look_at=(0.0, 0.0, 0.0), fov_y_deg=45.0)

_MAX_PIXELS = 4096


# ---------------------------------------------------------------------------- input helpers
def _positions(name: str, value: Any, num_worlds: int, shared_ok: bool = True) -> tuple[Any, int, bool]:
    """Return ``(data, n_per_world, shared)``.

    ``data`` is a float32 numpy array ``(W*n, 3)`` / ``(n, 3)`` (shared) or a flat ``wp.array``
    of vec3. Raises ``ValueError`` on wrong shapes or non-finite values (warp arrays on a CUDA
    device are not checked for finiteness, to avoid a device sync).
    """
    if is_warp_array(value):
        arr = value
        if arr.ndim == 2:
            if arr.shape[0] != num_worlds:
                raise ValueError(f"{name} has shape {arr.shape} but num_worlds={num_worlds}")
            arr = arr.flatten()
        if arr.size % num_worlds != 0:
            raise ValueError(
                f"{name} has {arr.size} entries, not a multiple of num_worlds={num_worlds} "
                "(expected a flat wp.array of W*N wp.vec3)"
            )
        if arr.device.is_cpu:
            host = arr.numpy()
            if not np.isfinite(host).all():
                raise ValueError(f"{name} contains NaN or inf")
        return arr, arr.size // num_worlds, False
    arr = np.asarray(value, dtype=np.float32)
    if arr.ndim == 3:
        if arr.shape[0] != num_worlds:
            raise ValueError(f"{name} has shape {arr.shape}: leading axis must be num_worlds={num_worlds}")
        n, shared = arr.shape[1], False
    elif arr.ndim == 2 and shared_ok:
        n, shared = arr.shape[0], True
    else:
        raise ValueError(f"{name} must have shape (W, N, 3){' or (N, 3)' if shared_ok else ''}, got {arr.shape}")
    if arr.shape[-1] != 3 or n < 1:
        raise ValueError(f"{name} must have shape (W, N, 3) or (N, 3) with N >= 1, got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} contains NaN or inf")
    return np.ascontiguousarray(arr.reshape(-1, 3)), n, shared


def _host(value: Any) -> Any:
    """warp array -> numpy (small arrays only); anything else unchanged."""
    if is_warp_array(value):
        out = value.numpy()
        if value.dtype == wp.vec3:
            out = out.reshape(-1, 3)
        return out
    return value


def _quat_to_mat(q: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions (x, y, z, w) -> (..., 3, 3) rotation matrices."""
    x, y, z, w = (q[..., i] for i in range(4))
    m = np.empty(q.shape[:-1] + (3, 3), dtype=np.float64)
    m[..., 0, 0] = 1 - 2 * (y * y + z * z)
    m[..., 0, 1] = 2 * (x * y - z * w)
    m[..., 0, 2] = 2 * (x * z + y * w)
    m[..., 1, 0] = 2 * (x * y + z * w)
    m[..., 1, 1] = 1 - 2 * (x * x + z * z)
    m[..., 1, 2] = 2 * (y * z - x * w)
    m[..., 2, 0] = 2 * (x * z - y * w)
    m[..., 2, 1] = 2 * (y * z + x * w)
    m[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return m


class _DeviceBuffer:
    """A growable device array written from numpy each call (zero-copy view on CPU)."""

    def __init__(self, dtype: Any, device: wp.context.Device, width: int = 1) -> None:
        self.dtype = dtype
        self.device = device
        self.width = width  # numpy trailing size per element (3 for vec3, 9 for mat33)
        self.array: wp.array | None = None
        self.capacity = -1
        self._last: np.ndarray | None = None

    def upload(self, data: np.ndarray) -> tuple[wp.array, bool]:
        """Copy ``data`` (n, width) or (n,) to the device; returns (array, reallocated)."""
        n = max(int(data.shape[0]), 1)
        realloc = False
        if self.array is None or n != self.capacity:
            self.array = wp.zeros(n, dtype=self.dtype, device=self.device)
            self.capacity = n
            self._last = None
            realloc = True
        if data.shape[0] == 0:
            return self.array, realloc
        if self._last is not None and self._last.shape == data.shape and np.array_equal(self._last, data):
            return self.array, realloc
        if self.device.is_cpu:
            view = self.array.numpy()
            view.reshape(data.shape)[...] = data
        else:
            self.array.assign(np.ascontiguousarray(data))
        self._last = data.copy()
        return self.array, realloc


# ---------------------------------------------------------------------------- renderer
class Renderer:
    """Batched headless ray-caster (Warp kernels; same code on ``cpu`` and ``cuda``).

    Args:
        width: Image width in pixels (>= 1).
        height: Image height in pixels (>= 1).
        camera: The :class:`Camera` (may be replaced later by assigning ``renderer.camera``).
            ``None`` uses :data:`DEFAULT_CAMERA`.
        device: Warp device, e.g. ``"cpu"`` or ``"cuda:0"``.
        background: Colour of rays that hit nothing.
        ground: Draw the ground/table plane ``z = ground_height``.
        ground_height: Height of that plane (the table top is z = 0).
        ground_color: Base colour of the plane.
        checker_size: Checker tile size in metres (0 = flat colour); odd tiles are 10% darker.
        light_direction: Direction *towards* the light (need not be unit).
        ambient: Ambient term in [0, 1]; the diffuse term is ``1 - ambient``.
        shadows: Cast a shadow ray per hit (about 1.5-2x the cost).
        supersample: ``s`` -> ``s*s`` rays per pixel averaged (anti-aliasing), 1..4.
        rebuild_every: Rebuild the cloth BVH every this many renders instead of refitting
            (0 = refit only; the BVH is always rebuilt when the topology changes).

    Output: :meth:`render` returns ``uint8`` RGB of shape ``(W, height, width, 3)``.
    """

    def __init__(
        self,
        width: int = 32,
        height: int = 32,
        camera: Camera | None = None,
        device: str | wp.context.Device = "cpu",
        *,
        background: Any = (0.80, 0.85, 0.90),
        ground: bool = True,
        ground_height: float = 0.0,
        ground_color: Any = (0.62, 0.60, 0.56),
        checker_size: float = 0.1,
        light_direction: Any = (0.3, -0.4, 1.0),
        ambient: float = 0.4,
        shadows: bool = False,
        supersample: int = 1,
        rebuild_every: int = 0,
    ) -> None:
        for name, value in (("width", width), ("height", height)):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 1 <= value <= _MAX_PIXELS:
                raise ValueError(f"{name} must be an int in [1, {_MAX_PIXELS}], got {value!r}")
        self.width = int(width)
        self.height = int(height)
        self.camera = DEFAULT_CAMERA if camera is None else camera
        try:
            self.device = wp.get_device(device)
        except Exception as exc:  # warp raises RuntimeError/ValueError depending on version
            raise ValueError(f"unknown warp device {device!r}: {exc}") from None
        self.background = as_color("background", background)
        self.ground_color = as_color("ground_color", ground_color)
        self.ground = bool(ground)
        self.ground_height = _finite("ground_height", ground_height)
        self.checker_size = _finite("checker_size", checker_size)
        if self.checker_size < 0:
            raise ValueError(f"checker_size must be >= 0, got {checker_size!r}")
        light = np.asarray(light_direction, dtype=np.float64)
        if light.shape != (3,) or not np.isfinite(light).all() or np.linalg.norm(light) < 1e-9:
            raise ValueError(f"light_direction must be a finite non-zero 3-vector, got {light_direction!r}")
        self.light_direction = light / np.linalg.norm(light)
        self.ambient = _finite("ambient", ambient)
        if not 0.0 <= self.ambient <= 1.0:
            raise ValueError(f"ambient must be in [0, 1], got {ambient!r}")
        self.shadows = bool(shadows)
        if isinstance(supersample, bool) or not isinstance(supersample, (int, np.integer)) or not 1 <= supersample <= 4:
            raise ValueError(f"supersample must be an int in [1, 4], got {supersample!r}")
        self.supersample = int(supersample)
        if isinstance(rebuild_every, bool) or not isinstance(rebuild_every, (int, np.integer)) or rebuild_every < 0:
            raise ValueError(f"rebuild_every must be an int >= 0, got {rebuild_every!r}")
        self.rebuild_every = int(rebuild_every)

        dev = self.device
        self._scene = SceneData()
        self._mesh: wp.Mesh | None = None
        self._mesh_key: tuple | None = None
        self._mesh_indices: list[np.ndarray] = []
        self._mesh_colors: tuple | None = None
        self._renders_since_build = 0
        self._out: wp.array | None = None
        self._dummy_vec3 = wp.zeros(1, dtype=wp.vec3, device=dev)
        self._bufs = {
            "face_front": _DeviceBuffer(wp.vec3, dev, 3),
            "face_back": _DeviceBuffer(wp.vec3, dev, 3),
            "round_pt_off": _DeviceBuffer(wp.int32, dev),
            "round_pt_stride": _DeviceBuffer(wp.int32, dev),
            "round_prim_off": _DeviceBuffer(wp.int32, dev),
            "round_prim_cnt": _DeviceBuffer(wp.int32, dev),
            "round_lo": _DeviceBuffer(wp.vec3, dev, 3),
            "round_hi": _DeviceBuffer(wp.vec3, dev, 3),
            "pts": _DeviceBuffer(wp.vec3, dev, 3),
            "prim_a": _DeviceBuffer(wp.int32, dev),
            "prim_b": _DeviceBuffer(wp.int32, dev),
            "prim_r": _DeviceBuffer(wp.float32, dev),
            "prim_color": _DeviceBuffer(wp.vec3, dev, 3),
            "box_off": _DeviceBuffer(wp.int32, dev),
            "box_stride": _DeviceBuffer(wp.int32, dev),
            "box_cnt": _DeviceBuffer(wp.int32, dev),
            "box_color_off": _DeviceBuffer(wp.int32, dev),
            "box_lo": _DeviceBuffer(wp.vec3, dev, 3),
            "box_hi": _DeviceBuffer(wp.vec3, dev, 3),
            "box_center": _DeviceBuffer(wp.vec3, dev, 3),
            "box_rot": _DeviceBuffer(wp.mat33, dev, 9),
            "box_half": _DeviceBuffer(wp.vec3, dev, 3),
            "box_color": _DeviceBuffer(wp.vec3, dev, 3),
        }
        s = self._scene
        s.face_front = s.face_back = self._dummy_vec3
        s.has_mesh = 0
        s.mesh_id = wp.uint64(0)
        s.tris_per_world = 1

    # ------------------------------------------------------------------ public API
    def render(self, layers: Sequence[Any], num_worlds: int | None = None) -> np.ndarray:
        """Render all worlds; returns a new ``uint8`` array ``(num_worlds, height, width, 3)``.

        Args:
            layers: Any mix of :class:`TriangleMeshLayer`, :class:`SphereLayer`,
                :class:`CapsuleChainLayer` and :class:`BoxLayer` (possibly several of a kind).
            num_worlds: Number of worlds ``W``. ``None`` infers it from the leading axis of
                numpy ``(W, N, 3)`` inputs (1 if there are none); pass it explicitly when the
                positions come as flat ``wp.array`` s.
        """
        out = self.render_warp(layers, num_worlds)
        host = out.numpy()
        return host.copy() if self.device.is_cpu else host

    def render_single(self, layers: Sequence[Any]) -> np.ndarray:
        """Render one world; returns ``uint8`` ``(height, width, 3)``."""
        return self.render(layers, 1)[0]

    def render_warp(self, layers: Sequence[Any], num_worlds: int | None = None) -> wp.array:
        """Like :meth:`render` but returns the device ``wp.array`` (uint8, 4-D).

        The array is reused by the next call; copy it if you keep it. Useful on CUDA to feed a
        GPU learner without a round trip through host memory.
        """
        if isinstance(layers, (TriangleMeshLayer, SphereLayer, CapsuleChainLayer, BoxLayer)):
            layers = [layers]
        try:
            layers = list(layers)
        except TypeError:
            raise ValueError(f"layers must be a sequence of layer objects, got {type(layers).__name__}") from None
        for k, layer in enumerate(layers):
            if not isinstance(layer, (TriangleMeshLayer, SphereLayer, CapsuleChainLayer, BoxLayer)):
                raise ValueError(
                    f"layers[{k}] is a {type(layer).__name__}; expected TriangleMeshLayer, SphereLayer, "
                    "CapsuleChainLayer or BoxLayer"
                )
        W = self._num_worlds(layers, num_worlds)
        if not isinstance(self.camera, Camera):
            raise ValueError(f"renderer.camera must be a Camera, got {type(self.camera).__name__}")

        s = self._scene
        s.num_worlds = W
        s.ground_on = int(self.ground)
        s.ground_z = float(self.ground_height)
        s.ground_color = wp.vec3(*self.ground_color)
        s.checker_size = float(self.checker_size)
        self._pack_mesh([l for l in layers if isinstance(l, TriangleMeshLayer)], W)
        self._pack_round([l for l in layers if isinstance(l, (SphereLayer, CapsuleChainLayer))], W)
        self._pack_boxes([l for l in layers if isinstance(l, BoxLayer)], W)

        if self._out is None or self._out.shape[0] != W:
            self._out = wp.empty((W, self.height, self.width, 3), dtype=wp.uint8, device=self.device)
        cols = self.width if self.device.is_cpu else 1
        wp.launch(
            render_kernel,
            dim=(W, self.height, (self.width + cols - 1) // cols),
            inputs=[s, self._view(), self.supersample, cols],
            outputs=[self._out],
            device=self.device,
        )
        return self._out

    # ------------------------------------------------------------------ internals
    def _num_worlds(self, layers: list, num_worlds: int | None) -> int:
        if num_worlds is not None:
            if isinstance(num_worlds, bool) or not isinstance(num_worlds, (int, np.integer)) or num_worlds < 1:
                raise ValueError(f"num_worlds must be an int >= 1, got {num_worlds!r}")
            return int(num_worlds)
        found = set()
        for layer in layers:
            for value in (getattr(layer, "points", None), getattr(layer, "centers", None)):
                if value is not None and not is_warp_array(value):
                    shape = np.shape(value)
                    if len(shape) == 3:
                        found.add(shape[0])
        if len(found) > 1:
            raise ValueError(f"layers disagree on the number of worlds: leading axes {sorted(found)}")
        return found.pop() if found else 1

    def _view(self) -> ViewData:
        forward, right, up = self.camera.basis()
        tx, ty = self.camera.tan_half_fov(self.width, self.height)
        v = ViewData()
        v.origin = wp.vec3(*self.camera.position)
        v.forward = wp.vec3(*forward)
        v.right = wp.vec3(*(right * tx))
        v.up = wp.vec3(*(up * ty))
        v.background = wp.vec3(*self.background)
        v.light_dir = wp.vec3(*self.light_direction)
        v.ambient = float(self.ambient)
        v.diffuse = float(1.0 - self.ambient)
        v.shadows = int(self.shadows)
        v.max_dist = 1.0e4
        return v

    def _pack_mesh(self, layers: list[TriangleMeshLayer], W: int) -> None:
        s = self._scene
        if not layers:
            s.has_mesh = 0
            return
        sources = []
        key: list = [W]
        for k, layer in enumerate(layers):
            name = f"TriangleMeshLayer[{k}].points"
            if layer.offset_by_world:
                if not is_warp_array(layer.points) and np.ndim(layer.points) == 2 and W != 1:
                    raise ValueError(
                        f"{name} has shape {np.shape(layer.points)} but num_worlds={W}; give (W, Nv, 3) "
                        "or set offset_by_world=False to draw the same mesh in every world"
                    )
                data, nv, _ = _positions(name, layer.points, W)
            else:
                data, nv, _ = _positions(name, layer.points, 1)
            sources.append((data, nv, layer.offset_by_world))
            key.append((nv, layer.indices.shape[0], layer.offset_by_world))

        key_t = tuple(key)
        same_topology = (
            self._mesh is not None
            and key_t == self._mesh_key
            and all(a is b or np.array_equal(a, b) for a, b in zip(self._mesh_indices, (l.indices for l in layers)))
        )
        rebuild = not same_topology or (self.rebuild_every > 0 and self._renders_since_build >= self.rebuild_every)

        if not same_topology:
            for k, (layer, (_, nv, _)) in enumerate(zip(layers, sources)):
                if layer.indices.max() >= nv:
                    raise ValueError(
                        f"TriangleMeshLayer[{k}].indices reference vertex {int(layer.indices.max())} "
                        f"but each world has only {nv} vertices"
                    )
            total_v = sum(W * nv for _, nv, _ in sources)
            points = wp.zeros(total_v, dtype=wp.vec3, device=self.device)
            self._mesh_points = points
            self._mesh_voff = []
            voff = 0
            for _, nv, _ in sources:
                self._mesh_voff.append(voff)
                voff += W * nv
            # faces world-major so that face % tris_per_world is the face within one world
            per_world = []
            for w in range(W):
                for (_, nv, _), layer, vo in zip(sources, layers, self._mesh_voff):
                    per_world.append(layer.indices + (vo + w * nv))
            indices = np.concatenate(per_world).astype(np.int32).ravel()
            tris_per_world = sum(l.indices.shape[0] for l in layers)
            groups = np.repeat(np.arange(W, dtype=np.int32), tris_per_world)
            self._mesh_index_array = wp.array(indices, dtype=wp.int32, device=self.device)
            self._mesh_groups = wp.array(groups, dtype=wp.int32, device=self.device)
            self._mesh_key = key_t
            self._mesh_indices = [l.indices for l in layers]
            self._mesh_colors = None
            s.tris_per_world = tris_per_world

        # vertex positions
        pts = self._mesh_points
        host_view = pts.numpy() if self.device.is_cpu else None
        for (data, nv, per_world), vo in zip(sources, self._mesh_voff):
            n = W * nv
            reps = 1 if per_world else W
            for r in range(reps):
                off = vo + r * nv
                count = n if per_world else nv
                if is_warp_array(data):
                    wp.copy(pts, data, dest_offset=off, src_offset=0, count=count)
                elif host_view is not None:
                    host_view[off : off + count] = data
                else:
                    pts[off : off + count].assign(data)

        if rebuild:
            self._mesh = wp.Mesh(points=pts, indices=self._mesh_index_array, groups=self._mesh_groups)
            self._renders_since_build = 0
        else:
            self._mesh.refit()
            self._renders_since_build += 1
        s.has_mesh = 1
        s.mesh_id = self._mesh.id

        colors = tuple((tuple(l.front_color), tuple(l.back_color), l.indices.shape[0]) for l in layers)
        if colors != self._mesh_colors:
            front = np.concatenate([np.broadcast_to(l.front_color, (l.indices.shape[0], 3)) for l in layers])
            back = np.concatenate([np.broadcast_to(l.back_color, (l.indices.shape[0], 3)) for l in layers])
            s.face_front, _ = self._bufs["face_front"].upload(front.astype(np.float32))
            s.face_back, _ = self._bufs["face_back"].upload(back.astype(np.float32))
            self._mesh_colors = colors

    def _pack_round(self, layers: list, W: int) -> None:
        s = self._scene
        s.n_round_layers = len(layers)
        pts_parts, a_parts, b_parts, r_parts, c_parts = [], [], [], [], []
        pt_off, pt_stride, prim_off, prim_cnt = [], [], [], []
        lo = np.zeros((max(len(layers), 1) * W, 3), np.float32)
        hi = np.zeros_like(lo)
        n_pts = n_prims = 0
        for k, layer in enumerate(layers):
            if isinstance(layer, SphereLayer):
                name = f"SphereLayer[{k}]"
                data, n, shared = _positions(f"{name}.centers", _host(layer.centers), W)
                radii = np.asarray(layer.radii, dtype=np.float32)
                if radii.ndim == 1 and radii.shape[0] != n:
                    raise ValueError(f"{name}.radii has {radii.shape[0]} entries but there are {n} spheres")
                radii = np.broadcast_to(radii, (n,))
                colors = as_color(f"{name}.colors", layer.colors, n)
                a = b = np.arange(n, dtype=np.int32)
            else:
                name = f"CapsuleChainLayer[{k}]"
                data, n, shared = _positions(f"{name}.points", _host(layer.points), W)
                pcol = as_color(f"{name}.colors", layer.colors, n)
                if n == 1:
                    a = b = np.zeros(1, np.int32)
                else:
                    a = np.arange(n - 1, dtype=np.int32)
                    b = a + 1
                    if layer.closed and n > 2:
                        a = np.append(a, n - 1).astype(np.int32)
                        b = np.append(b, 0).astype(np.int32)
                colors = pcol[a]
                radii = np.full(a.shape[0], float(layer.radius), np.float32)
            pts_parts.append(data)
            pt_off.append(n_pts)
            pt_stride.append(0 if shared else n)
            n_pts += data.shape[0]
            prim_off.append(n_prims)
            prim_cnt.append(a.shape[0])
            n_prims += a.shape[0]
            a_parts.append(a)
            b_parts.append(b)
            r_parts.append(radii)
            c_parts.append(colors)
            per_world = data.reshape(1 if shared else W, n, 3)
            pad = float(radii.max())
            lo[k * W : (k + 1) * W] = per_world.min(axis=1) - pad
            hi[k * W : (k + 1) * W] = per_world.max(axis=1) + pad

        def cat(parts, shape, dtype):
            return np.concatenate(parts).astype(dtype, copy=False) if parts else np.zeros(shape, dtype)

        b_ = self._bufs
        s.pts, _ = b_["pts"].upload(cat(pts_parts, (0, 3), np.float32))
        s.prim_a, _ = b_["prim_a"].upload(cat(a_parts, (0,), np.int32))
        s.prim_b, _ = b_["prim_b"].upload(cat(b_parts, (0,), np.int32))
        s.prim_r, _ = b_["prim_r"].upload(cat(r_parts, (0,), np.float32))
        s.prim_color, _ = b_["prim_color"].upload(cat(c_parts, (0, 3), np.float32))
        s.round_pt_off, _ = b_["round_pt_off"].upload(np.asarray(pt_off, np.int32))
        s.round_pt_stride, _ = b_["round_pt_stride"].upload(np.asarray(pt_stride, np.int32))
        s.round_prim_off, _ = b_["round_prim_off"].upload(np.asarray(prim_off, np.int32))
        s.round_prim_cnt, _ = b_["round_prim_cnt"].upload(np.asarray(prim_cnt, np.int32))
        s.round_lo, _ = b_["round_lo"].upload(lo)
        s.round_hi, _ = b_["round_hi"].upload(hi)

    def _pack_boxes(self, layers: list[BoxLayer], W: int) -> None:
        s = self._scene
        s.n_box_layers = len(layers)
        centers_p, rot_p, half_p, col_p = [], [], [], []
        off, stride, cnt, col_off = [], [], [], []
        lo = np.zeros((max(len(layers), 1) * W, 3), np.float32)
        hi = np.zeros_like(lo)
        n_boxes = n_cols = 0
        for k, layer in enumerate(layers):
            name = f"BoxLayer[{k}]"
            centers, n, shared = _positions(f"{name}.centers", _host(layer.centers), W)
            half = _finite_array(f"{name}.half_extents", _host(layer.half_extents))
            if half.shape == (3,):
                half = np.broadcast_to(half, (n, 3))
            if half.shape not in ((n, 3), (W, n, 3)):
                raise ValueError(f"{name}.half_extents must have shape (3,), ({n}, 3) or ({W}, {n}, 3), got {half.shape}")
            if np.any(half <= 0):
                raise ValueError(f"{name}.half_extents must be > 0")
            rot = layer.rotations
            if rot is None:
                rot = np.broadcast_to(np.eye(3), (n, 3, 3))
            else:
                rot = _finite_array(f"{name}.rotations", _host(rot))
                if is_warp_array(layer.rotations) and layer.rotations.dtype == wp.mat33:
                    rot = rot.reshape(-1, 3, 3)
                    rot = rot.reshape(W, n, 3, 3) if rot.shape[0] == W * n and not shared else rot
                elif is_warp_array(layer.rotations):
                    rot = rot.reshape(-1, 4)
                    rot = rot.reshape(W, n, 4) if rot.shape[0] == W * n and not shared else rot
                if rot.shape[-1] == 4 and rot.shape[:-1] in ((n,), (W, n)):
                    norm = np.linalg.norm(rot, axis=-1, keepdims=True)
                    if np.any(norm < 1e-6):
                        raise ValueError(f"{name}.rotations contains a zero quaternion")
                    rot = _quat_to_mat(rot / norm)
                elif rot.shape[-2:] != (3, 3) or rot.shape[:-2] not in ((n,), (W, n)):
                    raise ValueError(
                        f"{name}.rotations must be None, ({n}, 3, 3), ({W}, {n}, 3, 3), ({n}, 4) or ({W}, {n}, 4); "
                        f"got {rot.shape}"
                    )
            per_world = shared and half.ndim == 2 and rot.ndim == 3
            reps = 1 if per_world else W
            c = centers.reshape(1 if shared else W, n, 3)
            c = np.broadcast_to(c, (reps, n, 3)).reshape(-1, 3)
            h = np.broadcast_to(half, (reps, n, 3)).reshape(-1, 3)
            R = np.broadcast_to(rot, (reps, n, 3, 3)).reshape(-1, 3, 3)
            ext = np.einsum("bij,bj->bi", np.abs(R), h)
            glo = (c - ext).reshape(reps, n, 3).min(axis=1)
            ghi = (c + ext).reshape(reps, n, 3).max(axis=1)
            lo[k * W : (k + 1) * W] = glo
            hi[k * W : (k + 1) * W] = ghi
            centers_p.append(c)
            rot_p.append(R.reshape(-1, 9))
            half_p.append(h)
            col_p.append(as_color(f"{name}.colors", layer.colors, n))
            off.append(n_boxes)
            stride.append(0 if per_world else n)
            cnt.append(n)
            col_off.append(n_cols)
            n_boxes += c.shape[0]
            n_cols += n

        def cat(parts, shape):
            return np.concatenate(parts).astype(np.float32, copy=False) if parts else np.zeros(shape, np.float32)

        b_ = self._bufs
        s.box_center, _ = b_["box_center"].upload(cat(centers_p, (0, 3)))
        s.box_rot, _ = b_["box_rot"].upload(cat(rot_p, (0, 9)))
        s.box_half, _ = b_["box_half"].upload(cat(half_p, (0, 3)))
        s.box_color, _ = b_["box_color"].upload(cat(col_p, (0, 3)))
        s.box_off, _ = b_["box_off"].upload(np.asarray(off, np.int32))
        s.box_stride, _ = b_["box_stride"].upload(np.asarray(stride, np.int32))
        s.box_cnt, _ = b_["box_cnt"].upload(np.asarray(cnt, np.int32))
        s.box_color_off, _ = b_["box_color_off"].upload(np.asarray(col_off, np.int32))
        s.box_lo, _ = b_["box_lo"].upload(lo)
        s.box_hi, _ = b_["box_hi"].upload(hi)


def _finite(name: str, value: Any) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite number, got {value!r}") from None
    if not math.isfinite(out):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return out


def _finite_array(name: str, value: Any) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array") from None
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} contains NaN or inf")
    return arr
