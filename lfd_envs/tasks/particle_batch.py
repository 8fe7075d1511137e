"""Batched machinery of every particle task: ``W`` worlds of one task in ONE ``ParticleSim``.

:class:`ParticleBatch` owns the engine, the action mode, the per-world task context and the
renderers. The single env (``W = 1``) and the vector env (``W = num_envs``) are thin
Gymnasium front ends over it (:mod:`lfd_envs.tasks.particle_env`).

Variants: the start state of a variant is produced in a separate one-world *generator* engine
(build the scene, run the task's preparation, place the pickers) and copied into world ``w``
of the batch with ``ParticleSim.set_state(..., world=w)``; the other worlds are untouched, so a
world's future never depends on its neighbours. Start states are cached per variant (LRU).
"""

from __future__ import annotations

import dataclasses
from collections import OrderedDict
from collections.abc import Mapping
from typing import Any

import numpy as np

from lfd_envs.core.errors import check_float
from lfd_envs.core.state import check_range, task_id
from lfd_envs.physics import DEFAULT_PHYSICS, PHYSICS_PRESETS, PhysicsPreset, physics_preset
from lfd_envs.tasks.particle_task import Context, ParticleTask
from lfd_envs.tasks.particle_state_values import check_particle_values
from lfd_envs.tasks.picker_actions import ActionMode, make_action_mode

def with_sim_options(params: Any, sim_options: dict[str, Any] | None) -> Any:
    """``params`` (a ``SimParams``) with the fields named in ``sim_options`` replaced (validated by
    ``SimParams``); an unknown name is a ``ValueError`` listing the valid ones."""
    if sim_options is None:
        return params
    if not isinstance(sim_options, dict):
        raise ValueError(f"sim_options must be a dict of SimParams fields, got {type(sim_options).__name__}")
    unknown = sorted(set(sim_options) - set(params.field_names()))
    if unknown:
        raise ValueError(f"sim_options: unknown engine parameter(s) {unknown}; valid: {list(params.field_names())}")
    return dataclasses.replace(params, **sim_options)


#: colour of a picker that holds something in the images of ``observe_grasp`` envs (pickers are white;
#: black stands out against them, the cloth and the table)
HOLDING_PICKER_COLOR = (0.05, 0.05, 0.05)
#: where the holding marker of a picker that holds nothing is drawn: far below the table, out of sight
HIDDEN_BELOW = np.array([0.0, 0.0, -100.0])
#: accepted ``pick_place_speed`` range (m/s)
MIN_PICK_PLACE_SPEED, MAX_PICK_PLACE_SPEED = 0.01, 10.0

__all__ = ["ParticleBatch", "StartState"]

#: where pickers wait while a variant is prepared (far above the scene)
PARK_HEIGHT = 2.0
CTX_PREFIX = "ctx/"
#: bound (m) of positions accepted by :meth:`ParticleBatch.check_state` (the scenes are about 1 m)
STATE_POSITION_BOUND = 100.0


class StartState:
    """A prepared variant: its scene builder, engine state of one world and task context."""

    __slots__ = ("builder", "sim_state", "ctx")

    def __init__(self, builder: Any, sim_state: dict[str, np.ndarray], ctx: Context) -> None:
        self.builder = builder
        self.sim_state = sim_state
        self.ctx = ctx


def _rng_key(rng: np.random.Generator) -> tuple | None:
    """Cache key of a freshly seeded generator (its seed entropy), or None."""
    seq = getattr(rng.bit_generator, "seed_seq", None)
    entropy = getattr(seq, "entropy", None)
    if entropy is None:
        return None
    spawn = tuple(getattr(seq, "spawn_key", ()))
    return (tuple(np.atleast_1d(entropy).tolist()), spawn)


class ParticleBatch:
    """``num_worlds`` worlds of ``task`` stepped together.

    Args:
        task: The task description.
        num_worlds: Number of worlds ``W``.
        action_mode: ``"delta"`` or ``"pick_place"``.
        device: Warp device.
        cache_size: Prepared variants kept in memory.
        pick_place_speed: Speed limit (m/s) of pickers that hold something in pick-and-place
            steps (MAIL: 1 m/s), or None for the preset's (``fast``: the task's schedule, faster
            long carries; ``flex_like``: 1 m/s); with colliding pickers (``picker_collision``) it
            limits empty pickers too.
        sim_options: Engine parameters (:class:`~lfd_envs.sim.SimParams` fields) that replace
            the task's and the preset's, e.g. ``{"substeps": 10}``; None keeps those.
        physics: The physics preset, ``"fast"`` or ``"flex_like"`` (:mod:`lfd_envs.physics`).
        observe_grasp: Append to the reduced state one value per picker, 1.0 while it holds at
            least one particle, else 0.0 (:meth:`state_obs`), and draw a picker that holds
            something in :data:`HOLDING_PICKER_COLOR` in images (:meth:`images`), as a camera
            sees a gripper close.
    """

    def __init__(self, task: ParticleTask, num_worlds: int, action_mode: str, device: str = "cpu",
                 cache_size: int = 128, pick_place_speed: float | None = None,
                 sim_options: dict[str, Any] | None = None, physics: str = DEFAULT_PHYSICS,
                 observe_grasp: bool = False) -> None:
        from lfd_envs.sim import ParticleSim

        if not isinstance(observe_grasp, (bool, np.bool_)):
            raise ValueError(f"observe_grasp must be True or False, got {observe_grasp!r}")
        self.observe_grasp = bool(observe_grasp)
        self.physics = physics_preset(physics)
        self.task = task
        self.num_worlds = int(num_worlds)
        self.device = device
        self.workspace = task.workspace()
        params = with_sim_options(self.physics.sim_params(task.sim_params()), sim_options)
        schedule = task.pick_place_schedule()
        if pick_place_speed is None:
            pick_place_speed = self.physics.pick_place_speed
        if pick_place_speed is not None:
            speed = check_float("pick_place_speed", pick_place_speed, MIN_PICK_PLACE_SPEED, MAX_PICK_PLACE_SPEED)
            limit = speed * params.frame_dt
            # colliding pickers touch the cloth while empty too: limit those moves as well
            schedule = dataclasses.replace(schedule, max_speed=limit,
                                           max_free_speed=limit if params.picker_collision else None)
        self.action_mode: ActionMode = make_action_mode(action_mode, task.num_pickers, self.workspace, schedule=schedule)
        first = task.build(np.random.default_rng(0))  # any variant: fixes the topology
        self._gen = ParticleSim(first.builder, 1, params, task.num_pickers, device)
        self.sim = ParticleSim([first.builder] * self.num_worlds, None, params, task.num_pickers, device)
        self._cache: OrderedDict[tuple, StartState] = OrderedDict()
        self._cache_size = int(cache_size)
        start = self._prepare(first, np.random.default_rng(0))
        self.ctx: Context = {k: np.repeat(v[None], self.num_worlds, axis=0) for k, v in start.ctx.items()}
        self.p0 = np.zeros(self.num_worlds)
        self._positions: np.ndarray | None = None
        self._evaluation: dict[str, np.ndarray] | None = None
        self._renderers: dict[tuple[int, int], Any] = {}

    # ------------------------------------------------------------------ variants
    def _prepare(self, variant: Any, rng: np.random.Generator) -> StartState:
        gen, task = self._gen, self.task
        gen.reset_world(0, variant.builder)
        park = np.zeros((task.num_pickers, 3))
        park[:, 2] = PARK_HEIGHT
        gen.set_picker_positions(park, world=0)
        task.prepare(gen, variant, rng)
        gen.step(gen.picker_positions, np.zeros((1, task.num_pickers), bool))  # release all
        pos = gen.positions[0]
        gen.set_picker_positions(task.picker_start(pos, variant.data), world=0)
        ctx = task.episode_context(pos, variant.data)
        ctx.update(self._static_box_context(variant.builder))
        return StartState(variant.builder, gen.get_state(0), ctx)

    @staticmethod
    def _static_box_context(builder: Any) -> Context:
        boxes = builder.static_boxes
        return {
            "static_box_center": np.array([b.center for b in boxes], np.float64).reshape(-1, 3),
            "static_box_half_extents": np.array([b.half_extents for b in boxes], np.float64).reshape(-1, 3),
            "static_box_yaw": np.array([b.yaw for b in boxes], np.float64),
        }

    def start_state(self, rng: np.random.Generator) -> StartState:
        """Prepared start state of the variant drawn by ``rng`` (cached by the rng's seed)."""
        key = _rng_key(rng)
        if key is not None and key in self._cache:
            self._cache.move_to_end(key)
            return self._cache[key]
        start = self._prepare(self.task.build(rng), rng)
        if key is not None and self._cache_size > 0:
            self._cache[key] = start
            if len(self._cache) > self._cache_size:
                self._cache.popitem(last=False)
        return start

    def reset_world(self, world: int, rng: np.random.Generator) -> None:
        """Put world ``world`` into the start state of the variant drawn by ``rng``."""
        start = self.start_state(rng)
        self.sim.reset_world(world, start.builder)
        self.sim.set_state(start.sim_state, world=world)
        for k, v in start.ctx.items():
            self.ctx[k][world] = v
        self._positions = self._evaluation = None
        self.p0[world] = self.performance()[world]

    # ------------------------------------------------------------------ stepping
    def step(self, actions: np.ndarray) -> None:
        """One env step of every world with validated actions ``(W, A)``."""
        motion = self.action_mode.plan_motion(actions, self.sim.picker_positions)
        # bitwise the same as one sim.step per frame; each world stops after its own frames
        self.sim.step_frames(motion.targets, motion.grasp, motion.frames)
        self._positions = self._evaluation = None

    @property
    def positions(self) -> np.ndarray:
        """Particle positions ``(W, N, 3)`` float32 (cached until the next change; do not modify)."""
        if self._positions is None:
            self._positions = self.sim.positions
        return self._positions

    @property
    def pickers(self) -> np.ndarray:
        """Picker centres ``(W, P, 3)``."""
        return self.sim.picker_positions

    # ------------------------------------------------------------------ scoring
    def _scores(self) -> dict[str, np.ndarray]:
        if self._evaluation is None:
            scores = self.task.evaluate(self.positions, self.ctx)
            self._evaluation = {k: np.asarray(v, dtype=np.float64) for k, v in scores.items()}
        return self._evaluation

    def performance(self) -> np.ndarray:
        """Performance per world ``(W,)``."""
        return self._scores()["performance"].copy()

    def normalized(self, p: np.ndarray) -> np.ndarray:
        """Normalised performance per world for performances ``p`` ``(W,)``."""
        return np.asarray(self.task.normalized_performance(p, self.p0), dtype=np.float64)

    def metrics(self) -> dict[str, np.ndarray]:
        """Extra per-world ``info`` numbers."""
        return {k: v.copy() for k, v in self._scores().items() if k != "performance"}

    # ------------------------------------------------------------------ observations
    def state_obs(self) -> np.ndarray:
        """Reduced states ``(W, D)`` float32: the task's, then (``observe_grasp``) one flag per
        picker, 1.0 while it holds a particle."""
        state = self.task.reduced_state(self.positions, self.pickers, self.ctx).astype(np.float32)
        if not self.observe_grasp:
            return state
        return np.concatenate([state, (self.held_particles() > 0).astype(np.float32)], axis=1)

    def state_bounds(self, bound: float) -> tuple[np.ndarray, np.ndarray]:
        """Bounds ``(low, high)`` of a reduced state: ``±bound`` for the task's values, [0, 1]
        for the grasp flags."""
        n = self.task.state_dim()
        p = self.task.num_pickers if self.observe_grasp else 0
        low = np.concatenate([np.full(n, -bound), np.zeros(p)]).astype(np.float32)
        high = np.concatenate([np.full(n, bound), np.ones(p)]).astype(np.float32)
        return low, high

    def held_particles(self) -> np.ndarray:
        """Number of particles each picker holds ``(W, P)`` (0 for a flag on over nothing)."""
        attached = self.sim.attached  # (W, N) picker index or -1
        p = self.task.num_pickers
        world, _ = np.nonzero(attached >= 0)
        slots = world * p + attached[attached >= 0]  # one bincount over all worlds
        return np.bincount(slots, minlength=self.num_worlds * p).reshape(self.num_worlds, p)

    def particles_obs(self) -> np.ndarray:
        """All particle positions then the pickers, ``(W, N + P, 3)`` float32."""
        return np.concatenate([self.positions, self.pickers.astype(np.float32)], axis=1)

    def images(self, height: int, width: int) -> np.ndarray:
        """RGB images ``(W, height, width, 3)`` uint8 from the task camera."""
        renderer = self._renderers.get((height, width))
        if renderer is None:
            from lfd_envs.render import Renderer

            renderer = Renderer(width, height, self.task.camera(), self.device)
            self._renderers[(height, width)] = renderer
        layers = self.task.render_layers(self.positions, self.pickers, self.ctx)
        if self.observe_grasp and self.task.num_pickers:
            layers.append(self._holding_layer())
        return renderer.render(layers, self.num_worlds)

    def _holding_layer(self) -> Any:
        """Spheres that cover the pickers holding something in :data:`HOLDING_PICKER_COLOR`
        (slightly larger than the drawn picker); the others' lie out of sight below the table."""
        from lfd_envs.render import SphereLayer

        holding = self.held_particles() > 0  # (W, P)
        centers = np.where(holding[..., None], self.pickers, HIDDEN_BELOW)
        return SphereLayer(centers.astype(np.float32), radii=1.05 * self.task.picker_render_radius,
                           colors=HOLDING_PICKER_COLOR)

    # ------------------------------------------------------------------ state
    def get_state(self, world: int) -> dict[str, np.ndarray]:
        """Engine state and task context of one world (copies)."""
        state = self.sim.get_state(world)
        state.update({CTX_PREFIX + k: np.array(v[world], copy=True) for k, v in self.ctx.items()})
        return state

    @property
    def env_id(self) -> str:
        """Env id of this task under this physics preset, e.g. ``ClothFold-v1``."""
        return self.physics.env_id(self.task.name)

    def identity(self, physics: PhysicsPreset | None = None) -> dict[str, Any]:
        """Task identity of this batch's states (or of this task under another ``physics``): the
        env id, so the task (pinned or not included) and the physics preset. The picker count
        and resolution show in the state's shapes, so a teacher's state can be turned into a
        student's (another picker count) by replacing the picker entries."""
        return {"task": (physics or self.physics).env_id(self.task.name)}

    def check_physics(self, state: Any) -> None:
        """``ValueError`` naming both env ids if ``state`` (a ``get_state()`` dict) was saved by
        this task under another physics preset: its future there would differ. Anything else
        is left to the full checks of ``set_state``."""
        saved = state.get("episode/task_id") if isinstance(state, Mapping) else None
        if saved is None or np.ndim(saved) != 0 or np.asarray(saved).dtype.kind not in "iu":
            return
        for other in PHYSICS_PRESETS.values():
            if other is not self.physics and int(saved) == task_id(self.identity(other)):
                raise ValueError(
                    f"state['episode/task_id'] is from {other.env_id(self.task.name)} (physics={other.name!r}); "
                    f"this env is {self.env_id} (physics={self.physics.name!r}): a state runs only in the "
                    "physics that saved it")

    def check_state(self, state: dict[str, np.ndarray]) -> None:
        """Value ranges of one world's state (layout already checked); ``ValueError`` naming the key."""
        p = self.task.num_pickers
        check_range("sim/inv_mass", state["inv_mass"], 0.0)
        check_range("sim/radius", state["radius"], 0.0, strict_low=True)
        check_range("sim/sc_r", state["sc_r"], 0.0)
        check_range("sim/con_rest", state["con_rest"], 0.0)
        check_range("sim/attach", state["attach"], -1, p - 1)
        check_range("sim/box_kinematic", state["box_kinematic"], 0, 1)
        check_range("sim/box_half_extents", state["box_half_extents"], 0.0, strict_low=True)
        check_range("sim/static_half_extents", state["static_half_extents"], 0.0, strict_low=True)
        for key in ("positions", "rest", "box_pos", "static_pos"):
            check_range(f"sim/{key}", np.abs(state[key]), high=STATE_POSITION_BOUND)
        check_range("sim/picker_positions", np.abs(state["picker_positions"]), high=PARK_HEIGHT + 1.0)
        check_particle_values(state)
        self.task.check_state(state["positions"], {k[len(CTX_PREFIX):]: v for k, v in state.items()
                                                   if k.startswith(CTX_PREFIX)})

    def set_state(self, world: int, state: dict[str, np.ndarray]) -> None:
        """Restore one world from :meth:`get_state` (``ValueError`` on a malformed state)."""
        ctx = {k[len(CTX_PREFIX):]: np.asarray(v) for k, v in state.items() if k.startswith(CTX_PREFIX)}
        missing = sorted(set(self.ctx) - set(ctx))
        if missing:
            raise ValueError(f"state is missing task context {missing}; pass a dict from get_state()")
        for k, v in ctx.items():
            if k in self.ctx and v.shape != self.ctx[k].shape[1:]:
                raise ValueError(f"state[{CTX_PREFIX + k!r}] must have shape {self.ctx[k].shape[1:]}, got {v.shape}")
        sim_state = {k: v for k, v in state.items() if not k.startswith(CTX_PREFIX)}
        self.sim.set_state(sim_state, world=world)
        for k in self.ctx:
            self.ctx[k][world] = ctx[k]
        self._positions = self._evaluation = None
