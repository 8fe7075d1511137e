"""ClothFoldDiagonal-v0 (and the Pinned/Unpinned ids): fold a square cloth along its diagonal.

DMfD's ``ClothFoldRobot`` (pinned) and ``ClothFoldRobotHard`` (unpinned) in z-up coordinates.
The cloth is a 0.75 m square of ``resolution x resolution`` particles (default 40) lying flat in
the middle of the table; variants shift it by up to 2 cm and turn it by up to 3 degrees (DMfD
had a single variant). One picker (default) starts 0.1 m above the middle of the left edge.

* ``pinned=True``: a heavy block (half extents 0.1 x 0.1 x 0.04 m centred at (0.25, 0.25, 0.02),
  as in DMfD: 6 cm stand above the table) presses the cloth near the top-right corner to the
  table (the particles it touches, under it or within a particle radius of its sides, are
  pinned; the block is also a collider and is rendered).
* ``pinned=False`` (default of ``ClothFoldDiagonal-v0``): the cloth slides freely.

The fold carries the bottom-left corner onto the top-right corner (reflection across the
top-left/bottom-right diagonal). Performance (DMfD "edges" metric), with the grid's left edge
paired with the top edge and the right edge with the bottom edge::

    p = -(|left - top|_F + |right - bottom|_F),     p_opt = 0

(Frobenius norms over the particle rows). ``info["corner_distance"]`` is the distance between
the bottom-left and the top-right corners. Reward = change of ``p`` per step.

The edge metric only looks at the border, so crumpling fools it: shrinking the cloth to a
fraction ``f`` of its size scores p-hat = 1 - f, and dropping it from a height scores well above
0. ``info["fold_quality"]`` is a measure crumpling cannot fool (ClothFold's, across the
diagonal): group A = the bottom-left triangle, B = each A particle's mirror partner across the
diagonal, and::

    q = 1 - (mean |A - B| + 1.2 mean |B - B_flat|) / mean |A_flat - B_flat|

where ``B_flat`` is B laid out flat as at the start of the episode (the variant's offset and
turn). ``q = 0`` for the flat cloth, 1 for a perfect fold that leaves B where it was; a cloth
shrunk, crumpled or dropped moves B and scores about 0 or below. ``info`` also has the two means
(``fold_group_distance``, ``fold_fixation_distance``, m).
Default observation: a 32x32 RGB image (DMfD). Horizons: 100 (delta), 3 (pick_place).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from lfd_envs.tasks.cloth_task import ClothTask
from lfd_envs.tasks.particle_env import ParticleEnv, ParticleVectorEnv
from lfd_envs.tasks.particle_task import Context, TaskVariant
from lfd_envs.tasks.picker_actions import FAST_FREE_MOVES, PickPlaceSchedule, Workspace

__all__ = ["ClothFoldDiagonalTask", "ClothFoldDiagonalEnv", "ClothFoldDiagonalVectorEnv", "diagonal_edge_distance",
           "diagonal_fold_distances", "diagonal_pairs", "FIXATION_WEIGHT"]

CLOTH_SIZE = 0.75
MAX_OFFSET = 0.02
MAX_YAW = np.deg2rad(3.0)
BLOCK_CENTER_XY = (0.25, 0.25)
BLOCK_HALF_EXTENTS = (0.1, 0.1, 0.04)
BLOCK_CENTER_Z = 0.02  # DMfD: centre 0.02 above the table top, i.e. 2 cm sunk into it


def diagonal_edge_distance(grid: np.ndarray) -> np.ndarray:
    """``|left - top|_F + |right - bottom|_F`` per world for grids ``(W, n, n, 3)``."""
    left, right = grid[:, :, 0], grid[:, :, -1]
    top, bottom = grid[:, -1, ::-1], grid[:, 0, ::-1]
    return (np.linalg.norm((left - top).reshape(len(grid), -1), axis=1)
            + np.linalg.norm((right - bottom).reshape(len(grid), -1), axis=1))


#: weight of the fixation term of the fold quality (SoftGym ClothFold's 1.2)
FIXATION_WEIGHT = 1.2


@functools.lru_cache(maxsize=8)
def diagonal_pairs(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Flat grid indices ``(a, b)`` of the fold pairs of an ``n x n`` cloth: ``a`` = the
    bottom-left triangle (``row + col < n - 1``), ``b`` = their partners across the
    top-left/bottom-right diagonal (``(row, col) -> (n-1-col, n-1-row)``)."""
    r, c = np.nonzero(np.add.outer(np.arange(n), np.arange(n)) < n - 1)
    a, b = r * n + c, (n - 1 - c) * n + (n - 1 - r)
    a.setflags(write=False)
    b.setflags(write=False)
    return a, b


def _pair_distances(cloth: np.ndarray, flat_b: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    a_idx, b_idx = diagonal_pairs(n)
    b = cloth[:, b_idx]
    d_ab, d_fix = cloth[:, a_idx] - b, b - flat_b.astype(b.dtype, copy=False)
    group = np.sqrt(np.einsum("wmk,wmk->wm", d_ab, d_ab)).mean(axis=1, dtype=np.float64)
    fixation = np.sqrt(np.einsum("wmk,wmk->wm", d_fix, d_fix)).mean(axis=1, dtype=np.float64)
    return group, fixation


def diagonal_fold_distances(grid: np.ndarray, flat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(mean |A - B|, mean |B - B_flat|)`` per world for the diagonal fold (pairs of
    :func:`diagonal_pairs`).

    Args:
        grid: Cloth grids ``(W, n, n, 3)``.
        flat: The same grids laid out flat at the start of the episode ``(W, n, n, 3)``.
    """
    w, n = grid.shape[:2]
    flat_b = np.asarray(flat, np.float64).reshape(w, n * n, 3)[:, diagonal_pairs(n)[1]]
    return _pair_distances(np.asarray(grid).reshape(w, n * n, 3), flat_b, n)


class ClothFoldDiagonalTask(ClothTask):
    """Scene, state and score of the diagonal fold (see module docstring).

    Args:
        pinned: Hold the top-right corner region with a heavy block.
    """

    name = "ClothFoldDiagonal-v0"
    default_num_pickers = 1
    horizons = {"delta": 100, "pick_place": 3}
    default_obs_mode = "image"

    def __init__(self, resolution: int | None = None, num_pickers: int | None = None,
                 pinned: bool = False) -> None:
        super().__init__(resolution, num_pickers)
        if not isinstance(pinned, (bool, np.bool_)):
            raise ValueError(f"pinned must be a bool, got {pinned!r}")
        self.pinned = bool(pinned)
        # pinned and unpinned variants differ (their ids are separate tasks)
        self.name = "ClothFoldDiagonalPinned-v0" if self.pinned else "ClothFoldDiagonalUnpinned-v0"

    def workspace(self) -> Workspace:
        return Workspace((-0.6, -0.6, 0.0), (0.6, 0.6, 0.7), margin=self.picker_radius)

    def pick_place_schedule(self) -> PickPlaceSchedule:
        # 69 frames: the carry speed decides the fold quality (fewer carry frames lose p-hat), the
        # short hold/settle do not (the expert's final p-hat is unchanged; residual motion after a
        # step dies out in the next one)
        return PickPlaceSchedule(lift=0.02, arc_ratio=0.45, arc_max=0.6, carry_frames=56, hold_frames=2,
                                 settle_frames=2, **FAST_FREE_MOVES)

    def camera(self):
        from lfd_envs.render import Camera

        return Camera(position=(0.0, -0.95, 1.05), look_at=(0.0, 0.02, 0.0), fov_y_deg=45.0)

    @property
    def block_center(self) -> np.ndarray:
        """Centre of the pin block: as in DMfD it is sunk 2 cm into the table (6 cm visible);
        the cloth particles under it are pinned, so the overlap pushes nothing away."""
        return np.array([*BLOCK_CENTER_XY, BLOCK_CENTER_Z])

    def build(self, rng: np.random.Generator) -> TaskVariant:
        from lfd_envs.sim import SceneBuilder

        offset = rng.uniform(-MAX_OFFSET, MAX_OFFSET, size=2)
        yaw = float(rng.uniform(-MAX_YAW, MAX_YAW))
        builder = SceneBuilder()
        handle = self.add_square_cloth(builder, CLOTH_SIZE, center=tuple(offset), yaw=yaw)
        if self.pinned:
            builder.add_static_box(self.block_center, BLOCK_HALF_EXTENTS)
            builder.pin(handle.start + np.flatnonzero(self._under_block(offset, yaw)))
        return TaskVariant(builder, {"offset": offset, "yaw": np.float64(yaw)})

    def flat_points(self, offset: np.ndarray, yaw: np.ndarray, idx: np.ndarray | None = None) -> np.ndarray:
        """Grid particles ``idx`` (flat grid indices, default all) of the cloth as laid out flat on
        the table, ``(W, len(idx), 3)``, for offsets ``(W, 2)`` and yaws ``(W,)`` (the variant
        data; the same layout the scene builder uses)."""
        n = self.resolution
        if getattr(self, "_local_layout", None) is None:
            s = np.linspace(-0.5 * CLOTH_SIZE, 0.5 * CLOTH_SIZE, n)
            y, x = np.meshgrid(s, s, indexing="ij")
            self._local_layout = np.stack([x.ravel(), y.ravel()], axis=1)
        local = self._local_layout if idx is None else self._local_layout[idx]
        offset, yaw = np.atleast_2d(np.asarray(offset, np.float64)), np.atleast_1d(np.asarray(yaw, np.float64))
        c, si = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
        out = np.empty((len(yaw), len(local), 3))
        out[..., 0] = c * local[:, 0] - si * local[:, 1] + offset[:, 0, None]
        out[..., 1] = si * local[:, 0] + c * local[:, 1] + offset[:, 1, None]
        out[..., 2] = self.particle_radius
        return out

    def flat_grid(self, offset: np.ndarray, yaw: np.ndarray) -> np.ndarray:
        """The cloth as laid out flat on the table, ``(W, n, n, 3)`` (see :meth:`flat_points`)."""
        n = self.resolution
        return self.flat_points(offset, yaw).reshape(-1, n, n, 3)

    def _under_block(self, offset: np.ndarray, yaw: float) -> np.ndarray:
        """Mask ``(n*n,)`` of grid particles that touch the pin block: under its footprint or
        within a particle radius of its sides. A free particle that overlapped a side would be
        pushed out of the block at once, stretching its edge to the pinned neighbour."""
        flat = self.flat_grid(offset, yaw)[0]
        reach = np.asarray(BLOCK_HALF_EXTENTS[:2], float) + self.particle_radius
        return ((np.abs(flat[..., 0] - BLOCK_CENTER_XY[0]) <= reach[0])
                & (np.abs(flat[..., 1] - BLOCK_CENTER_XY[1]) <= reach[1])).ravel()

    def performance(self, positions: np.ndarray, ctx: Context) -> np.ndarray:
        return -diagonal_edge_distance(self.grid(positions))

    def metrics(self, positions: np.ndarray, ctx: Context) -> dict[str, np.ndarray]:
        bl, tr = self.grid_index(0, 0), self.grid_index(-1, -1)
        n = self.resolution
        cloth = positions[:, self.cloth_start:self.cloth_start + n * n]
        key = (np.asarray(ctx["offset"]).tobytes(), np.asarray(ctx["yaw"]).tobytes(), cloth.dtype)
        if getattr(self, "_flat_b", (None,))[0] != key:  # B laid out flat: fixed for an episode
            flat = self.flat_points(ctx["offset"], ctx["yaw"], diagonal_pairs(n)[1]).astype(cloth.dtype)
            self._flat_b = (key, flat)
        group, fixation = _pair_distances(cloth, self._flat_b[1], n)
        return {"corner_distance": np.linalg.norm(positions[:, bl] - positions[:, tr], axis=-1),
                "fold_group_distance": group, "fold_fixation_distance": fixation,
                "fold_quality": 1.0 - (group + FIXATION_WEIGHT * fixation) / self.flat_group_distance}

    @property
    def flat_group_distance(self) -> float:
        """``mean |A - B|`` of the flat cloth (the fold quality's 0; the same for every variant)."""
        if not hasattr(self, "_flat_group"):
            flat = self.flat_grid(np.zeros(2), 0.0)
            self._flat_group = float(diagonal_fold_distances(flat, flat)[0][0])
        return self._flat_group

    # ------------------------------------------------------------------ for experts
    def fold_pairs(self, num: int) -> tuple[np.ndarray, np.ndarray]:
        """``num`` pick particles on the bottom-left half's border (the bottom-left corner
        first, then points on the left and bottom edges) and their mirror partners."""
        n = self.resolution
        pts = [(0, 0)]
        m = num // 2  # distinct distances from the corner
        k = 1
        while len(pts) < num:  # a left-edge point, then its bottom-edge twin
            t = int(round(k * (n - 1) / (m + 1)))
            pts.append((t, 0))
            if len(pts) < num:
                pts.append((0, t))
            k += 1
        r, c = np.array(pts).T
        return self.grid_index(r, c), self.grid_index(n - 1 - c, n - 1 - r)


class ClothFoldDiagonalEnv(ParticleEnv):
    """ClothFoldDiagonal-v0 / ...Pinned-v0 / ...Unpinned-v0 (see module docstring).

    Same arguments as every particle env plus ``pinned`` (default False).
    """

    task_class = ClothFoldDiagonalTask

    def __init__(self, num_pickers: int | None = None, action_mode: str = "delta", obs_mode: str | None = None,
                 image_size: int | tuple[int, int] = 32, resolution: int | None = None, device: str = "cpu",
                 render_mode: str | None = None, horizon: int | None = None, pinned: bool = False,
                 render_size: int | tuple[int, int] | None = None,
                 pick_place_speed: float | None = None, sim_options: dict[str, Any] | None = None,
                 physics: str = "fast", observe_grasp: bool = False) -> None:
        self._setup(dict(num_pickers=num_pickers, resolution=resolution, pinned=pinned), action_mode, obs_mode,
                    image_size, device, render_mode, horizon, render_size,
                    pick_place_speed=pick_place_speed, sim_options=sim_options, physics=physics,
                    observe_grasp=observe_grasp)


class ClothFoldDiagonalVectorEnv(ParticleVectorEnv):
    """Batched diagonal fold (one engine call per frame for all worlds); ``pinned`` as above."""

    task_class = ClothFoldDiagonalTask

    def __init__(self, num_envs: int = 1, num_pickers: int | None = None, action_mode: str = "delta",
                 obs_mode: str | None = None, image_size: int | tuple[int, int] = 32,
                 resolution: int | None = None, device: str = "cpu", render_mode: str | None = None,
                 horizon: int | None = None, pinned: bool = False,
                 render_size: int | tuple[int, int] | None = None, max_episode_steps: int | None = None,
                 pick_place_speed: float | None = None, sim_options: dict[str, Any] | None = None,
                 physics: str = "fast", observe_grasp: bool = False) -> None:
        self._setup(num_envs, dict(num_pickers=num_pickers, resolution=resolution, pinned=pinned), action_mode,
                    obs_mode, image_size, device, render_mode, horizon, render_size, max_episode_steps,
                    pick_place_speed=pick_place_speed, sim_options=sim_options, physics=physics,
                    observe_grasp=observe_grasp)
