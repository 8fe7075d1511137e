"""Step by step, what a cell's learner does beside the demonstrator it learnt from.

A learning curve says that a policy fails, not where. This tool trains the learner of a suite
cell the way the cell does before any env step (BC: all its epochs; DMfD and AWAC: only their
offline steps on the demonstrations, the policy their online phase starts from), then plays the
same eval variants with it and with the cell's demonstrator (``demo_policy`` with
``demo_policy_kwargs``), printing for every step the action, the first picker's position and how
many particles the pickers hold (particle tasks; ``-`` elsewhere)::

    python -m tools.trace_policy --suite repro-cpu-v1 --env ClothFoldDiagonalUnpinned-v1 \\
        --label "state, delta, half-speed expert, learning rate 1e-3, isotropic fit" \\
        --agent dmfd --seed 2 --variants 0 1 --steps 40

``--load PATH`` skips the training and loads the learner's parameters from a file saved with
``agent.get_parameters()`` (the offline states that ``tools.online_probe`` caches in
``results/_probe``), so a policy the probe measured can be traced as it was.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["trace_episode", "train_learner", "demonstrator"]


def trace_episode(env: Any, policy: Any, variant: int, steps: int, seed: int = 0) -> list[dict[str, Any]]:
    """Play eval ``variant`` with ``policy`` for at most ``steps`` steps; one row per step:
    ``{"step", "action", "picker", "held", "p"}`` (picker and held are None without pickers)."""
    from lfd_envs.core.rollout import episode_steps

    obs, _ = env.reset(seed=seed, options={"split": "eval", "variant": int(variant)})
    if hasattr(policy, "reset"):
        policy.reset()
    base, rows = env.unwrapped, []
    for t, step in enumerate(episode_steps(env, policy, obs)):
        pickers = getattr(base, "picker_positions", None)
        held = getattr(base, "held_particles", None)
        rows.append({"step": t, "action": np.round(np.asarray(step.action, float), 3).tolist(),
                     "picker": None if pickers is None else np.round(pickers[0], 4).tolist(),
                     "held": None if held is None else int(np.sum(held)),
                     "p": round(float(step.info.get("normalized_performance", float("nan"))), 4)})
        if t + 1 >= steps:
            break
    return rows


def train_learner(env: Any, agent_name: str, agent_kwargs: dict[str, Any], seed: int, load: str | None = None) -> Any:
    """The cell's learner after what it learns before any env step (see the module docstring),
    or, with ``load``, built untrained and given the parameters saved in that file."""
    from stable_baselines3.common.logger import configure

    from lfd_bench.agents import DEFAULT_RESULTS, resolve_agent
    from lfd_bench.demo_cache import CACHE_DIRNAME

    kwargs = {"demo_cache": str(DEFAULT_RESULTS / CACHE_DIRNAME), **agent_kwargs}
    if load is not None and "offline_steps" in kwargs:
        kwargs["offline_steps"] = 0  # the loaded parameters replace them
    agent = resolve_agent(agent_name)(env, seed, **kwargs)
    if load is not None:
        import torch as th

        agent.set_parameters(th.load(load))
        return agent
    if hasattr(agent, "set_logger"):
        agent.set_logger(configure(None, []))
    agent.learn(total_timesteps=0)  # BC: its epochs; DMfD / AWAC: the offline steps only
    return agent


def demonstrator(env: Any, agent_kwargs: dict[str, Any], seed: int = 0) -> Any:
    """The cell's demonstrator: ``demo_policy`` (default the scripted expert) with ``demo_policy_kwargs``."""
    from lfd_envs.datasets import make_policy

    return make_policy(env, agent_kwargs.get("demo_policy", "expert"), seed,
                       **dict(agent_kwargs.get("demo_policy_kwargs") or {}))


def _format(row: dict[str, Any]) -> str:
    held = "-" if row["held"] is None else str(row["held"])
    return f"{row['step']:3d}  action {row['action']}  picker {row['picker']}  held {held}  p {row['p']:.3f}"


def main(argv: list[str] | None = None) -> int:
    import gymnasium as gym
    import torch as th

    import lfd_envs  # noqa: F401
    from tools.online_probe import add_cell_arguments, find_cell
    from lfd_bench.run import load_suite

    p = argparse.ArgumentParser(prog="python -m tools.trace_policy", description=__doc__.split("\n\n")[0])
    add_cell_arguments(p, default_agent="bc")
    p.add_argument("--variants", type=int, nargs="+", default=[0])
    p.add_argument("--steps", type=int, default=40)
    p.add_argument("--load", help="parameters saved with agent.get_parameters() (e.g. an online_probe offline state)")
    args = p.parse_args(argv)
    try:
        if args.steps < 1 or min(args.variants) < 0:
            raise ValueError("--steps must be >= 1 and --variants >= 0")
        if args.load is not None and not Path(args.load).is_file():
            raise ValueError(f"--load {args.load!r} is not a file")
        cell = find_cell(load_suite(args.suite), args.env, args.agent, args.label)
        env = gym.make(cell["env"], **cell["env_kwargs"])
        shown = demonstrator(env, cell["agent_kwargs"])
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    th.set_num_threads(1)
    agent = train_learner(env, args.agent, cell["agent_kwargs"], args.seed, args.load)
    for variant in args.variants:
        for name, policy in ((args.agent, agent), ("demonstrator", shown)):
            print(f"== eval variant {variant}: {name}")
            for row in trace_episode(env, policy, variant, args.steps):
                print(_format(row))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
