"""Figures of the leaderboard: learning curves and rliable's interval, profile and improvement plots.

Every figure is written atomically (:func:`lfd_bench.storage.atomic_write`), so a killed
run never leaves a truncated PNG behind.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from lfd_bench.storage import atomic_write


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig: Any, path: Path, dpi: int = 110) -> Path:
    """Save ``fig`` as PNG at ``path`` atomically and close it."""
    try:
        return atomic_write(path, lambda tmp: fig.savefig(tmp, dpi=dpi, format="png", bbox_inches="tight"))
    finally:
        _pyplot().close(fig)


def plot_curves(env_label: str, agents: Mapping[str, list[dict[str, Any]]], path: Path) -> bool:
    """Mean learning curve per trained agent (shaded: min–max over seeds). False if nothing to plot."""
    plt = _pyplot()
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
    if not plotted:
        plt.close(fig)
        return False
    ax.set_xlabel("env steps")
    ax.set_ylabel("normalized performance p̂")
    ax.set_title(env_label, fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)
    return True


def plot_improvement(probabilities: Mapping[str, tuple[float, float, float]], reference: str, title: str,
                     path: Path) -> Path:
    """rliable's probability-of-improvement plot: P(reference > baseline) with 95% CIs."""
    from rliable import plot_utils

    plt = _pyplot()
    names = sorted(probabilities)
    keys = [f"{reference},{b}" for b in names]
    point = {k: probabilities[b][0] for k, b in zip(keys, names)}
    ci = {k: np.array([probabilities[b][1], probabilities[b][2]]) for k, b in zip(keys, names)}
    fig, ax = plt.subplots(figsize=(4.2, 0.5 + 0.45 * len(names)))
    plot_utils.plot_probability_of_improvement(point, ci, ax=ax, xlabel=f"P({reference} > baseline)")
    ax.set_title(title, fontsize=9)
    return save_figure(fig, path)


def plot_interval_estimates(estimates: Mapping[str, Mapping[str, float]], path: Path) -> Path:
    """rliable's interval plot of IQM and mean (points and 95% CIs) per agent."""
    from rliable import plot_utils

    algorithms = sorted(estimates)
    point = {a: np.array([estimates[a]["iqm"], estimates[a]["mean"]]) for a in algorithms}
    ci = {a: np.array([[estimates[a]["iqm_ci_low"], estimates[a]["mean_ci_low"]],
                       [estimates[a]["iqm_ci_high"], estimates[a]["mean_ci_high"]]]) for a in algorithms}
    row_height = 0.5  # inches per algorithm; the x label goes 0.45 inch below the axes
    fig, _ = plot_utils.plot_interval_estimates(point, ci, metric_names=["IQM", "Mean"], algorithms=algorithms,
                                                xlabel="normalized performance p̂", row_height=row_height,
                                                xlabel_y_coordinate=-0.45 / (row_height * len(algorithms)))
    return save_figure(fig, path)


#: title of the performance-profile figure
PROFILES_TITLE = "Performance profiles: runs of every env, p̂ above each threshold τ"


def profiles_figure(profiles: Mapping[str, np.ndarray], cis: Mapping[str, np.ndarray], taus: np.ndarray,
                    title: str = PROFILES_TITLE) -> Any:
    """The figure of :func:`plot_profiles` (not yet saved)."""
    from rliable import plot_utils

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(5, 3.2))
    plot_utils.plot_performance_profiles(profiles, taus, performance_profile_cis=cis, ax=ax,
                                         xlabel="normalized performance τ", ylabel="fraction of runs with p̂ > τ")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="lower left")
    return fig


def plot_profiles(profiles: Mapping[str, np.ndarray], cis: Mapping[str, np.ndarray], taus: np.ndarray,
                  path: Path, title: str = PROFILES_TITLE) -> Path:
    """rliable's performance profiles (fraction of runs with p̂ > τ, with a title) saved at ``path``."""
    return save_figure(profiles_figure(profiles, cis, taus, title), path)
