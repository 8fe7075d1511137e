"""Shared parts of the square-cloth tasks (ClothFold, ClothFoldDiagonal, DryCloth, ...).

One ``n x n`` cloth grid per world (``n = resolution``), built by
:meth:`ClothTask.add_square_cloth`. Grid convention (as the engine builds it): particle
``(row, col)`` has world-local index ``start + row * n + col``; at yaw 0 columns grow along +x
and rows along +y, so ``grid[0, 0]`` is the bottom-left corner seen from above with +y up.
Reduced state = the 4 corners ``(BL, BR, TR, TL)`` then the pickers (``12 + 3P`` numbers, as
SoftGym's ``key_point``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from lfd_envs.tasks.particle_task import Context, ParticleTask, picker_ring

__all__ = ["ClothTask", "cloth_grid"]


def cloth_grid(positions: np.ndarray, start: int, n: int) -> np.ndarray:
    """View ``(W, n, n, 3)`` of the cloth particles of positions ``(W, N, 3)``."""
    return positions[:, start:start + n * n].reshape(positions.shape[0], n, n, 3)


class ClothTask(ParticleTask):
    """A task with one square cloth of ``resolution x resolution`` particles."""

    default_resolution = 40
    resolution_range = (4, 160)
    #: SoftGym cloth picker: radius 0.05, grasp threshold 0.005 + 0.05 + 0.00625
    picker_radius: ClassVar[float] = 0.05
    grasp_radius: ClassVar[float] = 0.06125
    #: pickers are drawn at their collision radius, as SoftGym draws its picker spheres (a smaller
    #: sphere is a pixel or two at 32x32, too little for a policy to see where its picker is)
    picker_render_radius: ClassVar[float] = 0.05
    #: cloth particle contact radius (m)
    particle_radius: ClassVar[float] = 0.00625
    cloth_mass: ClassVar[float] = 0.5
    #: SoftGym ClothFold: pickers start 0.1 m above the middle of the left edge
    picker_start_height = 0.1

    def __init__(self, resolution: int | None = None, num_pickers: int | None = None) -> None:
        super().__init__(resolution, num_pickers)
        self.cloth_start = 0  # first particle of the cloth (set by add_square_cloth)

    # ------------------------------------------------------------------ engine
    def sim_params(self):
        from lfd_envs.sim import SimParams

        return SimParams(particle_radius=self.particle_radius, picker_radius=self.picker_radius,
                         grasp_radius=self.grasp_radius)

    def add_square_cloth(self, builder: Any, size: float, center: tuple[float, float] = (0.0, 0.0),
                         yaw: float = 0.0) -> Any:
        """Add the task's flat square cloth (side ``size`` m) resting on the table."""
        n = self.resolution
        h = builder.add_cloth(n, n, size, size, center=(center[0], center[1], self.particle_radius),
                              yaw=float(yaw), mass=self.cloth_mass)
        self.cloth_start = h.start
        return h

    def grid(self, positions: np.ndarray) -> np.ndarray:
        """Cloth grid ``(W, n, n, 3)`` of positions ``(W, N, 3)``."""
        return cloth_grid(positions, self.cloth_start, self.resolution)

    def grid_index(self, row: int | np.ndarray, col: int | np.ndarray) -> np.ndarray:
        """World-local particle index of grid cell ``(row, col)`` (negative indices allowed)."""
        n = self.resolution
        return self.cloth_start + (np.asarray(row) % n) * n + (np.asarray(col) % n)

    @property
    def corner_indices(self) -> np.ndarray:
        """Particle indices of the corners ``(BL, BR, TR, TL)``."""
        return self.grid_index(np.array([0, 0, -1, -1]), np.array([0, -1, -1, 0]))

    # ------------------------------------------------------------------ start state
    def picker_start(self, positions: np.ndarray, data: dict[str, np.ndarray]) -> np.ndarray:
        """SoftGym: pickers around the middle of the left edge (corners BL and TL)."""
        corners = positions[self.corner_indices]
        center = 0.5 * (corners[0] + corners[3])
        center[2] = self.picker_start_height
        edge = corners[3] - corners[0]
        return picker_ring(center, self.num_pickers, self.picker_radius,
                           axis_angle=float(np.arctan2(edge[1], edge[0])))

    # ------------------------------------------------------------------ observations
    def state_dim(self) -> int:
        return 12 + 3 * self.num_pickers

    def reduced_state(self, positions: np.ndarray, pickers: np.ndarray, ctx: Context) -> np.ndarray:
        w = positions.shape[0]
        corners = positions[:, self.corner_indices].reshape(w, -1)
        return np.concatenate([corners, pickers.reshape(w, -1)], axis=1).astype(np.float32)

    def object_layers(self, positions: np.ndarray, ctx: Context) -> list[Any]:
        from lfd_envs.render import TriangleMeshLayer, grid_triangles

        n = self.resolution
        if not hasattr(self, "_triangles"):
            self._triangles = grid_triangles(n, n)
        cloth = positions[:, self.cloth_start:self.cloth_start + n * n]
        return [TriangleMeshLayer(cloth, self._triangles)]
