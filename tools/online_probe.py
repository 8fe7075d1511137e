"""What the online phase of an offline-then-online agent (DMfD, AWAC) does to its offline policy.

A suite cell trains such an agent with ``offline_steps`` gradient steps on its demonstrations and
then online; its learning curve has a few points, 5 episodes each. This probe looks at the
start of the online phase closely, for several settings at a time:

1. the agent of the cell (its env and agent settings from the suite) takes its offline steps
   once; policy and optimiser states are cached (``--cache``) so that later probes skip it;
2. for every ``--variant NAME JSON`` (agent keyword overrides; ``base`` = none) the agent is
   rebuilt with those settings, loads the offline state and runs ``--online-steps`` env steps,
   evaluated on ``--eval-episodes`` eval variants every ``--eval-every`` steps;
3. per evaluation it reports the mean p̂, the fraction of episodes in which a picker held a
   particle at the end of some step (particle tasks), the mean log-std of the actor and its
   standard deviation per action dimension, min-Q and the largest advantage weight on a
   demonstration batch and on an online batch, and at the end
   how far the actor's mean action moved, per action dimension, on demonstration and on online
   states.

Command line (one JSON line per evaluation on stdout, a table at the end; ``--out`` writes all)::

    python -m tools.online_probe --suite repro-cpu --env ClothFoldDiagonalUnpinned-v0 \\
        --label "noisy demos, state, delta" --agent dmfd --online-steps 2000 \\
        --variant base '{}' --variant demo_ratio_0.9 '{"demo_ratio": 0.9}'
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

__all__ = ["probe_cell", "find_cell", "add_cell_arguments", "add_variant_arguments", "variants_and_cell", "HeldRate"]

DEFAULT_CACHE = Path(__file__).resolve().parent.parent / "results" / "_probe"  #: offline states, reused


def find_cell(suite: dict[str, Any], env_id: str, agent: str, label: str | None = None) -> dict[str, Any]:
    """The suite cell of ``env_id`` (and ``label``) that lists ``agent``: ``{"env", "env_kwargs", "agent_kwargs"}``."""
    matches = [c for c in suite["cells"] if c["env"] == env_id and agent in c.get("agents", {})
               and (label is None or c.get("label") == label)]
    if len(matches) != 1:
        options = [(c["env"], c.get("label")) for c in suite["cells"] if agent in c.get("agents", {})]
        raise ValueError(f"{len(matches)} cells of suite {suite.get('name')!r} match env {env_id!r}, label "
                         f"{label!r} and agent {agent!r}; cells with that agent: {options}")
    from lfd_bench import recipes

    c = matches[0]
    agent_kwargs, _ = recipes.resolve(agent, dict(c["agents"][agent]))  # a recipe cell: its settings
    return {"env": env_id, "env_kwargs": dict(c.get("env_kwargs", {})), "agent_kwargs": agent_kwargs}


def _batch_stats(agent: Any, buffer: Any, name: str, n: int = 256) -> dict[str, float]:
    import torch as th

    from lfd_agents.networks import q_values

    if buffer is None or buffer.size() < n:
        return {}
    with th.no_grad():
        data = buffer.sample(n)
        loss = agent.actor_loss(data)
        q = q_values(agent.critic, data.observations, data.actions).min(dim=0).values
    return {f"{name}_q": float(q.mean()), f"{name}_max_weight": float(loss["weights"].max())}


class HeldRate(gym.Wrapper):
    """Eval-env wrapper: per episode, whether a picker held a particle at the end of any step
    (the env's ``held_particles``; pick-and-place steps end with the pickers released). On an env
    without pickers holding particles it passes steps through and :meth:`rate` is ``{}``."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.tracks = hasattr(env.unwrapped, "held_particles")
        self.episodes: list[bool] = []

    def reset(self, **kwargs: Any) -> Any:
        self.episodes.append(False)
        return self.env.reset(**kwargs)

    def step(self, action: Any) -> Any:
        out = self.env.step(action)
        if self.tracks:
            self.episodes[-1] |= bool(np.any(self.env.unwrapped.held_particles > 0))
        return out

    def rate(self) -> dict[str, float]:
        """``{"held_rate": fraction of the episodes since the last call}`` (``{}`` if none, or
        if the env has no held particles)."""
        episodes, self.episodes = self.episodes, []
        return {"held_rate": float(np.mean(episodes))} if episodes and self.tracks else {}


def _mean_drift(agent: Any, reference: Any, buffer: Any, n: int = 2000) -> list[float] | None:
    """Mean |μ_agent − μ_reference| per action dimension on ``n`` states of ``buffer``."""
    import torch as th

    if buffer is None or buffer.size() == 0:
        return None
    with th.no_grad():
        obs = buffer.sample(n).observations
        drift = (agent.actor.mean_std(obs)[0] - reference.actor.mean_std(obs)[0]).abs().mean(dim=0)
    return [round(float(x), 4) for x in drift]


def probe_cell(cell: dict[str, Any], variants: dict[str, dict[str, Any]], *, agent_name: str = "dmfd", seed: int = 0,
               online_steps: int = 2000, eval_every: int = 1000, eval_episodes: int = 10,
               cache: Path = DEFAULT_CACHE, demo_cache: Path | None = None,
               log: Any = None) -> dict[str, list[dict[str, Any]]]:
    """Run the probe (module docstring); returns ``{variant: [one record per evaluation, then the drift]}``."""
    import torch as th
    from stable_baselines3.common.logger import configure

    import lfd_envs  # noqa: F401
    from lfd_bench.agents import DEFAULT_RESULTS, resolve_agent
    from lfd_bench.demo_cache import CACHE_DIRNAME
    from lfd_bench.cell import evaluate

    if online_steps < 1 or eval_every < 1 or eval_episodes < 1:
        raise ValueError("online_steps, eval_every and eval_episodes must be >= 1")
    factory = resolve_agent(agent_name)
    base_kwargs = dict(cell["agent_kwargs"])
    if not base_kwargs.get("offline_steps"):
        raise ValueError(f"the cell's {agent_name} has no offline_steps: nothing to probe")
    base_kwargs.setdefault("demo_cache", str(demo_cache or DEFAULT_RESULTS / CACHE_DIRNAME))
    env = gym.make(cell["env"], **cell["env_kwargs"])
    eval_env = HeldRate(gym.make(cell["env"], **cell["env_kwargs"]))
    key = hashlib.sha256(json.dumps([cell, agent_name, seed], sort_keys=True).encode()).hexdigest()[:16]
    path = Path(cache) / f"offline_{key}.pt"

    def build(overrides: dict[str, Any]) -> Any:
        agent = factory(env, seed, **{**base_kwargs, **overrides, "offline_steps": 0})
        agent.set_logger(configure(None, []))
        return agent

    if not path.exists():
        agent = factory(env, seed, **base_kwargs)
        agent.set_logger(configure(None, []))
        agent.learn(total_timesteps=0)  # the offline steps only
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        th.save(agent.get_parameters(), tmp)  # policy and optimiser states (SB3)
        tmp.replace(path)
    offline = th.load(path)
    reference = build({})
    reference.set_parameters(offline)
    out: dict[str, list[dict[str, Any]]] = {}
    for name, overrides in variants.items():
        agent = build(overrides)
        agent.set_parameters(offline)
        records, done = [], 0
        while True:
            scores = evaluate(agent, eval_env, eval_episodes, seed=0)
            held = eval_env.rate()
            rec = {"variant": name, "online_steps": done, "mean_p": round(float(np.mean(scores)), 4),
                   **{k: round(v, 4) for k, v in held.items()},
                   "log_std": round(float(agent.actor.log_std().detach().mean()), 4),
                   "std_per_dim": [round(float(x), 4) for x in agent.actor.log_std().detach().exp().broadcast_to(
                       agent.action_space.shape)],
                   **{k: round(v, 4) for k, v in {**_batch_stats(agent, agent.demo_buffer, "demo"),
                                                   **_batch_stats(agent, agent.replay_buffer, "online")}.items()}}
            records.append(rec)
            if log is not None:
                print(json.dumps(rec), file=log, flush=True)
            if done >= online_steps:
                break
            step = min(eval_every, online_steps - done)
            agent.learn(step, reset_num_timesteps=done == 0)
            done += step
        records.append({"variant": name, "mean_action_drift_demo_states": _mean_drift(agent, reference, agent.demo_buffer),
                        "mean_action_drift_online_states": _mean_drift(agent, reference, agent.replay_buffer)})
        if log is not None:
            print(json.dumps(records[-1]), file=log, flush=True)
        out[name] = records
    return out


def add_cell_arguments(parser: argparse.ArgumentParser, default_agent: str) -> None:
    """``--suite --env --label --agent --seed``: the options that pick a cell's learner (:func:`find_cell`)."""
    parser.add_argument("--suite", required=True)
    parser.add_argument("--env", required=True)
    parser.add_argument("--label", help="the cell's label (when several cells have the env)")
    parser.add_argument("--agent", default=default_agent)
    parser.add_argument("--seed", type=int, default=0)


def add_variant_arguments(parser: argparse.ArgumentParser, default_agent: str) -> None:
    """:func:`add_cell_arguments` and ``--variant NAME JSON`` (repeatable): the settings to compare
    on the cell (:func:`variants_and_cell` reads them)."""
    add_cell_arguments(parser, default_agent)
    parser.add_argument("--variant", nargs=2, action="append", metavar=("NAME", "JSON"),
                        help="agent keyword overrides for one variant (repeatable; default: base '{}')")


def variants_and_cell(args: argparse.Namespace) -> tuple[dict[str, dict[str, Any]], dict[str, Any]]:
    """The ``--variant`` overrides by name and the cell that :func:`add_variant_arguments`' options
    pick; a malformed variant or an unknown cell is a ``ValueError``."""
    from lfd_bench.run import load_suite

    try:
        variants = {name: json.loads(text) for name, text in (args.variant or [("base", "{}")])}
    except json.JSONDecodeError as exc:
        raise ValueError(f"a --variant JSON does not parse: {exc}") from exc
    if not all(isinstance(v, dict) for v in variants.values()):
        raise ValueError("every --variant JSON must be an object of agent keywords")
    return variants, find_cell(load_suite(args.suite), args.env, args.agent, args.label)


def _table(results: dict[str, list[dict[str, Any]]]) -> str:
    steps = sorted({r["online_steps"] for recs in results.values() for r in recs if "online_steps" in r})
    lines = ["| variant | " + " | ".join(f"p̂ @{s}" for s in steps) + " |", "|---" * (len(steps) + 1) + "|"]
    for name, recs in results.items():
        by_step = {r["online_steps"]: r["mean_p"] for r in recs if "online_steps" in r}
        lines.append(f"| {name} | " + " | ".join(f"{by_step[s]:.3f}" if s in by_step else "—" for s in steps) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m tools.online_probe", description=__doc__.split("\n\n")[0])
    add_variant_arguments(p, default_agent="dmfd")
    p.add_argument("--online-steps", type=int, default=2000)
    p.add_argument("--eval-every", type=int, default=1000)
    p.add_argument("--eval-episodes", type=int, default=10)
    p.add_argument("--cache", type=Path, default=DEFAULT_CACHE)
    p.add_argument("--out", type=Path, help="write all records as JSON here")
    args = p.parse_args(argv)
    try:
        variants, cell = variants_and_cell(args)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    import torch as th

    th.set_num_threads(1)
    results = probe_cell(cell, variants, agent_name=args.agent, seed=args.seed, online_steps=args.online_steps,
                         eval_every=args.eval_every, eval_episodes=args.eval_episodes, cache=args.cache, log=sys.stdout)
    print(_table(results))
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
