"""How well the offline phase of an offline-then-online agent (DMfD, AWAC) fits its demonstrations.

A suite cell's DMfD takes ``offline_steps`` gradient steps on the demonstrations before its
first env step; its validation score at step 0 is the policy it starts online from. This probe
trains that offline phase alone, for several settings at a time, and scores each policy on
eval variants with the fraction of episodes in which a picker held cloth (:class:`HeldRate`),
so that an offline phase that fits the demonstrations worse than BC does can be told apart
from an online phase that forgets them.

Command line (one JSON line per variant, a table at the end)::

    python -m tools.offline_probe --suite repro-image --env ClothFoldDiagonalUnpinned-v1 \\
        --agent dmfd --variant base '{}' \\
        --variant separate '{"policy_kwargs": {"net_arch": [256, 256], "share_encoder": false}}'
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from tools.online_probe import HeldRate, add_variant_arguments, variants_and_cell


def probe_offline(cell: dict[str, Any], variants: dict[str, dict[str, Any]], *, agent_name: str = "dmfd",
                  seed: int = 0, eval_episodes: int = 10, demo_cache: Path | None = None,
                  log: Any = None) -> list[dict[str, Any]]:
    """Train the offline phase of every variant (agent keyword overrides) and score it: one record
    per variant with its mean p̂, held rate, gradient updates and training seconds."""
    from stable_baselines3.common.logger import configure

    import lfd_envs  # noqa: F401
    from lfd_bench.agents import DEFAULT_RESULTS, resolve_agent
    from lfd_bench.cell import evaluate
    from lfd_bench.demo_cache import CACHE_DIRNAME

    factory = resolve_agent(agent_name)
    base = dict(cell["agent_kwargs"])
    base.setdefault("demo_cache", str(demo_cache or DEFAULT_RESULTS / CACHE_DIRNAME))
    env = gym.make(cell["env"], **cell["env_kwargs"])
    eval_env = HeldRate(gym.make(cell["env"], **cell["env_kwargs"]))
    records = []
    for name, overrides in variants.items():
        t0 = time.perf_counter()
        agent = factory(env, seed, **{**base, **overrides})
        agent = getattr(agent, "model", agent)  # the learner inside a best-checkpoint wrapper
        agent.set_logger(configure(None, []))
        if hasattr(agent, "pretrain"):
            agent.pretrain()
        else:  # BC and other offline learners: their whole training
            agent.learn(total_timesteps=0)
        train_s = time.perf_counter() - t0
        scores = evaluate(agent, eval_env, eval_episodes, seed=0)
        rec = {"variant": name, "mean_p": round(float(np.mean(scores)), 4), **eval_env.rate(),
               "updates": int(agent._n_updates), "train_s": round(train_s, 1)}
        records.append(rec)
        if log is not None:
            print(json.dumps(rec), file=log, flush=True)
    return records


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m tools.offline_probe", description=__doc__.split("\n\n")[0])
    add_variant_arguments(p, default_agent="dmfd")
    p.add_argument("--eval-episodes", type=int, default=10)
    args = p.parse_args(argv)
    try:
        variants, cell = variants_and_cell(args)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    import torch as th

    th.set_num_threads(1)
    records = probe_offline(cell, variants, agent_name=args.agent, seed=args.seed,
                            eval_episodes=args.eval_episodes, log=sys.stdout)
    print("| variant | p̂ | held | train s |\n|---|---|---|---|")
    for r in records:
        print(f"| {r['variant']} | {r['mean_p']:.3f} | {r.get('held_rate', float('nan')):.2f} | {r['train_s']} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
