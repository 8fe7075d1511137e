"""Success rate of the Sawyer scripted experts: ``python -m benchmarks.sawyer_experts [--episodes 50]``.

Episode ``k`` resets with ``seed=k`` on eval variant ``k`` (``options={"split": "eval", "variant": k}``)
and runs the expert until success or the horizon (250). The markdown table reports the success
rate (target ≥ 0.9), mean episode length and return, and wall time per episode.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

ENV_IDS = ("SawyerPushObstacle-v0", "SawyerLiftObstacle-v0", "SawyerAssemblyObstacle-v0")


def evaluate(env_id: str, episodes: int) -> dict[str, Any]:
    """Run the scripted expert of ``env_id`` on the first ``episodes`` eval variants."""
    import gymnasium as gym

    import lfd_envs  # noqa: F401  (registers the ids)
    from lfd_envs.core.rollout import episode_steps
    from lfd_envs.experts import make_expert

    env = gym.make(env_id)
    expert = make_expert(env)
    success, lengths, returns = [], [], []
    t0 = time.perf_counter()
    for k in range(episodes):
        obs, _ = env.reset(seed=k, options={"split": "eval", "variant": k})
        expert.reset()
        steps = list(episode_steps(env, expert, obs))
        success.append(bool(steps[-1].info["is_success"]))
        lengths.append(len(steps))
        returns.append(sum(step.reward for step in steps))
    env.close()
    return {"env": env_id, "episodes": episodes, "success_rate": round(float(np.mean(success)), 3),
            "mean_length": round(float(np.mean(lengths)), 1), "mean_return": round(float(np.mean(returns)), 1),
            "s_per_episode": round((time.perf_counter() - t0) / episodes, 2),
            "failed_variants": [k for k, s in enumerate(success) if not s]}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--envs", default=",".join(ENV_IDS), help="comma-separated env ids")
    args = parser.parse_args(argv)
    rows = [evaluate(env_id, args.episodes) for env_id in args.envs.split(",")]
    keys = list(rows[0])
    print("| " + " | ".join(keys) + " |")
    print("|" + "|".join("---" for _ in keys) + "|")
    for row in rows:
        print("| " + " | ".join(str(row[k]) for k in keys) + " |")


if __name__ == "__main__":
    main()
