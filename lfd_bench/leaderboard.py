"""Turn the per-cell JSON results into ``leaderboard.md`` with its plots.

Per env: the thesis table (25th percentile, mean ± std, median, 75th percentile of p̂(H)),
IQM and mean with rliable's bootstrap CIs, the quality measures an env reports besides p̂
(``final_metrics`` of a cell, e.g. the diagonal folds' ``fold_quality``; results written before
they were recorded show a dash), what each agent spent (env steps, gradient updates,
demonstration transitions), reference rows a suite reports from the literature, the suite's
notes, learning curves and the probability that DMfD improves on each baseline. Across envs:
IQM / mean interval estimates and performance profiles. Files are written atomically.
"""

from __future__ import annotations

import os
import re
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

from lfd_bench import plots
from lfd_bench.coverage import coverage_markdown, coverage_of
from lfd_bench.agents import REFERENCE_AGENTS as _REFERENCE_AGENTS
from lfd_bench.cell import REPORTED_METRICS
from lfd_bench.stats import iqm_and_mean, performance_profiles, probability_of_improvement, summarize
from lfd_bench.storage import CorruptResult, atomic_write_text, read_result, result_files, safe_name

HEADER = ("| agent | seeds | episodes | 25th pct | mean ± std | median | 75th pct | per-seed means "
          "| IQM [95% CI] | env steps | gradient updates | demo transitions | train wall time |")
#: position of the env-steps column in a split row (``row.split("|")``)
_ENV_STEPS_COLUMN = HEADER.split("|").index(" env steps ")
#: agents that are references, not learners (never "baselines" of a comparison)
REFERENCE_AGENTS = _REFERENCE_AGENTS
#: what the reported metrics' columns mean (printed under a table that has them)
METRIC_NOTES = {"fold_quality": "1 = a perfect fold, 0 = the flat start; crumpling the cloth cannot fool it, "
                                "see the task's documentation",
                "is_success": "the fraction of episodes that succeed"}
#: the agent compared against every baseline with the probability of improvement
IMPROVER = "dmfd"

# kept importable from here for callers of the old module
plot_curves = plots.plot_curves


def load_results(results_dir: Path, suite: str | None = None) -> list[dict[str, Any]]:
    """All valid cell results under ``results_dir`` (optionally of one suite); corrupt ones are
    reported on stderr by path and left out. The demonstration cache (``_demos``) is not read."""
    results = []
    for path in result_files(results_dir, suite):
        try:
            results.append(read_result(path))
        except CorruptResult as exc:
            print(f"warning: skipping {exc}", file=sys.stderr)
    return results


def _env_label(cell: dict[str, Any]) -> str:
    label = cell.get("tags", {}).get("label")
    return cell["env_id"] + (f" ({label})" if label else "")


def cell_notes(suite_config: dict[str, Any] | None, env_label: str,
               agents: dict[str, list[dict[str, Any]]]) -> list[str]:
    """Notes under a table: the suite config's notes of the cell with this env label (notes are
    documentation, editable without re-running), else the notes the results recorded."""
    for spec in (suite_config or {}).get("cells", []):
        cell = {"env_id": str(spec.get("env")), "tags": {"label": spec["label"]} if "label" in spec else {}}
        if "notes" in spec and _env_label(cell) == env_label:
            return [str(spec["notes"])]
    return sorted({r["cell"].get("tags", {}).get("notes") for runs in agents.values() for r in runs} - {None})


def mark_headline(results: list[dict[str, Any]], suite_config: dict[str, Any] | None) -> None:
    """Set each result's ``headline`` tag from the suite config where the config lists its cell (the
    config is documentation: marking a cell headline needs no re-run); other results keep theirs."""
    marked: dict[str, bool] = {}
    for spec in (suite_config or {}).get("cells", []):
        cell = {"env_id": str(spec.get("env")), "tags": {"label": spec["label"]} if "label" in spec else {}}
        marked[_env_label(cell)] = bool(spec.get("headline", False))
    for r in results:
        label = _env_label(r["cell"])
        if label in marked:
            r["cell"].setdefault("tags", {})["headline"] = marked[label]


def group_by_env(results: list[dict[str, Any]]) -> dict[str, dict[str, list[dict[str, Any]]]]:
    """``{env label: {agent: [results over seeds]}}``."""
    table: dict[str, dict[str, list]] = defaultdict(lambda: defaultdict(list))
    for r in results:
        table[_env_label(r["cell"])][r["cell"]["agent"]].append(r)
    return table


def _fmt_time(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.1f} min"
    return f"{seconds / 3600:.1f} h"


def _fmt_count(n: float) -> str:
    if n >= 1e6:
        return f"{n / 1e6:.2f}M"
    if n >= 1e4:
        return f"{n / 1e3:.1f}k"
    return f"{n:.0f}"


def _budget(runs: list[dict[str, Any]], key: str) -> str:
    """Mean of ``key`` over seeds; results written before budgets were recorded show ``?``
    (env steps: the requested budget, marked ``*``)."""
    values = [r[key] for r in runs if key in r]
    if len(values) == len(runs):
        return _fmt_count(float(np.mean(values)))
    if key == "env_steps":
        requested = float(np.mean([r.get("trained_steps", 0) for r in runs]))
        return f"{_fmt_count(requested)}*" if requested else "0"
    return "?"


def reported_metrics(agents: dict[str, list[dict[str, Any]]]) -> list[str]:
    """The :data:`~lfd_bench.cell.REPORTED_METRICS` that some cell of an env recorded (in order)."""
    have = {k for runs in agents.values() for r in runs for k in r.get("final_metrics", {})}
    return [k for k in REPORTED_METRICS if k in have]


def header(metrics: list[str] = ()) -> str:
    """Table header with one ``<metric> mean ± std`` column per reported metric after p̂'s columns."""
    extra = "".join(f" {REPORTED_METRICS[k]} mean ± std |" for k in metrics)
    return HEADER.replace(" IQM [95% CI] |", " IQM [95% CI] |" + extra, 1)


def _metric_cell(runs: list[dict[str, Any]], key: str) -> str:
    """``mean ± std`` of a reported metric over every episode of ``runs``; ``—`` unless every run has it
    (results written before the metric was recorded, or an agent whose env lacks it)."""
    if not all(key in r.get("final_metrics", {}) for r in runs):
        return "—"
    v = np.concatenate([np.asarray(r["final_metrics"][key], dtype=float) for r in runs])
    return f"{_three(v.mean())} ± {_three(v.std())}"


def by_seed(runs: list[dict[str, Any]], metric: str = "normalized_performance") -> list[list[float]]:
    """Each seed's evaluation scores (p̂, or a reported metric such as ``is_success``), in seed order
    (the runs of the interval estimates); ``KeyError`` if a run did not record ``metric``."""
    ordered = sorted(runs, key=lambda r: r["cell"]["seed"])
    if metric == "normalized_performance":
        return [list(r["final_normalized_performance"]) for r in ordered]
    return [list(r.get("final_metrics", {})[metric]) for r in ordered]


def _interval(s: Any) -> str:
    """``IQM [low, high]``; one seed has no interval (``IQM (1 seed)``)."""
    if s.seeds < 2:
        return f"{s.iqm:.3f} (1 seed)"
    return f"{s.iqm:.3f} [{s.iqm_ci_low:.3f}, {s.iqm_ci_high:.3f}]"


def agent_row(agent: str, runs: list[dict[str, Any]], metrics: list[str] = ()) -> tuple[str, dict[str, Any]]:
    """Markdown row and summary numbers for one agent on one env (``metrics``: extra columns)."""
    s = summarize(by_seed(runs))
    wall = float(np.mean([r.get("train_wall_time_s", 0.0) for r in runs]))
    extra = "".join(f" {_metric_cell(runs, k)} |" for k in metrics)
    seeds = " / ".join(f"{m:.3f}" for m in s.seed_means)
    row = (f"| {agent} | {len(runs)} | {s.n} | {s.p25:.3f} | {s.mean:.3f} ± {s.std:.3f} | {s.median:.3f} | "
           f"{s.p75:.3f} | {seeds} | {_interval(s)} |{extra} "
           f"{_budget(runs, 'env_steps')} | {_budget(runs, 'gradient_updates')} | "
           f"{_budget(runs, 'demo_transitions')} | {_fmt_time(wall)} |")
    return row, s.as_dict()


def demonstrations_line(agents: dict[str, list[dict[str, Any]]]) -> str | None:
    """A sentence with the mean final p̂ of the demonstrations each agent learnt from (the cells'
    ``demo_performance``), or None when no cell recorded it (older results, no demonstrations)."""
    parts = []
    for agent in sorted(agents):
        values = [r["demo_performance"] for r in agents[agent] if isinstance(r.get("demo_performance"), float)]
        if values:
            demo = agents[agent][0]["cell"].get("agent_kwargs", {})
            source = demo.get("demo_policy", "expert")
            if demo.get("demo_policy_kwargs"):
                source += " " + ", ".join(f"{k}={v}" for k, v in sorted(demo["demo_policy_kwargs"].items()))
            parts.append(f"{agent}: {float(np.mean(values)):.3f} ({source})")
    if not parts:
        return None
    return "Demonstrations learnt from, mean final p̂ of their episodes: " + "; ".join(parts) + "."


def _num(row: dict[str, Any], key: str) -> str:
    v = row.get(key)
    return f"{float(v):.3f}" if isinstance(v, (int, float)) else "—"


def reference_row(agent: str, source: str, row: dict[str, Any], metrics: list[str] = ()) -> str:
    """A row of numbers reported elsewhere (``source``), labelled e.g. ``*thesis: dmfd*``."""
    prefix = source.split()[0] if source.strip() else "reported"
    mean = _num(row, "mean") + (f" ± {_num(row, 'std')}" if "std" in row else "")
    extra = "".join(f" {_num(row, k)} |" for k in metrics)  # e.g. a reported success rate
    return (f"| *{prefix}: {agent}* | — | — | {_num(row, 'p25')} | {mean} | {_num(row, 'median')} | "
            f"{_num(row, 'p75')} | — | — |{extra} — | — | — | — |")


def references_for(suite_config: dict[str, Any] | None, env_label: str, env_id: str) -> dict[str, Any] | None:
    """The suite's ``reference`` entry of this env (keyed by the env label or the env id)."""
    refs = (suite_config or {}).get("reference") or {}
    entry = refs.get(env_label)
    if entry is None and not any(key.startswith(f"{env_id} (") for key in refs):
        # keyed by env id: every label of the env shares it, unless some label has its own entry
        entry = refs.get(env_id) or refs.get(env_id.split(":")[-1])
    if entry is not None and not isinstance(entry.get("rows"), dict):
        raise ValueError(f"reference for {env_label!r} needs a 'rows' object {{agent: {{mean, std, ...}}}}")
    return entry


def _seed_scores(runs: list[dict[str, Any]]) -> np.ndarray:
    """Per-seed mean p̂ (one run per seed)."""
    return np.array([np.mean(v) for v in by_seed(runs)])


def improvement(agents: dict[str, list[dict[str, Any]]]) -> dict[str, tuple[float, float, float]]:
    """P(DMfD > baseline) with 95% CI for every learning baseline (seeds as runs)."""
    if IMPROVER not in agents:
        return {}
    x = _seed_scores(agents[IMPROVER])
    return {b: probability_of_improvement(x, _seed_scores(runs)) for b, runs in sorted(agents.items())
            if b != IMPROVER and b not in REFERENCE_AGENTS}


def seed_matrix(table: dict[str, dict[str, list[dict[str, Any]]]]) -> dict[str, np.ndarray]:
    """``{agent: (seeds, envs)}`` of per-seed mean p̂ for agents run on every env with common seeds."""
    envs = sorted(table)
    out = {}
    for agent in sorted({a for agents in table.values() for a in agents}):
        if not all(agent in table[e] for e in envs):
            continue
        per_env = [{r["cell"]["seed"]: float(np.mean(r["final_normalized_performance"])) for r in table[e][agent]}
                   for e in envs]
        seeds = sorted(set.intersection(*(set(d) for d in per_env)))
        if seeds:
            out[agent] = np.array([[d[s] for d in per_env] for s in seeds])
    return out


def is_headline(agents: dict[str, list[dict[str, Any]]]) -> bool:
    """Whether a cell (env label) is marked ``"headline": true`` in its results."""
    return any(r["cell"].get("tags", {}).get("headline") for runs in agents.values() for r in runs)


def main_cells(table: dict[str, dict[str, list[dict[str, Any]]]]) -> dict[str, dict[str, list[dict[str, Any]]]]:
    """The cells a suite's headline and aggregate compare agents on: those marked headline if any
    are; else, for every env id, its cell with the most agents (the first such in label order),
    leaving out ablation cells that run a few agents."""
    headline = {label: agents for label, agents in table.items() if is_headline(agents)}
    if headline:
        return dict(sorted(headline.items()))
    best: dict[str, str] = {}
    for label in sorted(table):
        env_id = next(r["cell"]["env_id"] for runs in table[label].values() for r in runs)
        if env_id not in best or len(table[label]) > len(table[best[env_id]]):
            best[env_id] = label
    return {label: table[label] for label in sorted(best.values())}


def _png(plot_dir: Path, suite: str | None, what: str) -> Path:
    return plot_dir / (f"{suite or 'all'}_" + re.sub(r"[^A-Za-z0-9_.-]+", "_", what) + ".png")


def render_markdown(results: list[dict[str, Any]], *, command: str, suite: str | None, plot_dir: Path | None,
                    relative_to: Path, suite_config: dict[str, Any] | None = None, progress: bool = False) -> str:
    """The leaderboard document (``progress``: a bar over the envs, whose bootstraps take seconds each)."""
    from tqdm import tqdm

    commits = sorted({r.get("environment", {}).get("commit", "?") for r in results})
    envs = [r.get("environment", {}) for r in results] or [{}]
    hardware = ", ".join(sorted({f"{e.get('cpu', '?')} ({e.get('cpu_count', '?')} cores)" for e in envs}))
    pythons = ", ".join(sorted({str(e.get("python", "?")) for e in envs}))
    lines = [
        "# Leaderboard",
        "",
        "Produced by the benchmark harness (`lfd_bench/run.py`); regenerate with:",
        "",
        f"```\n{command}\n```",
        "",
        f"Commit(s): {', '.join(commits)}. Hardware: {hardware}; Python {pythons}. Suite: `{suite or 'all'}`.",
        "",
        "Each cell: final normalised performance p̂(H) over evaluation episodes (eval variants) × seeds — "
        "25th percentile, mean ± std, median, 75th percentile (the thesis table format) — then the mean of each "
        "seed's episodes and the interquartile mean of those per-seed means with a 95% stratified-bootstrap CI "
        "(rliable). A *run* is one training seed: its episodes are averaged before any interval is computed, "
        "so the interval says how much another training run could differ. Budget columns are what training "
        "spent: steps in the training env, gradient updates, and demonstration transitions learnt from "
        "(BC: epochs × ⌈dataset size / batch size⌉ updates, no env steps). `expert` is the scripted oracle, `random` "
        "random actions (in pick-and-place: a random particle picked and placed at a random point, MAIL's random; "
        "`random_uniform`: uniform random actions), `zero` the all-zero action. Rows in *italics* are numbers reported "
        "elsewhere (source under the table), not measured here.",
        "",
    ]
    if (suite_config or {}).get("notes"):
        lines += [str(suite_config["notes"]), ""]
    table = group_by_env(results)
    legacy = False
    ordered = sorted(table.items(), key=lambda item: (not is_headline(item[1]), item[0]))  # headline cells first
    for env_label, agents in tqdm(ordered, desc="leaderboard", disable=not progress, leave=False, file=sys.stderr):
        env_id = next(iter(agents.values()))[0]["cell"]["env_id"]
        ref = references_for(suite_config, env_label, env_id)
        ref_rows = dict(ref["rows"]) if ref else {}
        metrics = reported_metrics(agents)
        head = header(metrics)
        lines += [f"## {env_label}" + (" — headline" if is_headline(agents) else ""), "", head, _sep(head)]
        order = sorted(agents, key=lambda a: (a != "expert", a in REFERENCE_AGENTS, a))
        for agent in order:
            row = agent_row(agent, agents[agent], metrics)[0]
            legacy |= "*" in row.split("|")[_ENV_STEPS_COLUMN + len(metrics)]
            lines.append(row)
            if agent in ref_rows:
                lines.append(reference_row(agent, ref["source"], ref_rows.pop(agent), metrics))
        for agent, numbers in ref_rows.items():
            lines.append(reference_row(agent, ref["source"], numbers, metrics))
        lines.append("")
        if metrics:
            lines += ["Beside p̂ (the task's published metric), per episode at its end: " + "; ".join(
                f"{REPORTED_METRICS[k]} = `info[\"{k}\"]`" + (f" ({METRIC_NOTES[k]})" if k in METRIC_NOTES else "")
                for k in metrics) + ".", ""]
        demos = demonstrations_line(agents)
        if demos:
            lines += [demos, ""]
        if ref:
            lines += [f"Reference rows: {ref.get('source', 'unknown source')}.", ""]
        notes = cell_notes(suite_config, env_label, agents)
        lines += [f"Note: {n}" for n in notes] + ([""] if notes else [])
        probs = improvement(agents)
        if probs:
            lines.append("Probability of improvement (rliable, seeds as runs): " + "; ".join(
                f"P({IMPROVER} > {b}) = {p:.2f} [{lo:.2f}, {hi:.2f}]" for b, (p, lo, hi) in probs.items()))
            lines.append("")
        if plot_dir is not None:
            images = []
            png = _png(plot_dir, suite, env_label)
            if plots.plot_curves(env_label, agents, png):
                images.append(f"![learning curves {env_label}]({os.path.relpath(png, relative_to)})")
            if probs:
                png = _png(plot_dir, suite, f"{env_label}_improvement")
                plots.plot_improvement(probs, IMPROVER, env_label, png)
                images.append(f"![probability of improvement {env_label}]({os.path.relpath(png, relative_to)})")
            if images:
                lines += [" ".join(images), ""]
            cov = coverage_markdown(coverage_of(agents), _png(plot_dir, suite, f"{env_label}_coverage"),
                                    relative_to, env_id)
            if cov:
                lines += [cov, ""]
    if legacy:
        lines += ["\\* requested budget: these results were written before env steps were counted.", ""]
    lines += _aggregate_section(table, suite, plot_dir, relative_to, suite_config)
    return "\n".join(lines)


def _aggregate_section(table: dict[str, dict[str, list[dict[str, Any]]]], suite: str | None,
                       plot_dir: Path | None, relative_to: Path,
                       suite_config: dict[str, Any] | None = None) -> list[str]:
    cells = main_cells(table)
    if len(cells) < 2:
        return []
    scores = seed_matrix(cells)
    if not scores:
        return []
    est = iqm_and_mean(scores)
    thesis = thesis_means(cells, suite_config)
    left_out = len(table) - len(cells)
    if any(is_headline(agents) for agents in cells.values()):
        scope = f"; the suite's headline cells: {'; '.join(cells)}"
    elif left_out:
        scope = (f"; per env, its cell with the most agents ({left_out} cell{'s' if left_out != 1 else ''} with "
                 f"fewer left out; ties go to the first label): {'; '.join(cells)}")
    else:
        scope = ""
    lines = ["## Across environments", "",
             f"Agents run on all {len(cells)} environments{scope}; runs = seeds (per-seed mean p̂ on each env), "
             "stratified-bootstrap 95% CIs (rliable). *Thesis mean*: the mean of the reference rows over the same "
             "environments, where every one has a row for the agent.", "",
             "| agent | runs × envs | IQM [95% CI] | mean [95% CI] | thesis mean |", "|---|---|---|---|---|"]
    for agent, e in sorted(est.items(), key=lambda kv: -kv[1]["iqm"]):
        ref = thesis.get(agent)
        lines.append(f"| {agent} | {scores[agent].shape[0]} × {scores[agent].shape[1]} | "
                     f"{e['iqm']:.3f} [{e['iqm_ci_low']:.3f}, {e['iqm_ci_high']:.3f}] | "
                     f"{e['mean']:.3f} [{e['mean_ci_low']:.3f}, {e['mean_ci_high']:.3f}] | "
                     f"{'—' if ref is None else f'{ref:.3f}'} |")
    lines.append("")
    if plot_dir is not None:
        taus = np.linspace(0.0, 1.0, 21)
        profiles, cis = performance_profiles(scores, taus)
        a = plots.plot_interval_estimates(est, _png(plot_dir, suite, "aggregate"))
        b = plots.plot_profiles(profiles, cis, taus, _png(plot_dir, suite, "profiles"))
        lines += [f"![IQM and mean]({os.path.relpath(a, relative_to)}) "
                  f"![performance profiles]({os.path.relpath(b, relative_to)})", ""]
    return lines


def _reference_means(cells: dict[str, dict[str, list[dict[str, Any]]]], suite_config: dict[str, Any] | None,
                     key: str = "mean") -> dict[str, dict[str, float]]:
    """``{env label: {agent: reported value}}`` of the suite's reference rows for these cells (``key``:
    ``"mean"`` for p̂, or a reported metric such as ``"is_success"``)."""
    out: dict[str, dict[str, float]] = {}
    for label, agents in cells.items():
        env_id = next(iter(agents.values()))[0]["cell"]["env_id"]
        ref = references_for(suite_config, label, env_id)
        rows = ref["rows"] if ref else {}
        out[label] = {a: float(row[key]) for a, row in rows.items() if isinstance(row.get(key), (int, float))}
    return out


def thesis_means(cells: dict[str, dict[str, list[dict[str, Any]]]], suite_config: dict[str, Any] | None
                 ) -> dict[str, float]:
    """Mean over ``cells`` of each agent's reported mean, for agents reported on every one of them."""
    refs = _reference_means(cells, suite_config)
    agents = set.intersection(*(set(r) for r in refs.values())) if refs else set()
    return {a: float(np.mean([r[a] for r in refs.values()])) for a in sorted(agents)}


def _sep(head: str = HEADER) -> str:
    return "|" + "---|" * (head.count("|") - 1)


# ------------------------------------------------------------------------------- headline
#: what a suite's headline table may show (``"headline_metric"``), as its caption names it
HEADLINE_METRICS = {"normalized_performance": "Mean final p̂", "is_success": "Success rate"}


def _reference_key(metric: str) -> str:
    """The key of a reference row holding the thesis's value of ``metric``."""
    return "mean" if metric == "normalized_performance" else metric


def _headline_value(runs: list[dict[str, Any]], metric: str = "normalized_performance") -> str:
    """``mean [95% CI]`` of the per-seed means (seeds as runs); one seed: ``mean (1 seed)``; ``—``
    where the runs did not record ``metric``."""
    try:
        s = summarize(by_seed(runs, metric))
    except KeyError:
        return "—"
    if s.seeds < 2:
        return f"{_three(s.mean)} (1 seed)"
    return f"{_three(s.mean)} [{_three(s.mean_ci_low)}, {_three(s.mean_ci_high)}]"


def _three(value: float) -> str:
    """``value`` to three decimals, never ``-0.000``."""
    return f"{0.0 if abs(value) < 5e-4 else value:.3f}"


def _beside_headline(runs: list[dict[str, Any]], metrics: list[str]) -> str:
    """`` · fold quality 0.789``: the mean over seeds of each reported metric the runs recorded."""
    parts = []
    for m in metrics:
        try:
            parts.append(f"{REPORTED_METRICS[m]} {_three(_mean_of_seeds(runs, m))}")
        except KeyError:
            continue
    return "".join(f" · {p}" for p in parts)


def _mean_of_seeds(runs: list[dict[str, Any]], metric: str) -> float:
    """The mean over seeds of each seed's mean ``metric``; ``KeyError`` if a run did not record it."""
    return float(np.mean([np.mean(v) for v in by_seed(runs, metric)]))


def _beside_caption(beside: dict[str, list[str]]) -> str:
    """The caption's sentence naming the reported metrics shown beside the headline metric, if any."""
    names = [REPORTED_METRICS[m] for m in REPORTED_METRICS if any(m in ms for ms in beside.values())]
    return f" Beside it: the mean over seeds of {' and '.join(names)}, where the task reports it." if names else ""


def verdicts(cells: dict[str, dict[str, list[dict[str, Any]]]], suite_config: dict[str, Any] | None,
             metric: str = "normalized_performance") -> list[str]:
    """One line per cell: each learner's mean beside the thesis's, met (ours ≥ thesis) or not, by how much."""
    refs = _reference_means(cells, suite_config, _reference_key(metric))
    lines = []
    for label, agents in cells.items():
        parts = []
        for agent in sorted(a for a in agents if a in refs[label] and a not in REFERENCE_AGENTS):
            try:
                ours = _mean_of_seeds(agents[agent], metric)
            except KeyError:
                continue
            diff = ours - refs[label][agent]
            parts.append(f"{agent} {ours:.3f} vs {refs[label][agent]:.3f}: "
                         f"{'met' if diff >= 0 else 'not met'} ({diff:+.3f})")
        lines.append(f"- {label}: " + ("; ".join(parts) if parts else "no learner here has a reported number."))
    return lines


def render_headline(results: list[dict[str, Any]], *, suite: str, suite_config: dict[str, Any] | None,
                    command: str, page: str) -> str:
    """The suite's section of ``leaderboard.md``: one table of its headline cells (agents × tasks,
    the thesis's row under each agent), a verdict per task, the budget cut and a link to ``page``
    (the appendix with every cell)."""
    config = suite_config or {}
    metric = config.get("headline_metric", "normalized_performance")
    table = group_by_env(results)
    cells = main_cells(table)
    refs = _reference_means(cells, suite_config, _reference_key(metric))
    marked = any(is_headline(agents) for agents in cells.values())
    beside = {label: [m for m in reported_metrics(cells[label]) if m != metric] for label in cells}
    lines = [f"# Suite `{suite}`", ""]
    if config.get("description"):
        lines += [str(config["description"]).split(". ")[0].rstrip(".") + ".", ""]
    lines += [("Headline cells: each agent runs one recipe on every task." if marked else
               "No cell is marked headline: per env, its cell with the most agents.") +
              (f" Budget: {config['budget_cut']}" if config.get("budget_cut") else ""),
              "", f"{HEADLINE_METRICS[metric]} over seeds, [95% CI] with seeds as runs; *thesis* rows: the reported "
              "value." + _beside_caption(beside), ""]
    head = "| agent | " + " | ".join(cells) + " |"
    lines += [head, _sep(head)]
    # agents with a thesis row but no finished cell yet keep their row: the reader sees what is missing
    agents = sorted({a for agents in cells.values() for a in agents} | {a for r in refs.values() for a in r},
                    key=lambda a: (a != "expert", a in REFERENCE_AGENTS, a))
    for agent in agents:
        lines.append(f"| {agent} | " + " | ".join(
            _headline_value(cells[label][agent], metric) + _beside_headline(cells[label][agent], beside[label])
            if agent in cells[label] else "—" for label in cells) + " |")
        if any(agent in refs[label] for label in cells):
            lines.append(f"| *thesis: {agent}* | " + " | ".join(
                f"{refs[label][agent]:.3f}" if agent in refs[label] else "—" for label in cells) + " |")
    lines += ["", "Against the thesis (mean of seeds vs reported value):"] + verdicts(cells, suite_config, metric)
    lines += ["", f"Every cell, per-seed numbers, curves and notes: [{page}]({page}). Regenerate: `{command}`."]
    return "\n".join(lines)


def write_leaderboard(results_dir: Path, out_path: Path, *, command: str, suite: str | None = None,
                      plot_dir: Path | None = None, suite_config: dict[str, Any] | None = None,
                      progress: bool = False, pages_dir: Path | None = None) -> Path:
    """Regenerate the suite's section of ``out_path`` (its headline, :func:`render_headline`) and its
    appendix page ``docs/results/<suite>.md`` beside it (every cell, :func:`render_markdown`) from the
    results of ``suite`` (all suites if None); ``pages_dir`` puts the appendix page elsewhere. Files are
    written atomically.

    ``suite_config`` (the suite JSON) supplies reference rows and notes; when omitted the
    committed suite named ``suite`` is used if there is one.
    """
    results = load_results(results_dir, suite)
    if not results:
        raise ValueError(f"no results found in {results_dir} for suite {suite!r}")
    if suite_config is None and suite:
        from lfd_bench.run import load_suite

        try:
            suite_config = load_suite(suite)
        except (ValueError, OSError):
            suite_config = None
    mark_headline(results, suite_config)
    out_path = Path(out_path)
    name = suite or "all"
    page = Path(pages_dir) / f"{safe_name(name)}.md" if pages_dir else appendix_path(out_path, name)
    plot_dir = plot_dir or out_path.parent / "docs" / "leaderboard"
    text = render_markdown(results, command=command, suite=suite, plot_dir=plot_dir, relative_to=page.parent,
                           suite_config=suite_config, progress=progress)
    atomic_write_text(page, text.replace("# Leaderboard", f"# Suite `{name}`: every cell", 1) + "\n")
    headline = render_headline(results, suite=name, suite_config=suite_config, command=command,
                               page=os.path.relpath(page, out_path.parent))
    previous = out_path.read_text() if out_path.exists() else ""
    return atomic_write_text(out_path, merge_suite_section(previous, name, headline))


def appendix_path(leaderboard: Path, suite: str) -> Path:
    """Where the appendix page of ``suite`` goes: ``docs/results/<suite>.md`` beside the leaderboard."""
    return Path(leaderboard).parent / "docs" / "results" / f"{safe_name(suite)}.md"


_TITLE = "# Leaderboard"
_INTRO = ("One section per benchmark suite: its headline table (each agent with one recipe on every task, "
          "the thesis's number under ours), a verdict per task and a link to the suite's appendix page with every "
          "other cell, per-seed numbers, curves and notes. Each section is rewritten by its own run of the harness "
          "(the command is at its end); the others are kept. A *run* is one training seed: its evaluation "
          "episodes are averaged before any interval is computed.")


def _block_markers(name: str) -> tuple[str, str]:
    return f"<!-- leaderboard:suite={name} -->", f"<!-- /leaderboard:suite={name} -->"


def _suite_blocks(document: str) -> dict[str, str]:
    """The suite sections of a leaderboard document, in order (none in an older single-suite file)."""
    blocks: dict[str, str] = {}
    for match in re.finditer(r"<!-- leaderboard:suite=(\S+) -->\n(.*?)\n<!-- /leaderboard:suite=\1 -->",
                             document, flags=re.S):
        blocks[match.group(1)] = match.group(2)
    return blocks


def merge_suite_section(document: str, suite: str, rendered: str) -> str:
    """``document`` (a leaderboard file, possibly empty) with the section of ``suite`` replaced by
    ``rendered`` (a :func:`render_headline` result, headings moved one level down), other suites'
    sections kept in their order and a new suite appended."""
    lines = rendered.splitlines()
    if lines and lines[0] == _TITLE:
        lines[0] = f"# Suite `{suite}`"
    body = "\n".join(("#" + line) if line.startswith("#") else line for line in lines).strip("\n")
    blocks = _suite_blocks(document)
    blocks[suite] = body
    parts = [_TITLE, "", _INTRO, "", "Suites: " + ", ".join(f"`{name}`" for name in blocks) + ".", ""]
    for name, text in blocks.items():
        start, end = _block_markers(name)
        parts += [start, text, end, ""]
    return "\n".join(parts)
