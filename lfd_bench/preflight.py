"""A minutes-long check that every cell of a suite runs, before the hours-long real run.

``python -m lfd_bench.run --suite paper-dmfd --preflight`` builds every (env, agent) pair of
the suite (first seed only) and runs it with a tiny budget: a few env steps and gradient
updates, one demonstration episode, one evaluation episode of at most ``episode_steps``
steps. Training, learning-curve and evaluation code paths all run, so a crash (a wrong
keyword, an observation space an agent cannot take) shows up here rather than hours into
the suite. The numbers it produces mean nothing and are written to a temporary folder.
"""

from __future__ import annotations

import dataclasses
import json
from typing import Any

#: per-agent kwargs that make training tiny but still take gradient steps
TINY_AGENT_KWARGS: dict[str, dict[str, Any]] = {
    "sac": {"learning_starts": 1, "batch_size": 4, "buffer_size": 1000},
    "td3": {"learning_starts": 1, "batch_size": 4, "buffer_size": 1000},
    "ppo": {"n_steps": 4, "batch_size": 4, "n_epochs": 1},
    "dmfd": {"demo_episodes": 1, "learning_starts": 0, "batch_size": 4, "buffer_size": 1000},
    "sac_lfd": {"demo_episodes": 1, "learning_starts": 0, "batch_size": 4, "buffer_size": 1000},
    "awac": {"demo_episodes": 1, "learning_starts": 0, "batch_size": 4, "buffer_size": 1000, "offline_steps": 4},
    "bc": {"demo_episodes": 1, "n_epochs": 1, "batch_size": 4},
    "drq": {"learning_starts": 1, "batch_size": 4, "buffer_size": 1000},
    "curl": {"learning_starts": 1, "batch_size": 4, "buffer_size": 1000},
    "mopa_sac": {"learning_starts": 0, "warmup_stored": 0, "batch_size": 4, "buffer_size": 1000},
    "mail": {"teacher_episodes": 1, "population": 4, "simulator_worlds": 4, "random_transitions": 8,
             "dynamics_epochs": 1, "batch_size": 4, "buffer_size": 1000},
    "nist_bc": {"n_demos": 1, "batch_size": 2},
    "nist_bc_h6": {"n_demos": 1, "batch_size": 2},
    "nist_bc_1cam": {"n_demos": 1, "batch_size": 2},
}

#: agents whose budget counts something finer than their own steps (MoPA: low-level steps, one
#: planned MoPA action may execute dozens) get this many, so that they reach a gradient update
TINY_BUDGETS: dict[str, int] = {"mopa_sac": 200}

#: any of these a suite sets is capped to this value (whatever agent it belongs to)
CAPS: dict[str, int] = {"offline_steps": 4, "n_epochs": 1, "demo_episodes": 1, "teacher_episodes": 1, "n_demos": 1,
                        "learning_starts": 1, "buffer_size": 1000, "batch_size": 4, "n_steps": 4,
                        "dynamics_epochs": 1, "random_transitions": 8, "population": 4, "simulator_worlds": 4}


def shrink(cell: Any, steps: int = 4, episode_steps: int | None = 10) -> Any:
    """A copy of ``cell`` with a tiny budget (module docstring); the suite's kwargs are kept
    except where a tiny value overrides them. ``episode_steps`` caps every episode
    (``max_episode_steps``); None keeps the env's horizon."""
    env_kwargs = dict(cell.env_kwargs)
    if episode_steps is not None:
        env_kwargs["max_episode_steps"] = int(episode_steps)
    agent_kwargs = {k: (min(v, CAPS[k]) if k in CAPS and isinstance(v, int) else v)
                    for k, v in cell.agent_kwargs.items()}
    agent_kwargs.update(TINY_AGENT_KWARGS.get(cell.agent, {}))
    return dataclasses.replace(cell, budget=max(int(steps), TINY_BUDGETS.get(cell.agent, 0)), eval_episodes=1, curve_points=1, env_kwargs=env_kwargs,
                               agent_kwargs=agent_kwargs, suite=f"{cell.suite}-preflight")


def preflight_cells(cells: list[Any], steps: int = 4, episode_steps: int | None = 10) -> list[Any]:
    """One shrunk cell per distinct (env, env kwargs, agent, agent kwargs) of ``cells``."""
    seen, out = set(), []
    for cell in cells:
        key = json.dumps([cell.env_id, cell.env_kwargs, cell.agent, cell.agent_kwargs, cell.tags.get("label")],
                         sort_keys=True, default=str)
        if key not in seen:
            seen.add(key)
            out.append(shrink(cell, steps, episode_steps))
    return out
