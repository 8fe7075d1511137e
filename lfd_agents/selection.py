"""Checkpoint selection on held-out training variants.

Off-policy learners that train on a handful of demonstrations can swing from one checkpoint
to the next (a policy that folds the cloth, a few thousand updates later one that drops it).
:class:`BestCheckpoint` scores the policy after each training chunk on a fixed set of
*training-split* variants that the learner never trains on (validation episodes; the eval
variants stay untouched) and keeps a frozen copy of the best-scoring policy, which is then the
one that acts (for a learner with an offline phase, the policy that phase ends with is the
first candidate)::

    best = BestCheckpoint(env, episodes=10)
    for _ in range(chunks):
        model.learn(chunk, reset_num_timesteps=False)
        best.update(model.policy)
    action, _ = best.predict(obs)

Validation episodes cost env steps of their own (``episodes`` episodes per ``update``); they are
counted in :attr:`BestCheckpoint.env_steps` and never enter a replay buffer.
:class:`SelectBest` wraps any SB3-style learner in that loop: its ``learn`` trains and scores,
its ``predict`` acts with the best checkpoint so far.
"""

from __future__ import annotations

import copy
from typing import Any

import gymnasium as gym
import numpy as np

from lfd_envs.core.rollout import play_episode

__all__ = ["BestCheckpoint", "SelectBest"]


class _Acting:
    """``predict`` of an SB3 policy, as :func:`play_episode` calls it."""

    def __init__(self, policy: Any) -> None:
        self.policy = policy

    def predict(self, obs: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        return self.policy.predict(obs, state, episode_start, deterministic=True)


class BestCheckpoint:
    """Keeps the policy that scores best on validation variants (see the module docstring).

    Args:
        env: an env made with ``gym.make`` (its id and keyword arguments make the validation env).
        episodes: validation episodes per score, on training variants
            ``first_variant .. first_variant + episodes - 1`` (mean final p̂).
        first_variant: first training variant of the validation set.
        seed: seed of the validation resets (the same in every score, so scores compare).
    """

    def __init__(self, env: gym.Env, episodes: int = 10, first_variant: int = 400, seed: int = 0) -> None:
        if env.spec is None:
            raise ValueError("BestCheckpoint needs an env made with gym.make (its id and kwargs define the validation env)")
        if int(episodes) < 1:
            raise ValueError(f"episodes must be >= 1, got {episodes!r}")
        self.env = gym.make(env.spec.id, **dict(env.spec.kwargs or {}))
        size = self.env.unwrapped.variants.size("train")
        if not 0 <= int(first_variant) or int(first_variant) + int(episodes) > size:
            self.env.close()
            raise ValueError(f"validation variants {first_variant}..{int(first_variant) + int(episodes) - 1} "
                             f"are outside the {size} training variants")
        self.episodes = int(episodes)
        self.first_variant = int(first_variant)
        self.seed = int(seed)
        self.best_policy: Any = None
        self.best_score = -np.inf
        self.scores: list[float] = []
        self.env_steps = 0

    def score(self, policy: Any) -> float:
        """Mean final p̂ of ``policy`` (deterministic actions) on the validation variants."""
        total = 0.0
        for k in range(self.episodes):
            info = play_episode(self.env, _Acting(policy), seed=self.seed * 100_003 + k,
                                options={"split": "train", "variant": self.first_variant + k})
            total += float(info["normalized_performance"])
            self.env_steps += int(self.env.unwrapped.elapsed_steps)
        return total / self.episodes

    def update(self, policy: Any) -> float:
        """Score ``policy``; keep a frozen copy if it beats every earlier score. Returns the score."""
        value = self.score(policy)
        self.scores.append(value)
        if value > self.best_score:
            self.best_score = value
            self.best_policy = copy.deepcopy(policy)
            self.best_policy.set_training_mode(False)
        return value

    def predict(self, obs: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        """The best policy's action (SB3 ``predict``)."""
        if self.best_policy is None:
            raise RuntimeError("call update() before predict()")
        return self.best_policy.predict(obs, state, episode_start, deterministic)

    def close(self) -> None:
        """Close the validation env."""
        self.env.close()


class SelectBest:
    """An SB3-style learner whose acting policy is its best checkpoint (see the module docstring).

    Every ``learn`` call trains ``model`` and then scores its policy on the validation variants
    (:class:`BestCheckpoint`); ``predict`` acts with the best-scoring policy so far;
    ``policy`` is the one ``model`` trains.

    Args:
        model: the learner (an SB3 algorithm, or anything with ``learn`` and a ``policy``).
        env: the env made with ``gym.make`` that the validation env copies.
        episodes, first_variant, seed: as in :class:`BestCheckpoint`.
    """

    def __init__(self, model: Any, env: gym.Env, episodes: int = 10, first_variant: int = 400,
                 seed: int = 0) -> None:
        self.model = model
        self.selector = BestCheckpoint(env, episodes, first_variant, seed=seed)

    def learn(self, total_timesteps: int, reset_num_timesteps: bool = True, **kwargs: Any) -> "SelectBest":
        """Train ``model`` for ``total_timesteps``, then score the result as a checkpoint. A
        learner with an offline phase still to run (``offline_pending``, e.g. DMfD and AWAC with
        ``offline_steps``) runs it first (``pretrain()``) and the policy it ends with is scored
        as the first checkpoint: the online phase starts from it and may not improve on it."""
        if getattr(self.model, "offline_pending", False):
            self.model.pretrain()
            self.selector.update(self.model.policy)
        self.model.learn(total_timesteps, reset_num_timesteps=reset_num_timesteps, **kwargs)
        self.selector.update(self.model.policy)
        return self

    def predict(self, obs: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        """The best checkpoint's action (SB3 ``predict``); before any ``learn``, ``model``'s."""
        if self.selector.best_policy is None:
            return self.model.predict(obs, state, episode_start, deterministic)
        return self.selector.predict(obs, state, episode_start, deterministic)

    def get_training_state(self) -> dict[str, Any]:
        """``model``'s training state and the selection so far (:mod:`lfd_agents.training_state`)."""
        from lfd_agents.training_state import get_training_state

        best = self.selector.best_policy
        return {"model": get_training_state(self.model), "scores": list(self.selector.scores),
                "best_score": float(self.selector.best_score), "env_steps": int(self.selector.env_steps),
                "best_policy": None if best is None else best.state_dict()}

    def set_training_state(self, state: dict[str, Any]) -> None:
        """Load a :meth:`get_training_state` of a ``SelectBest`` built the same way."""
        from lfd_agents.training_state import set_training_state

        set_training_state(self.model, state["model"])
        selector = self.selector
        selector.scores, selector.best_score = list(state["scores"]), float(state["best_score"])
        selector.env_steps = int(state["env_steps"])
        selector.best_policy = None
        if state["best_policy"] is not None:
            selector.best_policy = copy.deepcopy(self.model.policy)
            selector.best_policy.load_state_dict(state["best_policy"])
            selector.best_policy.set_training_mode(False)

    def reseed(self, seed: int) -> None:
        """Reseed ``model`` (validation episodes have fixed seeds of their own)."""
        from lfd_agents.training_state import reseed

        reseed(self.model, seed)

    @property
    def policy(self) -> Any:
        """The policy that ``model`` trains (not the best checkpoint's frozen copy)."""
        return self.model.policy

    @property
    def validation_env_steps(self) -> int:
        """Env steps of the validation episodes so far."""
        return self.selector.env_steps

    def close(self) -> None:
        """Close the validation env."""
        self.selector.close()
