"""Demonstrators of controlled quality: a policy (normally the scripted expert) with random slips.

:class:`EpsilonNoisyPolicy` replaces the wrapped policy's action, with probability ``epsilon`` at
each step, by a uniform random action of the env's action space. The wrapped policy stays closed
loop, so it recovers from most slips; a slip that drops a grasped cloth or rope at the wrong
moment is what makes some episodes fail. ``epsilon`` therefore sets the demonstrations' mean final
p̂ between the expert's (``epsilon = 0``) and random's (``epsilon = 1``)::

    from lfd_envs.experts.noisy import noisy_expert_policy
    demonstrator = noisy_expert_policy(env, epsilon=0.2, seed=0)
    action, _ = demonstrator.predict(obs)

``lfd_envs.datasets.collect(..., policy="noisy_expert", policy_kwargs={"epsilon": 0.2})`` records
such demonstrations.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

__all__ = ["EpsilonNoisyPolicy", "noisy_expert_policy"]


class EpsilonNoisyPolicy:
    """``policy`` whose action is, with probability ``epsilon`` per step, a uniform random action.

    Args:
        policy: any object with ``predict(obs, deterministic=True) -> (action, state)`` (and
            optionally ``reset()``).
        action_space: a bounded ``gymnasium.spaces.Box`` to draw the random actions from.
        epsilon: slip probability per step, in ``[0, 1]``.
        seed: seed of the slips and of the random actions.
    """

    def __init__(self, policy: Any, action_space: gym.spaces.Space, epsilon: float, seed: int = 0):
        if not isinstance(action_space, gym.spaces.Box) or not action_space.is_bounded():
            raise ValueError(f"EpsilonNoisyPolicy needs a bounded Box action space, got {action_space}")
        epsilon = float(epsilon)
        if not 0.0 <= epsilon <= 1.0:
            raise ValueError(f"epsilon must be in [0, 1], got {epsilon}")
        self.policy = policy
        self.action_space = action_space
        self.epsilon = epsilon
        self._rng = np.random.default_rng(seed)

    def reset(self) -> None:
        """Reset the wrapped policy (the slip generator keeps its stream)."""
        if hasattr(self.policy, "reset"):
            self.policy.reset()

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:
        """The wrapped policy's action, or a random one with probability ``epsilon``.

        The wrapped policy is queried every step (scripted experts track their episode's
        progress through these calls), whether or not its action is used.
        """
        action, state = self.policy.predict(observation, state=state, episode_start=episode_start,
                                            deterministic=deterministic)
        if self._rng.random() < self.epsilon:
            low, high = self.action_space.low, self.action_space.high
            action = self._rng.uniform(low, high).astype(self.action_space.dtype)
        return np.asarray(action, dtype=self.action_space.dtype), state


def noisy_expert_policy(env: gym.Env, epsilon: float = 0.2, seed: int = 0, **expert_kwargs: Any) -> EpsilonNoisyPolicy:
    """The task's scripted expert (``make_expert(env, **expert_kwargs)``) with random slips
    (see :class:`EpsilonNoisyPolicy`)."""
    from lfd_envs.experts import make_expert

    return EpsilonNoisyPolicy(make_expert(env, **expert_kwargs), env.action_space, epsilon, seed)
