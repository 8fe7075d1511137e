"""Batched position-based particle engine on NVIDIA Warp (CPU or CUDA).

Pipeline of one frame (``SimParams.frame_dt``), for every substep ``h = frame_dt/substeps``:

1. ``predict``: pickers move linearly from their position at the start of the frame towards
   the target; grasped particles are placed at ``picker + offset`` (kinematic); free particles
   get gravity, damping, the speed clamp and an explicit Euler position prediction.
2. self-collision neighbour lists: per-world spatial hash (counting sort), per particle the
   closest candidates sorted by (distance, index) so the lists do not depend on traversal order.
3. ``iterations`` x:
   a. Gauss-Seidel over the distance constraints (stretch, shear, bend), one launch per
      constraint colour (12 for a cloth grid, 4 for a rope): constraints of one colour share no
      particle, so every launch is race-free and deterministic;
   b. a per-particle Jacobi pass (each particle writes only itself, partners read from a
      snapshot): self-collision (with position-based cloth-on-cloth friction), long-range tethers to pinned/grasped particles, rigid-box
      contacts, ground and static boxes with continuous collision against the substep start;
   c. shape matching of the rigid boxes (one thread per box).
4. ``collision_passes`` extra particle passes, then ``update_velocity``: ``v = (x - x_prev)/h``
   with Coulomb friction from the accumulated contact corrections and the speed clamp.

A release (grasp True->False) first runs ``params.release_relaxation`` position-only solver
iterations on the worlds concerned, so the leftover constraint error around the held particles is
not turned into a velocity kick.  :meth:`ParticleSim.step_frames` runs many frames with one call.

All worlds are stepped by the same launches (flat arrays, world = particle // N); worlds never
interact.  The whole frame is recorded once as a Warp graph (CPU: APIC replay, CUDA: CUDA graph),
so launch overhead is negligible (~0.1 us per launch on CPU).  On CPU every kernel runs as one
thread looping over its items (CPU launches are serial anyway, and this avoids Warp's per-thread
argument copies); on CUDA the same kernels run one item per thread.  Same inputs, same bits.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Sequence

import numpy as np
import warp as wp

from lfd_envs.core.errors import check_int_range

from . import kernels as K
from .builder import SceneBuilder, StaticBox
from .params import SimParams

__all__ = ["ParticleSim"]

def _next_pow2(n: int) -> int:
    p = 1
    while p < n:
        p <<= 1
    return p


def _cloth_side_of_constraints(builder: SceneBuilder, con_i: np.ndarray) -> np.ndarray:
    """Per constraint: the particles along the longer side of the cloth its first particle
    belongs to, 0 for constraints of other objects (ropes, boxes)."""
    side = np.zeros(len(con_i), np.float64)
    for cloth in builder.cloths:
        inside = (con_i >= cloth.start) & (con_i < cloth.start + cloth.nx * cloth.ny)
        side[inside] = max(cloth.nx, cloth.ny)
    return side


class ParticleSim:
    """Batched particle simulator (cloth, rope, rigid boxes, pickers).

    Args:
        builders: One :class:`SceneBuilder` per world, or a single builder replicated
            ``num_worlds`` times.  All builders must share the same topology.
        num_worlds: Number of worlds when a single builder is given (default 1); if a list is
            given it must be ``None`` or equal to its length.
        params: :class:`SimParams` (default ``SimParams()``).
        num_pickers: Pickers per world (>= 0).
        device: Warp device, e.g. ``"cpu"`` or ``"cuda:0"``.
        use_graph: Record a frame as a Warp graph and replay it (fast); ``False`` issues the
            launches one by one (same results).

    Attributes exposed for the renderer: :attr:`particle_q` (``wp.array`` of ``vec3``, size
    ``num_worlds*num_particles``), :attr:`particle_v`, :attr:`picker_q`.
    """

    def __init__(self, builders: Sequence[SceneBuilder] | SceneBuilder, num_worlds: int | None = None,
                 params: SimParams | None = None, num_pickers: int = 1, device: str = "cpu",
                 use_graph: bool = True) -> None:
        if isinstance(builders, SceneBuilder):
            nw = 1 if num_worlds is None else check_int_range("num_worlds", num_worlds, 1)
            builders = [builders] * nw
        else:
            builders = list(builders)
            if not builders:
                raise ValueError("builders must be a SceneBuilder or a non-empty list of them")
            for b in builders:
                if not isinstance(b, SceneBuilder):
                    raise TypeError(f"builders must be SceneBuilder instances, got {type(b).__name__}")
            if num_worlds is not None and num_worlds != len(builders):
                raise ValueError(f"num_worlds={num_worlds} but {len(builders)} builders were given")
        if params is None:
            params = SimParams()
        if not isinstance(params, SimParams):
            raise TypeError(f"params must be a SimParams, got {type(params).__name__}")
        check_int_range("num_pickers", num_pickers, 0)

        wp.init()
        self._device = wp.get_device(device)
        self._finest_cloth = max((max(c.nx, c.ny) for b in builders for c in b.cloths), default=0)
        self._given_params = params
        self._params = params = params.for_resolution(self._finest_cloth)  # what runs
        self._use_graph = bool(use_graph)
        self._graph = None
        self._builders = list(builders)
        self._bend_ref = bend_ref = params.bend_reference_resolution  # fixes the bend constraint layout
        exports = [b._export(bend_ref) for b in builders]
        key0 = builders[0].topology_key(bend_ref)
        for w, b in enumerate(builders[1:], start=1):
            if b.topology_key(bend_ref) != key0:
                raise ValueError(f"builder of world {w} has a different topology than world 0 "
                                 "(particle count, constraints, objects and rigid boxes must match)")
        self._topology_key = key0
        e0 = exports[0]
        self._W = W = len(builders)
        self._N = N = int(e0["positions"].shape[0])
        self._P = P = int(num_pickers)
        self._nnz = nnz = int(e0["con_i"].shape[0])
        self._B = B = int(e0["rigid_start"].shape[0])
        self._S = S = max(int(e["static_center"].shape[0]) for e in exports)
        self._K = int(params.max_neighbors)
        n_sc = int(np.count_nonzero(e0["sc_dist"] != 0))
        self._M = _next_pow2(max(64, 2 * n_sc))
        dev = self._device

        def zeros(n, dtype):
            return wp.zeros(max(1, n), dtype=dtype, device=dev)

        # per-particle state
        self.particle_q = zeros(W * N, wp.vec3)
        self.particle_v = zeros(W * N, wp.vec3)
        self._q_prev = zeros(W * N, wp.vec3)
        self._q_snap = zeros(W * N, wp.vec3)
        self._fric = zeros(W * N, wp.vec3)
        self._picker_push = zeros(W * N, wp.vec3)  # picker pushes of each particle, per substep
        self._pusher = zeros(W * N, wp.int32)
        self._inv_mass = zeros(W * N, wp.float32)
        self._attach = wp.full(W * N, -1, dtype=wp.int32, device=dev)
        self._attach_off = zeros(W * N, wp.vec3)
        self._radius = zeros(W * N, wp.float32)
        self._sc_r = zeros(W * N, wp.float32)
        self._rest = zeros(W * N, wp.vec3)
        self._con_rest = zeros(W * nnz, wp.float32)
        self._con_kscale = wp.full(max(1, W * nnz), 1.0, dtype=wp.float32, device=dev)
        self._con_lambda = zeros(W * nnz, wp.float32)  # XPBD multipliers (compliant constraint types)
        self._w_eff = zeros(W * N, wp.float32)
        self._tether_anchor = wp.full(max(1, W * N), -1, dtype=wp.int32, device=dev)
        self._tether_len = zeros(W * N, wp.float32)
        self._anchors = zeros(W * N, wp.int32)
        # shared topology
        self._obj = wp.array(e0["obj"], dtype=wp.int32, device=dev)
        self._box_of = wp.array(e0["box"], dtype=wp.int32, device=dev)
        pad = np.zeros(1, np.int32)
        self._con_type = e0["con_type"]
        self._con_cloth_side = _cloth_side_of_constraints(builders[0], e0["con_i"])
        ij = np.stack([e0["con_i"], e0["con_j"]], axis=1) if nnz else np.zeros((1, 2), np.int32)
        self._con_ij = wp.array(ij.astype(np.int32), dtype=wp.vec2i, device=dev)
        self._rigid_start = wp.array(e0["rigid_start"] if B else np.zeros(1, np.int32), dtype=wp.int32, device=dev)
        self._rigid_count = wp.array(e0["rigid_count"] if B else np.zeros(1, np.int32), dtype=wp.int32, device=dev)
        # constraint colour sets: (offset, count) into the colour-sorted constraint arrays
        self._color_sets = []
        if nnz:
            colors, starts, counts = np.unique(e0["con_color"], return_index=True, return_counts=True)
            self._color_sets = [(int(o), int(c), int(e0["con_type"][o])) for o, c in zip(starts, counts)]
        # boxes
        self._box_quat = zeros(W * B, wp.quat)
        self._box_pos = zeros(W * B, wp.vec3)
        self._box_rot = zeros(W * B, wp.mat33)
        self._box_he = zeros(W * B, wp.vec3)
        self._box_kin = zeros(W * B, wp.int32)
        self._box_push = zeros(W * B, wp.vec3)  # pushes of each box out of pickers and the table, per substep
        self._box_pusher_v = zeros(W * B, wp.vec3)  # velocity of what pushed it last
        self._sbox_pos = zeros(W * S, wp.vec3)
        self._sbox_rot = zeros(W * S, wp.mat33)
        self._sbox_he = zeros(W * S, wp.vec3)
        # neighbour search
        self._grid_params = wp.array(np.ones(2, np.float32), dtype=wp.float32, device=dev)
        self._cell_start = zeros(W * self._M, wp.int32)
        self._cell_end = zeros(W * self._M, wp.int32)
        self._sorted = zeros(W * N, wp.int32)
        self._sorted_q = zeros(W * N, wp.vec3)
        self._sorted_r = zeros(W * N, wp.float32)
        self._nbr = zeros(W * N * self._K, wp.int32)
        self._nbr_d = zeros(W * N * self._K, wp.float32)
        self._nbr_count = zeros(W * N, wp.int32)
        # pickers
        self.picker_q = zeros(W * P, wp.vec3)
        self._pick_start = zeros(W * P, wp.vec3)
        self._pick_end = zeros(W * P, wp.vec3)
        self._pick_now = zeros(W * P, wp.vec3)  # picker centres at the current substep (colliders)
        self._pick_vel = zeros(W * P, wp.vec3)  # picker velocities during the current frame
        self._events = zeros(W * P, wp.int32)
        self._relax_flags = zeros(W, wp.int32)
        self._picker_pos = np.zeros((W, P, 3), np.float64)
        for p in range(P):
            self._picker_pos[:, p] = (0.0, 0.1 * (p - 0.5 * (P - 1)), 0.3)
        self._grasped = np.zeros((W, P), bool)
        self._holding = np.zeros((W, P), bool)  # picker holds at least one particle

        for w, e in enumerate(exports):
            self._write_world(w, e)
        self._sync_pickers()
        self._update_grid_params()
        self._update_tethers()
        self._update_stiffness_scale()
        self._particle_pass_structs = self._build_particle_pass_structs()
        self._compliance = self._build_compliance_structs()
        self._contact_pushes = self._build_contact_pushes()

    # ================================================================== properties
    @property
    def params(self) -> SimParams:
        """Simulation parameters as given (immutable; see :meth:`set_params`); :attr:`substeps`
        gives the substeps run per frame."""
        return self._given_params

    @property
    def substeps(self) -> int:
        """Substeps run per frame: ``params.substeps``, raised for fine cloth when
        ``params.substeps_reference_resolution`` is set."""
        return self._params.substeps

    @property
    def num_worlds(self) -> int:
        """Number of worlds W."""
        return self._W

    @property
    def num_particles(self) -> int:
        """Particles per world N."""
        return self._N

    @property
    def num_pickers(self) -> int:
        """Pickers per world P."""
        return self._P

    @property
    def num_rigid_boxes(self) -> int:
        """Rigid boxes per world B."""
        return self._B

    @property
    def num_static_boxes(self) -> int:
        """Static box slots per world (worlds with fewer boxes have disabled slots)."""
        return self._S

    @property
    def device(self) -> str:
        """Warp device string."""
        return str(self._device)

    @property
    def builders(self) -> list[SceneBuilder]:
        """The builder of each world (handles: ``builders[w].cloths[0].triangles`` ...)."""
        return list(self._builders)

    @property
    def positions(self) -> np.ndarray:
        """Particle positions, float32 ``(W, N, 3)`` (copy)."""
        return self.particle_q.numpy()[: self._W * self._N].reshape(self._W, self._N, 3).copy()

    @property
    def velocities(self) -> np.ndarray:
        """Particle velocities, float32 ``(W, N, 3)`` (copy)."""
        return self.particle_v.numpy()[: self._W * self._N].reshape(self._W, self._N, 3).copy()

    @property
    def inverse_masses(self) -> np.ndarray:
        """Base inverse masses ``(W, N)`` (0 = pinned; grasping does not change them)."""
        return self._inv_mass.numpy()[: self._W * self._N].reshape(self._W, self._N).copy()

    @property
    def attached(self) -> np.ndarray:
        """``(W, N)`` int32: index of the picker holding each particle, -1 if free."""
        return self._attach.numpy()[: self._W * self._N].reshape(self._W, self._N).copy()

    @property
    def picker_positions(self) -> np.ndarray:
        """Picker centres ``(W, P, 3)`` float64 (copy)."""
        return self._picker_pos.copy()

    @property
    def grasped(self) -> np.ndarray:
        """Grasp flags ``(W, P)`` bool (copy)."""
        return self._grasped.copy()

    def rigid_box_poses(self) -> tuple[np.ndarray, np.ndarray]:
        """Rigid box poses: centres ``(W, B, 3)`` and rotation matrices ``(W, B, 3, 3)`` (local->world)."""
        W, B = self._W, self._B
        c = self._box_pos.numpy()[: W * B].reshape(W, B, 3).copy()
        r = self._box_rot.numpy()[: W * B].reshape(W, B, 3, 3).copy()
        return c, r

    def rigid_box_quaternions(self) -> np.ndarray:
        """Rigid box orientations as quaternions ``(W, B, 4)`` in (x, y, z, w) order."""
        W, B = self._W, self._B
        return self._box_quat.numpy()[: W * B].reshape(W, B, 4).copy()

    @property
    def rigid_box_half_extents(self) -> np.ndarray:
        """Half extents of the rigid boxes ``(W, B, 3)``."""
        W, B = self._W, self._B
        return self._box_he.numpy()[: W * B].reshape(W, B, 3).copy()

    @property
    def static_boxes(self) -> dict[str, np.ndarray]:
        """Static boxes of all worlds: ``center (W,S,3)``, ``half_extents (W,S,3)``,
        ``rotation (W,S,3,3)`` and ``valid (W,S)`` (padding slots are invalid)."""
        W, S = self._W, self._S
        he = self._sbox_he.numpy()[: W * S].reshape(W, S, 3).copy()
        return dict(center=self._sbox_pos.numpy()[: W * S].reshape(W, S, 3).copy(), half_extents=he,
                    rotation=self._sbox_rot.numpy()[: W * S].reshape(W, S, 3, 3).copy(),
                    valid=he[..., 0] > 0)

    def static_box_list(self, world: int = 0) -> list[StaticBox]:
        """Static boxes of one world as :class:`StaticBox` objects (yaw recovered from the rotation)."""
        w = self._check_world(world)
        sb = self.static_boxes
        out = []
        for s in range(self._S):
            if sb["valid"][w, s]:
                rot = sb["rotation"][w, s]
                out.append(StaticBox(tuple(map(float, sb["center"][w, s])),
                                     tuple(map(float, sb["half_extents"][w, s])),
                                     float(math.atan2(rot[1, 0], rot[0, 0]))))
        return out

    # ================================================================== stepping
    def step(self, picker_targets: Any, grasp: Any = None) -> None:
        """Advance every world by one frame (``params.frame_dt``).

        Args:
            picker_targets: ``(W, P, 3)`` picker positions at the end of the frame; pickers move
                linearly from their current position over the substeps.
            grasp: ``(W, P)`` bool (nonzero = grasp), or ``None`` to keep the current flags.
                A picker whose flag is on and that holds nothing (``params.grasp_trigger ==
                "level"``, SoftGym) - or whose flag turns on (``"edge"``) - attaches particles
                within ``params.grasp_radius`` of its position at the start of the frame (all of
                them in ``"radius"`` mode, the closest free one in ``"closest"`` mode); a flag
                turning off releases them.

        Raises:
            ValueError: wrong shapes, NaN/inf values.
        """
        W, P = self._W, self._P
        targets = self._as_float_array(picker_targets, (W, P, 3), "picker_targets")
        if grasp is None:
            g = self._grasped.copy()
        else:
            g = self._as_bool_array(grasp, (W, P), "grasp")
        self._frame(targets, g)

    def step_frames(self, picker_targets: Any, grasp: Any = None, world_frames: Any = None) -> None:
        """Advance every world by ``F`` frames; the same as ``F`` calls of :meth:`step`, bit for bit.

        Args:
            picker_targets: ``(F, W, P, 3)`` picker positions at the end of each frame.
            grasp: ``(F, W, P)`` grasp flags of each frame, or ``None`` to keep the current flags.
            world_frames: ``(W,)`` frames each world runs, ``0..F`` (default ``F`` for all). A world
                stops after its own frames: the batch runs on, and the world is then put back in
                the state it had after them, so it ends exactly as if stepped alone.

        All inputs are validated and converted once; frames without a grasp change only set the
        picker path and replay the recorded frame graph (minimal Python work per frame).

        Raises:
            ValueError: wrong shapes, NaN/inf values, frame counts outside ``0..F``.
        """
        W, P = self._W, self._P
        arr = np.asarray(picker_targets) if not isinstance(picker_targets, np.ndarray) else picker_targets
        if arr.ndim != 4:
            raise ValueError(f"picker_targets must have shape (F, {W}, {P}, 3), got {np.shape(arr)}")
        F = arr.shape[0]
        targets = self._as_float_array(arr, (F, W, P, 3), "picker_targets")
        if grasp is None:
            flags = np.broadcast_to(self._grasped, (F, W, P))
        else:
            flags = self._as_bool_array(grasp, (F, W, P), "grasp")
        counts = self._frame_counts(world_frames, F)
        stops = sorted(set(counts.tolist()) - {F})
        saved: dict[int, dict[str, np.ndarray]] = {}
        begin = 0
        for stop in stops:  # run up to the next world's last frame, keep that world's state
            self._step_frames(targets[begin:stop], flags[begin:stop])
            begin = stop
            saved.update({int(w): self.get_state(int(w)) for w in np.flatnonzero(counts == stop)})
        self._step_frames(targets[begin:], flags[begin:])
        for w, state in saved.items():
            self.set_state(state, world=w)

    def _frame_counts(self, world_frames: Any, F: int) -> np.ndarray:
        """Validated ``world_frames`` of :meth:`step_frames` as ``(W,)`` int64."""
        if world_frames is None:
            return np.full(self._W, F, dtype=np.int64)
        counts = np.asarray(world_frames)
        if counts.shape != (self._W,) or not np.issubdtype(counts.dtype, np.integer):
            raise ValueError(f"world_frames must be {self._W} integers, got {world_frames!r}")
        if counts.min() < 0 or counts.max() > F:
            raise ValueError(f"world_frames must lie in 0..{F} (the frames given), got {counts.tolist()}")
        return counts.astype(np.int64)

    def _step_frames(self, targets: np.ndarray, flags: np.ndarray) -> None:
        """:meth:`step_frames` on validated targets ``(F, W, P, 3)`` and flags ``(F, W, P)``."""
        W, P = self._W, self._P
        F = targets.shape[0]
        if F == 0:
            return
        if not P:
            for _ in range(F):
                self._run_frame()
            return
        path = np.empty((F + 1, W * P, 3), np.float32)  # picker positions at frame boundaries
        path[0] = self._picker_pos.reshape(-1, 3)
        path[1:] = targets.reshape(F, W * P, 3)
        changes = np.concatenate([(flags[:1] != self._grasped[None]), flags[1:] != flags[:-1]]).any(axis=(1, 2))
        level = self._params.grasp_trigger == "level"
        if self._device.is_cpu:
            start_view, end_view = self._pick_start.numpy(), self._pick_end.numpy()

            def set_path(f: int) -> None:
                start_view[: W * P] = path[f]
                end_view[: W * P] = path[f + 1]
        else:
            dev_path = wp.array(path.reshape(-1, 3), dtype=wp.vec3, device=self._device)

            def set_path(f: int) -> None:
                if edited[f] or edited[f + 1]:  # rows changed on the host after the upload
                    self._write_pickers(self._pick_start, path[f])
                    self._write_pickers(self._pick_end, path[f + 1])
                    return
                wp.copy(self._pick_start, dev_path, src_offset=f * W * P, count=W * P)
                wp.copy(self._pick_end, dev_path, src_offset=(f + 1) * W * P, count=W * P)
        ends = targets.copy()  # float64 picker positions at the end of each frame, as in step()
        edited = np.zeros(F + 1, bool)
        for f in range(F):
            if changes[f] or (level and (flags[f] & ~self._holding).any()):
                self._picker_pos = ends[f - 1] if f else self._picker_pos
                self._grasp_events(np.array(flags[f], dtype=bool))
                self._grasped = np.array(flags[f], dtype=bool)
            limited = self._limit_picker_targets(ends[f - 1] if f else self._picker_pos, ends[f])
            if not np.array_equal(limited, ends[f]):
                ends[f] = limited
                path[f + 1] = limited.reshape(-1, 3)
                edited[f + 1] = True
            set_path(f)
            self._run_frame()
        self._picker_pos = ends[-1].copy()
        self._grasped = np.array(flags[-1], dtype=bool)
        self._write_pickers(self.picker_q, self._picker_pos)

    def _frame(self, targets: np.ndarray, g: np.ndarray) -> None:
        """One frame with validated picker targets ``(W, P, 3)`` float64 and grasp flags ``(W, P)``."""
        P = self._P
        if P:
            self._grasp_events(g)
            targets = self._limit_picker_targets(self._picker_pos, targets)
            self._write_pickers(self._pick_start, self._picker_pos)
            self._write_pickers(self._pick_end, targets)
        self._run_frame()
        self._picker_pos = targets
        self._grasped = g
        if P:
            self._write_pickers(self.picker_q, targets)

    def _grasp_events(self, g: np.ndarray) -> None:
        """Attach/release particles where the grasp flags ``g`` change; relax released worlds."""
        W, P = self._W, self._P
        grab = g & ~(self._holding if self._params.grasp_trigger == "level" else self._grasped)
        release = ~g & self._grasped
        if not (grab.any() or release.any()):
            return
        events = np.zeros((W, P), np.int32)
        events[grab] = 1
        events[release] = 2
        self._events.assign(events.ravel())
        self._sync_pickers()
        wp.launch(K.grasp_update, dim=W, device=self._device,
                  inputs=[self.particle_q, self._inv_mass, self._attach, self._attach_off,
                          self.picker_q, self._events, self._N, P,
                          float(self._params.grasp_radius),
                          int(self._params.grasp_mode == "closest")])
        held = self._holding
        self._update_holding()
        if release.any() or not np.array_equal(held, self._holding):  # a missed grasp changes nothing
            self._update_tethers()
        if release.any() and self._params.release_relaxation > 0:
            self._relax(release.any(axis=1))

    def _relax(self, worlds: np.ndarray) -> None:
        """Position-only relaxation of the free particles of ``worlds`` ``(W,)`` bool (see
        ``SimParams.release_relaxation``): constraint and collision projections, no velocity update."""
        flags = worlds.astype(np.int32)
        if self._P and self._params.picker_collision:
            wp.copy(self._pick_now, self.picker_q)  # the pickers where they are now
        if self._device.is_cpu:
            self._relax_flags.numpy()[:] = flags
        else:
            self._relax_flags.assign(flags)
        if not self._use_graph:
            self._relax_ops()
            return
        key = (id(self._params), self._has_sc)
        if getattr(self, "_relax_graph_key", None) != key:
            wp.load_module(K, device=self._device)
            wp.capture_begin(device=self._device)
            try:
                self._relax_ops()
            finally:
                self._relax_graph = wp.capture_end(device=self._device)
            self._relax_graph_key = key
        wp.capture_launch(self._relax_graph)

    def _relax_ops(self) -> None:
        """Launches of the release relaxation (recorded into a graph, flags in ``_relax_flags``)."""
        p, dev = self._params, self._device
        W, N = self._W, self._N
        wp.launch(K.relax_prepare, dim=self._dim(W * N), device=dev,
                  inputs=[self.particle_q, self._q_prev, self._inv_mass, self._attach, self._box_of,
                          self._relax_flags, self._w_eff, N, W * N, self._chunk(W * N)])
        sc_on = int(p.self_collision and self._has_sc)
        if sc_on:
            self._build_neighbors()
        self._reset_multipliers()
        for _ in range(p.release_relaxation):
            self._solve_distance_constraints()
            self._particle_pass(sc_on, skip_kinematic=1)

    def _run_frame(self) -> None:
        if not self._use_graph:
            self._frame_ops()
            return
        if self._graph is None:
            try:
                wp.load_module(K, device=self._device)
                wp.capture_begin(device=self._device)
                try:
                    self._frame_ops()
                finally:
                    self._graph = wp.capture_end(device=self._device)
            except Exception:  # pragma: no cover - capture unsupported: fall back to launches
                self._graph = None
                self._use_graph = False
                self._frame_ops()
                return
        wp.capture_launch(self._graph)

    def _frame_ops(self) -> None:
        """Issue all launches of one frame (recorded into the graph)."""
        p = self._params
        W, N, P, B, S, dev = self._W, self._N, self._P, self._B, self._S, self._device
        h = p.substep_dt
        damp = max(0.0, 1.0 - p.damping * h)
        sc_on = int(p.self_collision and self._has_sc)
        q = self.particle_q
        for s in range(p.substeps):
            alpha = (s + 1) / p.substeps
            if P and p.picker_collision:
                wp.launch(K.picker_substep_positions, dim=W * P, device=dev,
                          inputs=[self._pick_start, self._pick_end, alpha, 1.0 / p.frame_dt, self._pick_now,
                                  self._pick_vel])
            wp.launch(K.predict, dim=self._dim(W * N), device=dev,
                      inputs=[q, self._q_prev, self.particle_v, self._inv_mass, self._attach,
                              self._attach_off, self._pick_start, self._pick_end, self._fric,
                              self._w_eff, N, max(P, 1), alpha, p.gravity, h, damp, p.max_speed,
                              W * N, self._chunk(W * N)])
            if P and p.picker_collision:  # clear the contact-push accumulators (see K.ContactPushes)
                self._picker_push.zero_()
                if B:
                    self._box_push.zero_()
            if sc_on and s % p.self_collision_interval == 0:
                self._build_neighbors()
            self._reset_multipliers()
            for _ in range(p.iterations):
                self._solve_distance_constraints()
                self._particle_pass(sc_on)
                if B:
                    wp.launch(K.shape_match, dim=W * B, device=dev,
                              inputs=[q, self._rest, self._inv_mass, self._attach,
                                      self._rigid_start, self._rigid_count, N, B,
                                      p.rigid_weight_kinematic, self._box_quat, self._box_pos,
                                      self._box_rot, self._box_kin, self._box_he, self._picker_spheres,
                                      self._box_push, self._box_pusher_v])
            for _ in range(p.collision_passes if sc_on else 0):
                self._particle_pass(sc_on)
            wp.launch(K.update_velocity, dim=self._dim(W * N), device=dev,
                      inputs=[q, self._q_prev, self.particle_v, self._inv_mass, self._attach,
                              self._fric, 1.0 / h, p.static_friction, p.dynamic_friction,
                              p.max_speed, self._picker_spheres, self._contact_pushes, W * N, self._chunk(W * N)])

    def _build_neighbors(self) -> None:
        """Rebuild the self-collision hash grid and neighbour lists from the current positions."""
        W, N, dev, q = self._W, self._N, self._device, self.particle_q
        wp.launch(K.build_grid, dim=W, device=dev,
                  inputs=[q, self._sc_r, self._grid_params, N, self._M, self._cell_start,
                          self._cell_end, self._sorted, self._sorted_q, self._sorted_r])
        wp.launch(K.build_neighbors, dim=self._dim(W * N), device=dev,
                  inputs=[q, self._sc_r, self._obj, self._rest, self._grid_params, N,
                          self._M, self._K, self._cell_start, self._cell_end, self._sorted,
                          self._sorted_q, self._sorted_r, self._nbr, self._nbr_d, self._nbr_count, W * N,
                          self._chunk(W * N)])

    def _solve_distance_constraints(self) -> None:
        """One Gauss-Seidel sweep over the distance constraints, one launch per colour."""
        p, W, N, dev = self._params, self._W, self._N, self._device
        stiffness = (p.stretch_stiffness, p.shear_stiffness, p.bend_stiffness)  # by constraint type
        for off, cnt, typ in self._color_sets:
            args = [self._con_ij, self._con_rest, self._con_kscale, stiffness[typ], off, cnt, self._nnz, N, self.particle_q,
                    self._w_eff]
            if dev.is_cpu:
                wp.launch(K.solve_constraints_serial, dim=1, device=dev, inputs=args + [W, self._compliance[typ]])
            else:
                wp.launch(K.solve_constraints, dim=W * cnt, device=dev, inputs=args + [self._compliance[typ]])

    def _build_compliance_structs(self) -> tuple[Any, ...]:
        """XPBD settings per constraint type (stretch, shear, bend) from the ``*_compliance``
        parameters (``None``: the PBD stiffness is used)."""
        p = self._params
        out = []
        for value in (p.stretch_compliance, p.shear_compliance, p.bend_compliance):
            c = K.Compliance()
            c.enabled = int(value is not None)
            c.alpha_tilde = 0.0 if value is None else float(value) / p.substep_dt ** 2
            c.multipliers = self._con_lambda
            out.append(c)
        return tuple(out)

    def _reset_multipliers(self) -> None:
        """Zero the XPBD multipliers (start of a substep or of a release relaxation)."""
        if self._nnz and any(c.enabled for c in self._compliance):
            n = self._W * self._nnz
            wp.launch(K.zero_floats, dim=self._dim(n), device=self._device,
                      inputs=[self._con_lambda, n, self._chunk(n)])

    def _build_particle_pass_structs(self) -> tuple[Any, ...]:
        """Arguments of :func:`kernels.solve_particles` grouped in its ``wp.struct``s (the arrays
        live as long as the engine; rebuilt by :meth:`set_params` for the contact parameters)."""
        p = self._params
        particles = K.ParticleArrays()
        particles.particles_per_world = self._N
        particles.positions, particles.snapshot, particles.substep_start = self.particle_q, self._q_snap, self._q_prev
        particles.inverse_mass, particles.attached_picker = self._w_eff, self._attach
        particles.radius, particles.friction_displacement = self._radius, self._fric
        particles.picker_push, particles.pusher = self._picker_push, self._pusher
        collision = K.SelfCollision()
        collision.radius = self._sc_r
        collision.relaxation = p.self_collision_relaxation
        collision.static_friction, collision.dynamic_friction = p.particle_static_friction, p.particle_dynamic_friction
        collision.max_neighbors, collision.neighbors, collision.neighbor_count = self._K, self._nbr, self._nbr_count
        tethers = K.Tethers()
        tethers.anchor, tethers.length = self._tether_anchor, self._tether_len
        boxes = K.RigidBoxes()
        boxes.boxes_per_world, boxes.box_of_particle = self._B, self._box_of
        boxes.position, boxes.rotation, boxes.half_extents = self._box_pos, self._box_rot, self._box_he
        boxes.kinematic = self._box_kin
        static_boxes = K.StaticBoxes()
        static_boxes.boxes_per_world = self._S
        static_boxes.position, static_boxes.rotation = self._sbox_pos, self._sbox_rot
        static_boxes.half_extents = self._sbox_he
        pickers = K.PickerSpheres()
        pickers.pickers_per_world, pickers.position, pickers.velocity = self._P, self._pick_now, self._pick_vel
        pickers.radius, pickers.enabled = p.picker_radius, int(p.picker_collision and self._P > 0)
        return particles, collision, tethers, boxes, static_boxes, pickers

    def _particle_pass(self, sc_on: int, skip_kinematic: int = 0) -> None:
        W, N = self._W, self._N
        wp.copy(self._q_snap, self.particle_q, count=W * N)
        wp.launch(K.solve_particles, dim=self._dim(W * N), device=self._device,
                  inputs=[*self._particle_pass_structs, sc_on, skip_kinematic, W * N, self._chunk(W * N)])

    def _chunk(self, total: int) -> int:
        """Particles per thread: CPU launches run serially, so one thread loops over all of them
        (avoids per-thread argument overhead); CUDA uses one particle per thread."""
        return max(1, total) if self._device.is_cpu else 1

    def _dim(self, total: int) -> int:
        c = self._chunk(total)
        return max(1, (total + c - 1) // c)

    def set_params(self, params: SimParams) -> None:
        """Replace the parameters (takes effect at the next step; ``max_neighbors`` is fixed;
        ``substeps_reference_resolution`` is applied as at construction)."""
        if not isinstance(params, SimParams):
            raise TypeError(f"params must be a SimParams, got {type(params).__name__}")
        if params.max_neighbors != self._K:
            raise ValueError("max_neighbors cannot change after construction")
        spans = self._builders[0].bend_spans(params.bend_reference_resolution)
        if spans != self._builders[0].bend_spans(self._bend_ref):
            raise ValueError(f"bend_reference_resolution={params.bend_reference_resolution} changes the bend "
                             f"constraints of this scene's cloth (spans {spans}); it is fixed at construction")
        self._given_params = params
        self._params = params.for_resolution(self._finest_cloth)
        self._graph = None
        self._particle_pass_structs = self._build_particle_pass_structs()
        self._compliance = self._build_compliance_structs()
        for w, b in enumerate(self._builders):
            self._write_sc_radius(w, b._export(self._bend_ref))
        self._update_grid_params()
        self._update_tethers()
        self._update_stiffness_scale()

    # ================================================================== pickers
    def set_picker_positions(self, positions: Any, world: int | None = None) -> None:
        """Teleport pickers: ``(W, P, 3)``, or ``(P, 3)`` for one ``world``.  Particles they hold
        keep their offset and jump along at the next step."""
        if world is None:
            pos = self._as_float_array(positions, (self._W, self._P, 3), "positions")
            self._picker_pos = pos
        else:
            w = self._check_world(world)
            pos = self._as_float_array(positions, (self._P, 3), "positions")
            self._picker_pos = self._picker_pos.copy()
            self._picker_pos[w] = pos
        self._sync_pickers()

    def _sync_pickers(self) -> None:
        if self._P:
            self._write_pickers(self.picker_q, self._picker_pos)

    def _write_pickers(self, arr: wp.array, values: np.ndarray) -> None:
        v = np.ascontiguousarray(values, dtype=np.float32).reshape(-1, 3)
        if self._device.is_cpu:
            arr.numpy()[:] = v
        else:
            arr.assign(v)

    # ================================================================== state
    def get_state(self, world: int | None = None) -> dict[str, np.ndarray]:
        """Complete simulator state as numpy arrays (copies).

        With ``world=None`` every array has a leading world axis; with ``world=w`` that axis is
        dropped.  Contains the dynamic state (positions, velocities, picker positions, grasp flags,
        attachments and offsets, rigid-box poses), the per-particle inverse masses and the
        per-world geometry (rest shapes, rest lengths, radii, static boxes) so that
        :meth:`set_state` reproduces the future bit for bit, even into another world.
        """
        worlds = slice(None) if world is None else self._check_world(world)
        st = {}
        for key, (attr, count_attr, shape_fn, _) in self._STATE_SPEC.items():
            n = getattr(self, count_attr)
            per_world = getattr(self, attr).numpy()[: self._W * n].reshape((self._W,) + shape_fn(self))
            st[key] = per_world[worlds].copy()
        st["picker_positions"] = self._picker_pos[worlds].copy()
        st["grasped"] = self._grasped[worlds].copy()
        return st

    _STATE_SPEC = {
        # key: (wp array attribute, per-world count attr, trailing shape fn, dtype)
        "positions": ("particle_q", "_N", lambda s: (s._N, 3), np.float32),
        "velocities": ("particle_v", "_N", lambda s: (s._N, 3), np.float32),
        "inv_mass": ("_inv_mass", "_N", lambda s: (s._N,), np.float32),
        "attach": ("_attach", "_N", lambda s: (s._N,), np.int32),
        "attach_offset": ("_attach_off", "_N", lambda s: (s._N, 3), np.float32),
        "rest": ("_rest", "_N", lambda s: (s._N, 3), np.float32),
        "radius": ("_radius", "_N", lambda s: (s._N,), np.float32),
        "sc_r": ("_sc_r", "_N", lambda s: (s._N,), np.float32),
        "con_rest": ("_con_rest", "_nnz", lambda s: (s._nnz,), np.float32),
        "box_quat": ("_box_quat", "_B", lambda s: (s._B, 4), np.float32),
        "box_pos": ("_box_pos", "_B", lambda s: (s._B, 3), np.float32),
        "box_rot": ("_box_rot", "_B", lambda s: (s._B, 3, 3), np.float32),
        "box_half_extents": ("_box_he", "_B", lambda s: (s._B, 3), np.float32),
        "box_kinematic": ("_box_kin", "_B", lambda s: (s._B,), np.int32),
        "static_pos": ("_sbox_pos", "_S", lambda s: (s._S, 3), np.float32),
        "static_rot": ("_sbox_rot", "_S", lambda s: (s._S, 3, 3), np.float32),
        "static_half_extents": ("_sbox_he", "_S", lambda s: (s._S, 3), np.float32),
    }

    def set_state(self, state: dict[str, Any], world: int | None = None) -> None:
        """Restore a state from :meth:`get_state` (all worlds, or one ``world``)."""
        if not isinstance(state, dict):
            raise TypeError("state must be a dict from get_state()")
        expected = set(self._STATE_SPEC) | {"picker_positions", "grasped"}
        missing = expected - set(state)
        extra = set(state) - expected
        if missing or extra:
            raise ValueError(f"state keys mismatch: missing {sorted(missing)}, unknown {sorted(extra)}")
        worlds = range(self._W) if world is None else [self._check_world(world)]
        lead = (self._W,) if world is None else ()
        checked = {}
        for key, (_, _, shape_fn, dtype) in self._STATE_SPEC.items():
            arr = np.asarray(state[key])
            shape = lead + shape_fn(self)
            if arr.shape != shape:
                raise ValueError(f"state[{key!r}] must have shape {shape}, got {arr.shape}")
            if dtype is np.float32 and not np.all(np.isfinite(arr)):
                raise ValueError(f"state[{key!r}] contains NaN/inf")
            checked[key] = arr.astype(dtype, copy=False)
        pp = self._as_float_array(state["picker_positions"], lead + (self._P, 3), "state['picker_positions']")
        gr = self._as_bool_array(state["grasped"], lead + (self._P,), "state['grasped']")
        for key, (attr, count_attr, shape_fn, _) in self._STATE_SPEC.items():
            n = getattr(self, count_attr)
            if n == 0:
                continue
            arr = getattr(self, attr)
            if world is None:
                self._write_slice(arr, 0, checked[key].reshape((self._W * n,) + shape_fn(self)[1:]))
            else:
                self._write_slice(arr, worlds[0] * n, checked[key])
        self._picker_pos = self._picker_pos.copy()
        self._grasped = self._grasped.copy()
        if world is None:
            self._picker_pos[:] = pp
            self._grasped[:] = gr
        else:
            self._picker_pos[worlds[0]] = pp
            self._grasped[worlds[0]] = gr
        self._sync_pickers()
        self._update_holding()
        self._update_grid_params()
        self._update_tethers()
        self._update_stiffness_scale()

    def reset_world(self, world: int, builder: SceneBuilder) -> None:
        """Re-initialise one world from a builder with the same topology (new task variant):
        positions, zero velocities, inverse masses, rest shape, static and rigid boxes; releases
        that world's grasps.  Picker positions are kept (use :meth:`set_picker_positions`)."""
        w = self._check_world(world)
        if not isinstance(builder, SceneBuilder):
            raise TypeError("builder must be a SceneBuilder")
        if builder.topology_key(self._bend_ref) != self._topology_key:
            raise ValueError("builder topology differs from the simulator's (particle count, "
                             "constraints, objects and rigid boxes must match)")
        e = builder._export(self._bend_ref)
        if e["static_center"].shape[0] > self._S:
            raise ValueError(f"builder has {e['static_center'].shape[0]} static boxes but the "
                             f"simulator was built with {self._S} slots")
        self._builders[w] = builder
        self._write_world(w, e)
        self._grasped = self._grasped.copy()
        self._grasped[w] = False
        self._update_holding()
        self._update_grid_params()
        self._update_tethers()
        self._update_stiffness_scale()

    def set_particles(self, world: int, positions: Any, velocities: Any | None = None) -> None:
        """Overwrite positions ``(N, 3)`` (and velocities, default zero) of one world."""
        w = self._check_world(world)
        N = self._N
        pos = self._as_float_array(positions, (N, 3), "positions")
        vel = np.zeros((N, 3)) if velocities is None else self._as_float_array(velocities, (N, 3), "velocities")
        self._write_slice(self.particle_q, w * N, pos.astype(np.float32))
        self._write_slice(self.particle_v, w * N, vel.astype(np.float32))

    # ================================================================== internals
    def _check_world(self, world: Any) -> int:
        if isinstance(world, bool) or not isinstance(world, (int, np.integer)):
            raise TypeError(f"world must be an int, got {type(world).__name__}")
        if not 0 <= world < self._W:
            raise IndexError(f"world {world} out of range [0, {self._W})")
        return int(world)

    @staticmethod
    def _as_float_array(value: Any, shape: tuple, name: str) -> np.ndarray:
        try:
            arr = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{name} must be a numeric array of shape {shape}") from exc
        if arr.shape != shape:
            raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} contains NaN or inf")
        return arr.copy()

    @staticmethod
    def _as_bool_array(value: Any, shape: tuple, name: str) -> np.ndarray:
        arr = np.asarray(value)
        if arr.shape != shape:
            raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
        if arr.dtype == bool:
            return arr.copy()
        if not (np.issubdtype(arr.dtype, np.integer) or np.issubdtype(arr.dtype, np.floating)):
            raise ValueError(f"{name} must be bool or numeric, got dtype {arr.dtype}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} contains NaN or inf")
        return arr != 0

    def _write_slice(self, arr: wp.array, start: int, values: np.ndarray) -> None:
        values = np.ascontiguousarray(values)
        n = values.shape[0]
        if n == 0:
            return
        if self._device.is_cpu:
            view = arr.numpy()
            view[start:start + n] = values.reshape(view[start:start + n].shape)
        else:
            tmp = wp.array(values, dtype=arr.dtype, device=self._device)
            wp.copy(arr, tmp, dest_offset=start, src_offset=0, count=n)

    def _sc_radius(self, e: dict) -> np.ndarray:
        p = self._params
        d = e["sc_dist"].copy()
        auto = np.isnan(d)
        if p.self_collision_distance is not None:
            d[auto] = p.self_collision_distance
        else:
            d[auto] = p.self_collision_spacing_factor * e["sc_spacing"][auto]
        return 0.5 * d

    def _write_sc_radius(self, w: int, e: dict) -> None:
        self._write_slice(self._sc_r, w * self._N, self._sc_radius(e).astype(np.float32))

    def _write_world(self, w: int, e: dict) -> None:
        N, B, S, nnz = self._N, self._B, self._S, self._nnz
        f32 = np.float32
        self._write_slice(self.particle_q, w * N, e["positions"].astype(f32))
        self._write_slice(self.particle_v, w * N, np.zeros((N, 3), f32))
        self._write_slice(self._inv_mass, w * N, e["inv_mass"].astype(f32))
        self._write_slice(self._attach, w * N, np.full(N, -1, np.int32))
        self._write_slice(self._attach_off, w * N, np.zeros((N, 3), f32))
        rad = e["radius"].copy()
        rad[np.isnan(rad)] = self._params.particle_radius
        self._write_slice(self._radius, w * N, rad.astype(f32))
        self._write_sc_radius(w, e)
        self._write_slice(self._rest, w * N, e["rest"].astype(f32))
        if nnz:
            self._write_slice(self._con_rest, w * nnz, e["con_rest"].astype(f32))
        if B:
            yaw_q = []
            for rot in e["rigid_rot"]:
                yaw = math.atan2(rot[1, 0], rot[0, 0])
                yaw_q.append((0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw)))
            self._write_slice(self._box_quat, w * B, np.asarray(yaw_q, f32))
            self._write_slice(self._box_pos, w * B, e["rigid_center"].astype(f32))
            self._write_slice(self._box_rot, w * B, e["rigid_rot"].astype(f32))
            self._write_slice(self._box_he, w * B, e["rigid_half_extents"].astype(f32))
        if S:
            ns = e["static_center"].shape[0]
            pos = np.zeros((S, 3), f32)
            rot = np.tile(np.eye(3, dtype=f32), (S, 1, 1))
            he = np.full((S, 3), -1.0, f32)
            pos[:ns] = e["static_center"]
            rot[:ns] = e["static_rot"]
            he[:ns] = e["static_half_extents"]
            self._write_slice(self._sbox_pos, w * S, pos)
            self._write_slice(self._sbox_rot, w * S, rot)
            self._write_slice(self._sbox_he, w * S, he)

    def _update_stiffness_scale(self) -> None:
        """Per-constraint stiffness factors: 1, except bend constraints longer than twice
        ``params.bend_reference_spacing``, bend and shear constraints of cloth coarser than
        ``params.bend_reference_resolution`` and bend constraints of cloth finer than it (see
        :class:`SimParams`)."""
        p, W, nnz = self._params, self._W, self._nnz
        if not nnz:
            return
        scale = np.ones((W, nnz), np.float32)
        if p.bend_reference_spacing is not None:
            rest = self._con_rest.numpy()[: W * nnz].reshape(W, nnz).astype(np.float64)
            bend = self._con_type == 2
            ratio = 2.0 * p.bend_reference_spacing / np.maximum(rest[:, bend], 1e-12)
            scale[:, bend] = np.minimum(1.0, ratio ** p.bend_spacing_exponent)
        if p.bend_reference_resolution is not None:
            side = self._con_cloth_side
            # bend constraints and cell diagonals (shear), which span a crease along a diagonal
            for typ, exponent in ((2, p.bend_resolution_exponent), (1, p.shear_resolution_exponent)):
                coarse = (self._con_type == typ) & (side > 0) & (side < p.bend_reference_resolution)
                factor = (side[coarse] / p.bend_reference_resolution) ** exponent
                scale[:, coarse] *= factor.astype(np.float32)
            fine = (self._con_type == 2) & (side > p.bend_reference_resolution)
            # each frame projects the longer bend constraints about as much as at the reference
            scale[:, fine] *= np.float32(self._given_params.substeps / p.substeps)
        self._write_slice(self._con_kscale, 0, scale.reshape(-1))

    def held_clearance(self) -> np.ndarray:
        """How far (m) each picker may descend before something it holds touches the ground,
        ``(W, P)``: the smallest ``z - radius`` over the particles it grasped and over every
        particle of a rigid box it grasped (``inf`` for a picker that holds nothing; negative when
        a held object is already below the ground)."""
        W, N, P = self._W, self._N, self._P
        out = np.full((W, P), np.inf)
        if not (P and N and self._holding.any()):
            return out
        owner = self._attach.numpy()[: W * N].reshape(W, N).copy()
        if self._B:
            box = self._box_of.numpy()[:N]
            for b in range(self._B):
                members = box == b
                held_by = owner[:, members].max(axis=1)  # the highest picker index holding box b (-1: none)
                owner[:, members] = np.where(held_by[:, None] >= 0, held_by[:, None], owner[:, members])
        w, i = np.nonzero(owner >= 0)
        if len(w):
            np.minimum.at(out, (w, owner[w, i]), self._heights_above_table()[w, i])
        return out

    def _heights_above_table(self) -> np.ndarray:
        """``z - radius`` of every particle, ``(W, N)`` float64 (0: resting on the table)."""
        W, N = self._W, self._N
        z = self.particle_q.numpy()[: W * N].reshape(W, N, 3)[..., 2]
        return (z - self._radius.numpy()[: W * N].reshape(W, N)).astype(np.float64)

    def _build_contact_pushes(self) -> Any:
        """The contact-push accumulators read by :func:`kernels.update_velocity` (the arrays live
        as long as the engine and no parameter enters, so :meth:`set_params` keeps them)."""
        pushes = K.ContactPushes()
        pushes.particles_per_world, pushes.boxes_per_world = self._N, self._B
        pushes.box_of_particle, pushes.particle_push, pushes.pusher = self._box_of, self._picker_push, self._pusher
        pushes.box_push, pushes.box_pusher_velocity = self._box_push, self._box_pusher_v
        return pushes

    @property
    def _picker_spheres(self) -> Any:
        """The picker sphere struct of the particle passes (also read by shape matching)."""
        return self._particle_pass_structs[-1]

    @property
    def _pickers_press_boxes(self) -> bool:
        return bool(self._params.picker_collision and self._B and self._P)

    def _limit_picker_targets(self, start: np.ndarray, end: np.ndarray) -> np.ndarray:
        """Picker targets ``end`` ``(W, P, 3)`` kept where the table stops them: a holding picker
        stays above the height at which what it holds would enter the table (one already below
        is lifted out), and a colliding picker does not press a free box into it. ``end`` itself
        is returned when nothing is held and pickers do not collide."""
        if not (self._holding.any() or self._pickers_press_boxes):
            return end
        out = np.array(end, dtype=np.float64)
        clearance = self.held_clearance()
        if np.isfinite(clearance).any():
            out[..., 2] = np.maximum(out[..., 2], np.asarray(start, np.float64)[..., 2] - clearance)
        if self._pickers_press_boxes:
            boxes = self._box_contact_state()
            for _ in range(4):  # a target inside a box is first raised out of it, then onto its face
                excess = self._box_press_excess(out, *boxes)
                out[..., 2] += excess
                if excess.max() < 1e-6:
                    break
        return out.astype(end.dtype, copy=False)

    def _box_contact_state(self) -> tuple[np.ndarray, ...]:
        """Rigid box centres, rotations, half extents, free flags ``(W, B)`` and clearances above
        the table ``(W, B)`` for :meth:`_box_press_excess` (read once per frame)."""
        W, N, B = self._W, self._N, self._B
        centers, rots = self.rigid_box_poses()
        he = self._box_he.numpy()[: W * B].reshape(W, B, 3)
        free = self._box_kin.numpy()[: W * B].reshape(W, B) == 0
        heights, box = self._heights_above_table(), self._box_of.numpy()[:N]
        clearance = np.stack([heights[:, box == b].min(axis=1) for b in range(B)], axis=1)
        return centers, rots, he, free, clearance

    def _box_press_excess(self, pickers: np.ndarray, centers: np.ndarray, rots: np.ndarray, he: np.ndarray,
                          free: np.ndarray, clearances: np.ndarray) -> np.ndarray:
        """How far (m) each colliding picker at ``pickers`` ``(W, P, 3)`` would push a free rigid
        box below the table: the downward part of the sphere's push on the box (sphere against
        the box's faces) beyond the box's clearance above the table, ``(W, P)`` (0 if none)."""
        W, P, B = self._W, self._P, self._B
        radius = self._params.picker_radius
        excess = np.zeros((W, P))
        for b in range(B):
            clearance = clearances[:, b]  # (W,)
            local = np.einsum("wpk,wkj->wpj", pickers - centers[:, None, b], rots[:, b])
            d = local - np.clip(local, -he[:, None, b], he[:, None, b])
            dist = np.linalg.norm(d, axis=-1)
            # the push moves the box along -d by (radius - dist); its downward part is
            # (radius - dist) * (upward component of d / dist). A centre inside the box: the height
            # (m) that takes it out through the face that looks most upwards, plus the radius
            above = np.einsum("wkj,wpj->wpk", rots[:, b], d)[..., 2] / np.maximum(dist, 1e-9)
            up = rots[:, b, 2, :]  # world z of each local axis, (W, 3)
            axis = np.abs(up).argmax(axis=1)
            u = np.take_along_axis(up, axis[:, None], 1)[:, 0]  # (W,)
            face = np.sign(u) * np.take_along_axis(he[:, b], axis[:, None], 1)[:, 0]
            along = np.take_along_axis(local, axis[:, None, None].repeat(P, 1), 2)[..., 0]  # (W, P)
            out_of_box = (face[:, None] - along) * np.sign(u)[:, None] / np.abs(u)[:, None] + radius
            push_down = np.where(dist > 1e-9, (radius - dist) * np.clip(above, 0.0, None), out_of_box)
            push_down = np.where((dist < radius) & free[:, b, None], push_down, 0.0)
            excess = np.maximum(excess, np.where(push_down > 0, push_down - clearance[:, None], 0.0))
        return excess

    def _update_holding(self) -> None:
        """Recompute which pickers hold at least one particle (``(W, P)``, from the attachments)."""
        W, N, P = self._W, self._N, self._P
        attach = self._attach.numpy()[: W * N].reshape(W, N)
        self._holding = (attach[:, :, None] == np.arange(P)[None, None, :]).any(axis=1) if N else np.zeros((W, P), bool)

    def _update_tethers(self) -> None:
        """Recompute the long-range attachments (after pins/grasps/state changes)."""
        p = self._params
        wp.launch(K.update_tethers, dim=self._W, device=self._device,
                  inputs=[self._inv_mass, self._attach, self._obj, self._box_of, self._rest, self._N,
                          float(p.tether_slack), int(p.tethers), self._anchors,
                          self._tether_anchor, self._tether_len])

    def _update_grid_params(self) -> None:
        sc = self._sc_r.numpy()[: self._W * self._N]
        rmax = float(sc.max()) if sc.size else 0.0
        self._has_sc = rmax > 0.0
        fac = 1.0 + self._params.self_collision_margin
        cell = max(4.0 * rmax * fac, 1e-4)  # 2 x (largest pair cut-off): 8-cell queries suffice
        vals = np.array([cell, fac], np.float32)
        if self._device.is_cpu:
            gp = self._grid_params.numpy()
            changed = not np.array_equal(gp, vals)
            gp[:] = vals
        else:
            changed = True
            self._grid_params.assign(vals)
        if changed and getattr(self, "_graph_sc", None) != self._has_sc:
            self._graph = None
        self._graph_sc = self._has_sc
