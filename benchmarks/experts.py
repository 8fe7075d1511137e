"""Scripted-expert scores of the particle tasks: ``python -m benchmarks.experts [--variants N]``.

For every (task, picker count, action mode) row, the expert runs one episode on each of the
first ``N`` eval variants (``reset(seed=0, options={"variant": k, "split": "eval"})``) and the
table reports the mean, standard deviation and minimum of the final normalised performance
p̂(H), next to the project's target where there is one. Output is a markdown table, so the
numbers in the docs can be reproduced with the same command.

Examples::

    python -m benchmarks.experts --variants 100 [--jobs 16]
    python -m benchmarks.experts --variants 10 --tasks ClothFold-v0 --modes delta
    python -m benchmarks.experts --variants 6 --env-kwargs '{"pick_place_speed": 1.0}'
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import dataclass, replace
from typing import Any, Iterator

import numpy as np

__all__ = ["Row", "ROWS", "evaluate_expert", "expert_results", "select_rows", "table_row", "main"]


@dataclass(frozen=True)
class Row:
    """One benchmark row: env id, picker count, action mode and the target (if any)."""

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

#: DryCloth / ThreeBoxes (MAIL): teacher and student picker counts; the DryCloth targets are
#: MAIL's and apply to its pick-and-place action space
ROWS += tuple(
    Row(env_id, pickers, mode, target if mode == "pick_place" else None)
    for env_id, pickers, target in (
        ("DryCloth-v0", 2, 0.74),
        ("DryCloth-v0", 1, 0.48),
        ("ThreeBoxes-v0", 3, None),
        ("ThreeBoxes-v0", 2, None),
        ("ThreeBoxes-v0", 1, None),
    )
    for mode in ("pick_place", "delta")
)


def evaluate_expert(env_id: str, num_variants: int, num_pickers: int | None = None, action_mode: str = "delta",
                    split: str = "eval", resolution: int | None = None, seed: int = 0,
                    first_variant: int = 0, env_kwargs: dict[str, Any] | None = None) -> np.ndarray:
    """Final p̂ of the scripted expert on variants ``first_variant .. first_variant+num_variants-1``
    (``env_kwargs``: further ``gym.make`` arguments, e.g. ``sim_options``)."""
    import gymnasium as gym

    import lfd_envs  # noqa: F401  (registers the ids)
    from lfd_envs.core.rollout import play_episode
    from lfd_envs.experts import make_expert

    kwargs: dict[str, Any] = {"action_mode": action_mode, "obs_mode": "state"}
    if num_pickers is not None:
        kwargs["num_pickers"] = num_pickers
    if resolution is not None:
        kwargs["resolution"] = resolution
    env = gym.make(env_id, **{**kwargs, **(env_kwargs or {})})
    expert = make_expert(env)
    scores = []
    for k in range(first_variant, first_variant + num_variants):
        info = play_episode(env, expert, seed=seed, options={"variant": k, "split": split})
        scores.append(info["normalized_performance"])
    env.close()
    return np.asarray(scores, dtype=np.float64)


def _chunk(args: tuple) -> tuple[int, int, np.ndarray, float]:
    """Worker: (row index, first variant, scores, seconds)."""
    import warp as wp

    wp.config.quiet = True
    index, row, first, count, resolution, env_kwargs = args
    t0 = time.perf_counter()
    scores = evaluate_expert(row.env_id, count, row.num_pickers, row.action_mode, resolution=resolution,
                             first_variant=first, env_kwargs=env_kwargs)
    return index, first, scores, time.perf_counter() - t0


TABLE_HEADER = ("| task | pickers | action mode | mean p̂ | std | min | target | met | s/episode |\n"
                "|---|---|---|---|---|---|---|---|---|")


def select_rows(tasks: set[str] | None = None, modes: set[str] | None = None) -> list[Row]:
    """The rows of :data:`ROWS` of ``tasks`` (env ids) and action ``modes`` (all when None/empty).

    Another version of a listed task (``ClothFold-v1``) gets the rows of its ``-v0`` id.
    """
    rows = list(ROWS)
    for task in sorted(tasks or ()):
        base = task.rsplit("-v", 1)[0] + "-v0"
        if task != base:
            rows += [replace(r, env_id=task) for r in ROWS if r.env_id == base]
    return [r for r in rows if (not tasks or r.env_id in tasks) and (not modes or r.action_mode in modes)]


def expert_results(rows: list[Row], variants: int, resolution: int | None = None,
                   jobs: int = 1, env_kwargs: dict[str, Any] | None = None) -> Iterator[tuple[Row, np.ndarray, float]]:
    """``(row, final p̂ per variant, seconds per episode)`` for every row, as each row finishes
    (``jobs`` > 1: variants split into chunks over worker processes)."""
    chunk = variants if jobs <= 1 else max(1, -(-variants * len(rows) // (2 * jobs)))
    work = [(i, row, first, min(chunk, variants - first), resolution, env_kwargs)
            for i, row in enumerate(rows) for first in range(0, variants, chunk)]
    results: dict[int, list[tuple[int, np.ndarray, float]]] = {i: [] for i in range(len(rows))}
    if jobs <= 1:
        outputs = map(_chunk, work)
    else:
        from concurrent.futures import ProcessPoolExecutor

        pool = ProcessPoolExecutor(jobs)
        outputs = pool.map(_chunk, work)
    for index, first, scores, sec in outputs:
        results[index].append((first, scores, sec))
        if sum(len(s) for _, s, _ in results[index]) < variants:
            continue
        s = np.concatenate([sc for _, sc, _ in sorted(results[index], key=lambda r: r[0])])
        yield rows[index], s, sum(t for _, _, t in results[index]) / len(s)


def table_row(row: Row, scores: np.ndarray, sec: float) -> str:
    """One markdown line of the expert table."""
    target = "" if row.target is None else f"{row.target:.3f}"
    met = "" if row.target is None else ("yes" if scores.mean() >= row.target else "no")
    return (f"| {row.env_id} | {row.num_pickers} | {row.action_mode} | {scores.mean():.3f} | {scores.std():.3f} | "
            f"{scores.min():.3f} | {target} | {met} | {sec:.2f} |")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", type=int, default=100, help="eval variants per row (default 100)")
    parser.add_argument("--tasks", default="", help="comma-separated env ids (default: all rows)")
    parser.add_argument("--modes", default="delta,pick_place", help="comma-separated action modes")
    parser.add_argument("--resolution", type=int, default=None, help="particles per side (default: task default)")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (variants are split into chunks)")
    parser.add_argument("--env-kwargs", type=json.loads, default=None,
                        help="JSON object of further gym.make arguments, e.g. "
                             "'{\"pick_place_speed\": 0.5, \"sim_options\": {\"substeps\": 40}}' (on top of the "
                             "id's physics; they do not change the experts' plans)")
    args = parser.parse_args(argv)
    import warp as wp

    wp.config.quiet = True
    rows = select_rows(set(filter(None, args.tasks.split(","))), set(args.modes.split(",")))
    print(f"Scripted experts: mean final p̂ over eval variants 0..{args.variants - 1} "
          f"(resolution {args.resolution or 'default'}{f', env kwargs {args.env_kwargs}' if args.env_kwargs else ''})\n")
    print(TABLE_HEADER)
    for row, scores, sec in expert_results(rows, args.variants, args.resolution, args.jobs, args.env_kwargs):
        print(table_row(row, scores, sec), flush=True)


if __name__ == "__main__":
    main()
