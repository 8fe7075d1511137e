"""Keeps ``gymnasium.make``'s ``TimeLimit`` at the env's own horizon.

The MuJoCo ids are registered with ``max_episode_steps`` = the horizon of their default
configuration, so ``gym.spec(id).max_episode_steps`` and ``gym.make(id).spec.max_episode_steps``
tell tools the episode length. The horizon also depends on the arguments (``horizon=``), and the
env truncates its episodes itself. :class:`MatchHorizon` is registered as an additional wrapper
(``gymnasium.make`` applies it right outside its ``TimeLimit``) and sets that ``TimeLimit`` to the
env's horizon, so both truncate at the same step; a ``max_episode_steps`` passed to
``gymnasium.make`` explicitly is kept. (Particle ids cannot have additional wrappers, see
:func:`lfd_envs.registration.register_all`.)
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
from gymnasium.envs.registration import WrapperSpec
from gymnasium.wrappers import TimeLimit


class MatchHorizon(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Sets the ``TimeLimit`` it wraps (if any) to ``env.unwrapped.horizon`` unless that limit
    was chosen explicitly (differs from the registered ``max_episode_steps``). Otherwise a
    pass-through wrapper."""

    def __init__(self, env: gym.Env) -> None:
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.Wrapper.__init__(self, env)
        horizon = getattr(env.unwrapped, "horizon", None)
        if isinstance(env, TimeLimit) and isinstance(horizon, int) and self._registered_limit(env) in (
                None, env._max_episode_steps):
            env._max_episode_steps = horizon

    @staticmethod
    def _registered_limit(env: gym.Env) -> Any:
        spec = env.unwrapped.spec
        if spec is None or spec.id not in gym.registry:
            return None
        return gym.registry[spec.id].max_episode_steps


class GoalMatchHorizon(MatchHorizon):
    """:class:`MatchHorizon` of a goal env: ``compute_reward``, ``compute_terminated`` and
    ``compute_truncated`` of the env are reachable on the wrapper (SB3's ``check_env`` and
    ``HerReplayBuffer`` call them on the env they are given)."""

    def compute_reward(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """The unwrapped env's ``compute_reward``."""
        return self.env.unwrapped.compute_reward(achieved_goal, desired_goal, info)

    def compute_terminated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """The unwrapped env's ``compute_terminated``."""
        return self.env.unwrapped.compute_terminated(achieved_goal, desired_goal, info)

    def compute_truncated(self, achieved_goal: Any, desired_goal: Any, info: Any) -> Any:
        """The unwrapped env's ``compute_truncated``."""
        return self.env.unwrapped.compute_truncated(achieved_goal, desired_goal, info)


def match_horizon(env: gym.Env) -> MatchHorizon:
    """:class:`GoalMatchHorizon` for envs with ``compute_reward``, else :class:`MatchHorizon`."""
    if hasattr(env.unwrapped, "compute_reward"):
        return GoalMatchHorizon(env)
    return MatchHorizon(env)


#: the wrapper spec used at registration
MATCH_HORIZON = WrapperSpec("MatchHorizon", f"{__name__}:match_horizon", {})

__all__ = ["MatchHorizon", "GoalMatchHorizon", "match_horizon", "MATCH_HORIZON"]
