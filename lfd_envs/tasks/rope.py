"""StraightenRope-v0: pull a crumpled rope straight (SoftGym RopeFlatten / DMfD StraightenRope).

Rope: 0.5 m long, ``resolution`` particles (default 41 as SoftGym), contact radius 12.5 mm.
Variants: a straight rope in a random direction is crumpled by four random lift-and-drops
(SoftGym's ``random_pick_and_place``: grab a random particle, move it along a random direction
that always rises, release), left to settle and centred on the table. Pickers (default 2,
radius 0.02 m, grasp distance 0.05 m) start 0.1 m above the centre of the rope's bounding box.
Camera: top-down.

Performance: ``p = -| |x_first - x_last| - L |`` with ``L = 0.5`` m. As in SoftGym the
normalised performance is absolute, not relative to the start state:
``p_hat = 1 - |d - L| / L`` (``info["end_point_distance"] = d``). Reward = change of ``p``.
Reduced state: 10 keypoints (particles ``0, k, ..., 8k, N-1``, ``k = (N-2)//8``) then the pickers
(``30 + 3P`` numbers). Horizons: 75 (delta), 3 (pick_place).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lfd_envs.tasks.particle_env import ParticleEnv, ParticleVectorEnv
from lfd_envs.tasks.particle_task import Context, ParticleTask, TaskVariant, picker_ring
from lfd_envs.tasks.picker_actions import PickPlaceSchedule, Workspace

__all__ = ["StraightenRopeTask", "StraightenRopeEnv", "StraightenRopeVectorEnv", "rope_keypoint_indices"]

ROPE_LENGTH = 0.5
ROPE_RADIUS = 0.0125
ROPE_MASS = 0.5 * 41 / 2  # SoftGym: inverse mass 2 per particle of 41
NUM_DROPS = 4


def rope_keypoint_indices(n: int) -> np.ndarray:
    """SoftGym's 10 rope keypoints ``[0, k, 2k, ..., 8k, n-1]`` with ``k = (n-2)//8``."""
    k = max((n - 2) // 8, 1)
    return np.minimum(np.array([i * k for i in range(9)] + [n - 1]), n - 1)


class StraightenRopeTask(ParticleTask):
    """Scene, state and score of StraightenRope (see module docstring)."""

    name = "StraightenRope-v0"
    default_num_pickers = 2
    horizons = {"delta": 75, "pick_place": 3}
    default_resolution = 41
    resolution_range = (5, 400)
    picker_start_height = 0.1
    picker_radius = 0.02
    picker_render_radius = 0.015
    performance_optimum = 0.0

    def sim_params(self):
        from lfd_envs.sim import SimParams

        return SimParams(particle_radius=ROPE_RADIUS, picker_radius=self.picker_radius, grasp_radius=0.05,
                         dynamic_friction=1.0, static_friction=1.0)

    def workspace(self) -> Workspace:
        return Workspace((-0.35, -0.35, 0.0), (0.35, 0.35, 0.3), margin=self.picker_radius)

    def pick_place_schedule(self) -> PickPlaceSchedule:
        return PickPlaceSchedule(hover=0.04, lift=0.03, arc_ratio=0.0, carry_speed=0.012)

    def camera(self):
        from lfd_envs.render import Camera

        return Camera(position=(0.0, 0.0, 0.85), look_at=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_y_deg=45.0)

    # ------------------------------------------------------------------ variants
    def build(self, rng: np.random.Generator) -> TaskVariant:
        from lfd_envs.sim import SceneBuilder

        angle = rng.uniform(-np.pi, np.pi)
        direction = np.array([np.cos(angle), np.sin(angle), 0.0])
        start = -0.5 * ROPE_LENGTH * direction + np.array([0.0, 0.0, ROPE_RADIUS])
        builder = SceneBuilder()
        builder.add_rope(self.resolution, ROPE_LENGTH, start=start, direction=direction,
                         mass=ROPE_MASS * self.resolution / 41)
        return TaskVariant(builder, {"length": np.float64(ROPE_LENGTH)})

    def prepare(self, sim: Any, variant: TaskVariant, rng: np.random.Generator) -> None:
        """SoftGym-style random lift-and-drop (4 times), settle, then centre the rope."""
        p = sim.num_pickers
        pickers = sim.picker_positions  # parked far above
        for _ in range(NUM_DROPS):
            idx = int(rng.integers(self.resolution))
            direction = np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(0, 2)])
            target = pickers.copy()
            target[0, 0] = sim.positions[0, idx]
            sim.set_picker_positions(target[0], world=0)
            grasp = np.zeros((1, p), dtype=bool)
            grasp[0, 0] = True
            for _ in range(40):
                target[0, 0] += 0.0075 * direction
                target[0, 0, 2] = max(target[0, 0, 2], self.picker_radius)
                sim.step(target, grasp)
            sim.step(target, np.zeros((1, p), dtype=bool))
            sim.set_picker_positions(pickers[0], world=0)
            self._settle(sim, 60)
        self._settle(sim, 100)
        pos = sim.positions[0]
        shift = 0.5 * (pos.min(axis=0) + pos.max(axis=0))
        shift[2] = 0.0
        sim.set_particles(0, pos - shift)

    @staticmethod
    def _settle(sim: Any, max_frames: int, tol: float = 0.01) -> None:
        grasp = np.zeros((1, sim.num_pickers), dtype=bool)
        for frame in range(max_frames):
            sim.step(sim.picker_positions, grasp)
            if frame % 10 == 9 and np.abs(sim.velocities).max() < tol:
                break

    def picker_start(self, positions: np.ndarray, data: dict[str, np.ndarray]) -> np.ndarray:
        center = 0.5 * (positions.min(axis=0) + positions.max(axis=0))
        center[2] = self.picker_start_height
        return picker_ring(center, self.num_pickers, self.picker_radius)

    # ------------------------------------------------------------------ observations
    def state_dim(self) -> int:
        return 30 + 3 * self.num_pickers

    def reduced_state(self, positions: np.ndarray, pickers: np.ndarray, ctx: Context) -> np.ndarray:
        w = positions.shape[0]
        keys = positions[:, rope_keypoint_indices(self.resolution)].reshape(w, -1)
        return np.concatenate([keys, pickers.reshape(w, -1)], axis=1).astype(np.float32)

    def object_layers(self, positions: np.ndarray, ctx: Context) -> list[Any]:
        from lfd_envs.render import CapsuleChainLayer

        return [CapsuleChainLayer(positions, radius=ROPE_RADIUS)]

    # ------------------------------------------------------------------ scoring
    def end_distance(self, positions: np.ndarray) -> np.ndarray:
        """Distance between the rope's end particles per world ``(W,)``."""
        return np.linalg.norm(positions[:, 0] - positions[:, -1], axis=-1)

    def performance(self, positions: np.ndarray, ctx: Context) -> np.ndarray:
        return -np.abs(self.end_distance(positions) - ctx["length"])

    def normalized_performance(self, p: np.ndarray, p0: np.ndarray) -> np.ndarray:
        """Absolute (SoftGym): ``1 - |d - L| / L``, independent of the start state."""
        return 1.0 + np.asarray(p, np.float64) / ROPE_LENGTH

    def metrics(self, positions: np.ndarray, ctx: Context) -> dict[str, np.ndarray]:
        return {"end_point_distance": self.end_distance(positions)}


class StraightenRopeEnv(ParticleEnv):
    """StraightenRope-v0 (see :mod:`lfd_envs.tasks.rope`)."""

    task_class = StraightenRopeTask


class StraightenRopeVectorEnv(ParticleVectorEnv):
    """Batched StraightenRope-v0 (one engine call per frame for all worlds)."""

    task_class = StraightenRopeTask
