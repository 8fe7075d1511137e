"""What MoPA-SAC's actions do while it trains: ``python -m benchmarks.mopa_modes [--steps N]``.

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

    python -m benchmarks.mopa_modes [--env Push2DObstacle-v0] [--steps 20000] [--window 5000]
        [--learning-starts 100] [--seed 0] [--update-per-stored]

``--update-per-stored`` trains with MoPA-RL's schedule (one gradient step per stored transition,
reused path segments included) instead of SB3's one per decision.
"""

from __future__ import annotations

import argparse
import collections
import time
from typing import Any

import numpy as np


def mode_rows(env_id: str = "Push2DObstacle-v0", steps: int = 20_000, window: int = 5000, learning_starts: int = 100,
              seed: int = 0, update_per_stored: bool = False) -> tuple[list[dict[str, Any]], float]:
    """Per-window rows (decisions, share of each mode, low-level steps per decision, rewarded
    decisions, gradient updates so far and, on Push2D, the closest fingertip-box distance) of one
    MoPA-SAC training run, and the final entropy coefficient."""
    import gymnasium as gym
    from stable_baselines3.common.callbacks import BaseCallback

    import lfd_envs  # noqa: F401  (registers the ids)
    from lfd_agents.mopa import MoPAAgent
    from lfd_agents.mopa.wrapper import MOPA_MODES

    agent = MoPAAgent(gym.make(env_id), seed=seed, learning_starts=learning_starts,
                      update_per_stored=update_per_stored)
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


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(prog="python -m benchmarks.mopa_modes", description=__doc__.split("\n")[0])
    p.add_argument("--env", default="Push2DObstacle-v0")
    p.add_argument("--steps", type=int, default=20_000, help="low-level env steps of training")
    p.add_argument("--window", type=int, default=5000, help="low-level steps per row")
    p.add_argument("--learning-starts", type=int, default=100, help="uniform-random warm-up, in decisions")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--update-per-stored", action="store_true", help="MoPA-RL's update schedule")
    args = p.parse_args(argv)
    t0 = time.perf_counter()
    rows, ent = mode_rows(args.env, args.steps, args.window, args.learning_starts, args.seed, args.update_per_stored)
    keys = list(rows[0]) if rows else []
    schedule = "one update per stored transition" if args.update_per_stored else "one update per decision"
    print(f"MoPA-SAC on {args.env}, seed {args.seed}, warm-up {args.learning_starts} decisions, {args.steps} steps, "
          f"{schedule}\n")
    print("| " + " | ".join(keys) + " |\n|" + "---|" * len(keys))
    for r in rows:
        print("| " + " | ".join(str(r[k]) for k in keys) + " |")
    print(f"\nentropy coefficient at the end: {ent:.4f}; {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
