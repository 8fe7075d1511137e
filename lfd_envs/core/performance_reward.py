"""SoftGym's reward convention as a wrapper: the task's performance at every step, scaled.

The suite's envs reward the *change* of performance during a step (the rewards of an episode
sum to its improvement). SoftGym's envs reward the performance itself at every step, and
SoftAgent / DMfD train their RL baselines on it multiplied by ``scale_reward`` (50 for cloth
and rope). Under that convention a policy is paid every step for the state it keeps, not only
for the step that improves it, which gives an off-policy learner's critic a much larger signal
per transition::

    env = PerformanceReward(gym.make("lfd_envs:StraightenRope-v0", obs_mode="state"), scale=50)

:func:`performance_rewards` gives demonstration episodes (collected with the suite's own
rewards) the same convention from the per-step ``performance`` their infos record.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from lfd_envs.core.errors import check_float

__all__ = ["PerformanceReward", "performance_rewards"]


def _check_scale(scale: Any) -> float:
    value = check_float("scale", scale, 0.0)
    if value == 0.0:
        raise ValueError(f"scale must be > 0, got {scale!r}")
    return value


class PerformanceReward(gym.Wrapper):
    """Reward = ``scale`` × ``info["performance"]`` after every step (SoftGym's convention).

    Args:
        env: an env whose step ``info`` has ``performance`` (every lfd_envs task).
        scale: reward multiplier (SoftAgent / DMfD: 50 for cloth and rope, 20 for water).
    """

    def __init__(self, env: gym.Env, scale: float = 1.0) -> None:
        super().__init__(env)
        self.scale = _check_scale(scale)

    def step(self, action: Any):
        obs, _, terminated, truncated, info = self.env.step(action)
        if "performance" not in info:
            raise KeyError(f"PerformanceReward needs info['performance'] from {self.env}; this env has none")
        return obs, self.scale * float(info["performance"]), terminated, truncated, info


def performance_rewards(performance: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """Rewards of an episode under :class:`PerformanceReward` from its per-step performance.

    ``performance`` holds T+1 values (the reset state's, then one after each step, as
    ``lfd_envs.datasets`` records them in ``infos["performance"]``); returns T rewards.
    """
    perf = np.asarray(performance, dtype=np.float64).reshape(-1)
    if perf.size < 2:
        raise ValueError(f"performance needs T+1 >= 2 values (reset state and each step), got {perf.size}")
    return _check_scale(scale) * perf[1:]
