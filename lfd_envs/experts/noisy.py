"""Demonstrators of controlled quality: a policy (normally the scripted expert) with random slips.

:class:`EpsilonNoisyPolicy` replaces the wrapped policy's action, with probability ``epsilon`` at
each step, by a uniform random action of the env's action space. The wrapped policy stays closed
loop, so it recovers from most slips; a slip that drops a grasped cloth or rope at the wrong
moment is what makes some episodes fail. ``epsilon`` therefore sets the demonstrations' mean final
p̂ between the expert's (``epsilon = 0``) and random's (``epsilon = 1``).

``action_noise`` adds zero-mean Gaussian noise to every action that is not a slip (its standard
deviation in units of half the action range; the result is clipped to the bounds), as noise
injection into the demonstrator does (DART, Laskey et al. 2017): the closed-loop expert then
visits states a little off its own path and records the actions that bring it back, which a
policy fitted to its own noise-free path never sees. The recorded action is the executed one,
so the transitions stay consistent for a critic; a regression on them fits the expert's mean
action where that action changes smoothly with the state. Near the expert's own thresholds
(e.g. "settle over the corner, then drop") the noise mixes states on both sides: on the
``-v1`` diagonal fold with ``action_noise`` 0.02, BC averaged the drop with the waiting and
crept down without ever grasping (the ``repro-cpu-v1`` action-noise cell)::

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
    """``policy`` whose action is, with probability ``epsilon`` per step, a uniform random action,
    and otherwise its own action plus Gaussian noise of standard deviation ``action_noise``.

    Args:
        policy: any object with ``predict(obs, deterministic=True) -> (action, state)`` (and
            optionally ``reset()``).
        action_space: a bounded ``gymnasium.spaces.Box`` to draw the random actions from.
        epsilon: slip probability per step, in ``[0, 1]``.
        seed: seed of the slips, the random actions and the noise.
        action_noise: standard deviation of the Gaussian noise on the wrapped policy's actions,
            in units of half the action range per dimension (``>= 0``; 0 = none).
    """

    def __init__(self, policy: Any, action_space: gym.spaces.Space, epsilon: float, seed: int = 0,
                 action_noise: float = 0.0):
        if not isinstance(action_space, gym.spaces.Box) or not action_space.is_bounded():
            raise ValueError(f"EpsilonNoisyPolicy needs a bounded Box action space, got {action_space}")
        epsilon, action_noise = float(epsilon), float(action_noise)
        if not 0.0 <= epsilon <= 1.0:
            raise ValueError(f"epsilon must be in [0, 1], got {epsilon}")
        if not np.isfinite(action_noise) or action_noise < 0.0:
            raise ValueError(f"action_noise must be a finite number >= 0, got {action_noise}")
        self.policy = policy
        self.action_space = action_space
        self.epsilon = epsilon
        self.action_noise = action_noise
        self._rng = np.random.default_rng(seed)

    def reset(self) -> None:
        """Reset the wrapped policy (the slip generator keeps its stream)."""
        if hasattr(self.policy, "reset"):
            self.policy.reset()

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, Any]:
        """The wrapped policy's action (plus ``action_noise``), or a random one with probability
        ``epsilon``.

        The wrapped policy is queried every step (scripted experts track their episode's
        progress through these calls), whether or not its action is used.
        """
        action, state = self.policy.predict(observation, state=state, episode_start=episode_start,
                                            deterministic=deterministic)
        low, high = self.action_space.low, self.action_space.high
        if self._rng.random() < self.epsilon:
            action = self._rng.uniform(low, high)
        elif self.action_noise > 0.0:
            noise = self._rng.normal(0.0, self.action_noise, size=np.shape(low)) * (high - low) / 2.0
            action = np.clip(np.asarray(action, np.float64) + noise, low, high)
        return np.asarray(action, dtype=self.action_space.dtype), state


def noisy_expert_policy(env: gym.Env, epsilon: float = 0.2, seed: int = 0, action_noise: float = 0.0,
                        **expert_kwargs: Any) -> EpsilonNoisyPolicy:
    """The task's scripted expert (``make_expert(env, **expert_kwargs)``) with random slips and
    Gaussian action noise (see :class:`EpsilonNoisyPolicy`)."""
    from lfd_envs.experts import make_expert

    return EpsilonNoisyPolicy(make_expert(env, **expert_kwargs), env.action_space, epsilon, seed, action_noise)
