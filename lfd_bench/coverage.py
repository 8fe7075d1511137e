"""Exploration coverage: where the end-effector went during the first N training steps.

A cell of a suite with ``"coverage_steps": N`` records, in its training env, the end-effector
position after each of the first ``N`` low-level steps (:class:`EndEffectorRecorder`); the
result JSON then has a ``coverage`` entry (see :meth:`EndEffectorRecorder.summary`): the number
of distinct ``cell`` × ``cell`` squares (2 cm by default) of the horizontal plane visited, and
up to ``max_points`` evenly spaced positions for a picture. :func:`plot_coverage` draws the
positions of several agents side by side (the exploration picture of MoPA-RL: MoPA-SAC's
end-effector covers much more of the 2D Push workspace than SAC's) and
:func:`coverage_markdown` gives the leaderboard lines for it (``coverage_markdown(coverage_of(results
of one env), png, folder_of_the_markdown, env_id)``).

The recorder hooks the *unwrapped* env's ``step`` (an instance attribute), so it also sees the
steps that a wrapper executes on the base env directly (MoPA's planned paths call
``env.unwrapped.execute_path``, which steps the base env once per waypoint).

Command line::

    python -m lfd_bench.coverage --suite repro-mopa --env Push2DObstacle-v0 \\
        --out results --png docs/leaderboard/repro-mopa-coverage.png
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

__all__ = ["EndEffectorRecorder", "end_effector_xy", "load_coverage", "coverage_of", "plot_coverage",
           "coverage_figure", "coverage_markdown"]


def end_effector_xy(base: Any) -> Callable[[], np.ndarray]:
    """A function returning the end-effector's horizontal position ``(x, y)`` of env ``base``.

    Uses ``fingertip_xy()`` (Push2DObstacle) or ``eef_pos()`` (the Sawyer tasks).
    """
    if callable(getattr(base, "fingertip_xy", None)):
        return lambda: np.asarray(base.fingertip_xy(), dtype=np.float64)[:2]
    if callable(getattr(base, "eef_pos", None)):
        return lambda: np.asarray(base.eef_pos(), dtype=np.float64)[:2]
    raise TypeError(f"{type(base).__name__} has no end-effector position (fingertip_xy() or eef_pos())")


class EndEffectorRecorder:
    """Records the end-effector position after each of the first ``max_steps`` steps of ``env``.

    Args:
        env: the training env (any wrapper stack; its ``unwrapped`` env is hooked).
        max_steps: how many low-level steps to record (≥ 1).
        cell: side of the squares counted as visited [m] (default 0.02).
        max_points: at most this many positions are kept for the picture (evenly spaced in time).
    """

    def __init__(self, env: Any, max_steps: int, cell: float = 0.02, max_points: int = 2000) -> None:
        if isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) or max_steps < 1:
            raise ValueError(f"max_steps must be an integer >= 1, got {max_steps!r}")
        if not (np.isfinite(cell) and cell > 0):
            raise ValueError(f"cell must be a positive length, got {cell!r}")
        if isinstance(max_points, bool) or not isinstance(max_points, (int, np.integer)) or max_points < 1:
            raise ValueError(f"max_points must be an integer >= 1, got {max_points!r}")
        self.base = env.unwrapped
        self._position = end_effector_xy(self.base)
        self.max_steps, self.cell = int(max_steps), float(cell)
        self.every = max(1, math.ceil(self.max_steps / int(max_points)))
        self.steps = 0
        self.cells: set[tuple[int, int]] = set()
        self.points: list[tuple[float, float]] = []
        self._step = self.base.step  # the bound method of the class
        self.base.step = self._recording_step  # instance attribute: seen by wrappers and execute_path

    def _recording_step(self, action: Any):
        out = self._step(action)
        if self.steps < self.max_steps:
            xy = self._position()
            self.cells.add((int(math.floor(xy[0] / self.cell)), int(math.floor(xy[1] / self.cell))))
            if self.steps % self.every == 0:
                self.points.append((round(float(xy[0]), 4), round(float(xy[1]), 4)))
            self.steps += 1
        return out

    def get_state(self) -> dict[str, Any]:
        """What was recorded so far (for a checkpoint; :meth:`set_state` loads it)."""
        return {"steps": self.steps, "cells": sorted(self.cells), "points": list(self.points)}

    def set_state(self, state: dict[str, Any]) -> None:
        """Continue from a :meth:`get_state` of a recorder with the same settings."""
        self.steps = int(state["steps"])
        self.cells = {tuple(c) for c in state["cells"]}
        self.points = [tuple(p) for p in state["points"]]

    def detach(self) -> None:
        """Stop recording (restores the env's own ``step``)."""
        if self.base.__dict__.get("step") == self._recording_step:
            del self.base.step

    def summary(self) -> dict[str, Any]:
        """JSON-ready record: ``steps`` recorded, ``cell`` size, ``visited_cells``, ``every``
        (one kept position per ``every`` steps) and ``points`` (list of ``[x, y]``)."""
        return {"steps": self.steps, "cell": self.cell, "visited_cells": len(self.cells), "every": self.every,
                "points": [list(p) for p in self.points]}


# ----------------------------------------------------------------------------- reading, plots
def load_coverage(out: Path | str, suite: str, env_dir: str) -> dict[str, list[dict[str, Any]]]:
    """``{agent: [coverage of seed 0, seed 1, ...]}`` from the result JSONs of ``suite``'s ``env_dir``
    (the cell folder name: env id without namespace, plus ``__label`` when the cell has one)."""
    root = Path(out) / suite / env_dir
    found: dict[str, list[dict[str, Any]]] = {}
    if not root.is_dir():
        return found
    for agent_dir in sorted(p for p in root.iterdir() if p.is_dir()):
        results = []
        for path in agent_dir.glob("seed*.json"):
            try:
                results.append(json.loads(path.read_text()))
            except (OSError, json.JSONDecodeError):
                continue
        found.update(coverage_of({agent_dir.name: results}))
    return found


def coverage_of(agent_results: dict[str, list[dict[str, Any]]]) -> dict[str, list[dict[str, Any]]]:
    """``{agent: [coverage records]}`` from ``{agent: [result dicts]}`` (as the leaderboard groups
    them; results without ``coverage`` are left out, agents without any are dropped)."""
    out: dict[str, list[dict[str, Any]]] = {}
    for agent, runs in agent_results.items():
        covs = [{**r["coverage"], "seed": r.get("cell", {}).get("seed")} for r in runs
                if isinstance(r.get("coverage"), dict)]
        if covs:
            out[agent] = sorted(covs, key=lambda c: (c["seed"] is None, c["seed"] or 0))
    return out


def _obstacles(env_id: str) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    if env_id.split(":")[-1].startswith("Push2DObstacle"):
        from lfd_envs.mujoco.push2d import OBSTACLES

        return [(tuple(c), tuple(h)) for _, c, h in OBSTACLES]
    return []


def _has_points(run: dict[str, Any]) -> bool:
    return len(run.get("points") or []) > 0


def coverage_figure(data: dict[str, list[dict[str, Any]]], env_id: str = "",
                    agents: Sequence[str] | None = None, seed: int | None = None) -> Any | None:
    """The matplotlib figure of :func:`plot_coverage` (one panel per agent that recorded
    positions, a colour bar of the training step), or None when no agent recorded any."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    names = [a for a in (agents or sorted(data)) if a in data and any(_has_points(r) for r in data[a])]
    if not names:
        return None
    fig, axes = plt.subplots(1, len(names), figsize=(4.2 * len(names) + 1.0, 4.2), squeeze=False,
                             layout="constrained")
    everything = np.concatenate([np.asarray(r["points"], dtype=float).reshape(-1, 2)
                                 for a in names for r in data[a]])
    boxes = _obstacles(env_id)
    if boxes:  # show the whole obstacle layout, not only where the agents went
        corners = np.array([[c[0] + sx * h[0], c[1] + sy * h[1]] for c, h in boxes for sx in (-1, 1) for sy in (-1, 1)])
        everything = np.concatenate([everything, corners])
    lo, hi = everything.min(axis=0) - 0.05, everything.max(axis=0) + 0.05
    chosen = {name: _shown_run(data[name], seed) for name in names}
    last_step = max(max(1, run["steps"]) for run in chosen.values())
    dots = None
    for ax, name in zip(axes[0], names):
        runs, run = data[name], chosen[name]
        pts = np.asarray(run["points"], dtype=float).reshape(-1, 2)
        for centre, half in boxes:
            ax.add_patch(Rectangle((centre[0] - half[0], centre[1] - half[1]), 2 * half[0], 2 * half[1],
                                   color="0.6", zorder=0))
        steps = np.arange(len(pts)) * max(1, int(run.get("every", 1)))  # the env step of each kept position
        dots = ax.scatter(pts[:, 0], pts[:, 1], c=steps, cmap="viridis", vmin=0, vmax=last_step, s=3, zorder=1)
        cells = ", ".join(str(r["visited_cells"]) for r in runs)
        ax.set_title(f"{name} (seed {run.get('seed')}): first {run['steps']} steps\n"
                     f"visited {run['cell'] * 100:g} cm cells, seeds {cells}", fontsize=9)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
    fig.colorbar(dots, ax=list(axes[0]), label="training step", shrink=0.85)
    return fig


def _shown_run(runs: list[dict[str, Any]], seed: int | None) -> dict[str, Any]:
    """The record of ``seed`` if it has positions, else the first one that has."""
    with_points = [r for r in runs if _has_points(r)]
    return next((r for r in with_points if r.get("seed") == seed), with_points[0])


def plot_coverage(data: dict[str, list[dict[str, Any]]], png: Path | str, env_id: str = "",
                  agents: Sequence[str] | None = None, seed: int | None = None) -> Path | None:
    """Draw the recorded positions of each agent (one panel per agent, colour = training step,
    with a colour bar) into ``png``.

    ``data`` is ``{agent: [coverage records]}`` (:func:`load_coverage`, :func:`coverage_of`);
    ``env_id`` adds the env's obstacles where known (Push2DObstacle). ``seed`` selects one
    seed's positions (default: the lowest recorded seed); the panel title gives the visited
    cells of every seed. Agents that recorded no position get no panel. Returns the path, or
    None when nothing was recorded.
    """
    import matplotlib.pyplot as plt

    fig = coverage_figure(data, env_id, agents, seed)
    if fig is None:
        return None
    png = Path(png)
    png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=110)
    plt.close(fig)
    return png


def coverage_markdown(data: dict[str, list[dict[str, Any]]], png: Path | str, relative_to: Path | str,
                      env_id: str = "", agents: Sequence[str] | None = None) -> str:
    """Markdown for a leaderboard section: the picture of :func:`plot_coverage` (written to
    ``png``, linked relative to the folder ``relative_to``) and a table of visited cells per
    agent and seed. ``data``: ``{agent: [coverage records]}``, e.g. ``coverage_of(results of
    one env)``. Empty string when nothing was recorded."""
    import os

    path = plot_coverage(data, png, env_id, agents=agents)
    if path is None:
        return ""
    rows = ["| agent | steps recorded | visited cells per seed | mean |", "| --- | --- | --- | --- |"]
    for name in [a for a in (agents or sorted(data)) if a in data]:
        runs = data[name]
        cells = [r["visited_cells"] for r in runs]
        rows.append(f"| {name} | {runs[0]['steps']} | {', '.join(map(str, cells))} | {np.mean(cells):.0f} |")
    size = data[next(iter(data))][0]["cell"] * 100
    link = Path(os.path.relpath(path, Path(relative_to))).as_posix()
    return "\n".join([f"End-effector positions during the first training steps (colour: time; {size:g} cm "
                      "cells of the horizontal plane counted as visited):", "", f"![coverage]({link})", "", *rows])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m lfd_bench.coverage", description=__doc__.split("\n")[0])
    p.add_argument("--suite", required=True)
    p.add_argument("--env", required=True, help="cell folder: env id (no namespace) plus __label if any")
    p.add_argument("--out", default="results", help="results folder (default: ./results)")
    p.add_argument("--png", required=True)
    p.add_argument("--agents", nargs="+")
    args = p.parse_args(argv)
    env_dir = args.env.split(":")[-1]
    data = load_coverage(args.out, args.suite, env_dir)
    path = plot_coverage(data, args.png, env_dir.split("__")[0], agents=args.agents)
    if path is None:
        print(f"error: no result of {args.suite}/{env_dir} under {args.out} recorded coverage", file=sys.stderr)
        return 1
    for agent, runs in data.items():
        print(agent, [r["visited_cells"] for r in runs])
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
