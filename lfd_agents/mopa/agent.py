"""MoPA agent for harnesses that step the plain task env (``lfd_bench.run``).

:class:`MoPAAgent` trains :class:`~lfd_agents.mopa.sac.MoPASAC` (or MoPA-TD3) on the task
wrapped in :class:`~lfd_agents.mopa.wrapper.MoPAWrapper`, with the budget counted in
**low-level env steps** (each waypoint of a planned path counts), so MoPA and plain SAC get
the same number of simulator steps. For evaluation on an unwrapped env, :meth:`bind` attaches
a wrapper to that env; :meth:`predict` then plans a MoPA action and returns its low-level
actions one call at a time (one waypoint per ``env.step``).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

from lfd_agents.mopa.sac import MoPASAC, MoPATD3, make_mopa_env, mopa_agent_kwargs

__all__ = ["MoPAAgent"]


class _LowLevelBudget(BaseCallback):
    """Stops ``learn`` once the wrapper has executed ``budget`` more low-level steps."""

    def __init__(self, wrapper, budget: int) -> None:
        super().__init__()
        self.wrapper, self.stop_at = wrapper, wrapper.low_level_steps + int(budget)

    def _on_step(self) -> bool:
        return self.wrapper.low_level_steps < self.stop_at


class MoPAAgent:
    """MoPA-SAC/TD3 on a task env, with the ``learn``/``predict``/``bind``/``reset`` harness API.

    Args:
        env: the plain task env (its ``spec.id`` selects :data:`MOPA_DEFAULTS`).
        seed: agent seed.
        algo: ``"sac"`` (default) or ``"td3"`` (ablation).
        wrapper_kwargs: :class:`MoPAWrapper` overrides (ablations, planner time limit ...); the
            planners (training and :meth:`bind`) are seeded with ``seed`` unless
            ``planner_kwargs`` names another seed or a ready ``planner`` is given.
        **agent_kwargs: :class:`MoPASAC` arguments (reward_scale, reuse, SB3 SAC arguments).
    """

    def __init__(self, env: gym.Env, seed: int = 0, algo: str = "sac", wrapper_kwargs: dict | None = None,
                 **agent_kwargs: Any) -> None:
        if algo not in ("sac", "td3"):
            raise ValueError(f"algo must be 'sac' or 'td3', got {algo!r}")
        self.env_id = env.spec.id if env.spec is not None else type(env.unwrapped).__name__
        self.wrapper_kwargs = dict(wrapper_kwargs or {})
        if "planner" not in self.wrapper_kwargs:  # seeded planners: paths independent of earlier runs
            planner_kwargs = dict(self.wrapper_kwargs.get("planner_kwargs") or {})
            planner_kwargs.setdefault("seed", int(seed))
            self.wrapper_kwargs["planner_kwargs"] = planner_kwargs
        self.train_env = make_mopa_env(env, **self.wrapper_kwargs)
        kwargs = mopa_agent_kwargs(self.env_id)
        kwargs.update(verbose=0, device="cpu", buffer_size=100_000)
        kwargs.update(agent_kwargs)
        cls = MoPASAC if algo == "sac" else MoPATD3
        self.model = cls("MlpPolicy", self.train_env, seed=seed, **kwargs)
        self._eval: Any = None
        self._queue: list[np.ndarray] = []

    @classmethod
    def for_benchmark(cls, env: gym.Env, seed: int = 0, **kwargs: Any) -> "MoPAAgent":
        return cls(env, seed=seed, **kwargs)

    def learn(self, total_timesteps: int, reset_num_timesteps: bool = True, callback: Any = None,
              **kwargs: Any) -> "MoPAAgent":
        """Train for ``total_timesteps`` low-level env steps (``callback``: SB3 callbacks, called
        once per decision of the policy)."""
        budget = _LowLevelBudget(self.train_env, total_timesteps)
        extra = [] if callback is None else list(callback) if isinstance(callback, (list, tuple)) else [callback]
        self.model.learn(total_timesteps=int(total_timesteps), callback=[budget, *extra],
                         reset_num_timesteps=reset_num_timesteps, **kwargs)
        return self

    def get_training_state(self) -> dict[str, Any]:
        """The model's training state plus the wrapper's counters: low-level steps, mode
        statistics and the planner's query index (which, with its seed, seeds the next query)."""
        from lfd_agents.training_state import get_training_state

        planner = self.train_env.planner
        return {"model": get_training_state(self.model), "low_level_steps": int(self.train_env.low_level_steps),
                "stats": dict(self.train_env.stats), "ompl_queries": getattr(planner, "ompl_queries", None)}

    def set_training_state(self, state: dict[str, Any]) -> None:
        """Load a :meth:`get_training_state` of a ``MoPAAgent`` built the same way."""
        from lfd_agents.training_state import set_training_state

        set_training_state(self.model, state["model"])
        self.train_env.low_level_steps = int(state["low_level_steps"])
        self.train_env.stats = dict(state["stats"])
        if state["ompl_queries"] is not None:
            self.train_env.planner.ompl_queries = int(state["ompl_queries"])

    def reseed(self, seed: int) -> None:
        """Reseed the model and its env's next reset (the planner keeps its own query seeds)."""
        self.model.set_random_seed(int(seed))

    def bind(self, env: gym.Env) -> None:
        """Act on ``env`` (unwrapped task env) through a MoPA wrapper of its own."""
        self._eval = make_mopa_env(env, **self.wrapper_kwargs)
        self._queue = []

    def reset(self) -> None:
        self._queue = []

    def predict(self, obs: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        """Low-level env action when bound (see :meth:`bind`), else the MoPA action."""
        if self._eval is None:
            return self.model.predict(obs, deterministic=deterministic)
        if not self._queue:
            action, _ = self.model.predict(obs, deterministic=deterministic)
            self._queue = self._eval.low_level_actions(self._eval.resolve(action))
        return self._queue.pop(0), None
