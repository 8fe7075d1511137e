"""What a cell actually spent: env steps, gradient updates and demonstration transitions.

The suite's ``budget`` is a request; agents spend it differently (BC ignores it and runs epochs
over its dataset, MoPA counts low-level steps, NIST BC counts gradient steps). The harness
wraps the training env in :class:`StepCounter` and reads the rest from the agent after
training, so the leaderboard shows what each row cost. Steps an agent takes in envs it makes
itself (MAIL's CEM on a batched simulator) are not counted; the validation episodes of a
checkpoint selection are.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym


class StepCounter(gym.Wrapper):
    """Counts every ``step`` the agent takes in its training env (resets are not steps)."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        self.env_steps = 0

    def step(self, action: Any):
        self.env_steps += 1
        return self.env.step(action)


def _inner_models(agent: Any) -> list[Any]:
    """``agent`` and the learner objects it wraps (MoPA / MAIL keep an SB3 model in ``.model``)."""
    found, todo = [], [agent]
    while todo:
        obj = todo.pop()
        if obj is None or any(obj is f for f in found):
            continue
        found.append(obj)
        todo.append(getattr(obj, "model", None))
    return found


def gradient_updates(agent: Any) -> int:
    """Optimiser steps taken by ``agent`` (SB3's ``_n_updates``; NIST BC's gradient steps)."""
    from lfd_agents.nist_bc import NistBC

    total = 0
    for obj in _inner_models(agent):
        if isinstance(obj, NistBC):
            total += int(obj.num_timesteps)
        elif isinstance(getattr(obj, "_n_updates", None), int):
            total += int(obj._n_updates)
    return total


def demo_transitions(agent: Any) -> int:
    """Demonstration transitions ``agent`` learnt from (0 if it uses none)."""
    from lfd_agents.nist_bc import NistBC

    n = getattr(agent, "demo_transitions", None)
    if isinstance(n, int):
        return n
    if isinstance(agent, NistBC):
        data = getattr(agent, "_data", None)
        return int(len(data["labels"])) if data else 0
    if type(agent).__name__ == "MAILAgent" and getattr(agent, "mail", None) is not None:
        from lfd_agents.demos import load_episodes

        return int(sum(len(ep) for ep in load_episodes(str(agent.teacher_dataset()))))
    return 0


def env_steps(agent: Any, train_env: StepCounter) -> int:
    """Simulator steps of training: the counter's, or a MoPA wrapper's ``low_level_steps`` (it
    executes planned paths on the task env directly, past the counter), plus the steps of an
    agent's checkpoint-selection episodes (``validation_env_steps``)."""
    n = int(train_env.env_steps)
    validation = 0
    for obj in _inner_models(agent):
        low = getattr(getattr(obj, "train_env", None), "low_level_steps", None)
        if isinstance(low, int):
            n = max(n, low)
        extra = getattr(obj, "validation_env_steps", None)
        if isinstance(extra, int):
            validation += extra
    return n + validation


def spent(agent: Any, train_env: StepCounter) -> dict[str, Any]:
    """The three budget numbers recorded in every cell's JSON, plus the demonstrations' mean final
    p̂ (``demo_performance``) for agents that learnt from harness-collected demonstrations."""
    out: dict[str, Any] = {"env_steps": env_steps(agent, train_env), "gradient_updates": gradient_updates(agent),
                           "demo_transitions": demo_transitions(agent)}
    quality = getattr(agent, "demo_performance", None)
    if isinstance(quality, float):
        out["demo_performance"] = quality
    return out
