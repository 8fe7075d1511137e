"""The environment contract shared by every lfd env.

A task subclasses :class:`LfdEnv` and only describes the task through a handful of hooks
(``_setup_variant``, ``_apply_action``, ``_state_obs``, ``_render``, ``_performance``,
``_get_sim_state``/``_set_sim_state``). Everything users rely on lives here once:
seeding, the train/eval variant split, observation modes, action checking and clipping,
``info`` keys, normalised performance, ``get_state``/``set_state`` and headless rendering.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from lfd_envs.core.errors import StrictInitKwargs, as_real_array, check_choice, check_image_size, check_int_range
from lfd_envs.core.state import check_episode, check_state_layout, episode_arrays
from lfd_envs.core.variants import VariantSplit

OBS_MODES = ("state", "image", "state+image")
RESET_OPTIONS = ("split", "variant")
#: render modes of every lfd env (headless: no window of their own). ``gymnasium.make(...,
#: render_mode="human")`` wraps the ``rgb_array`` env in ``gymnasium.wrappers.HumanRendering``,
#: which needs pygame and a display.
RENDER_MODES = ["rgb_array"]


def check_render_mode(render_mode: Any) -> str | None:
    """``render_mode`` if it is None or ``"rgb_array"``; a clear ``ValueError`` otherwise."""
    if render_mode == "human":
        raise ValueError("render_mode='human' is not supported by the env itself: lfd envs render headless and "
                         "open no window. Use render_mode='rgb_array' and show the frames of env.render(), or "
                         "gymnasium.make(..., render_mode='human'), which adds gymnasium.wrappers.HumanRendering "
                         "(needs pygame and a display)")
    if render_mode is not None:
        check_choice("render_mode", render_mode, ("rgb_array",))
    return render_mode


def reset_options_dict(options: Any) -> dict[str, Any]:
    """Copy of ``reset`` ``options`` (``{}`` for None); ``ValueError`` unless a dict or None."""
    if options is None:
        return {}
    if not isinstance(options, Mapping):
        raise ValueError(f"options must be a dict such as {{'split': 'eval', 'variant': 3}} or None, "
                         f"got {type(options).__name__}")
    return dict(options)


def check_reset_options(options: Any) -> dict[str, Any]:
    """Copy of ``reset`` ``options`` (``{}`` for None); ``ValueError`` naming unknown keys."""
    options = reset_options_dict(options)
    unknown = sorted(set(options) - set(RESET_OPTIONS))
    if unknown:
        raise ValueError(f"unknown reset options {unknown}; valid options are {list(RESET_OPTIONS)}")
    return options


def check_seed(seed: Any) -> int | None:
    """``seed`` as an int if it is None or a non-negative int (bools refused), else ``ValueError``."""
    if seed is None:
        return None
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be None or a non-negative int, got {seed!r}")
    return int(seed)


def observation_space(obs_mode: str, image_size: tuple[int, int], state_space: spaces.Space,
                      particles_space: spaces.Space | None = None) -> spaces.Space:
    """Observation space of one env for ``obs_mode``: the state space, a uint8 ``(h, w, 3)``
    image, a ``Dict`` of both (``"state+image"``) or the particle space (``"particles"``)."""
    h, w = image_size
    image = spaces.Box(0, 255, (h, w, 3), np.uint8)
    if obs_mode == "state":
        return state_space
    if obs_mode == "image":
        return image
    if obs_mode == "state+image":
        return spaces.Dict({"state": state_space, "image": image})
    if obs_mode == "particles" and particles_space is not None:
        return particles_space
    raise ValueError(f"obs_mode {obs_mode!r} has no observation space here")


class LfdEnv(StrictInitKwargs, gym.Env):
    """Base class of every lfd environment.

    Subclasses set ``task_name``; their ``__init__`` calls ``super().__init__(obs_mode=...,
    image_size=..., render_mode=..., horizon=...)`` first, builds ``self.action_space`` and
    ``self.state_space`` (a float32 ``Box`` of the reduced state) and calls
    :meth:`_finish_init` last. Constructors reject unknown keyword arguments with a
    ``TypeError`` listing the valid ones (:class:`~lfd_envs.core.errors.StrictInitKwargs`).

    Episode conventions:
        * ``reset(seed=..., options={"variant": k, "split": "train"|"eval"})`` draws variant
          ``k`` of the split (random when omitted, from the env's seeded generator).
        * ``step`` validates the action (``ValueError`` naming the expected shape for a wrong
          shape or NaN/inf) and clips it to the action space bounds.
        * reward = ``performance(t) - performance(t-1)`` unless the task documents otherwise.
        * ``terminated`` is True only for tasks whose episode ends on success;
          ``truncated`` becomes True after ``horizon`` steps.
        * ``info`` has ``performance``, ``normalized_performance``, ``variant`` (global id;
          train ids come before eval ids) and ``is_success`` where the task defines success.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": RENDER_MODES, "render_fps": 10}
    task_name: ClassVar[str] = "LfdEnv"
    #: observation modes this task supports (particle tasks add "particles")
    supported_obs_modes: ClassVar[tuple[str, ...]] = OBS_MODES
    #: whether the episode terminates when the task is solved
    terminate_on_success: ClassVar[bool] = False
    #: default ``(height, width)`` of frames returned by ``render()`` (the ``render_size`` argument)
    render_size: tuple[int, int] = (256, 256)

    # ------------------------------------------------------------------ construction
    def __init__(
        self,
        *,
        obs_mode: str,
        image_size: int | tuple[int, int],
        render_mode: str | None,
        horizon: int,
        render_size: int | tuple[int, int] | None = None,
        num_train_variants: int = 800,
        num_eval_variants: int = 200,
    ) -> None:
        """Store and validate the arguments every env shares.

        A subclass's ``__init__`` calls ``super().__init__(...)`` with these first, then builds
        its simulation, ``action_space`` and ``state_space``, and calls :meth:`_finish_init` last.
        ``render_size`` (an int or ``(height, width)``, like ``image_size``) sets the frames of
        ``render()``; None keeps the class default.
        """
        self.obs_mode = check_choice("obs_mode", obs_mode, self.supported_obs_modes)
        self.image_size = check_image_size(image_size)
        self.render_mode = check_render_mode(render_mode)
        if render_size is not None:
            self.render_size = check_image_size(render_size, "render_size")
        self.horizon = check_int_range("horizon", horizon, 1)
        self.variants = VariantSplit(self.task_name, int(num_train_variants), int(num_eval_variants))
        self._variant_split = "train"
        self._variant_index = -1
        self._step_count = 0
        self._p0 = 0.0
        self._prev_perf = 0.0
        self._episode_count = 0
        self._closed = False

    def _init_contract(self, **contract: Any) -> None:
        """Former name of ``LfdEnv.__init__(self, **contract)`` (kept for envs written against it)."""
        LfdEnv.__init__(self, **contract)

    def _finish_init(self) -> None:
        """Build ``observation_space`` from ``obs_mode`` and the spaces set by the subclass.
        Call last in ``__init__``."""
        self.observation_space = self._observation_space_for(self.obs_mode)

    def _observation_space_for(self, obs_mode: str) -> spaces.Space:
        check_choice("obs_mode", obs_mode, self.supported_obs_modes)
        return observation_space(obs_mode, self.image_size, self.state_space, getattr(self, "particles_space", None))

    # ------------------------------------------------------------------ hooks for tasks
    state_space: spaces.Box
    particles_space: spaces.Box

    def _setup_variant(self, rng: np.random.Generator) -> None:
        """Put the simulation into a freshly drawn variant (geometry, goals, start state)."""
        raise NotImplementedError

    def _apply_action(self, action: np.ndarray) -> None:
        """Advance the simulation by one env step with a validated, clipped action."""
        raise NotImplementedError

    def _state_obs(self) -> np.ndarray:
        """Reduced state vector (float32, matches ``state_space``)."""
        raise NotImplementedError

    def _particles_obs(self) -> np.ndarray:
        raise NotImplementedError(f"{type(self).__name__} has no particle observation")

    def _render(self, height: int, width: int) -> np.ndarray:
        """RGB uint8 image ``(height, width, 3)`` from the task camera."""
        raise NotImplementedError

    def _performance(self) -> float:
        """Task performance ``p(s_t)`` (higher is better)."""
        raise NotImplementedError

    @property
    def performance_optimum(self) -> float:
        """``p_opt`` used by the normalised performance."""
        return 0.0

    def _is_success(self) -> bool | None:
        """True/False where the task defines success, else None (no ``is_success`` key)."""
        return None

    def _get_sim_state(self) -> dict[str, np.ndarray]:
        raise NotImplementedError

    def _set_sim_state(self, state: dict[str, np.ndarray]) -> None:
        raise NotImplementedError

    def _reward(self, performance: float, prev_performance: float) -> float:
        """Default reward: performance change during the step."""
        return float(performance - prev_performance)

    def normalized_performance(self, performance: float) -> float:
        """p̂ = (p - p0) / (p_opt - p0) relative to the episode's start state."""
        denom = self.performance_optimum - self._p0
        if abs(denom) < 1e-9:
            return 1.0 if performance >= self.performance_optimum - 1e-9 else 0.0
        return float((performance - self._p0) / denom)

    # ------------------------------------------------------------------ gymnasium API
    def _check_reset(self, options: dict[str, Any] | None) -> tuple[str, int | None]:
        """``(split, variant or None)`` of valid ``reset`` options; ``ValueError`` otherwise."""
        options = check_reset_options(options)
        split = options.get("split", "train")
        self.variants.size(split)  # validates split
        k = options.get("variant")
        if k is not None:
            self.variants.global_id(split, k)  # validates k
        return split, k

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self._check_open("reset")
        split, k = self._check_reset(options)  # before seeding: a failed reset changes nothing
        super().reset(seed=check_seed(seed))
        if k is None:
            k = int(self.np_random.integers(self.variants.size(split)))
        rng = self.variants.rng(split, k)
        self._variant_split, self._variant_index = split, int(k)
        self._setup_variant(rng)
        self._episode_count += 1
        self._step_count = 0
        self._p0 = self._prev_perf = float(self._performance())
        return self._observation(), self._info(self._p0)

    def step(self, action: Any):
        self._check_open("step")
        if self._variant_index < 0:
            raise RuntimeError("call reset() before step()")
        action = self.validate_action(action)
        self._apply_action(action)
        self._step_count += 1
        perf = float(self._performance())
        reward = self._reward(perf, self._prev_perf)
        self._prev_perf = perf
        info = self._info(perf)
        terminated = bool(self.terminate_on_success and info.get("is_success", False))
        truncated = self._step_count >= self.horizon and not terminated
        return self._observation(), float(reward), terminated, truncated, info

    def render(self) -> np.ndarray | None:
        self._check_open("render")
        if self.render_mode != "rgb_array":
            return None
        return self._render(*self.render_size)

    def close(self) -> None:
        """Release the env's resources; ``reset``, ``step`` and ``render`` then raise."""
        self._closed = True
        super().close()

    # ------------------------------------------------------------------ helpers
    def _check_open(self, call: str) -> None:
        """``RuntimeError`` if :meth:`close` was called."""
        if getattr(self, "_closed", False):
            raise RuntimeError(f"{call}() after close(): this env is closed; make a new one")

    def validate_action(self, action: Any) -> np.ndarray:
        """Check shape and finiteness (``ValueError`` otherwise) and clip to the bounds."""
        space = self.action_space
        assert isinstance(space, spaces.Box), "override validate_action for non-Box action spaces"
        arr = as_real_array("action", action, space.shape)
        if arr.shape != space.shape:
            if arr.size == int(np.prod(space.shape)) and arr.ndim <= 1 and len(space.shape) == 1:
                arr = arr.reshape(space.shape)
            else:
                raise ValueError(f"action must have shape {space.shape}, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"action must be finite (no NaN/inf); expected shape {space.shape}, got {arr}")
        return np.clip(arr, space.low, space.high).astype(np.float32)

    def _observation(self) -> Any:
        mode = self.obs_mode
        if mode == "state":
            return self._state_obs()
        if mode == "image":
            return self._render(*self.image_size)
        if mode == "state+image":
            return {"state": self._state_obs(), "image": self._render(*self.image_size)}
        return self._particles_obs()

    def _info(self, performance: float) -> dict[str, Any]:
        info: dict[str, Any] = {
            "performance": float(performance),
            "normalized_performance": self.normalized_performance(performance),
            "variant": int(self.variants.global_id(self._variant_split, self._variant_index)),
        }
        success = self._is_success()
        if success is not None:
            info["is_success"] = bool(success)
        return info

    @property
    def variant(self) -> tuple[str, int]:
        """``(split, k)`` of the current variant."""
        return self._variant_split, self._variant_index

    @property
    def elapsed_steps(self) -> int:
        """Steps taken in the current episode."""
        return self._step_count

    @property
    def episode_count(self) -> int:
        """Episodes started so far: one more after every ``reset`` and every ``set_state``
        (experts use it to notice a new episode without being reset by hand)."""
        return self._episode_count

    # ------------------------------------------------------------------ state
    def _task_identity(self) -> dict[str, Any]:
        """What makes a state belong to this task (stored as ``episode/task_id``): the task name
        plus construction arguments that change the task. Override to add arguments."""
        return {"task": self.task_name}

    def _check_sim_state(self, sim: dict[str, np.ndarray]) -> None:
        """Check task-specific value ranges of the ``sim/*`` part of a state (keys without the
        prefix; shapes, dtypes and finiteness are already checked). ``ValueError`` naming the key."""

    def _state_reference(self) -> dict[str, np.ndarray]:
        """Layout (keys, shapes, dtypes) of this env's states, for checking incoming ones."""
        try:
            sim = self._get_sim_state()
        except (AttributeError, TypeError):
            raise RuntimeError("call reset() before set_state()") from None
        reference = {f"sim/{k}": np.asarray(v) for k, v in sim.items()}
        reference.update(episode_arrays("train", 0, 0, 0.0, 0.0, self._task_identity()))
        return reference

    def get_state(self) -> dict[str, np.ndarray]:
        """Full simulator + episode state as a flat dict of numpy arrays (copies)."""
        if self._variant_index < 0:
            raise RuntimeError("call reset() before get_state()")
        state = {f"sim/{k}": np.array(v, copy=True) for k, v in self._get_sim_state().items()}
        state.update(episode_arrays(self._variant_split, self._variant_index, self._step_count, self._p0,
                                    self._prev_perf, self._task_identity()))
        return state

    def set_state(self, state: dict[str, np.ndarray]) -> None:
        """Restore a state from :meth:`get_state`; the futures of both are identical.

        The whole state is checked first (keys, shapes, dtypes, finiteness, episode counters,
        task identity and the task's value ranges): a bad state raises ``TypeError`` or
        ``ValueError`` naming the key and changes nothing. The variant is rebuilt if it differs
        from the current one.
        """
        arrays = check_state_layout(state, self._state_reference())
        episode = check_episode(arrays, self.variants, self.horizon, self._task_identity())
        sim = {key[4:]: v for key, v in arrays.items() if key.startswith("sim/")}
        self._check_sim_state(sim)
        if (episode.split, episode.variant) != (self._variant_split, self._variant_index):
            self._setup_variant(self.variants.rng(episode.split, episode.variant))
            self._variant_split, self._variant_index = episode.split, episode.variant
        self._set_sim_state(sim)
        self._episode_count += 1
        self._step_count = episode.step
        self._p0 = episode.p0
        self._prev_perf = episode.prev_performance

    def state_observation(self) -> np.ndarray:
        """Reduced state vector of the current state (float32, matches ``state_space``), whatever
        the ``obs_mode`` (privileged for image-observation agents, e.g. reference-state rewards)."""
        return self._state_obs()

    def current_observation(self) -> Any:
        """Observation of the current state (e.g. after :meth:`set_state`)."""
        return self._observation()

    def current_info(self) -> dict[str, Any]:
        """``info`` dict of the current state."""
        return self._info(float(self._performance()))
