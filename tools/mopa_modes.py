"""What MoPA-SAC's actions do while it trains: ``python -m tools.mopa_modes [--steps N]``.

Trains MoPA-SAC (:class:`lfd_agents.mopa.MoPAAgent`, the harness's ``mopa_sac``) on one task and
reports, per window of low-level env steps, how many decisions the policy took, how they were
executed (``direct``, ``interpolation``, ``planner``, or held still: ``failed`` /
``invalid_target``), how many low-level steps a decision lasted on average and how many
decisions earned reward (on Push2D also the closest the fingertip came to the box at the end of
a decision; the reward starts within 0.1 m), plus the entropy coefficient at the end. A
warm-up longer than the run (``--learning-starts 1000000``) measures uniform-random MoPA
exploration. A policy that keeps moving the arm by planned paths lasts about ten low-level steps
per decision; one that turns to targets it cannot reach lasts one.

Usage::

    python -m tools.mopa_modes [--env Push2DObstacle-v0] [--steps 20000] [--window 5000]
        [--learning-starts 100] [--seed 0] [--update-per-stored] [--schedule sb3] [--planner suite]

``--update-per-stored`` trains with MoPA-RL's update schedule (one gradient step per stored
transition, reused path segments included) instead of SB3's one per decision; ``--schedule
mopa-rl`` with all of ``MOPA_RL_SCHEDULE`` (warm-up of 10k stored transitions, those updates,
timeouts stored as done: the harness's ``mopa_sac``). ``--planner mopa-rl`` plans with MoPA-RL's
search limit and validity checks (below) instead of the task's ``MOPA_DEFAULTS``.

``--speed`` measures instead how fast MoPA-SAC learns with two planner settings, in alternating
rounds of the same run (each round a fresh agent with the same seed): ``mopa-rl`` (MoPA-RL's
1 s time limit per OMPL search, every validity check copying the live state) and ``suite`` (the
task's ``MOPA_DEFAULTS``: a budget of validity checks per search, one scene snapshot per query).
Where the budget is above every successful search, as on Push2D, both runs take the same
decisions with the same outcomes (same ``decisions`` and ``failed_share``) unless a search hits
the 1 s limit on a loaded machine, so only their cost differs. It prints the low-level env steps
per second of ``learn``, the share of wall time spent planning and the share of failed
decisions, median over ``--rounds``; ``--schedule sb3`` (SB3's warm-up of 100 decisions
and one update per decision, the settings of the first ``repro-mopa`` cells) or ``mopa-rl``
(``MOPA_RL_SCHEDULE``)::

    python -m tools.mopa_modes --speed [--steps 5000] [--rounds 2] [--schedule sb3]
"""

from __future__ import annotations

import argparse
import collections
import os
import time
from typing import Any

import numpy as np


#: wrapper settings of ``--planner mopa-rl``: MoPA-RL's 1 s per OMPL search, every validity check
#: copying the live state (``suite``: the task's ``MOPA_DEFAULTS``, a check budget and one scene
#: snapshot per query); everything else as the task's defaults
MOPA_RL_PLANNER = {"time_limit": 1.0, "planner_kwargs": {"max_checks": None, "snapshot_scene": False}}
#: agent settings of ``--schedule sb3`` (``mopa-rl``: ``MOPA_RL_SCHEDULE``, the harness's default)
SB3_SCHEDULE = {"warmup_stored": 0, "update_per_stored": False, "timeouts_as_done": False, "learning_starts": 100}


def _settings(planner: str, schedule: str) -> tuple[dict[str, Any], dict[str, Any]]:
    """(wrapper kwargs, agent kwargs) of MoPAAgent for a planner and a schedule name."""
    if planner not in ("mopa-rl", "suite") or schedule not in ("sb3", "mopa-rl"):
        raise ValueError(f"planner must be 'mopa-rl' or 'suite' and schedule 'sb3' or 'mopa-rl', "
                         f"got {planner!r}, {schedule!r}")
    wrapper = {**MOPA_RL_PLANNER, "planner_kwargs": dict(MOPA_RL_PLANNER["planner_kwargs"])} if planner == "mopa-rl" \
        else {}
    return wrapper, dict(SB3_SCHEDULE) if schedule == "sb3" else {}


def mode_rows(env_id: str = "Push2DObstacle-v0", steps: int = 20_000, window: int = 5000, learning_starts: int = 100,
              seed: int = 0, update_per_stored: bool = False, planner: str = "suite", schedule: str = "sb3"
              ) -> tuple[list[dict[str, Any]], float]:
    """Per-window rows (decisions, share of each mode, low-level steps per decision, rewarded
    decisions, gradient updates so far and, on Push2D, the closest fingertip-box distance) of one
    MoPA-SAC training run, and the final entropy coefficient. With ``schedule="sb3"``,
    ``learning_starts`` and ``update_per_stored`` set the warm-up and updates."""
    import gymnasium as gym
    from stable_baselines3.common.callbacks import BaseCallback

    import lfd_envs  # noqa: F401  (registers the ids)
    from lfd_agents.mopa import MoPAAgent
    from lfd_agents.mopa.wrapper import MOPA_MODES

    wrapper_kwargs, agent_kwargs = _settings(planner, schedule)
    if schedule == "sb3":
        agent_kwargs.update(learning_starts=learning_starts, update_per_stored=update_per_stored)
    agent = MoPAAgent(gym.make(env_id), seed=seed, wrapper_kwargs=wrapper_kwargs, **agent_kwargs)
    counts: dict[int, collections.Counter] = collections.defaultdict(collections.Counter)
    task = agent.train_env.unwrapped
    push2d = hasattr(task, "fingertip_xy") and hasattr(task, "box_xy")  # then: how close the arm came

    class Record(BaseCallback):
        def _on_step(self) -> bool:
            info = self.locals["infos"][0]
            c = counts[(agent.train_env.low_level_steps - 1) // window]
            c[info["mopa_mode"]] += 1
            c["decisions"] += 1
            c["low_level"] += int(info["mopa_k"])
            c["rewarded"] += int(float(self.locals["rewards"][0]) > 0)
            c["updates"] = agent.model._n_updates
            if push2d:
                d = float(np.linalg.norm(task.fingertip_xy() - task.box_xy()))
                c["closest"] = min(c.get("closest", np.inf), d)
            return True

    agent.learn(steps, callback=Record())
    rows = []
    for w in sorted(counts):
        c = counts[w]
        n = max(c["decisions"], 1)
        rows.append({"steps": f"{w * window}-{(w + 1) * window}", "decisions": c["decisions"],
                     **{m: round(c[m] / n, 3) for m in MOPA_MODES},
                     "steps_per_decision": round(c["low_level"] / n, 2), "rewarded_decisions": c["rewarded"],
                     "updates_so_far": c["updates"],
                     **({"closest_to_box_m": round(c["closest"], 3)} if "closest" in c else {})})
    log_ent = getattr(agent.model, "log_ent_coef", None)
    ent = float(log_ent.detach().exp()) if log_ent is not None else float(agent.model.ent_coef)
    return rows, ent


def _speed_run(env_id: str, steps: int, seed: int, wrapper_kwargs: dict[str, Any], agent_kwargs: dict[str, Any]
               ) -> dict[str, float]:
    import gymnasium as gym

    import lfd_envs  # noqa: F401  (registers the ids)
    from lfd_agents.mopa import MoPAAgent

    agent = MoPAAgent(gym.make(env_id), seed=seed, wrapper_kwargs=wrapper_kwargs, **agent_kwargs)
    t0 = time.perf_counter()
    agent.learn(steps)
    wall = time.perf_counter() - t0
    wrapper = agent.train_env
    decisions = max(sum(wrapper.stats.values()), 1)
    failed = wrapper.stats["failed"] + wrapper.stats["invalid_target"]
    return {"low_level_steps_per_s": wrapper.low_level_steps / wall, "decisions": decisions,
            "planning_share": wrapper.planner.stats["time"] / wall, "failed_share": failed / decisions,
            "updates": agent.model._n_updates}


def speed_rows(env_id: str = "Push2DObstacle-v0", steps: int = 5000, rounds: int = 2, seed: int = 0,
               schedule: str = "sb3") -> list[dict[str, Any]]:
    """Median learning speed of MoPA-SAC with MoPA-RL's and the suite's planner settings
    (module docstring), measured in alternating rounds."""
    runs: dict[str, list[dict[str, float]]] = {name: [] for name in ("mopa-rl", "suite")}
    for _ in range(rounds):
        for name in runs:
            runs[name].append(_speed_run(env_id, steps, seed, *_settings(name, schedule)))
    rows = []
    for name, results in runs.items():
        row = {"planner": name, "schedule": schedule}
        for key in results[0]:
            row[key] = round(float(np.median([r[key] for r in results])), 3 if "share" in key else 1)
        rows.append(row)
    base = rows[0]["low_level_steps_per_s"]
    for row in rows:
        row["vs_mopa_rl"] = round(row["low_level_steps_per_s"] / base, 2)
    return rows


def _print(rows: list[dict[str, Any]]) -> None:
    keys = list(rows[0]) if rows else []
    print("| " + " | ".join(keys) + " |\n|" + "---|" * len(keys))
    for r in rows:
        print("| " + " | ".join(str(r[k]) for k in keys) + " |")


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(prog="python -m tools.mopa_modes", description=__doc__.split("\n")[0])
    p.add_argument("--env", default="Push2DObstacle-v0")
    p.add_argument("--steps", type=int, default=None, help="low-level env steps of training (20000; --speed: 5000)")
    p.add_argument("--window", type=int, default=5000, help="low-level steps per row")
    p.add_argument("--learning-starts", type=int, default=100, help="uniform-random warm-up, in decisions")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--update-per-stored", action="store_true", help="MoPA-RL's update schedule")
    p.add_argument("--speed", action="store_true", help="learning speed with MoPA-RL's and the suite's planner")
    p.add_argument("--rounds", type=int, default=2, help="--speed: alternating rounds per setting")
    p.add_argument("--schedule", choices=("sb3", "mopa-rl"), default="sb3",
                   help="sb3: --learning-starts and --update-per-stored; mopa-rl: MoPA-RL's warm-up, updates, timeouts")
    p.add_argument("--planner", choices=("suite", "mopa-rl"), default="suite",
                   help="suite: the task's MOPA_DEFAULTS; mopa-rl: 1 s per OMPL query, no check budget")
    p.add_argument("--threads", type=int, default=None,
                   help="torch CPU threads (default: torch's; --speed: 1, as the harness runs a cell)")
    args = p.parse_args(argv)
    threads = args.threads or (1 if args.speed else None)
    if threads:
        import torch as th

        th.set_num_threads(threads)
    t0 = time.perf_counter()
    if args.speed:
        steps = args.steps or 5000
        rows = speed_rows(args.env, steps, args.rounds, args.seed, args.schedule)
        print(f"MoPA-SAC on {args.env}, seed {args.seed}, {steps} low-level steps per run, {args.rounds} rounds, "
              f"schedule {args.schedule}, load average {os.getloadavg()[0]:.2f}\n")
        _print(rows)
        print(f"\n{time.perf_counter() - t0:.0f} s")
        return
    args.steps = args.steps or 20_000
    rows, ent = mode_rows(args.env, args.steps, args.window, args.learning_starts, args.seed, args.update_per_stored,
                          args.planner, args.schedule)
    schedule = "one update per stored transition" if args.update_per_stored else "one update per decision"
    schedule = (f"warm-up {args.learning_starts} decisions, {schedule}" if args.schedule == "sb3"
                else "MoPA-RL's schedule")
    print(f"MoPA-SAC on {args.env}, seed {args.seed}, {schedule}, {args.planner} planner, {args.steps} steps\n")
    _print(rows)
    print(f"\nentropy coefficient at the end: {ent:.4f}; {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
