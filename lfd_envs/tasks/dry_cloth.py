"""DryCloth-v0: hang a square cloth over a drying plank (MAIL's DryCloth, z-up).

Scene: a 0.5 m square cloth (``resolution x resolution`` particles, default 36, at least 20 so
that the particle spacing stays below the plank thickness; MAIL: 80x80)
lies flat on the table beside a static drying plank: a box 2 cm thick, 0.3 m tall and 1.2 m
long, centred at ``x = PLANK_X = -0.25`` and running along y (half extents 0.01 x 0.6 x 0.15).
Variants: cloth rotation ``U(-45, 45)`` degrees about z and the cloth centre's offset from the
plank, ``x - PLANK_X ~ U(0.40, 0.50)`` m, ``y ~ U(-0.1, 0.1)`` m (the cloth never touches the
plank at the start). Grid column 0 (the cloth's local -x edge) faces the plank. Pickers (default
1; MAIL's teacher has 2) start 0.1 m above the middle of that edge.

Performance (MAIL's formula, in our axes; ``u`` = unit vector along the plank, ``x0`` = plank
centre line, ``L`` = cloth side)::

    A = columns [0, int(0.4 n))         (the plank-side 40 %: must hang on the FAR side)
    B = columns [int(0.6 n), n)         (the other 40 %: must hang on the NEAR side)
    frac_A = mean_A[ x < x0  and  z > 0.05 ]        frac_B = mean_B[ x > x0  and  z > 0.05 ]
    ext(c) = | u . (grid[0, c] - grid[n-1, c]) |    (extent of column c along the plank)
    spread_A = -| (ext(0) + ext(int(0.4 n))) / 2 - L |
    spread_B = -| (ext(int(0.6 n)) + ext(n-1)) / 2 - L |
    p = (frac_A + frac_B) / 2 + (spread_A + spread_B) / 2         (spread in metres)

``p_opt = 1`` (every particle of both groups above the ground on its side and the cloth spread
along the plank); ``normalized_performance = (p - p0) / (1 - p0)``. By default ``L`` is the
cloth side; ``metric="mail"`` uses MAIL's reference instead, the extent along the plank of the
particle-0-to-last diagonal of the cloth as laid out at the start (``L |cos t + sin t|`` for a
cloth turned by ``t``: it depends on the variant's rotation, from 0 to ``sqrt(2) L``).
``info`` adds ``hanging_fraction`` ((frac_A + frac_B)/2), ``spread_error``
(-(spread_A + spread_B)/2, metres) and ``spread_reference`` (``L``, metres).
Reward = change of ``p`` per step.

``reach`` (m, default 0.35) is how far past the plank's centre line the picker centres may go;
MAIL's normalised action box ends 0.1 m past its plank (``reach=0.1``). The workspace (and so
the pick-and-place action normalisation) starts there.

Reduced state: the 4 cloth corners, the plank (centre xyz and yaw) and the pickers
(``16 + 3P`` numbers). Horizons: 75 (delta), 3 (pick_place; MAIL's student; its teacher
used 1). Default action mode: ``pick_place``. Workspace: x in [PLANK_X - reach - 0.05, 0.7]
(default [-0.65, 0.7]), y in [-0.6, 0.6], z in [0, 0.7] (picker radius 0.05 kept inside).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lfd_envs.core.errors import check_choice, check_float
from lfd_envs.tasks.cloth_task import ClothTask
from lfd_envs.tasks.particle_env import PickPlaceParticleEnv, PickPlaceParticleVectorEnv
from lfd_envs.tasks.particle_task import Context, TaskVariant
from lfd_envs.tasks.picker_actions import PickPlaceSchedule, Workspace

__all__ = ["DryClothTask", "DryClothEnv", "DryClothVectorEnv", "dry_cloth_scores", "mail_spread_reference",
           "PLANK_X", "PLANK_HALF_EXTENTS", "CLOTH_SIZE", "METRICS", "DEFAULT_REACH"]

CLOTH_SIZE = 0.5
PLANK_X = -0.25
PLANK_HALF_EXTENTS = (0.01, 0.6, 0.15)
HANG_HEIGHT = 0.05
MAX_YAW = np.pi / 4
OFFSET_X = (0.40, 0.50)
OFFSET_Y = (-0.1, 0.1)
#: scores: ours (spread reference = the cloth side) and MAIL's (spread reference from the start)
METRICS = ("default", "mail")
#: default reach (m) of the picker centres past the plank's centre line
DEFAULT_REACH = 0.35


def mail_spread_reference(yaw: np.ndarray, u: np.ndarray, side: float) -> np.ndarray:
    """MAIL's spread reference per world: the extent along the plank (unit vectors ``u``
    ``(W, 3)``) of the particle-0-to-last diagonal of a flat cloth of side ``side`` turned by
    ``yaw`` ``(W,)``."""
    yaw = np.asarray(yaw, np.float64)
    diagonal = side * np.stack([np.cos(yaw) - np.sin(yaw), np.sin(yaw) + np.cos(yaw), np.zeros_like(yaw)], axis=1)
    return np.abs(np.einsum("wd,wd->w", diagonal, u))


def dry_cloth_scores(grid: np.ndarray, x0: np.ndarray, u: np.ndarray,
                     side: float | np.ndarray) -> dict[str, np.ndarray]:
    """MAIL DryCloth scores per world (see module docstring).

    Args:
        grid: Cloth grids ``(W, n, n, 3)``.
        x0: Plank centre ``(W, 3)``; only the horizontal offset across the plank matters.
        u: Unit vectors along the plank ``(W, 3)`` (horizontal).
        side: Spread reference ``L`` (m), one number or one per world ``(W,)``.
    """
    n = grid.shape[1]
    xl, xr = int(0.4 * n), int(0.6 * n)
    normal = np.stack([u[:, 1], -u[:, 0], np.zeros(len(u))], axis=1)  # across the plank
    across = np.einsum("wrcd,wd->wrc", grid - x0[:, None, None, :], normal)  # > 0: the near (+x) side
    high = grid[..., 2] > HANG_HEIGHT
    frac_a = ((across[:, :, :xl] < 0) & high[:, :, :xl]).mean(axis=(1, 2))
    frac_b = ((across[:, :, xr:] > 0) & high[:, :, xr:]).mean(axis=(1, 2))

    def ext(c: int) -> np.ndarray:
        return np.abs(np.einsum("wd,wd->w", grid[:, 0, c] - grid[:, -1, c], u))

    spread_a = -np.abs(0.5 * (ext(0) + ext(xl)) - side)
    spread_b = -np.abs(0.5 * (ext(xr) + ext(n - 1)) - side)
    hanging = 0.5 * (frac_a + frac_b)
    spread = 0.5 * (spread_a + spread_b)
    return {"performance": hanging + spread, "hanging_fraction": hanging, "spread_error": -spread,
            "spread_reference": np.broadcast_to(np.asarray(side, np.float64), hanging.shape).copy()}


class DryClothTask(ClothTask):
    """Scene, state and score of DryCloth (see module docstring).

    Args:
        metric: ``"default"`` (spread reference = cloth side) or ``"mail"`` (MAIL's reference).
        reach: How far (m) past the plank's centre line the picker centres may go (> 0.05).
    """

    name = "DryCloth-v0"
    default_num_pickers = 1
    horizons = {"delta": 75, "pick_place": 3}
    performance_optimum = 1.0
    #: collisions are particle-vs-plank only, so the particle spacing (0.5 m / (n - 1)) must stay
    #: below the plank thickness + 2 particle radii (3.25 cm), or cloth edges can straddle the plank
    resolution_range = (20, 160)
    #: 36 x 36 (spacing 1.4 cm) keeps a pick-and-place step >= 5 env steps/s on one CPU core
    default_resolution = 36
    static_box_color = (0.7, 0.5, 0.2)  # MAIL's plank colour

    def __init__(self, resolution: int | None = None, num_pickers: int | None = None, metric: str = "default",
                 reach: float = DEFAULT_REACH) -> None:
        super().__init__(resolution, num_pickers)
        self.metric = check_choice("metric", metric, METRICS)
        self.reach = check_float("reach", reach, 0.05, 0.6)

    # ------------------------------------------------------------------ engine
    def workspace(self) -> Workspace:
        return Workspace((PLANK_X - self.reach - self.picker_radius, -0.6, 0.0), (0.7, 0.6, 0.7),
                         margin=self.picker_radius)

    def pick_place_schedule(self) -> PickPlaceSchedule:
        # a carry from the ground to above the far side of the plank, then time for the cloth
        # to fall and drape before the step ends
        # (80 frames in all: with the 36x36 default: >= 5 env steps/s on one CPU core)
        return PickPlaceSchedule(hover=0.05, lift=0.05, arc_ratio=0.2, arc_max=0.2, free_speed=0.05,
                                 carry_speed=0.022, approach_frames=12, descend_frames=4, lift_frames=4,
                                 carry_frames=40, lower_frames=3, retreat_frames=2, settle_frames=14)

    def camera(self):
        from lfd_envs.render import Camera

        return Camera(position=(0.85, -0.5, 1.35), look_at=(-0.08, 0.0, 0.05), fov_y_deg=45.0)

    # ------------------------------------------------------------------ variants
    @property
    def plank_center(self) -> np.ndarray:
        return np.array([PLANK_X, 0.0, PLANK_HALF_EXTENTS[2]])

    def build(self, rng: np.random.Generator) -> TaskVariant:
        from lfd_envs.sim import SceneBuilder

        yaw = float(rng.uniform(-MAX_YAW, MAX_YAW))
        center = np.array([PLANK_X + rng.uniform(*OFFSET_X), rng.uniform(*OFFSET_Y)])
        builder = SceneBuilder()
        self.add_square_cloth(builder, CLOTH_SIZE, center=tuple(center), yaw=yaw)
        builder.add_static_box(self.plank_center, PLANK_HALF_EXTENTS)
        return TaskVariant(builder, {"yaw": np.float64(yaw), "offset": center,
                                     "plank": np.array([*self.plank_center, 0.0])})

    # ------------------------------------------------------------------ observations
    def state_dim(self) -> int:
        return 16 + 3 * self.num_pickers

    def reduced_state(self, positions: np.ndarray, pickers: np.ndarray, ctx: Context) -> np.ndarray:
        w = positions.shape[0]
        corners = positions[:, self.corner_indices].reshape(w, -1)
        return np.concatenate([corners, ctx["plank"].reshape(w, 4), pickers.reshape(w, -1)],
                              axis=1).astype(np.float32)

    # ------------------------------------------------------------------ scoring
    @staticmethod
    def plank_axis(ctx: Context) -> np.ndarray:
        """Unit vectors along the plank ``(W, 3)`` (its local y axis)."""
        yaw = np.asarray(ctx["plank"])[:, 3]
        return np.stack([-np.sin(yaw), np.cos(yaw), np.zeros_like(yaw)], axis=1)

    def evaluate(self, positions: np.ndarray, ctx: Context) -> dict[str, np.ndarray]:
        plank = np.asarray(ctx["plank"], np.float64)
        u = self.plank_axis(ctx)
        side = mail_spread_reference(ctx["yaw"], u, CLOTH_SIZE) if self.metric == "mail" else CLOTH_SIZE
        return dry_cloth_scores(self.grid(positions).astype(np.float64), plank[:, :3], u, side)

    def performance(self, positions: np.ndarray, ctx: Context) -> np.ndarray:
        return self.evaluate(positions, ctx)["performance"]

    # ------------------------------------------------------------------ for experts / data
    @property
    def edge_indices(self) -> np.ndarray:
        """Particle indices of the plank-side edge (grid column 0), rows 0 .. n-1."""
        n = self.resolution
        return self.grid_index(np.arange(n), 0)

    def far_side_point(self, ctx_world: dict[str, np.ndarray], along: float, beyond: float,
                       height: float) -> np.ndarray:
        """World point ``beyond`` m past the plank (far side), ``along`` m along it, at ``height``."""
        plank = np.asarray(ctx_world["plank"], np.float64)
        yaw = plank[3]
        u = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
        normal = np.array([u[1], -u[0], 0.0])  # points to the near (+x) side
        out = plank[:3] + along * u - beyond * normal
        out[2] = height
        return out

    def sample_pick_place(self, positions: np.ndarray, ctx_world: dict[str, np.ndarray],
                          rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """MAIL's random action for the dynamics data: every picker picks a random cloth
        particle and places it at a random point around the plank (0 to 0.3 m beyond it,
        anywhere along the cloth's reach, 0.55 m high). Returns ``(pick, place)``, ``(P, 3)``."""
        p = self.num_pickers
        n = self.resolution
        idx = self.cloth_start + rng.integers(n * n, size=p)
        pick = np.asarray(positions, np.float64)[idx].copy()
        place = np.stack([self.far_side_point(ctx_world, rng.uniform(-0.45, 0.45), rng.uniform(0.0, 0.3), 0.55)
                          for _ in range(p)])
        return pick, place


class DryClothEnv(PickPlaceParticleEnv):
    """DryCloth-v0 (see :mod:`lfd_envs.tasks.dry_cloth`); default action mode ``pick_place``.

    Same arguments as every particle env plus ``metric`` (``"default"`` or ``"mail"``) and
    ``reach`` (m past the plank, default 0.35; MAIL 0.1).
    """

    task_class = DryClothTask

    def __init__(self, num_pickers: int | None = None, action_mode: str = "pick_place", obs_mode: str | None = None,
                 image_size: int | tuple[int, int] = 32, resolution: int | None = None, device: str = "cpu",
                 render_mode: str | None = None, horizon: int | None = None,
                 render_size: int | tuple[int, int] | None = None, metric: str = "default",
                 reach: float = DEFAULT_REACH,
                 pick_place_speed: float | None = None, sim_options: dict[str, Any] | None = None,
                 physics: str = "fast", observe_grasp: bool = False) -> None:
        self._setup(dict(num_pickers=num_pickers, resolution=resolution, metric=metric, reach=reach), action_mode,
                    obs_mode, image_size, device, render_mode, horizon, render_size,
                    pick_place_speed=pick_place_speed, sim_options=sim_options, physics=physics,
                    observe_grasp=observe_grasp)


class DryClothVectorEnv(PickPlaceParticleVectorEnv):
    """Batched DryCloth-v0 (one engine call per frame for all worlds); ``metric``, ``reach`` as above."""

    task_class = DryClothTask

    def __init__(self, num_envs: int = 1, num_pickers: int | None = None, action_mode: str = "pick_place",
                 obs_mode: str | None = None, image_size: int | tuple[int, int] = 32,
                 resolution: int | None = None, device: str = "cpu", render_mode: str | None = None,
                 horizon: int | None = None, render_size: int | tuple[int, int] | None = None,
                 max_episode_steps: int | None = None, metric: str = "default", reach: float = DEFAULT_REACH,
                 pick_place_speed: float | None = None, sim_options: dict[str, Any] | None = None,
                 physics: str = "fast", observe_grasp: bool = False) -> None:
        self._setup(num_envs, dict(num_pickers=num_pickers, resolution=resolution, metric=metric, reach=reach),
                    action_mode, obs_mode, image_size, device, render_mode, horizon, render_size, max_episode_steps,
                    pick_place_speed=pick_place_speed, sim_options=sim_options, physics=physics,
                    observe_grasp=observe_grasp)
