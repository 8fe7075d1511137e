"""Turn the per-cell JSON results into ``leaderboard.md`` and learning-curve PNGs."""

from __future__ import annotations

import json
import re
import os
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.stats import summarize

HEADER = ("| agent | seeds | episodes | 25th pct | mean ± std | median | 75th pct | IQM [95% CI] "
          "| budget (steps) | train wall time |")


def load_results(results_dir: Path, suite: str | None = None) -> list[dict[str, Any]]:
    """All cell results under ``results_dir`` (optionally of one suite)."""
    root = Path(results_dir) / suite if suite else Path(results_dir)
    return [json.loads(p.read_text()) for p in sorted(root.rglob("*.json"))]


def group_by_env(results: list[dict[str, Any]]) -> dict[str, dict[str, list[dict[str, Any]]]]:
    """``{env label: {agent: [results over seeds]}}``."""
    table: dict[str, dict[str, list]] = defaultdict(lambda: defaultdict(list))
    for r in results:
        cell = r["cell"]
        label = cell["env_id"] + (f" ({cell['tags']['label']})" if cell.get("tags", {}).get("label") else "")
        table[label][cell["agent"]].append(r)
    return table


def _fmt_time(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"


def agent_row(agent: str, runs: list[dict[str, Any]]) -> tuple[str, dict[str, float]]:
    """Markdown row and summary numbers for one agent on one env."""
    values = np.concatenate([np.asarray(r["final_normalized_performance"], dtype=float) for r in runs])
    s = summarize(values)
    budget = max(int(r["cell"]["budget"]) if r.get("trained_steps") else 0 for r in runs)
    wall = float(np.mean([r["train_wall_time_s"] for r in runs]))
    row = (f"| {agent} | {len(runs)} | {s.n} | {s.p25:.3f} | {s.mean:.3f} ± {s.std:.3f} | {s.median:.3f} | "
           f"{s.p75:.3f} | {s.iqm:.3f} [{s.iqm_ci_low:.3f}, {s.iqm_ci_high:.3f}] | "
           f"{budget if budget else '—'} | {_fmt_time(wall)} |")
    return row, s.as_dict()


def plot_curves(env_label: str, agents: dict[str, list[dict[str, Any]]], path: Path) -> bool:
    """Mean learning curve per trained agent (shaded: min–max over seeds). False if nothing to plot."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5, 3.2))
    plotted = False
    for agent, runs in sorted(agents.items()):
        curves = [r["learning_curve"] for r in runs if r.get("learning_curve")]
        if not curves:
            continue
        n = min(len(c) for c in curves)
        steps = [c["steps"] for c in curves[0][:n]]
        ys = np.array([[p["mean_normalized_performance"] for p in c[:n]] for c in curves])
        ax.plot(steps, ys.mean(0), marker="o", label=agent)
        if len(ys) > 1:
            ax.fill_between(steps, ys.min(0), ys.max(0), alpha=0.2)
        plotted = True
    for agent, runs in sorted(agents.items()):
        if not any(r.get("learning_curve") for r in runs):  # reference rows as horizontal lines
            mean = np.mean([np.mean(r["final_normalized_performance"]) for r in runs])
            ax.axhline(mean, linestyle="--", linewidth=1, color="gray" if agent == "random" else "black")
            ax.annotate(agent, (0.01, mean), xycoords=("axes fraction", "data"), fontsize=7, va="bottom")
    if plotted:
        ax.set_xlabel("env steps")
        ax.set_ylabel("normalized performance p̂")
        ax.set_title(env_label, fontsize=9)
        ax.legend(fontsize=7)
        fig.tight_layout()
        path.parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=110)
    plt.close(fig)
    return plotted


def render_markdown(results: list[dict[str, Any]], *, command: str, suite: str | None, plot_dir: Path | None,
                    relative_to: Path) -> str:
    """The leaderboard document."""
    commits = sorted({r["environment"].get("commit", "?") for r in results})
    hw = results[0]["environment"] if results else {}
    lines = [
        "# Leaderboard",
        "",
        "Produced by the benchmark harness (`benchmarks/run.py`); regenerate with:",
        "",
        f"```\n{command}\n```",
        "",
        f"Commit(s): {', '.join(commits)}. Hardware: {hw.get('cpu', '?')} ({hw.get('cpu_count', '?')} cores), "
        f"Python {hw.get('python', '?')}. Suite: `{suite or 'all'}`.",
        "",
        "Each cell: final normalised performance p̂(H) over evaluation episodes (eval variants) × seeds — "
        "25th percentile, mean ± std, median, 75th percentile (the thesis table format) and the "
        "interquartile mean with a 95% percentile-bootstrap CI. `expert` is the scripted oracle, "
        "`random` uniform random actions. Budgets here are tiny (CPU smoke runs); the paper suites "
        "(`benchmarks/configs/paper-*.json`) hold the full comparisons.",
        "",
    ]
    for env_label, agents in sorted(group_by_env(results).items()):
        lines += [f"## {env_label}", "", HEADER, _sep()]
        order = sorted(agents, key=lambda a: (a != "expert", a == "random", a))
        for agent in order:
            lines.append(agent_row(agent, agents[agent])[0])
        if plot_dir is not None:
            png = plot_dir / (f"{suite or 'all'}_" + re.sub(r'[^A-Za-z0-9_.-]+', '_', env_label) + ".png")
            if plot_curves(env_label, agents, png):
                lines += ["", f"![learning curves {env_label}]({os.path.relpath(png, relative_to)})"]
        lines.append("")
    return "\n".join(lines)


def _sep() -> str:
    return "|" + "---|" * (HEADER.count("|") - 1)


def write_leaderboard(results_dir: Path, out_path: Path, *, command: str, suite: str | None = None,
                      plot_dir: Path | None = None) -> Path:
    """Regenerate ``out_path`` from the results of ``suite`` (all suites if None)."""
    results = load_results(results_dir, suite)
    if not results:
        raise ValueError(f"no results found in {results_dir} for suite {suite!r}")
    out_path = Path(out_path)
    plot_dir = plot_dir or out_path.parent / "docs" / "leaderboard"
    text = render_markdown(results, command=command, suite=suite, plot_dir=plot_dir, relative_to=out_path.parent)
    out_path.write_text(text)
    return out_path
