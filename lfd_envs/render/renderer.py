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

from lfd_envs.core.errors import check_int_range

from .camera import Camera
from .raycast import (
    ROUND_CLUSTER,
    SceneData,
    ViewData,
    accumulate_vertex_normals,
    render_kernel,
    round_cluster_bounds,
)
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
def _positions(
    name: str, value: Any, num_worlds: int, shared_ok: bool = True, to_host: bool = False
) -> tuple[Any, int, bool]:
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
        if arr.device.is_cpu or to_host:
            host = arr.numpy().reshape(-1, 3)
            if not np.isfinite(host).all():
                raise ValueError(f"{name} contains NaN or inf")
            if to_host:
                return host, arr.size // num_worlds, False
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


def _key(value: Any) -> Any:
    """A hashable fingerprint of a (small) layer parameter, to detect changes cheaply."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, tuple) and all(isinstance(v, (int, float)) for v in value):
        return value
    arr = np.asarray(_host(value))
    return (arr.shape, arr.dtype.str, arr.tobytes())


class _DeviceBuffer:
    """A device array plus a host-side numpy array to fill (the same memory on CPU)."""

    def __init__(self, dtype: Any, device: wp.context.Device, width: int = 1) -> None:
        self.dtype = dtype
        self.device = device
        self.width = width  # floats/ints per element (3 for vec3, 9 for mat33, 1 for scalars)
        self.array: wp.array | None = None
        self.host: np.ndarray | None = None

    def resize(self, n: int) -> bool:
        """Make room for ``n`` elements; True if the device array was (re)allocated."""
        n = max(int(n), 1)
        if self.array is not None and self.array.shape[0] == n:
            return False
        self.array = wp.zeros(n, dtype=self.dtype, device=self.device)
        shape = (n, self.width) if self.width > 1 else (n,)
        if self.device.is_cpu:
            self.staging = None
            self.host = self.array.numpy().reshape(shape)  # zero-copy view
        else:
            self.staging = wp.zeros(n, dtype=self.dtype, device="cpu", pinned=True)
            self.host = self.staging.numpy().reshape(shape)
        return True

    def sync(self) -> None:
        """Copy the host array to the device (no-op on CPU, where they share memory)."""
        if self.staging is not None:
            wp.copy(self.array, self.staging)


# ---------------------------------------------------------------------------- renderer
_BUFFERS = {
    # name: (dtype, width)
    "face_front": (wp.vec3, 3),
    "face_back": (wp.vec3, 3),
    "round_pt_off": (wp.int32, 1),
    "round_pt_stride": (wp.int32, 1),
    "round_prim_off": (wp.int32, 1),
    "round_prim_cnt": (wp.int32, 1),
    "round_bound_off": (wp.int32, 1),
    "round_bound_layer": (wp.int32, 1),
    "round_lo": (wp.vec3, 3),
    "round_hi": (wp.vec3, 3),
    "pts": (wp.vec3, 3),
    "prim_a": (wp.int32, 1),
    "prim_b": (wp.int32, 1),
    "prim_r": (wp.float32, 1),
    "prim_color": (wp.vec3, 3),
    "box_off": (wp.int32, 1),
    "box_stride": (wp.int32, 1),
    "box_cnt": (wp.int32, 1),
    "box_color_off": (wp.int32, 1),
    "box_lo": (wp.vec3, 3),
    "box_hi": (wp.vec3, 3),
    "box_center": (wp.vec3, 3),
    "box_rot": (wp.mat33, 9),
    "box_half": (wp.vec3, 3),
    "box_color": (wp.vec3, 3),
}

_LAYER_TYPES = (TriangleMeshLayer, SphereLayer, CapsuleChainLayer, BoxLayer)


class Renderer:
    """Batched headless ray-caster (Warp kernels; same code on ``cpu`` and ``cuda``).

    Args:
        width: Image width in pixels (1..4096).
        height: Image height in pixels (1..4096).
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
        shadows: Cast a shadow ray per hit (roughly doubles the kernel time).
        smooth_shading: Shade the cloth with interpolated vertex normals (one extra small
            kernel per render) instead of flat per-triangle normals.
        supersample: ``s`` -> ``s*s`` rays per pixel averaged (anti-aliasing), 1..4.
        rebuild_every: Rebuild the cloth BVH every this many renders instead of refitting
            (0 = refit only; the BVH is always rebuilt when the topology changes).

    The lighting/colour attributes may be changed between calls. :meth:`render` returns
    ``uint8`` RGB of shape ``(W, height, width, 3)``.
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
        smooth_shading: bool = True,
        supersample: int = 1,
        rebuild_every: int = 0,
    ) -> None:
        self.width = check_int_range("width", width, 1, _MAX_PIXELS)
        self.height = check_int_range("height", height, 1, _MAX_PIXELS)
        if camera is not None and not isinstance(camera, Camera):
            raise ValueError(f"camera must be a Camera or None, got {type(camera).__name__}")
        self.camera = DEFAULT_CAMERA if camera is None else camera
        try:
            self.device = wp.get_device(device)
        except Exception as exc:  # warp raises RuntimeError/ValueError depending on version
            raise ValueError(f"unknown warp device {device!r}: {exc}") from None
        self.background = background
        self.ground = ground
        self.ground_height = ground_height
        self.ground_color = ground_color
        self.checker_size = checker_size
        self.light_direction = light_direction
        self.ambient = ambient
        self.shadows = shadows
        self.smooth_shading = smooth_shading
        self.supersample = check_int_range("supersample", supersample, 1, 4)
        self.rebuild_every = check_int_range("rebuild_every", rebuild_every, 0)
        self._settings_key: tuple | None = None
        self._check_settings()  # validate now, not at the first render

        self._scene = SceneData()
        self._bufs = {name: _DeviceBuffer(dt, self.device, width_) for name, (dt, width_) in _BUFFERS.items()}
        for name, buf in self._bufs.items():
            buf.resize(1)
            setattr(self._scene, name, buf.array)
        self._scene.has_mesh = 0
        self._scene.mesh_id = wp.uint64(0)
        self._scene.tris_per_world = 1
        self._scene.smooth = 0
        self._dummy_int = wp.zeros(1, dtype=wp.int32, device=self.device)
        self._scene.mesh_indices = self._dummy_int
        self._scene.vertex_normals = self._bufs["face_front"].array
        self._scene.n_round_layers = 0
        self._scene.n_box_layers = 0
        self._scene_vals: dict[str, Any] = {}
        self._view_data: ViewData | None = None
        self._view_key: tuple | None = None
        self._mesh: wp.Mesh | None = None
        self._mesh_key: tuple | None = None
        self._mesh_indices: list[np.ndarray] = []
        self._mesh_colors: tuple | None = None
        self._renders_since_build = 0
        self._round_sig: tuple | None = None
        self._round_layout: list[tuple] = []
        self._box_sig: tuple | None = None
        self._out: wp.array | None = None
        self._launches: dict[str, tuple] = {}

    # ------------------------------------------------------------------ public API
    def render(self, layers: Sequence[Any], num_worlds: int | None = None) -> np.ndarray:
        """Render all worlds; returns a new ``uint8`` array ``(num_worlds, height, width, 3)``.

        Args:
            layers: Any mix of :class:`TriangleMeshLayer`, :class:`SphereLayer`,
                :class:`CapsuleChainLayer` and :class:`BoxLayer` (several of a kind allowed;
                a single layer may be passed without a list).
            num_worlds: Number of worlds ``W``. ``None`` infers it from the leading axis of
                numpy ``(W, N, 3)`` inputs (1 if there are none); pass it explicitly when the
                positions come as flat ``wp.array`` s.

        Raises:
            ValueError: on malformed layers (shapes, sizes, NaN/inf positions, bad colours).
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
        if isinstance(layers, _LAYER_TYPES):
            layers = [layers]
        try:
            layers = list(layers)
        except TypeError:
            raise ValueError(f"layers must be a sequence of layer objects, got {type(layers).__name__}") from None
        meshes, rounds, boxes = [], [], []
        for k, layer in enumerate(layers):
            if isinstance(layer, TriangleMeshLayer):
                meshes.append(layer)
            elif isinstance(layer, (SphereLayer, CapsuleChainLayer)):
                rounds.append(layer)
            elif isinstance(layer, BoxLayer):
                boxes.append(layer)
            else:
                raise ValueError(
                    f"layers[{k}] is a {type(layer).__name__}; expected TriangleMeshLayer, SphereLayer, "
                    "CapsuleChainLayer or BoxLayer"
                )
        W = self._num_worlds(layers, num_worlds)
        view = self._view()
        self._set_scalar("num_worlds", W)
        self._pack_mesh(meshes, W)
        self._pack_round(rounds, W)
        self._pack_boxes(boxes, W)

        if self._out is None or self._out.shape[0] != W:
            self._out = wp.empty((W, self.height, self.width, 3), dtype=wp.uint8, device=self.device)
        cols = self.width if self.device.is_cpu else 1
        self._launch(
            render_kernel,
            (W, self.height, (self.width + cols - 1) // cols),
            [self._scene, view, self.supersample, cols, self._out],
        )
        return self._out

    def reset_cache(self) -> None:
        """Forget cached geometry, so the next render rebuilds the cloth BVH from scratch.

        Call it when an episode resets: the tree is then built for the new (flat) cloth
        instead of being refitted from the last episode's crumpled one.
        """
        self._mesh_key = None
        self._round_sig = None
        self._box_sig = None
        self._mesh_colors = None

    # ------------------------------------------------------------------ internals
    def _launch(self, kernel: Any, dim: Any, args: list) -> None:
        """Launch ``kernel``, replaying a recorded launch when dim and arguments are unchanged.

        Struct arguments are passed by reference to their ctypes mirror, so field updates on
        the same struct instance reach a recorded launch. The cache keeps the argument objects
        alive, so the identity comparison below cannot be fooled by recycled ids.
        """
        cached = self._launches.get(kernel.key)
        if (
            cached is None
            or cached[0] != dim
            or len(cached[1]) != len(args)
            or any(a is not b and not (isinstance(a, (int, float)) and a == b) for a, b in zip(cached[1], args))
        ):
            cmd = wp.launch(kernel, dim=dim, inputs=args, device=self.device, record_cmd=True)
            cached = (dim, list(args), cmd)
            self._launches[kernel.key] = cached
        cached[2].launch()

    def _set_scalar(self, name: str, value: Any) -> None:
        if self._scene_vals.get(name) != value:
            setattr(self._scene, name, value)
            self._scene_vals[name] = value

    def _upload_tables(self, tables: dict[str, np.ndarray]) -> None:
        """Copy host tables into their device buffers and rebind them in the scene struct."""
        for name, values in tables.items():
            buf = self._bufs[name]
            buf.resize(values.shape[0])
            buf.host[:] = values
            buf.sync()
            self._set_array(name)

    def _set_array(self, name: str) -> None:
        arr = self._bufs[name].array
        if self._scene_vals.get(name) is not arr:
            setattr(self._scene, name, arr)
            self._scene_vals[name] = arr

    def _num_worlds(self, layers: list, num_worlds: int | None) -> int:
        if num_worlds is not None:
            return check_int_range("num_worlds", num_worlds, 1)
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

    def _check_settings(self) -> tuple:
        """Validate the lighting/colour attributes (they may be changed between renders)."""
        key = (
            _key(self.background), _key(self.ground), _key(self.ground_height), _key(self.ground_color),
            _key(self.checker_size), _key(self.light_direction), _key(self.ambient), _key(self.shadows),
        )  # fmt: skip
        if key == self._settings_key:
            return key
        self._background = as_color("background", self.background)
        self._ground_color = as_color("ground_color", self.ground_color)
        ground_z = _finite("ground_height", self.ground_height)
        checker = _finite("checker_size", self.checker_size)
        if checker < 0:
            raise ValueError(f"checker_size must be >= 0, got {self.checker_size!r}")
        light = np.asarray(self.light_direction, dtype=np.float64)
        if light.shape != (3,) or not np.isfinite(light).all() or np.linalg.norm(light) < 1e-9:
            raise ValueError(f"light_direction must be a finite non-zero 3-vector, got {self.light_direction!r}")
        self._light = light / np.linalg.norm(light)
        self._ambient = _finite("ambient", self.ambient)
        if not 0.0 <= self._ambient <= 1.0:
            raise ValueError(f"ambient must be in [0, 1], got {self.ambient!r}")
        if hasattr(self, "_scene"):
            self._set_scalar("ground_on", int(bool(self.ground)))
            self._set_scalar("ground_z", ground_z)
            self._set_scalar("checker_size", checker)
            self._scene.ground_color = wp.vec3(*self._ground_color)
        else:
            self._pending_ground = (int(bool(self.ground)), ground_z, checker)
        self._settings_key = key
        return key

    def _view(self) -> ViewData:
        if not isinstance(self.camera, Camera):
            raise ValueError(f"renderer.camera must be a Camera, got {type(self.camera).__name__}")
        settings = self._check_settings()
        if hasattr(self, "_pending_ground"):
            ground_on, ground_z, checker = self._pending_ground
            del self._pending_ground
            self._set_scalar("ground_on", ground_on)
            self._set_scalar("ground_z", ground_z)
            self._set_scalar("checker_size", checker)
            self._scene.ground_color = wp.vec3(*self._ground_color)
        key = (self.camera, settings, self.width, self.height)
        if key == self._view_key and self._view_data is not None:
            return self._view_data
        forward, right, up = self.camera.basis()
        tx, ty = self.camera.tan_half_fov(self.width, self.height)
        v = ViewData()
        v.origin = wp.vec3(*self.camera.position)
        v.forward = wp.vec3(*forward)
        v.right = wp.vec3(*(right * tx))
        v.up = wp.vec3(*(up * ty))
        v.background = wp.vec3(*self._background)
        v.light_dir = wp.vec3(*self._light)
        v.ambient = float(self._ambient)
        v.diffuse = float(1.0 - self._ambient)
        v.shadows = int(bool(self.shadows))
        v.max_dist = 1.0e4
        self._view_data, self._view_key = v, key
        return v

    # .................................................................. cloth mesh
    def _pack_mesh(self, layers: list[TriangleMeshLayer], W: int) -> None:
        if not layers:
            self._set_scalar("has_mesh", 0)
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
            self._mesh_points = wp.zeros(total_v, dtype=wp.vec3, device=self.device)
            self._mesh_points_host = self._mesh_points.numpy() if self.device.is_cpu else None
            self._mesh_voff = []
            voff = 0
            for _, nv, _ in sources:
                self._mesh_voff.append(voff)
                voff += W * nv
            # faces world-major, so that face % tris_per_world is the face within one world
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
            self._set_scalar("tris_per_world", tris_per_world)

        # vertex positions (static meshes shared by all worlds are tiled W times)
        pts, host = self._mesh_points, self._mesh_points_host
        for (data, nv, per_world), vo in zip(sources, self._mesh_voff):
            count = W * nv if per_world else nv
            for r in range(1 if per_world else W):
                off = vo + r * nv
                if is_warp_array(data):
                    wp.copy(pts, data, dest_offset=off, src_offset=0, count=count)
                elif host is not None:
                    host[off : off + count] = data
                else:
                    pts[off : off + count].assign(data)

        if rebuild:
            self._mesh = wp.Mesh(points=pts, indices=self._mesh_index_array, groups=self._mesh_groups)
            self._renders_since_build = 0
        else:
            self._mesh.refit()
            self._renders_since_build += 1
        self._set_scalar("has_mesh", 1)
        self._set_scalar("mesh_id", self._mesh.id)

        smooth = bool(self.smooth_shading)
        self._set_scalar("smooth", int(smooth))
        if smooth:
            if getattr(self, "_vertex_normals", None) is None or self._vertex_normals.shape[0] != pts.shape[0]:
                self._vertex_normals = wp.zeros(pts.shape[0], dtype=wp.vec3, device=self.device)
            self._vertex_normals.zero_()
            self._launch(
                accumulate_vertex_normals,
                self._mesh_index_array.shape[0] // 3,
                [pts, self._mesh_index_array, self._vertex_normals],
            )
            if self._scene_vals.get("vertex_normals") is not self._vertex_normals:
                self._scene.vertex_normals = self._vertex_normals
                self._scene_vals["vertex_normals"] = self._vertex_normals
            if self._scene_vals.get("mesh_indices") is not self._mesh_index_array:
                self._scene.mesh_indices = self._mesh_index_array
                self._scene_vals["mesh_indices"] = self._mesh_index_array

        colors = tuple((tuple(l.front_color), tuple(l.back_color), l.indices.shape[0]) for l in layers)
        if colors != self._mesh_colors:
            n_faces = sum(l.indices.shape[0] for l in layers)
            for name, attr in (("face_front", "front_color"), ("face_back", "back_color")):
                buf = self._bufs[name]
                buf.resize(n_faces)
                buf.host[:] = np.concatenate(
                    [np.broadcast_to(getattr(l, attr), (l.indices.shape[0], 3)) for l in layers]
                )
                buf.sync()
                self._set_array(name)
            self._mesh_colors = colors

    # .................................................................. spheres, capsules
    def _pack_round(self, layers: list, W: int) -> None:
        self._set_scalar("n_round_layers", len(layers))
        if not layers:
            return
        items = []
        sig: list = [W]
        for k, layer in enumerate(layers):
            if isinstance(layer, SphereLayer):
                data, n, shared = _positions(f"SphereLayer[{k}].centers", layer.centers, W)
                sig.append(("s", n, shared, _key(layer.radii), _key(layer.colors)))
            else:
                data, n, shared = _positions(f"CapsuleChainLayer[{k}].points", layer.points, W)
                sig.append(("c", n, shared, _key(layer.radius), _key(layer.colors), bool(layer.closed)))
            items.append((data, n, shared))
        sig_t = tuple(sig)
        if sig_t != self._round_sig:
            self._build_round_tables(layers, items, W)
            self._round_sig = sig_t

        # positions: numpy through the host buffer, warp arrays device to device
        pts_buf = self._bufs["pts"]
        for (data, _, _), off in zip(items, self._round_layout):
            if not is_warp_array(data):
                pts_buf.host[off : off + data.shape[0]] = data
        pts_buf.sync()
        for (data, _, _), off in zip(items, self._round_layout):
            if is_warp_array(data):
                wp.copy(pts_buf.array, data, dest_offset=off, src_offset=0, count=data.shape[0])
        self._launch(
            round_cluster_bounds,
            self._round_n_bounds,
            [self._scene, self._bufs["round_lo"].array, self._bufs["round_hi"].array],
        )

    def _build_round_tables(self, layers: list, items: list, W: int) -> None:
        a_parts, b_parts, r_parts, c_parts, bound_layer = [], [], [], [], []
        meta = np.zeros((5, len(layers)), np.int32)  # pt_off, pt_stride, prim_off, prim_cnt, bound_off
        layout = []
        n_pts = n_prims = n_bounds = 0
        for k, (layer, (data, n, shared)) in enumerate(zip(layers, items)):
            if isinstance(layer, SphereLayer):
                name = f"SphereLayer[{k}]"
                radii = np.asarray(layer.radii, dtype=np.float32)
                if radii.ndim == 1 and radii.shape[0] != n:
                    raise ValueError(f"{name}.radii has {radii.shape[0]} entries but there are {n} spheres")
                radii = np.broadcast_to(radii, (n,))
                colors = as_color(f"{name}.colors", layer.colors, n)
                a = b = np.arange(n, dtype=np.int32)
            else:
                name = f"CapsuleChainLayer[{k}]"
                point_colors = as_color(f"{name}.colors", layer.colors, n)
                if n == 1:
                    a = b = np.zeros(1, np.int32)
                else:
                    a = np.arange(n - 1, dtype=np.int32)
                    b = a + 1
                    if layer.closed and n > 2:
                        a = np.append(a, n - 1).astype(np.int32)
                        b = np.append(b, 0).astype(np.int32)
                colors = point_colors[a]
                radii = np.full(a.shape[0], float(layer.radius), np.float32)
            na = a.shape[0]
            ncl = -(-na // ROUND_CLUSTER)
            meta[:, k] = (n_pts, 0 if shared else n, n_prims, na, n_bounds)
            layout.append(n_pts)
            bound_layer.append(np.full(W * ncl, k, np.int32))
            n_bounds += W * ncl
            n_pts += data.shape[0]
            n_prims += na
            a_parts.append(a)
            b_parts.append(b)
            r_parts.append(radii)
            c_parts.append(colors)
        tables = {
            "prim_a": np.concatenate(a_parts),
            "prim_b": np.concatenate(b_parts),
            "prim_r": np.concatenate(r_parts),
            "prim_color": np.concatenate(c_parts),
            "round_pt_off": meta[0],
            "round_pt_stride": meta[1],
            "round_prim_off": meta[2],
            "round_prim_cnt": meta[3],
            "round_bound_off": meta[4],
            "round_bound_layer": np.concatenate(bound_layer),
        }
        self._upload_tables(tables)
        for name, size in (("pts", n_pts), ("round_lo", n_bounds), ("round_hi", n_bounds)):
            self._bufs[name].resize(size)
            self._set_array(name)
        self._round_layout = layout
        self._round_n_bounds = n_bounds

    # .................................................................. boxes
    def _pack_boxes(self, layers: list[BoxLayer], W: int) -> None:
        self._set_scalar("n_box_layers", len(layers))
        if not layers:
            return
        hosted = [
            (
                _positions(f"BoxLayer[{k}].centers", layer.centers, W, to_host=True),
                _host(layer.half_extents),
                _host(layer.rotations),
                layer.colors,
            )
            for k, layer in enumerate(layers)
        ]
        sig = (W,) + tuple(
            (_key(c[0]), c[2], _key(h), _key(r), _key(col), is_warp_array(layer.rotations) and layer.rotations.dtype)
            for (c, h, r, col), layer in zip(hosted, layers)
        )
        if sig == self._box_sig:
            return  # nothing moved
        self._box_sig = None  # stays None if validation below fails
        centers_p, rot_p, half_p, col_p = [], [], [], []
        meta = np.zeros((4, len(layers)), np.int32)  # off, stride, cnt, color_off
        lo = np.zeros((len(layers) * W, 3), np.float32)
        hi = np.zeros_like(lo)
        n_boxes = n_cols = 0
        for k, ((centers_in, half_in, rot_in, colors_in), layer) in enumerate(zip(hosted, layers)):
            name = f"BoxLayer[{k}]"
            centers, n, shared = centers_in
            half = _finite_array(f"{name}.half_extents", half_in)
            if is_warp_array(layer.half_extents):  # flat warp array of vec3: B or W*B entries
                half = half.reshape(-1, 3)
                if half.shape[0] == W * n and W > 1:
                    half = half.reshape(W, n, 3)
            if half.shape == (3,):
                half = np.broadcast_to(half, (n, 3))
            if half.shape not in ((n, 3), (W, n, 3)):
                raise ValueError(
                    f"{name}.half_extents must have shape (3,), ({n}, 3) or ({W}, {n}, 3), got {half.shape}"
                )
            if np.any(half <= 0):
                raise ValueError(f"{name}.half_extents must be > 0")
            if rot_in is None:
                rot = np.broadcast_to(np.eye(3), (n, 3, 3))
            else:
                rot = _finite_array(f"{name}.rotations", rot_in)
                if is_warp_array(layer.rotations):  # flat warp arrays of mat33 or quat
                    per = (3, 3) if layer.rotations.dtype == wp.mat33 else (4,)
                    rot = rot.reshape((-1,) + per)
                    if rot.shape[0] == W * n and (W > 1 or not shared):
                        rot = rot.reshape((W, n) + per)
                if rot.shape[-1] == 4 and rot.shape[:-1] in ((n,), (W, n)):
                    norm = np.linalg.norm(rot, axis=-1, keepdims=True)
                    if np.any(norm < 1e-6):
                        raise ValueError(f"{name}.rotations contains a zero quaternion")
                    rot = _quat_to_mat(rot / norm)
                elif rot.shape[-2:] != (3, 3) or rot.shape[:-2] not in ((n,), (W, n)):
                    raise ValueError(
                        f"{name}.rotations must be None, ({n}, 3, 3), ({W}, {n}, 3, 3), ({n}, 4) or ({W}, {n}, 4) "
                        f"(quaternions x, y, z, w); got {rot.shape}"
                    )
            same_everywhere = shared and half.ndim == 2 and rot.ndim == 3
            reps = 1 if same_everywhere else W
            c = np.broadcast_to(centers.reshape(1 if shared else W, n, 3), (reps, n, 3)).reshape(-1, 3)
            h = np.broadcast_to(half, (reps, n, 3)).reshape(-1, 3)
            R = np.broadcast_to(rot, (reps, n, 3, 3)).reshape(-1, 3, 3)
            ext = np.einsum("bij,bj->bi", np.abs(R), h)
            lo[k * W : (k + 1) * W] = (c - ext).reshape(reps, n, 3).min(axis=1)
            hi[k * W : (k + 1) * W] = (c + ext).reshape(reps, n, 3).max(axis=1)
            centers_p.append(c)
            rot_p.append(R.reshape(-1, 9))
            half_p.append(h)
            col_p.append(as_color(f"{name}.colors", colors_in, n))
            meta[:, k] = (n_boxes, 0 if same_everywhere else n, n, n_cols)
            n_boxes += c.shape[0]
            n_cols += n
        tables = {
            "box_center": np.concatenate(centers_p),
            "box_rot": np.concatenate(rot_p),
            "box_half": np.concatenate(half_p),
            "box_color": np.concatenate(col_p),
            "box_off": meta[0],
            "box_stride": meta[1],
            "box_cnt": meta[2],
            "box_color_off": meta[3],
            "box_lo": lo,
            "box_hi": hi,
        }
        self._upload_tables(tables)
        self._box_sig = sig


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
