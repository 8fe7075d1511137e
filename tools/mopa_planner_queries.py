"""Fixed, seeded sets of MoPA planner queries, replayed under different planner settings.

Diagnostic (not installed): ``python tools/mopa_planner_queries.py collect --out Q.pkl
[--source random|learning] [--queries N] [--seed S]`` records the planner queries whose straight
line is blocked (the ones that reach OMPL) on ``Push2DObstacle-v0``: the env state, start and
goal of each, from uniform-random MoPA actions (the warm-up) or from a MoPA-SAC training run
with the settings of the first ``repro-mopa`` cells (SB3's schedule, MoPA-RL's 1 s planner). ``python tools/mopa_planner_queries.py replay Q.pkl
--time-limit 1.0 0.3 ...`` replays every query with each time limit (same planner seed, same
query order) and prints the success rate, the total and per-query planning time, and
percentiles of the successful queries' solve times and validity-check counts. ``--max-checks``
replays with a check budget (one row per budget, ``0`` for none) and ``--no-snapshot`` with
the live-state validity check of every configuration (the planner before the scene snapshot).
``python tools/mopa_planner_queries.py compare Q.pkl`` replays every query with MoPA-RL's
settings (1 s, no budget, no snapshot) and with the task's ``MOPA_DEFAULTS``, one after the
other, so both see the same machine load, and prints both rows.
"""

from __future__ import annotations

import argparse
import pickle
import time
from typing import Any

import numpy as np


def collect(source: str = "random", queries: int = 200, seed: int = 0, env_id: str = "Push2DObstacle-v0",
            out_path: str | None = None) -> list[dict[str, Any]]:
    """Planner queries (env state, start, goal) whose straight line is blocked (written to
    ``out_path`` after every 10, so a stopped collection keeps what it has)."""
    import gymnasium as gym

    import lfd_envs  # noqa: F401
    from lfd_agents.mopa import MoPAAgent, make_mopa_env

    out: list[dict[str, Any]] = []
    if source == "learning":  # the first repro-mopa cells' settings: SB3's schedule, MoPA-RL's planner
        from tools.mopa_modes import _settings

        wrapper_kwargs, agent_kwargs = _settings("mopa-rl", "sb3")
        agent = MoPAAgent(gym.make(env_id), seed=seed, wrapper_kwargs=wrapper_kwargs, **agent_kwargs)
        wrapper = agent.train_env
    else:
        wrapper = make_mopa_env(env_id, planner_kwargs={"seed": seed})
    base, planner = wrapper.unwrapped, wrapper.planner
    plan = planner.plan

    def recording_plan(start, goal, time_limit=None):
        state = base.get_state()
        blocked = planner.interpolate(planner.clip(start), planner.clip(goal)) is None
        result = plan(start, goal, time_limit)
        if blocked and len(out) < queries:
            out.append({"state": state, "start": np.array(start), "goal": np.array(goal), "status": result.status})
            if out_path is not None and len(out) % 10 == 0:
                with open(out_path, "wb") as f:
                    pickle.dump(out, f)
        return result

    planner.plan = recording_plan
    if source == "learning":
        from stable_baselines3.common.callbacks import BaseCallback

        class Stop(BaseCallback):
            def _on_step(self) -> bool:
                return len(out) < queries

        agent.learn(10**7, callback=Stop())
    else:
        rng = np.random.default_rng(seed)
        wrapper.reset(seed=seed)
        while len(out) < queries:
            _, _, term, trunc, _ = wrapper.step(rng.uniform(-1, 1, wrapper.action_space.shape))
            if term or trunc:
                wrapper.reset()
    return out


def replay(queries: list[dict[str, Any]], time_limit: float, seed: int = 0, env_id: str = "Push2DObstacle-v0",
           max_checks: int | None = None, snapshot_scene: bool = True, motion_resolution: float | None = None
           ) -> dict[str, Any]:
    """Success rate, timing and check counts of ``queries`` under one planner setting."""
    import gymnasium as gym

    import lfd_envs  # noqa: F401
    from lfd_agents.mopa import make_mopa_env

    kw = {"seed": seed, "max_checks": max_checks, "snapshot_scene": snapshot_scene,
          "motion_resolution": motion_resolution}
    wrapper = make_mopa_env(gym.make(env_id), time_limit=time_limit, planner_kwargs=kw)
    wrapper.reset(seed=0)
    base, planner = wrapper.unwrapped, wrapper.planner
    times, ok, checks = [], [], []
    for q in queries:
        base.set_state(q["state"])
        t0 = time.perf_counter()
        result = planner.plan(q["start"], q["goal"])
        times.append(time.perf_counter() - t0)
        ok.append(result.success)
        checks.append(result.extra.get("checks", 0))
    times_a, ok_a, checks_a = np.array(times), np.array(ok), np.array(checks)

    def pct(x: np.ndarray, digits: int) -> dict[str, float]:
        return {f"p{p}": round(float(np.percentile(x, p)), digits) for p in (50, 90, 99, 100)} if len(x) else {}

    return {"time_limit": time_limit, "max_checks": max_checks, "snapshot_scene": snapshot_scene,
            "motion_resolution": motion_resolution,
            "queries": len(queries), "success_rate": round(float(ok_a.mean()), 4),
            "total_s": round(float(times_a.sum()), 2), "mean_s": round(float(times_a.mean()), 4),
            "failed_s": round(float(times_a[~ok_a].sum()), 2), "solve_s": pct(times_a[ok_a], 4),
            "solve_checks": pct(checks_a[ok_a], 0), "failed_checks_mean": round(float(checks_a[~ok_a].mean()), 0)
            if (~ok_a).any() else 0}


def compare(queries: list[dict[str, Any]], seed: int = 0, env_id: str = "Push2DObstacle-v0"
            ) -> list[dict[str, Any]]:
    """MoPA-RL's planner settings against the task's defaults, query by query (module docstring)."""
    import gymnasium as gym

    import lfd_envs  # noqa: F401
    from tools.mopa_modes import MOPA_RL_PLANNER
    from lfd_agents.mopa import make_mopa_env

    old = dict(MOPA_RL_PLANNER, planner_kwargs={**MOPA_RL_PLANNER["planner_kwargs"], "seed": seed})
    wrappers = {"mopa-rl": make_mopa_env(gym.make(env_id), **old),
                "suite": make_mopa_env(gym.make(env_id), planner_kwargs={"seed": seed})}
    rec: dict[str, dict[str, list]] = {name: {"t": [], "ok": []} for name in wrappers}
    for w in wrappers.values():
        w.reset(seed=0)
    for q in queries:
        for name, w in wrappers.items():
            w.unwrapped.set_state(q["state"])
            t0 = time.perf_counter()
            ok = w.planner.plan(q["start"], q["goal"]).success
            rec[name]["t"].append(time.perf_counter() - t0)
            rec[name]["ok"].append(ok)
    rows = []
    for name, r in rec.items():
        t, ok = np.array(r["t"]), np.array(r["ok"])
        rows.append({"planner": name, "queries": len(t), "success_rate": round(float(ok.mean()), 4),
                     "total_s": round(float(t.sum()), 2), "failed_s": round(float(t[~ok].sum()), 2),
                     "solved_median_s": round(float(np.median(t[ok])), 4) if ok.any() else None})
    return rows


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("collect")
    c.add_argument("--out", required=True)
    c.add_argument("--source", choices=("random", "learning"), default="random")
    c.add_argument("--queries", type=int, default=200)
    c.add_argument("--seed", type=int, default=0)
    r = sub.add_parser("replay")
    r.add_argument("path")
    r.add_argument("--time-limit", type=float, nargs="+", default=[1.0])
    r.add_argument("--seed", type=int, default=0)
    r.add_argument("--max-checks", type=int, nargs="+", default=[0], help="check budgets (0: none)")
    r.add_argument("--no-snapshot", action="store_true", help="check every configuration against the live state")
    r.add_argument("--motion-resolution", type=float, default=None, help="OMPL edge-check spacing (rad, L2)")
    cmp = sub.add_parser("compare")
    cmp.add_argument("path")
    cmp.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    if args.cmd == "compare":
        import os

        with open(args.path, "rb") as f:
            qs = pickle.load(f)
        load = os.getloadavg()[0]
        rows = compare(qs, args.seed)
        print(f"load average {load:.2f} -> {os.getloadavg()[0]:.2f}")
        for row in rows:
            print(row)
        return
    if args.cmd == "collect":
        qs = collect(args.source, args.queries, args.seed, out_path=args.out)
        with open(args.out, "wb") as f:
            pickle.dump(qs, f)
        print(f"{len(qs)} queries -> {args.out}; statuses when collected: "
              f"{ {s: sum(q['status'] == s for q in qs) for s in {q['status'] for q in qs}} }")
    else:
        with open(args.path, "rb") as f:
            qs = pickle.load(f)
        for tl in args.time_limit:
            for budget in args.max_checks:
                print(replay(qs, tl, args.seed, max_checks=budget or None, snapshot_scene=not args.no_snapshot,
                             motion_resolution=args.motion_resolution), flush=True)


if __name__ == "__main__":
    main()
