"""What a particle task is, independent of how it is stepped (SPEC §4.4).

A :class:`ParticleTask` only *describes* a task: the scene of a variant (a
:class:`~lfd_envs.sim.SceneBuilder` per variant, plus a short preparation run such as the rope's
lift-and-drop), the reduced state, the performance, the camera, the horizons and the default
picker count. Everything else - batched stepping, action modes, observations, rendering,
variants, autoreset - is shared machinery in :mod:`lfd_envs.tasks.particle_batch` and
:mod:`lfd_envs.tasks.particle_env`. Every method that looks at the simulation is batched over
``W`` worlds: positions come as ``(W, N, 3)`` and per-world task data as arrays with a leading
``W`` axis (the *context*, see :meth:`ParticleTask.episode_context`).

Adding a task = subclass :class:`ParticleTask`, then declare the env classes with
:func:`lfd_envs.tasks.particle_env.particle_envs`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from lfd_envs.core.errors import check_int_range
from lfd_envs.tasks.picker_actions import PickPlaceSchedule, Workspace

if TYPE_CHECKING:  # pragma: no cover
    from lfd_envs.render import Camera
    from lfd_envs.sim import ParticleSim, SceneBuilder, SimParams

__all__ = ["ParticleTask", "TaskVariant", "picker_ring"]

Context = dict[str, np.ndarray]


@dataclass
class TaskVariant:
    """One drawn variant of a task.

    Attributes:
        builder: The world's scene (same topology for every variant of a task instance).
        data: Per-variant numbers the task needs later (fixed shapes, no leading world axis).
    """

    builder: "SceneBuilder"
    data: dict[str, np.ndarray] = field(default_factory=dict)


def picker_ring(center: np.ndarray, num_pickers: int, radius: float, axis_angle: float = 0.0) -> np.ndarray:
    """SoftGym's initial picker placement: ``P`` pickers on a circle of radius
    ``sqrt(P-1) * 2 * radius`` around ``center`` (one picker sits at the centre), ``(P, 3)``."""
    ring = np.sqrt(num_pickers - 1) * 2.0 * radius
    ang = axis_angle + 2.0 * np.pi * np.arange(num_pickers) / num_pickers
    out = np.repeat(np.asarray(center, dtype=np.float64)[None], num_pickers, axis=0)
    out[:, 0] += ring * np.cos(ang)
    out[:, 1] += ring * np.sin(ang)
    return out


class ParticleTask(ABC):
    """Description of a particle task (subclass per task; see module docstring).

    Args:
        resolution: Particles per cloth side or rope particles (task-specific range).
        num_pickers: Number of pickers (1..4).
    """

    #: task name (seeds the variants)
    name: ClassVar[str]
    #: default number of pickers (SPEC §4.4 table)
    default_num_pickers: ClassVar[int] = 1
    #: default observation mode of the env
    default_obs_mode: ClassVar[str] = "state"
    #: default horizons per action mode
    horizons: ClassVar[dict[str, int]] = {"delta": 100, "pick_place": 3}
    #: default resolution and the allowed range
    default_resolution: ClassVar[int] = 40
    resolution_range: ClassVar[tuple[int, int]] = (4, 160)
    max_pickers: ClassVar[int] = 4
    #: frames run after building a variant before its start state is taken
    settle_frames: ClassVar[int] = 5
    #: picker centre height at the start of an episode (m)
    picker_start_height: ClassVar[float] = 0.1

    def __init__(self, resolution: int | None = None, num_pickers: int | None = None) -> None:
        lo, hi = self.resolution_range
        res = self.default_resolution if resolution is None else resolution
        self.resolution = check_int_range("resolution", res, lo, hi)
        pickers = self.default_num_pickers if num_pickers is None else num_pickers
        self.num_pickers = check_int_range("num_pickers", pickers, 1, self.max_pickers)

    # ------------------------------------------------------------------ engine set-up
    @abstractmethod
    def sim_params(self) -> "SimParams":
        """Engine parameters of this task."""

    @abstractmethod
    def workspace(self) -> Workspace:
        """Box in which the picker centres move (margin = picker radius)."""

    def pick_place_schedule(self) -> PickPlaceSchedule:
        """Timing of a pick-and-place step (override for task-specific lift heights)."""
        return PickPlaceSchedule()

    @abstractmethod
    def camera(self) -> "Camera":
        """Fixed camera of observations and ``render()``."""

    # ------------------------------------------------------------------ variants
    @abstractmethod
    def build(self, rng: np.random.Generator) -> TaskVariant:
        """Draw a variant: its scene and per-variant data."""

    def prepare(self, sim: "ParticleSim", variant: TaskVariant, rng: np.random.Generator) -> None:
        """Run the one-world ``sim`` (just reset to ``variant``) into the episode's start state.

        The default lets the scene settle for :attr:`settle_frames` frames (the pickers are
        parked far above the scene while a variant is prepared). Tasks that perturb their object (rope lift-and-drop) override it.
        """
        grasp = np.zeros((1, sim.num_pickers), dtype=bool)
        for _ in range(self.settle_frames):
            sim.step(sim.picker_positions, grasp)

    @abstractmethod
    def picker_start(self, positions: np.ndarray, data: dict[str, np.ndarray]) -> np.ndarray:
        """Picker centres ``(P, 3)`` at the start of an episode, from one world's settled
        particle positions ``(N, 3)`` and the variant data."""

    def episode_context(self, positions: np.ndarray, data: dict[str, np.ndarray]) -> Context:
        """Per-world numbers fixed at the start of an episode (e.g. initial positions the
        performance refers to), from one world's start positions ``(N, 3)``. The default is the
        variant data itself."""
        return {k: np.asarray(v) for k, v in data.items()}

    # ------------------------------------------------------------------ observations
    @abstractmethod
    def state_dim(self) -> int:
        """Length of the reduced state (pickers included)."""

    @abstractmethod
    def reduced_state(self, positions: np.ndarray, pickers: np.ndarray, ctx: Context) -> np.ndarray:
        """Reduced state ``(W, state_dim)`` from positions ``(W, N, 3)`` and pickers ``(W, P, 3)``."""

    @abstractmethod
    def object_layers(self, positions: np.ndarray, ctx: Context) -> list[Any]:
        """Renderer layers of the task's objects (cloth, rope, ...) in ``W`` worlds."""

    #: radius (m) pickers are drawn with (white spheres)
    picker_render_radius: ClassVar[float] = 0.02

    def render_layers(self, positions: np.ndarray, pickers: np.ndarray, ctx: Context) -> list[Any]:
        """Renderer layers of ``W`` worlds: objects, static boxes (from the context) and pickers."""
        from lfd_envs.render import BoxLayer, SphereLayer

        layers = self.object_layers(positions, ctx)
        if "static_box_center" in ctx and ctx["static_box_center"].shape[1] > 0:
            yaw = ctx["static_box_yaw"]
            c, s = np.cos(yaw), np.sin(yaw)
            rot = np.zeros(yaw.shape + (3, 3))
            rot[..., 0, 0], rot[..., 0, 1], rot[..., 1, 0], rot[..., 1, 1] = c, -s, s, c
            rot[..., 2, 2] = 1.0
            layers.append(BoxLayer(ctx["static_box_center"], ctx["static_box_half_extents"], rot,
                                   colors=self.static_box_color))
        layers.append(SphereLayer(pickers, radii=self.picker_render_radius))
        return layers

    #: colour of static boxes (pin block, plank)
    static_box_color: ClassVar[tuple[float, float, float]] = (0.45, 0.45, 0.5)

    def check_state(self, positions: np.ndarray, ctx: dict[str, np.ndarray]) -> None:
        """Task-specific plausibility of one world's particle ``positions`` ``(N, 3)`` and context
        (``set_state`` input, layout already checked); ``ValueError`` naming the key. Default: none."""

    # ------------------------------------------------------------------ scoring
    @abstractmethod
    def performance(self, positions: np.ndarray, ctx: Context) -> np.ndarray:
        """Performance ``p`` per world ``(W,)`` (higher is better)."""

    def metrics(self, positions: np.ndarray, ctx: Context) -> dict[str, np.ndarray]:
        """Extra per-world numbers for ``info`` (each ``(W,)``)."""
        return {}

    def evaluate(self, positions: np.ndarray, ctx: Context) -> dict[str, np.ndarray]:
        """``{"performance": (W,), **metrics}`` in one go (override to share work)."""
        return {"performance": self.performance(positions, ctx), **self.metrics(positions, ctx)}

    #: optimum of the performance (``p_opt``)
    performance_optimum: ClassVar[float] = 0.0

    def normalized_performance(self, p: np.ndarray, p0: np.ndarray) -> np.ndarray:
        """SoftGym normalisation ``(p - p0) / (p_opt - p0)`` per world."""
        p, p0 = np.asarray(p, np.float64), np.asarray(p0, np.float64)
        denom = self.performance_optimum - p0
        safe = np.where(np.abs(denom) < 1e-9, 1.0, denom)
        return np.where(np.abs(denom) < 1e-9, (p >= self.performance_optimum - 1e-9).astype(np.float64),
                        (p - p0) / safe)

    def success(self, p: np.ndarray, p_hat: np.ndarray) -> np.ndarray | None:
        """Per-world success flags, or ``None`` where the task defines no success."""
        return None

    # ------------------------------------------------------------------ helpers
    def horizon(self, action_mode: str) -> int:
        """Default horizon for ``action_mode``."""
        return int(self.horizons[action_mode])
