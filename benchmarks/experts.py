"""Scripted-expert scores of the particle tasks: ``python -m benchmarks.experts [--variants N]``.

For every (task, picker count, action mode) row, the expert runs one episode on each of the
first ``N`` eval variants (``reset(seed=0, options={"variant": k, "split": "eval"})``) and the
table reports the mean, standard deviation and minimum of the final normalised performance
p̂(H), next to the target of SPEC §4.4 where there is one. Output is a markdown table, so the
numbers in the docs can be reproduced with the same command.

Examples::

    python -m benchmarks.experts --variants 100
    python -m benchmarks.experts --variants 10 --tasks ClothFold-v0 --modes delta
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Row", "ROWS", "evaluate_expert", "main"]


@dataclass(frozen=True)
class Row:
    """One benchmark row: env id, picker count, action mode and the SPEC target (if any)."""

    env_id: str
    num_pickers: int
    action_mode: str
    target: float | None = None


ROWS: tuple[Row, ...] = tuple(
    Row(env_id, pickers, mode, target if mode == "delta" else None)
    for env_id, pickers, target in (
        ("StraightenRope-v0", 2, 0.83),
        ("StraightenRope-v0", 1, None),
        ("ClothFold-v0", 2, 0.71),
        ("ClothFold-v0", 1, None),
        ("ClothFoldDiagonalPinned-v0", 1, 0.906),
        ("ClothFoldDiagonalUnpinned-v0", 1, 0.927),
    )
    for mode in ("delta", "pick_place")
)


def evaluate_expert(env_id: str, num_variants: int, num_pickers: int | None = None, action_mode: str = "delta",
                    split: str = "eval", resolution: int | None = None, seed: int = 0) -> np.ndarray:
    """Final p̂ of the scripted expert on variants ``0 .. num_variants-1`` of ``split``."""
    import gymnasium as gym

    import lfd_envs  # noqa: F401  (registers the ids)
    from lfd_envs.experts import make_expert

    kwargs: dict[str, Any] = {"action_mode": action_mode, "obs_mode": "state"}
    if num_pickers is not None:
        kwargs["num_pickers"] = num_pickers
    if resolution is not None:
        kwargs["resolution"] = resolution
    env = gym.make(env_id, **kwargs)
    expert = make_expert(env)
    scores = []
    for k in range(num_variants):
        obs, info = env.reset(seed=seed, options={"variant": k, "split": split})
        expert.reset()
        done = False
        while not done:
            action, _ = expert.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
        scores.append(info["normalized_performance"])
    env.close()
    return np.asarray(scores, dtype=np.float64)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", type=int, default=100, help="eval variants per row (default 100)")
    parser.add_argument("--tasks", default="", help="comma-separated env ids (default: all rows)")
    parser.add_argument("--modes", default="delta,pick_place", help="comma-separated action modes")
    parser.add_argument("--resolution", type=int, default=None, help="particles per side (default: task default)")
    args = parser.parse_args(argv)
    import warp as wp

    wp.config.quiet = True
    tasks = set(filter(None, args.tasks.split(",")))
    modes = set(args.modes.split(","))
    print(f"Scripted experts: mean final p̂ over eval variants 0..{args.variants - 1} "
          f"(resolution {args.resolution or 'default'})\n")
    print("| task | pickers | action mode | mean p̂ | std | min | target | met | s/episode |")
    print("|---|---|---|---|---|---|---|---|---|")
    for row in ROWS:
        if (tasks and row.env_id not in tasks) or row.action_mode not in modes:
            continue
        t0 = time.perf_counter()
        s = evaluate_expert(row.env_id, args.variants, row.num_pickers, row.action_mode, resolution=args.resolution)
        sec = (time.perf_counter() - t0) / len(s)
        target = "" if row.target is None else f"{row.target:.3f}"
        met = "" if row.target is None else ("yes" if s.mean() >= row.target else "no")
        print(f"| {row.env_id} | {row.num_pickers} | {row.action_mode} | {s.mean():.3f} | {s.std():.3f} | "
              f"{s.min():.3f} | {target} | {met} | {sec:.2f} |", flush=True)


if __name__ == "__main__":
    main()
