"""The episode loop: a policy acting in an env until the episode ends.

A policy is anything with SB3's ``predict(obs, deterministic=True) -> (action, state)`` (agents,
experts) and optionally ``reset()`` (called at the start of an episode). Evaluations, expert
benchmarks and demonstration recorders share these helpers instead of writing the loop again::

    info = play_episode(env, expert, seed=0, options={"split": "eval", "variant": 3})
    info["normalized_performance"]

    obs, _ = env.reset(seed=0)
    for step in episode_steps(env, policy, obs):   # per-step access (recording, checks)
        ...
"""

from __future__ import annotations

from typing import Any, Iterator, NamedTuple

import gymnasium as gym


class Step(NamedTuple):
    """One env step of :func:`episode_steps`: the action taken and what ``env.step`` returned."""

    action: Any
    obs: Any
    reward: float
    terminated: bool
    truncated: bool
    info: dict[str, Any]


def episode_steps(env: gym.Env, policy: Any, obs: Any) -> Iterator[Step]:
    """Act with ``policy.predict(obs, deterministic=True)`` from observation ``obs`` (the env's
    current one) until the episode is terminated or truncated, yielding every :class:`Step`."""
    done = False
    while not done:
        action, _ = policy.predict(obs, deterministic=True)
        obs, reward, terminated, truncated, info = env.step(action)
        done = terminated or truncated
        yield Step(action, obs, reward, terminated, truncated, info)


def finish_episode(env: gym.Env, policy: Any, obs: Any) -> dict[str, Any]:
    """Play the rest of the episode from observation ``obs`` (at least one step); return the
    final info."""
    info: dict[str, Any] = {}
    for step in episode_steps(env, policy, obs):
        info = step.info
    return info


def play_episode(env: gym.Env, policy: Any, *, seed: int | None = None,
                 options: dict[str, Any] | None = None) -> dict[str, Any]:
    """Reset ``env`` (``seed``, ``options``) and ``policy`` (if it has ``reset``), play one
    episode with :func:`episode_steps` and return its final info."""
    obs, _ = env.reset(seed=seed, options=options)
    if hasattr(policy, "reset"):
        policy.reset()
    return finish_episode(env, policy, obs)


__all__ = ["Step", "episode_steps", "finish_episode", "play_episode"]
