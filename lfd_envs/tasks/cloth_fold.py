"""ClothFold-v0: fold a square cloth in half, one half onto the other (SoftGym ClothFold).

Variants: side ``U(0.375, 0.744)`` m (SoftGym's 60-119 particles at 6.25 mm), rotation
``U(-45, 45)`` degrees about z, centred on the table. The particle count per side is
``resolution`` (default 40) whatever the size. Pickers (default 2) start 0.1 m above the middle
of the left edge.

Performance (SoftGym): group A = the left half's columns ``[0, n//2)``, group B = their mirror
images across the vertical centre line (same row)::

    p = -mean_i |A_i - B_i| - 1.2 * mean_i |B_i - B_i(0)|,      p_opt = 0

so the left half must land on the right half while the right half stays where it was.
``info`` adds ``group_distance`` and ``fixation_distance`` (the two means). Reward = change of
``p`` per step; ``normalized_performance`` = ``(p - p0) / (0 - p0)``.

``metric="mail"`` scores as MAIL's ClothFold, which adds the distances of the left corners to
their right partners::

    p = -mean_i |A_i - B_i| - 1.2 * mean_i |B_i - B_i(0)| - (|TL - TR| + |BL - BR|)

(``info["corner_term"]`` is the bracket, reported with either metric).
Horizons: 100 steps (delta), 3 steps (pick_place).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lfd_envs.core.errors import check_choice
from lfd_envs.tasks.cloth_task import ClothTask
from lfd_envs.tasks.particle_env import ParticleEnv, ParticleVectorEnv
from lfd_envs.tasks.particle_task import Context, TaskVariant
from lfd_envs.tasks.picker_actions import FAST_FREE_MOVES, PickPlaceSchedule, Workspace

__all__ = ["ClothFoldTask", "ClothFoldEnv", "ClothFoldVectorEnv", "fold_distances", "METRICS"]

SIZE_RANGE = (60 * 0.00625, 119 * 0.00625)
MAX_YAW = np.pi / 4
#: scores of ClothFold: SoftGym's (default) and MAIL's (with the corner term)
METRICS = ("default", "mail")


def fold_distances(grid: np.ndarray, b_init: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(mean |A - B|, mean |B - B(0)|)`` per world for cloth grids ``(W, n, n, 3)``.

    ``b_init`` ``(W, n, n//2, 3)`` holds group B at the start of the episode.
    """
    half = grid.shape[2] // 2
    a = grid[:, :, :half]
    b = grid[:, :, ::-1][:, :, :half]
    group = np.linalg.norm(a - b, axis=-1).mean(axis=(1, 2))
    fixation = np.linalg.norm(b - b_init, axis=-1).mean(axis=(1, 2))
    return group, fixation


def group_b(grid: np.ndarray) -> np.ndarray:
    """Group B (mirrored right half) ``(W, n, n//2, 3)`` of grids ``(W, n, n, 3)``."""
    return grid[:, :, ::-1][:, :, :grid.shape[2] // 2].copy()


class ClothFoldTask(ClothTask):
    """Scene, state and score of ClothFold (see module docstring).

    Args:
        metric: ``"default"`` (SoftGym) or ``"mail"`` (MAIL: plus the corner term).
    """

    name = "ClothFold-v0"
    default_num_pickers = 2
    horizons = {"delta": 100, "pick_place": 3}

    def __init__(self, resolution: int | None = None, num_pickers: int | None = None,
                 metric: str = "default") -> None:
        super().__init__(resolution, num_pickers)
        self.metric = check_choice("metric", metric, METRICS)

    def workspace(self) -> Workspace:
        return Workspace((-0.6, -0.6, 0.0), (0.6, 0.6, 0.7), margin=self.picker_radius)

    def pick_place_schedule(self) -> PickPlaceSchedule:
        return PickPlaceSchedule(lift=0.02, arc_ratio=0.45, arc_max=0.5, carry_frames=48, hold_frames=8,
                                 **FAST_FREE_MOVES)  # 71 frames

    def camera(self):
        from lfd_envs.render import Camera

        # SoftGym's cloth camera direction (45 degrees down), a bit farther so every variant fits
        return Camera(position=(0.0, -1.0, 1.0), look_at=(0.0, 0.04, 0.0), fov_y_deg=45.0)

    def build(self, rng: np.random.Generator) -> TaskVariant:
        from lfd_envs.sim import SceneBuilder

        size = float(rng.uniform(*SIZE_RANGE))
        yaw = float(rng.uniform(-MAX_YAW, MAX_YAW))
        builder = SceneBuilder()
        self.add_square_cloth(builder, size, yaw=yaw)
        return TaskVariant(builder, {"size": np.float64(size), "yaw": np.float64(yaw)})

    def episode_context(self, positions: np.ndarray, data: dict[str, np.ndarray]) -> Context:
        ctx = super().episode_context(positions, data)
        ctx["b_init"] = group_b(self.grid(positions[None]))[0]
        return ctx

    def performance(self, positions: np.ndarray, ctx: Context) -> np.ndarray:
        return self.evaluate(positions, ctx)["performance"]

    def evaluate(self, positions: np.ndarray, ctx: Context) -> dict[str, np.ndarray]:
        group, fixation = fold_distances(self.grid(positions), ctx["b_init"])
        bl, br, tr, tl = (positions[:, i] for i in self.corner_indices)
        corner = np.linalg.norm(tl - tr, axis=-1) + np.linalg.norm(bl - br, axis=-1)
        p = -group - 1.2 * fixation - (corner if self.metric == "mail" else 0.0)
        return {"performance": p, "group_distance": group, "fixation_distance": fixation, "corner_term": corner}

    # ------------------------------------------------------------------ for experts
    def fold_pairs(self, num: int) -> tuple[np.ndarray, np.ndarray]:
        """Particle indices of ``num`` points evenly spread along the left edge (both corners
        when ``num >= 2``, the bottom corner for 1) and of their mirror partners on the right
        edge, ``(num,)`` each."""
        n = self.resolution
        rows = np.round(np.linspace(0, n - 1, max(num, 2))).astype(int)[:num] if num > 1 else np.array([0])
        return self.grid_index(rows, 0), self.grid_index(rows, n - 1)


class ClothFoldEnv(ParticleEnv):
    """ClothFold-v0 (see :mod:`lfd_envs.tasks.cloth_fold`).

    Same arguments as every particle env plus ``metric`` (``"default"`` or ``"mail"``).
    """

    task_class = ClothFoldTask

    def __init__(self, num_pickers: int | None = None, action_mode: str = "delta", obs_mode: str | None = None,
                 image_size: int | tuple[int, int] = 32, resolution: int | None = None, device: str = "cpu",
                 render_mode: str | None = None, horizon: int | None = None,
                 render_size: int | tuple[int, int] | None = None, metric: str = "default",
                 pick_place_speed: float | None = None, sim_options: dict[str, Any] | None = None,
                 physics: str = "fast", observe_grasp: bool = False) -> None:
        self._setup(dict(num_pickers=num_pickers, resolution=resolution, metric=metric), action_mode, obs_mode,
                    image_size, device, render_mode, horizon, render_size,
                    pick_place_speed=pick_place_speed, sim_options=sim_options, physics=physics,
                    observe_grasp=observe_grasp)


class ClothFoldVectorEnv(ParticleVectorEnv):
    """Batched ClothFold-v0 (one engine call per frame for all worlds); ``metric`` as above."""

    task_class = ClothFoldTask

    def __init__(self, num_envs: int = 1, num_pickers: int | None = None, action_mode: str = "delta",
                 obs_mode: str | None = None, image_size: int | tuple[int, int] = 32,
                 resolution: int | None = None, device: str = "cpu", render_mode: str | None = None,
                 horizon: int | None = None, render_size: int | tuple[int, int] | None = None,
                 max_episode_steps: int | None = None, metric: str = "default",
                 pick_place_speed: float | None = None, sim_options: dict[str, Any] | None = None,
                 physics: str = "fast", observe_grasp: bool = False) -> None:
        self._setup(num_envs, dict(num_pickers=num_pickers, resolution=resolution, metric=metric), action_mode,
                    obs_mode, image_size, device, render_mode, horizon, render_size, max_episode_steps,
                    pick_place_speed=pick_place_speed, sim_options=sim_options, physics=physics,
                    observe_grasp=observe_grasp)
