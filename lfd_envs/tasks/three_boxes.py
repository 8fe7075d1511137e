"""ThreeBoxes-v0: move three rigid boxes on a line to their goals (MAIL's ThreeCubes, z-up).

Scene: three dynamic rigid boxes (shape-matched particle boxes of the engine) stand on the
table along the x axis (y = 0): half extents (0.05, 0.05, 0.05), (0.08, 0.05, 0.05) and
(0.02, 0.05, 0.05) m (x, y, z), mass 0.1 kg each. Unlike MAIL (kinematic teleports without
collision checks) the boxes are physical: they collide with the table and with each other and
are carried by pickers that grasp the particles of their top face (``grasp_mode="radius"``).

Variants (MAIL's 3-picker variations, used for every picker count): start x of box i
``U(0, 0.1)``, ``U(0.3, 0.4)``, ``U(0.8, 0.9)``; goals at x = ``1.1``, ``0.7``, ``0.1`` (MAIL's
fixed goals, part of the state all the same). The start order is the reverse of the goal order, so a single
picker must choose its order (box 3 has to leave before box 2 can reach its goal).

Performance: ``p = -sum_i |c_i - g_i|`` (box centres ``c_i`` and goal centres ``g_i`` =
goal on the table, 3-D distance in metres), ``p_opt = 0``; ``normalized_performance =
(p - p0) / (0 - p0)``; ``is_success`` when ``p > -0.05``. ``info["max_box_error"]`` is the
largest single-box distance. Reward = change of ``p`` per step.

Reduced state: per box its centre and orientation quaternion ``(x, y, z, qx, qy, qz, qw)``,
then the 3 goal centres, then the pickers (``30 + 3P`` numbers). ``resolution`` = particles
per axis on the surface lattice of the widest box (2..6, default 4). Horizons: 75 (delta),
3 (pick_place). Default action mode ``pick_place``. Workspace: x in [-0.2, 1.45], y in
[-0.3, 0.3], z in [0, 1.2]. Pick-and-place carries follow an arc whose height grows with the
carry distance (0.8 per metre with several pickers, so that boxes moved at the same time pass
over each other with >= 4 cm to spare in every variant; 0.25 per metre with one picker, enough
to clear the standing boxes).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from lfd_envs.tasks.particle_env import PickPlaceParticleEnv, PickPlaceParticleVectorEnv
from lfd_envs.tasks.particle_task import Context, ParticleTask, TaskVariant
from lfd_envs.tasks.particle_state_values import check_boxes_apart
from lfd_envs.tasks.picker_actions import PickPlaceSchedule, Workspace

__all__ = ["ThreeBoxesTask", "ThreeBoxesEnv", "ThreeBoxesVectorEnv", "BOX_HALF_EXTENTS", "box_poses",
           "matrix_to_quaternion", "frame_particles"]

BOX_HALF_EXTENTS = np.array([[0.05, 0.05, 0.05], [0.08, 0.05, 0.05], [0.02, 0.05, 0.05]])
START_X = ((0.0, 0.1), (0.3, 0.4), (0.8, 0.9))
GOAL_X = (1.1, 0.7, 0.1)
BOX_MASS = 0.1
BOX_COLORS = ((0.85, 0.35, 0.25), (0.25, 0.55, 0.85), (0.35, 0.75, 0.35))
SUCCESS_DISTANCE = 0.05
#: MAIL's place range along the line (action bounds of ThreeCubes)
PLACE_X = (-0.1, 1.35)


def frame_particles(local: np.ndarray, slices: list[slice]) -> np.ndarray:
    """Per box three corner particles ``(B, 3)`` (global indices) spanning its frame: the
    (-, -, -) corner, the (+, -, -) corner (local x) and the (-, +, -) corner (local y)."""
    out = []
    for sl in slices:
        l = local[sl]
        picks = [np.argmin(l @ [1, 1, 1]), np.argmax(l @ [1, -1, -1]), np.argmax(l @ [-1, 1, -1])]
        out.append([sl.start + int(i) for i in picks])
    return np.asarray(out, dtype=np.int64)


def box_poses(positions: np.ndarray, local: np.ndarray, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Centres ``(W, B, 3)`` and rotations ``(W, B, 3, 3)`` of rigid particle boxes.

    Shape matching keeps the particles of a box exactly rigid, so the frame of three corner
    particles (:func:`frame_particles`) gives the pose; only elementwise arithmetic is used, so
    a world's result is bitwise independent of the batch it is in (unlike LAPACK/BLAS calls).
    ``local`` ``(W, N, 3)`` holds each world's rest offsets of every particle from its box centre.
    """
    x = np.asarray(positions, np.float64)
    a, b, c = (x[:, corners[:, i]] for i in range(3))  # (W, B, 3)

    def unit(v: np.ndarray) -> np.ndarray:
        return v / np.sqrt((v * v).sum(axis=-1, keepdims=True))

    e1 = unit(b - a)
    v = c - a
    e2 = unit(v - (v * e1).sum(axis=-1, keepdims=True) * e1)
    e3 = np.cross(e1, e2)
    rots = np.stack([e1, e2, e3], axis=-1)  # columns = local axes in the world
    la = np.asarray(local, np.float64)[:, corners[:, 0]]  # (W, B, 3)
    centers = a - (rots * la[:, :, None, :]).sum(axis=-1)
    return centers, rots


def matrix_to_quaternion(r: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(..., 4)`` in ``(x, y, z, w)`` order (w >= 0) of rotations ``(..., 3, 3)``."""
    r = np.asarray(r, np.float64)
    m00, m11, m22 = r[..., 0, 0], r[..., 1, 1], r[..., 2, 2]
    q = np.stack([
        np.sqrt(np.maximum(0.0, 1 + m00 - m11 - m22)) * 0.5 * np.sign(r[..., 2, 1] - r[..., 1, 2] + 1e-30),
        np.sqrt(np.maximum(0.0, 1 - m00 + m11 - m22)) * 0.5 * np.sign(r[..., 0, 2] - r[..., 2, 0] + 1e-30),
        np.sqrt(np.maximum(0.0, 1 - m00 - m11 + m22)) * 0.5 * np.sign(r[..., 1, 0] - r[..., 0, 1] + 1e-30),
        np.sqrt(np.maximum(0.0, 1 + m00 + m11 + m22)) * 0.5,
    ], axis=-1)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


class ThreeBoxesTask(ParticleTask):
    """Scene, state and score of ThreeBoxes (see module docstring)."""

    name = "ThreeBoxes-v0"
    default_num_pickers = 1
    horizons = {"delta": 75, "pick_place": 3}
    default_resolution = 4
    resolution_range = (2, 6)
    performance_optimum = 0.0
    picker_radius: ClassVar[float] = 0.02
    picker_render_radius = 0.02
    picker_start_height = 0.25
    #: radius (m) around the picker within which top-face particles are grasped
    grasp_radius: ClassVar[float] = 0.06

    def __init__(self, resolution: int | None = None, num_pickers: int | None = None) -> None:
        super().__init__(resolution, num_pickers)
        self.box_slices: list[slice] = []
        self._corners: np.ndarray | None = None

    # ------------------------------------------------------------------ engine
    def sim_params(self):
        from lfd_envs.sim import SimParams

        return SimParams(picker_radius=self.picker_radius, grasp_radius=self.grasp_radius, grasp_mode="radius",
                         self_collision=False, particle_radius=0.005)

    def workspace(self) -> Workspace:
        return Workspace((-0.2, -0.3, 0.0), (1.45, 0.3, 1.2), margin=self.picker_radius)

    def pick_place_schedule(self) -> PickPlaceSchedule:
        ratio = 0.8 if self.num_pickers > 1 else 0.25
        return PickPlaceSchedule(hover=0.05, lift=0.03, arc_ratio=ratio, arc_max=0.9, free_speed=0.04,
                                 carry_speed=0.03, approach_frames=24, descend_frames=6, lift_frames=4,
                                 carry_frames=96, lower_frames=6, retreat_frames=3, settle_frames=10)

    def camera(self):
        from lfd_envs.render import Camera

        return Camera(position=(0.55, -1.6, 0.95), look_at=(0.55, 0.0, 0.1), fov_y_deg=45.0)

    # ------------------------------------------------------------------ variants
    @property
    def box_spacing(self) -> float:
        """Surface-lattice spacing giving ``resolution`` particles along the widest box."""
        return float(2.0 * (BOX_HALF_EXTENTS[:, 0].max() - 0.005) / max(self.resolution - 1, 1)) + 1e-9

    def build(self, rng: np.random.Generator) -> TaskVariant:
        from lfd_envs.sim import SceneBuilder

        start = np.array([rng.uniform(*r) for r in START_X])
        goal_x = np.asarray(GOAL_X, np.float64)
        builder = SceneBuilder()
        slices = []
        for i, he in enumerate(BOX_HALF_EXTENTS):
            h = builder.add_rigid_box((start[i], 0.0, he[2]), he, mass=BOX_MASS, spacing=self.box_spacing)
            slices.append(slice(h.start, h.start + h.count))
        self.box_slices = slices
        goals = np.stack([goal_x, np.zeros(3), BOX_HALF_EXTENTS[:, 2]], axis=1)
        return TaskVariant(builder, {"goals": goals})

    def picker_start(self, positions: np.ndarray, data: dict[str, np.ndarray]) -> np.ndarray:
        """Pickers in a row 0.25 m above the middle of the line, 0.2 m apart."""
        p = self.num_pickers
        out = np.zeros((p, 3))
        out[:, 0] = 0.55 + 0.2 * (np.arange(p) - 0.5 * (p - 1))
        out[:, 2] = self.picker_start_height
        return out

    def episode_context(self, positions: np.ndarray, data: dict[str, np.ndarray]) -> Context:
        ctx = super().episode_context(positions, data)
        local = np.asarray(positions, np.float64).copy()
        for sl in self.box_slices:  # the boxes start upright: rest offsets = offsets from the centroid
            local[sl] -= local[sl].mean(axis=0)
        ctx["box_local"] = local
        return ctx

    # ------------------------------------------------------------------ observations
    def poses(self, positions: np.ndarray, ctx: Context) -> tuple[np.ndarray, np.ndarray]:
        """Box centres ``(W, 3, 3)`` and rotations ``(W, 3, 3, 3)``."""
        local = np.asarray(ctx["box_local"])
        if self._corners is None:
            self._corners = frame_particles(local[0], self.box_slices)
        return box_poses(positions, local, self._corners)

    def check_state(self, positions: np.ndarray, ctx: dict[str, np.ndarray]) -> None:
        """The boxes that the particles form do not interpenetrate (a box put inside another)."""
        centers, rots = self.poses(np.asarray(positions)[None], {"box_local": np.asarray(ctx["box_local"])[None]})
        check_boxes_apart("sim/positions", centers[0], rots[0], BOX_HALF_EXTENTS)

    def state_dim(self) -> int:
        return 30 + 3 * self.num_pickers

    def reduced_state(self, positions: np.ndarray, pickers: np.ndarray, ctx: Context) -> np.ndarray:
        w = positions.shape[0]
        centers, rots = self.poses(positions, ctx)
        boxes = np.concatenate([centers, matrix_to_quaternion(rots)], axis=-1).reshape(w, -1)
        return np.concatenate([boxes, np.asarray(ctx["goals"]).reshape(w, -1), pickers.reshape(w, -1)],
                              axis=1).astype(np.float32)

    def object_layers(self, positions: np.ndarray, ctx: Context) -> list[Any]:
        from lfd_envs.render import BoxLayer

        centers, rots = self.poses(positions, ctx)
        goals = np.array(ctx["goals"], np.float64, copy=True)
        goals[..., 2] = 0.0015
        marker = BOX_HALF_EXTENTS.copy()
        marker[:, 2] = 0.0015
        light = [tuple(0.55 + 0.45 * np.asarray(c)) for c in BOX_COLORS]
        return [BoxLayer(goals, marker, colors=light), BoxLayer(centers, BOX_HALF_EXTENTS, rots, colors=BOX_COLORS)]

    # ------------------------------------------------------------------ scoring
    def box_centers(self, positions: np.ndarray) -> np.ndarray:
        """Box centres ``(W, 3, 3)`` (centroids of their particles; for experts and tests)."""
        return np.stack([np.asarray(positions[:, sl], np.float64).mean(axis=1) for sl in self.box_slices], axis=1)

    def evaluate(self, positions: np.ndarray, ctx: Context) -> dict[str, np.ndarray]:
        d = self.poses(positions, ctx)[0] - np.asarray(ctx["goals"])
        dist = np.sqrt((d * d).sum(axis=-1))
        return {"performance": -dist.sum(axis=1), "max_box_error": dist.max(axis=1)}

    def performance(self, positions: np.ndarray, ctx: Context) -> np.ndarray:
        return self.evaluate(positions, ctx)["performance"]

    def success(self, p: np.ndarray, p_hat: np.ndarray) -> np.ndarray:
        return np.asarray(p) > -SUCCESS_DISTANCE

    # ------------------------------------------------------------------ for experts / data
    def grasp_point(self, center: np.ndarray, box: int) -> np.ndarray:
        """Picker centre that grasps box ``box`` (middle of its top face) at ``center``."""
        return np.asarray(center, np.float64) + np.array([0.0, 0.0, BOX_HALF_EXTENTS[box, 2]])

    def sample_pick_place(self, positions: np.ndarray, ctx_world: dict[str, np.ndarray],
                          rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Random action for dynamics data (MAIL): each picker takes a different random box
        with nothing on top of it and places it at a random point of the line (x in
        [-0.1, 1.35]) resting on the table or on the boxes that stay there (places of the same
        action never overlap; up to 20 draws each). Pickers without a box stay idle at the
        workspace top. Returns ``(pick, place)``, ``(P, 3)`` each."""
        p = self.num_pickers
        centers = self.box_centers(np.asarray(positions)[None])[0]
        he = BOX_HALF_EXTENTS
        free = [b for b in rng.permutation(3) if not any(self._on_top(centers, o, b) for o in range(3) if o != b)]
        movers = [int(b) for b in free[:p]]
        top = self.workspace().hi[2] - self.picker_radius
        pick = np.tile([0.55, 0.0, top], (p, 1))
        place = pick.copy()
        stay = [b for b in range(3) if b not in movers]
        placed: list[tuple[int, float]] = []
        for k, b in enumerate(movers):
            for _ in range(20):
                x = rng.uniform(*PLACE_X)
                if all(abs(x - xo) >= he[b, 0] + he[o, 0] + 0.005 for o, xo in placed):
                    break
            support = [centers[o, 2] + he[o, 2] for o in stay if abs(x - centers[o, 0]) < he[b, 0] + he[o, 0]]
            bottom = max(support, default=0.0)
            pick[k] = self.grasp_point(centers[b], b)
            place[k] = self.grasp_point([x, 0.0, bottom + he[b, 2] + 0.002], b)
            placed.append((b, x))
        return pick, place

    @staticmethod
    def _on_top(centers: np.ndarray, upper: int, lower: int) -> bool:
        """Whether box ``upper`` rests on (or above) box ``lower``."""
        he = BOX_HALF_EXTENTS
        over = np.all(np.abs(centers[upper, :2] - centers[lower, :2]) < he[upper, :2] + he[lower, :2])
        return bool(over and centers[upper, 2] - he[upper, 2] >= centers[lower, 2] + he[lower, 2] - 0.01)


class ThreeBoxesEnv(PickPlaceParticleEnv):
    """ThreeBoxes-v0 (see :mod:`lfd_envs.tasks.three_boxes`); default action mode ``pick_place``."""

    task_class = ThreeBoxesTask


class ThreeBoxesVectorEnv(PickPlaceParticleVectorEnv):
    """Batched ThreeBoxes-v0 (one engine call per frame for all worlds)."""

    task_class = ThreeBoxesTask
