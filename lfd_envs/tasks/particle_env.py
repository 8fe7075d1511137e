"""Gymnasium front ends of the particle tasks: a single env and a batched vector env.

Both wrap :class:`~lfd_envs.tasks.particle_batch.ParticleBatch`:

* :class:`ParticleEnv` - an :class:`~lfd_envs.core.LfdEnv` over one world (``W = 1``).
* :class:`ParticleVectorEnv` - a ``gymnasium.vector.VectorEnv`` over ``num_envs`` worlds in ONE
  engine (one batched engine call per frame) with ``SAME_STEP`` autoreset: when a world ends,
  ``infos["final_obs"][i]`` / ``infos["final_info"]`` hold its last observation and info and
  the returned observation is already the first one of its next episode. World ``i`` seeded
  with ``seed + i`` behaves exactly like a single env reset with ``seed + i`` and stepped alone.
  Wrap it with :class:`lfd_envs.core.sb3_vec.SB3VecEnv` for Stable-Baselines3.

A task module declares its envs in two lines::

    class ClothFoldEnv(ParticleEnv):
        task_class = ClothFoldTask

    class ClothFoldVectorEnv(ParticleVectorEnv):
        task_class = ClothFoldTask

Constructor arguments (both): ``num_pickers`` (1..4, task default), ``action_mode``
(``"delta"`` | ``"pick_place"``), ``obs_mode`` (``"state"``, ``"image"``, ``"state+image"``,
``"particles"``; task default), ``image_size`` (default 32), ``resolution`` (particles per
cloth side / rope particles), ``device`` (Warp device, default ``"cpu"``), ``render_mode``
(``"rgb_array"`` or None), ``render_size`` (frames of ``render()``), ``horizon`` (default from
the task per action mode; the vector env also takes ``max_episode_steps``, which
``gymnasium.make_vec`` fills in from the spec, as an upper bound like ``gymnasium.make``'s
``TimeLimit``), ``physics`` (``"fast"``, default, the ``-v0`` ids; or ``"flex_like"``, the
``-v1`` ids: the physics preset, see :mod:`lfd_envs.physics`; ``env.physics`` says which runs),
``pick_place_speed`` (m/s limit on pickers that hold something in pick-and-place steps, e.g. 1.0
as in MAIL; default None: the preset's, for ``fast`` the task's own, faster schedule),
``sim_options`` (engine parameters replacing the task's and the preset's, a dict of
``SimParams`` fields such as ``{"self_collision_distance": 0.01}``; default None; they do not
change ``physics``, which the scripted experts plan for), ``observe_grasp`` (default False;
True appends to the reduced state one value per picker, 1.0 while it holds a particle, else 0.0,
and images draw a picker that holds something black:
the gripper state a robot knows, without which a memoryless policy cannot tell a picker that
is about to grasp from one that has just grasped at the same spot); plus
task options such as ``pinned``. ``particles`` observations are ``(N + P, 3)``: every particle,
then the pickers. Tasks whose default action mode is ``"pick_place"`` derive from
:class:`PickPlaceParticleEnv` / :class:`PickPlaceParticleVectorEnv` instead.
"""

from __future__ import annotations

from typing import Any, ClassVar, Sequence

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector.utils import batch_space

from lfd_envs.core.base_env import (OBS_MODES, RENDER_MODES, LfdEnv, check_render_mode, check_reset_options,
                                   check_seed, observation_space)
from lfd_envs.core.errors import (StrictInitKwargs, as_real_array, check_choice, check_image_size,
                                  check_int_range)
from lfd_envs.core.state import check_episode, check_state_layout, episode_arrays
from lfd_envs.core.variants import VariantSplit
from lfd_envs.tasks.particle_batch import ParticleBatch
from lfd_envs.tasks.particle_task import ParticleTask
from lfd_envs.tasks.picker_actions import ACTION_MODES, ActionMode, Workspace

__all__ = ["ParticleEnv", "ParticleVectorEnv", "PickPlaceParticleEnv", "PickPlaceParticleVectorEnv",
           "PARTICLE_OBS_MODES"]

PARTICLE_OBS_MODES = OBS_MODES + ("particles",)
#: bound (m) of the position entries of state and particle observations
POSITION_BOUND = 5.0


def _check_device(device: Any) -> str:
    import warp as wp

    if not isinstance(device, str):
        raise ValueError(f"device must be a Warp device name such as 'cpu' or 'cuda:0', got {device!r}")
    try:
        wp.get_device(device)
    except Exception as exc:  # warp raises different types per version
        raise ValueError(f"device must be a Warp device such as 'cpu' or 'cuda:0', got {device!r} ({exc})") from None
    return str(device)


def _horizon(task: ParticleTask, action_mode: str, horizon: Any) -> int:
    return task.horizon(action_mode) if horizon is None else check_int_range("horizon", horizon, 1)


class _ParticleBatchViews:
    """Spaces and public read-only views of the particle batch (shared by both front ends)."""

    batch: ParticleBatch
    task: ParticleTask

    @property
    def num_particles(self) -> int:
        """Particles ``N`` of one world (pickers not counted)."""
        return int(self.batch.sim.num_particles)

    @property
    def physics(self) -> str:
        """The physics preset this env runs: ``"fast"`` (the ``-v0`` ids) or ``"flex_like"`` (the
        ``-v1`` ids), see :mod:`lfd_envs.physics`. ``sim_options`` on top of it do not change it."""
        return self.batch.physics.name

    @property
    def workspace(self) -> Workspace:
        """Workspace box of the pickers (bounds of pick-and-place targets)."""
        return self.batch.workspace

    @property
    def picker_actions(self) -> ActionMode:
        """The action mode object turning normalised actions into picker motions (``join`` for
        pick-and-place actions, ``frames_per_step``)."""
        return self.batch.action_mode

    def _task_spaces(self) -> tuple[spaces.Box, spaces.Box, spaces.Box]:
        low, high = self.batch.state_bounds(POSITION_BOUND)
        state = spaces.Box(low, high, dtype=np.float32)
        n = self.batch.sim.num_particles + self.task.num_pickers
        particles = spaces.Box(-POSITION_BOUND, POSITION_BOUND, (n, 3), np.float32)
        return self.batch.action_mode.action_space, state, particles


class ParticleEnv(_ParticleBatchViews, LfdEnv):
    """Single particle-task env (``LfdEnv`` contract over a one-world batch).

    Subclasses set ``task_class`` (and ``task_options`` defaults for extra task arguments).
    """

    task_class: ClassVar[type[ParticleTask]]
    task_options: ClassVar[dict[str, Any]] = {}
    supported_obs_modes = PARTICLE_OBS_MODES

    def __init__(self, num_pickers: int | None = None, action_mode: str = "delta", obs_mode: str | None = None,
                 image_size: int | tuple[int, int] = 32, resolution: int | None = None, device: str = "cpu",
                 render_mode: str | None = None, horizon: int | None = None,
                 render_size: int | tuple[int, int] | None = None,
                 pick_place_speed: float | None = None, sim_options: dict[str, Any] | None = None,
                 physics: str = "fast", observe_grasp: bool = False) -> None:
        self._setup(dict(num_pickers=num_pickers, resolution=resolution), action_mode, obs_mode, image_size,
                    device, render_mode, horizon, render_size,
                    pick_place_speed=pick_place_speed, sim_options=sim_options, physics=physics,
                    observe_grasp=observe_grasp)

    def _setup(self, task_options: dict[str, Any], action_mode: str, obs_mode: str | None,
               image_size: Any, device: str, render_mode: str | None, horizon: int | None,
               render_size: Any = None, pick_place_speed: float | None = None,
               sim_options: dict[str, Any] | None = None, physics: str = "fast",
               observe_grasp: bool = False) -> None:
        """The construction shared by every particle env's ``__init__`` (they differ only in
        defaults and task options): the task, ``LfdEnv.__init__``, the batch, the spaces."""
        check_choice("action_mode", action_mode, ACTION_MODES)
        device = _check_device(device)
        task = self.task_class(**{**self.task_options, **task_options})
        self.task_name = task.name
        super().__init__(obs_mode=obs_mode or task.default_obs_mode, image_size=image_size,
                         render_mode=render_mode, horizon=_horizon(task, action_mode, horizon),
                         render_size=render_size)
        self.task = task
        self.action_mode = action_mode
        self.num_pickers = task.num_pickers
        self.device = device
        self.batch = ParticleBatch(task, 1, action_mode, device, pick_place_speed=pick_place_speed,
                                   sim_options=sim_options, physics=physics, observe_grasp=observe_grasp)
        self.action_space, self.state_space, self.particles_space = self._task_spaces()
        self._finish_init()

    # ------------------------------------------------------------------ LfdEnv hooks
    def _setup_variant(self, rng: np.random.Generator) -> None:
        self.batch.reset_world(0, rng)

    def _apply_action(self, action: np.ndarray) -> None:
        self.batch.step(action[None])

    def _state_obs(self) -> np.ndarray:
        return self.batch.state_obs()[0]

    def _particles_obs(self) -> np.ndarray:
        return self.batch.particles_obs()[0]

    def _render(self, height: int, width: int) -> np.ndarray:
        return self.batch.images(height, width)[0]

    def _performance(self) -> float:
        return float(self.batch.performance()[0])

    @property
    def performance_optimum(self) -> float:
        return float(self.task.performance_optimum)

    def normalized_performance(self, performance: float) -> float:
        return float(self.task.normalized_performance(np.array([performance]), np.array([self._p0]))[0])

    def _info(self, performance: float) -> dict[str, Any]:
        info = super()._info(performance)
        for key, value in self.batch.metrics().items():
            info[key] = float(value[0])
        return info

    def _is_success(self) -> bool | None:
        p = self.batch.performance()
        success = self.task.success(p, self.batch.normalized(p))
        return None if success is None else bool(success[0])

    def _get_sim_state(self) -> dict[str, np.ndarray]:
        return self.batch.get_state(0)

    def _task_identity(self) -> dict[str, Any]:
        return self.batch.identity()

    def _check_sim_state(self, sim: dict[str, np.ndarray]) -> None:
        self.batch.check_state(sim)

    def _set_sim_state(self, state: dict[str, np.ndarray]) -> None:
        self.batch.set_state(0, state)

    def set_state(self, state: dict[str, np.ndarray]) -> None:
        """:meth:`LfdEnv.set_state <lfd_envs.core.LfdEnv.set_state>`; a state saved by this task
        under the other physics preset is refused with a ``ValueError`` naming both env ids."""
        self.batch.check_physics(state)
        super().set_state(state)

    # ------------------------------------------------------------------ privileged views (experts)
    @property
    def particle_positions(self) -> np.ndarray:
        """Particle positions ``(N, 3)`` (privileged; for experts and analysis)."""
        return self.batch.positions[0]

    @property
    def picker_positions(self) -> np.ndarray:
        """Picker centres ``(P, 3)``."""
        return self.batch.pickers[0]

    @property
    def grasped(self) -> np.ndarray:
        """Grasp flags ``(P,)``."""
        return self.batch.sim.grasped[0]

    @property
    def held_particles(self) -> np.ndarray:
        """Number of particles each picker holds now ``(P,)`` (0 for a flag that is on over nothing)."""
        return self.batch.held_particles()[0]


class ParticleVectorEnv(_ParticleBatchViews, StrictInitKwargs, gym.vector.VectorEnv):
    """Batched particle-task env: ``num_envs`` worlds in one engine, SAME_STEP autoreset.

    ``reset(seed=s)`` seeds world ``i`` with ``s + i`` (or ``seed`` may be a list);
    ``options={"variant": k or [k_i], "split": "train"|"eval"}`` picks variants.
    Actions have shape ``(num_envs, A)``; a wrong shape or NaN/inf raises ``ValueError`` and
    changes nothing; out-of-range actions are clipped to [-1, 1].
    """

    task_class: ClassVar[type[ParticleTask]]
    task_options: ClassVar[dict[str, Any]] = {}
    metadata: ClassVar[dict[str, Any]] = {
        "render_modes": RENDER_MODES, "render_fps": 10,
        "autoreset_mode": gym.vector.AutoresetMode.SAME_STEP,
    }
    render_size: tuple[int, int] = (256, 256)
    terminate_on_success: ClassVar[bool] = False

    def __init__(self, num_envs: int = 1, num_pickers: int | None = None, action_mode: str = "delta",
                 obs_mode: str | None = None, image_size: int | tuple[int, int] = 32,
                 resolution: int | None = None, device: str = "cpu", render_mode: str | None = None,
                 horizon: int | None = None, render_size: int | tuple[int, int] | None = None,
                 max_episode_steps: int | None = None,
                 pick_place_speed: float | None = None, sim_options: dict[str, Any] | None = None,
                 physics: str = "fast", observe_grasp: bool = False) -> None:
        self._setup(num_envs, dict(num_pickers=num_pickers, resolution=resolution), action_mode, obs_mode,
                    image_size, device, render_mode, horizon, render_size, max_episode_steps,
                    pick_place_speed=pick_place_speed, sim_options=sim_options, physics=physics,
                    observe_grasp=observe_grasp)

    def _setup(self, num_envs: int, task_options: dict[str, Any], action_mode: str, obs_mode: str | None,
               image_size: Any, device: str, render_mode: str | None, horizon: int | None,
               render_size: Any = None, max_episode_steps: int | None = None,
               pick_place_speed: float | None = None, sim_options: dict[str, Any] | None = None,
               physics: str = "fast", observe_grasp: bool = False) -> None:
        num_envs = check_int_range("num_envs", num_envs, 1)
        check_choice("action_mode", action_mode, ACTION_MODES)
        device = _check_device(device)
        task = self.task_class(**{**self.task_options, **task_options})
        self.task = task
        self.num_envs = num_envs
        self.action_mode = action_mode
        self.obs_mode = check_choice("obs_mode", obs_mode or task.default_obs_mode,
                                     PARTICLE_OBS_MODES)
        self.image_size = check_image_size(image_size)
        self.render_mode = check_render_mode(render_mode)
        if render_size is not None:
            self.render_size = check_image_size(render_size, "render_size")
        self.horizon = _horizon(task, action_mode, horizon)
        if max_episode_steps is not None:  # an upper bound, like gymnasium.make's TimeLimit
            self.horizon = min(self.horizon, check_int_range("max_episode_steps", max_episode_steps, 1))
        self.device = device
        self.variants = VariantSplit(task.name)
        self.batch = ParticleBatch(task, self.num_envs, action_mode, device, pick_place_speed=pick_place_speed,
                                   sim_options=sim_options, physics=physics, observe_grasp=observe_grasp)
        self.single_action_space, state, particles = self._task_spaces()
        self.single_observation_space = observation_space(self.obs_mode, self.image_size, state, particles)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        n = self.num_envs
        self._rngs = [seeding.np_random(None)[0] for _ in range(n)]
        self._split = np.zeros(n, dtype=np.int64)  # 0 train, 1 eval
        self._variant = np.full(n, -1, dtype=np.int64)
        self._steps = np.zeros(n, dtype=np.int64)
        self._prev = np.zeros(n)

    # ------------------------------------------------------------------ API
    def reset(self, *, seed: int | Sequence[int] | None = None, options: dict[str, Any] | None = None):
        self._check_open("reset")
        options = check_reset_options(options)
        n = self.num_envs
        split = options.get("split", "train")
        size = self.variants.size(split)
        variant = options.get("variant")
        ks = [variant] * n if variant is None or np.isscalar(variant) else list(variant)
        if len(ks) != n:
            raise ValueError(f"options['variant'] must be an int or a list of {n} ints, got {variant!r}")
        for i, k in enumerate(ks):
            if k is not None:
                self.variants.global_id(split, k)  # validate all before changing anything
        if seed is not None:
            self._rngs = [seeding.np_random(s)[0] for s in self._seeds(seed)]
        for i, k in enumerate(ks):
            self._reset_world(i, split, None if k is None else int(k), size)
        return self._observations(), self._infos(self.batch.performance())

    def step(self, actions: Any):
        self._check_open("step")
        if np.any(self._variant < 0):
            raise RuntimeError("call reset() before step()")
        actions = self._validate(actions)
        self.batch.step(actions)
        self._steps += 1
        perf = self.batch.performance()
        reward = perf - self._prev
        self._prev = perf.copy()
        infos = self._infos(perf)
        success = infos.get("is_success")
        terminated = (success.astype(bool) if (success is not None and self.terminate_on_success)
                      else np.zeros(self.num_envs, dtype=bool))
        truncated = (self._steps >= self.horizon) & ~terminated
        obs = self._observations()
        done = np.flatnonzero(terminated | truncated)
        if done.size:
            final_obs = np.full(self.num_envs, None, dtype=object)
            for i in done:
                final_obs[i] = self._index(obs, i)
            mask = np.zeros(self.num_envs, dtype=bool)
            mask[done] = True
            final_info = {k: v.copy() for k, v in infos.items()}
            final_info.update({f"_{k}": mask.copy() for k in infos})
            for i in done:
                self._reset_world(int(i), "train" if self._split[i] == 0 else "eval", None, None)
            obs = self._observations()
            infos = self._infos(self.batch.performance())
            infos["final_obs"], infos["_final_obs"] = final_obs, mask.copy()
            infos["final_info"], infos["_final_info"] = final_info, mask.copy()
        return obs, reward.astype(np.float64), terminated, truncated, infos

    def render(self) -> tuple[np.ndarray, ...] | None:
        self._check_open("render")
        if self.render_mode != "rgb_array":
            return None
        return tuple(self.batch.images(*self.render_size))

    def close(self, **kwargs: Any) -> None:
        """Mark the env closed; ``reset``, ``step`` and ``render`` then raise."""
        self.closed = True

    def _check_open(self, call: str) -> None:
        """``RuntimeError`` if :meth:`close` was called."""
        if self.closed:
            raise RuntimeError(f"{call}() after close(): this env is closed; make a new one")

    # ------------------------------------------------------------------ state of one world
    def get_state(self, index: int) -> dict[str, np.ndarray]:
        """Engine state + task context + episode counters of world ``index`` (copies)."""
        index = check_int_range("index", index, 0, self.num_envs - 1)
        state = {f"sim/{k}": v for k, v in self.batch.get_state(index).items()}
        split = "train" if self._split[index] == 0 else "eval"
        state.update(episode_arrays(split, int(self._variant[index]), int(self._steps[index]),
                                    float(self.batch.p0[index]), float(self._prev[index]), self.batch.identity()))
        return state

    def set_state(self, index: int, state: dict[str, np.ndarray]) -> None:
        """Restore world ``index`` from :meth:`get_state` or a single env's ``get_state()``.

        The whole state is checked first (as in a single env's ``set_state``); a bad state raises
        ``TypeError``/``ValueError`` naming the key and changes nothing, a state saved under the
        other physics preset one naming both env ids.
        """
        index = check_int_range("index", index, 0, self.num_envs - 1)
        self.batch.check_physics(state)
        reference = {f"sim/{k}": v for k, v in self.batch.get_state(index).items()}
        reference.update(episode_arrays("train", 0, 0, 0.0, 0.0, self.batch.identity()))
        arrays = check_state_layout(state, reference)
        episode = check_episode(arrays, self.variants, self.horizon, self.batch.identity())
        sim = {k[4:]: v for k, v in arrays.items() if k.startswith("sim/")}
        self.batch.check_state(sim)
        self.batch.set_state(index, sim)
        self._split[index] = 0 if episode.split == "train" else 1
        self._variant[index] = episode.variant
        self._steps[index] = episode.step
        self.batch.p0[index] = episode.p0
        self._prev[index] = episode.prev_performance

    # ------------------------------------------------------------------ privileged views (agents, analysis)
    @property
    def particle_positions(self) -> np.ndarray:
        """Particle positions of every world ``(num_envs, N, 3)`` float32 (cached; do not modify)."""
        return self.batch.positions

    @property
    def variant_indices(self) -> np.ndarray:
        """Variant ``k`` (within its split) of every world ``(num_envs,)`` int64, a copy; -1 before
        the first reset."""
        return self._variant.copy()

    def world_context(self, index: int) -> dict[str, np.ndarray]:
        """Task context (goals, geometry of the variant) of world ``index``: views, not copies."""
        return {k: v[index] for k, v in self.batch.ctx.items()}

    # ------------------------------------------------------------------ internals
    def _seeds(self, seed: int | Sequence[int]) -> list[int]:
        """One seed per world (``seed + i`` for an int); ``ValueError`` before anything is seeded."""
        n = self.num_envs
        seeds = [check_seed(seed) + i for i in range(n)] if np.isscalar(seed) else list(seed)
        if len(seeds) != n or not all(isinstance(s, (int, np.integer)) and not isinstance(s, (bool, np.bool_))
                                      and s >= 0 for s in seeds):
            raise ValueError(f"seed must be a non-negative int or a list of {n} such ints, got {seed!r}")
        return [int(s) for s in seeds]

    def _reset_world(self, i: int, split: str, k: int | None, size: int | None) -> None:
        if k is None:
            k = int(self._rngs[i].integers(size if size is not None else self.variants.size(split)))
        self.batch.reset_world(i, self.variants.rng(split, k))
        self._split[i] = 0 if split == "train" else 1
        self._variant[i] = k
        self._steps[i] = 0
        self._prev[i] = self.batch.p0[i]

    def _validate(self, actions: Any) -> np.ndarray:
        shape = (self.num_envs,) + self.single_action_space.shape
        arr = as_real_array("actions", actions, shape)
        if arr.shape != shape:
            raise ValueError(f"actions must have shape {shape}, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"actions must be finite (no NaN/inf); expected shape {shape}")
        return np.clip(arr, -1.0, 1.0).astype(np.float32)

    def _observations(self) -> Any:
        mode = self.obs_mode
        if mode == "state":
            return self.batch.state_obs()
        if mode == "particles":
            return self.batch.particles_obs()
        image = self.batch.images(*self.image_size)
        if mode == "image":
            return image
        return {"state": self.batch.state_obs(), "image": image}

    @staticmethod
    def _index(obs: Any, i: int) -> Any:
        if isinstance(obs, dict):
            return {k: v[i].copy() for k, v in obs.items()}
        return obs[i].copy()

    def _infos(self, perf: np.ndarray) -> dict[str, np.ndarray]:
        n = self.num_envs
        p_hat = self.batch.normalized(perf)
        global_ids = np.where(self._split == 0, self._variant, self.variants.num_train + self._variant)
        infos: dict[str, np.ndarray] = {
            "performance": perf.astype(np.float64),
            "normalized_performance": p_hat.astype(np.float64),
            "variant": global_ids.astype(np.int64),
        }
        success = self.task.success(perf, p_hat)
        if success is not None:
            infos["is_success"] = np.asarray(success, dtype=bool)
        for key, value in self.batch.metrics().items():
            infos[key] = np.asarray(value, dtype=np.float64)
        out = dict(infos)
        for key in infos:
            out[f"_{key}"] = np.ones(n, dtype=bool)
        return out


class PickPlaceParticleEnv(ParticleEnv):
    """:class:`ParticleEnv` whose default action mode is ``"pick_place"``."""

    def __init__(self, num_pickers: int | None = None, action_mode: str = "pick_place", obs_mode: str | None = None,
                 image_size: int | tuple[int, int] = 32, resolution: int | None = None, device: str = "cpu",
                 render_mode: str | None = None, horizon: int | None = None,
                 render_size: int | tuple[int, int] | None = None,
                 pick_place_speed: float | None = None, sim_options: dict[str, Any] | None = None,
                 physics: str = "fast", observe_grasp: bool = False) -> None:
        self._setup(dict(num_pickers=num_pickers, resolution=resolution), action_mode, obs_mode, image_size,
                    device, render_mode, horizon, render_size,
                    pick_place_speed=pick_place_speed, sim_options=sim_options, physics=physics,
                    observe_grasp=observe_grasp)


class PickPlaceParticleVectorEnv(ParticleVectorEnv):
    """:class:`ParticleVectorEnv` whose default action mode is ``"pick_place"``."""

    def __init__(self, num_envs: int = 1, num_pickers: int | None = None, action_mode: str = "pick_place",
                 obs_mode: str | None = None, image_size: int | tuple[int, int] = 32,
                 resolution: int | None = None, device: str = "cpu", render_mode: str | None = None,
                 horizon: int | None = None, render_size: int | tuple[int, int] | None = None,
                 max_episode_steps: int | None = None,
                 pick_place_speed: float | None = None, sim_options: dict[str, Any] | None = None,
                 physics: str = "fast", observe_grasp: bool = False) -> None:
        self._setup(num_envs, dict(num_pickers=num_pickers, resolution=resolution), action_mode, obs_mode,
                    image_size, device, render_mode, horizon, render_size, max_episode_steps,
                    pick_place_speed=pick_place_speed, sim_options=sim_options, physics=physics,
                    observe_grasp=observe_grasp)
