"""Benchmark harness: statistics, an end-to-end tiny suite, resume, and clear errors."""

import json
import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import lfd_envs  # noqa: F401  (registers the env ids)
from lfd_bench import run as bench
from lfd_bench.agents import resolve_agent
from lfd_bench.stats import iqm_and_mean, probability_of_improvement, summarize

README = Path(__file__).resolve().parent.parent / "README.md"


def third_party_factory(env, seed, **kwargs):
    """A third-party agent: always moves straight to the goal (reads the toy env's state)."""
    class Agent:
        def learn(self, total_timesteps):
            return self

        def predict(self, obs, deterministic=True):
            return np.clip((obs[2:] - obs[:2]) / 0.1, -1, 1), None

    return Agent()


@pytest.fixture(autouse=True)
def fast_bootstrap(request, monkeypatch):
    """Fewer bootstrap replications in harness tests (the statistics test keeps the defaults)."""
    from lfd_bench import stats

    if "stats" not in request.node.name:
        monkeypatch.setattr(stats, "REPS", 200)
        monkeypatch.setattr(stats, "POI_REPS", 100)


def test_stats_match_numpy_and_rliable():
    x = np.arange(20, dtype=float)
    s = summarize(x)
    assert s.p25 == np.percentile(x, 25) and s.p75 == np.percentile(x, 75)
    assert s.mean == x.mean() and s.std == x.std() and s.median == np.median(x)
    assert s.iqm == pytest.approx(np.mean(x[5:15]))
    assert s.iqm_ci_low <= s.iqm <= s.iqm_ci_high and s.mean_ci_low <= s.mean <= s.mean_ci_high
    wide = iqm_and_mean({"x": x})["x"]
    narrow = iqm_and_mean({"x": np.tile(x, 10)})["x"]
    assert narrow["iqm_ci_high"] - narrow["iqm_ci_low"] < wide["iqm_ci_high"] - wide["iqm_ci_low"]
    p, lo, hi = probability_of_improvement(x + 100, x)
    assert p == 1.0 and lo == hi == 1.0


def test_stats_cell_intervals_treat_seeds_as_runs():
    """Three seeds of 20 episodes whose means differ widely: the interval spans the seeds' spread
    (episodes of one seed are not independent runs), the percentiles still cover every episode."""
    rng = np.random.default_rng(0)
    seeds = [m + rng.normal(0, 0.01, 20) for m in (0.515, 0.896, 0.942)]
    s = summarize(seeds)
    assert s.seeds == 3 and s.n == 60
    assert s.seed_means == pytest.approx([float(np.mean(v)) for v in seeds])
    assert s.mean_ci_low < 0.55 and s.mean_ci_high > 0.9
    episodes = summarize([[v] for v in np.concatenate(seeds)])  # the old, wrong unit: 60 "runs"
    assert episodes.mean_ci_high - episodes.mean_ci_low < 0.5 * (s.mean_ci_high - s.mean_ci_low)
    with pytest.raises(ValueError, match="empty"):
        summarize([[0.5], []])


def test_stats_bootstraps_are_reproducible_and_leave_the_global_rng_alone():
    """Two computations from the same scores give the same intervals (rliable draws its resampling
    indices from NumPy's global generator), and the caller's global random stream is untouched."""
    rng = np.random.default_rng(0)
    x, y = rng.random(60), rng.random(60)
    np.random.seed(123)
    expected_next = np.random.RandomState(123).random_sample()
    first = (iqm_and_mean({"x": x}), probability_of_improvement(x, y))
    np.random.random_sample()  # the global stream moves on between the two computations
    assert (iqm_and_mean({"x": x}), probability_of_improvement(x, y)) == first
    np.random.seed(123)
    iqm_and_mean({"x": x})
    assert np.random.random_sample() == expected_next


def _suite(tmp_path):
    suite = {
        "name": "tiny",
        "seeds": [0],
        "eval_episodes": 6,
        "budget": 20,
        "curve_points": 2,
        "cells": [{"env": "toy_env:lfd_test/PointReach-v0", "agents": {"random": {}, f"{__name__}:third_party_factory": {}}}],
    }
    path = tmp_path / "tiny.json"
    path.write_text(json.dumps(suite))
    return path


def test_tiny_suite_end_to_end_and_resume(tmp_path):
    suite = _suite(tmp_path)
    out, board = tmp_path / "results", tmp_path / "leaderboard.md"
    args = ["--suite", str(suite), "--out", str(out), "--leaderboard", str(board), "--no-progress"]
    assert bench.main(args) == 0
    files = sorted(out.rglob("*.json"))
    assert len(files) == 2
    headline = board.read_text()
    pages = sorted((tmp_path / "docs" / "results").glob("*.md"))
    assert len(pages) == 1 and f"({pages[0].relative_to(tmp_path)})" in headline  # linked from the headline
    text = pages[0].read_text()  # every cell in detail
    for f in files:
        r = json.loads(f.read_text())
        finals = np.asarray(r["final_normalized_performance"])
        assert len(finals) == 6
        row = next(l for l in text.splitlines() if l.startswith(f"| {r['cell']['agent']} |"))
        assert f"{finals.mean():.3f} ± {finals.std():.3f}" in row
        assert f"{np.median(finals):.3f}" in row
        assert any(l.startswith(f"| {r['cell']['agent']} | {finals.mean():.3f}") for l in headline.splitlines())
    rows = {l.split("|")[1].strip(): l for l in text.splitlines() if l.startswith("| ")}
    mean = lambda row: float(row.split("|")[5].split("±")[0])
    assert mean(rows[f"{__name__}:third_party_factory"]) > mean(rows["random"]) + 0.5
    mtimes = [f.stat().st_mtime_ns for f in files]
    assert bench.main(args) == 0  # resume: nothing re-run
    assert [f.stat().st_mtime_ns for f in files] == mtimes


def test_bad_agent_and_env_errors(tmp_path, capsys):
    with pytest.raises(ValueError, match="valid built-in agents are .*random"):
        resolve_agent("not_an_agent")
    with pytest.raises(ValueError, match="no callable"):
        resolve_agent("lfd_bench.stats:nothing_here")
    assert bench.main(["--suite", str(_suite(tmp_path)), "--envs", "Nope-v0", "--out", str(tmp_path)]) == 2
    assert "valid:" in capsys.readouterr().err
    with pytest.raises(ValueError, match="valid suites are"):
        bench.load_suite("no-such-suite")
    with pytest.raises(ValueError, match="select_episodes must be >= 0"):
        resolve_agent("bc")(gym.make("ThreeBoxes-v0", **THREE_BOXES), 0, select_episodes=-1)


def test_readme_third_party_example_runs(tmp_path, monkeypatch):
    """The README's third-party agent example runs as written through the harness."""
    text = README.read_text()
    code = re.search(r"```python\n(# my_agents.py.*?)```", text, re.S).group(1)
    (tmp_path / "my_agents.py").write_text(code)
    monkeypatch.syspath_prepend(str(tmp_path))
    suite = json.loads(_suite(tmp_path).read_text())
    suite["cells"][0]["agents"] = {"random": {}}
    (tmp_path / "s.json").write_text(json.dumps(suite))
    out = tmp_path / "res"
    assert bench.main(["--suite", str(tmp_path / "s.json"), "--agent", "my_agents:make_agent", "--out", str(out),
                       "--leaderboard", str(tmp_path / "lb.md"), "--no-progress"]) == 0
    assert "my_agents:make_agent" in (tmp_path / "lb.md").read_text()


# ---------------------------------------------------------------------- crash safety and budgets
THREE_BOXES = {"num_pickers": 1, "action_mode": "pick_place", "obs_mode": "state"}


def _bc_suite(tmp_path, **extra):
    suite = {"name": "bcs", "seeds": [0], "eval_episodes": 2, "budget": 5, "curve_points": 1,
             "cells": [{"env": "ThreeBoxes-v0", "env_kwargs": THREE_BOXES, "label": "pp",
                        "agents": {"bc": {"demo_episodes": 2, "n_epochs": 3, "batch_size": 4}, "random": {}},
                        **extra}]}
    path = tmp_path / "bcs.json"
    path.write_text(json.dumps(suite))
    return path


def _args(suite, tmp_path, *more):
    return ["--suite", str(suite), "--out", str(tmp_path / "res"), "--leaderboard", str(tmp_path / "lb.md"),
            "--no-progress", *more]


def test_demo_cache_under_out_rebuilt_when_broken_and_budgets_recorded(tmp_path, capsys):
    suite = _bc_suite(tmp_path)
    assert bench.main(_args(suite, tmp_path)) == 0
    cache = tmp_path / "res" / "_demos"
    h5 = sorted(cache.rglob("*.hdf5"))
    assert len(h5) == 1, "the demonstration cache lives under --out"
    assert not list(cache.glob(".*tmp*")), "no temporary collection folder left behind"
    bc = json.loads((tmp_path / "res" / "bcs" / "ThreeBoxes-v0__pp" / "bc" / "seed0.json").read_text())
    n = bc["demo_transitions"]
    assert n == 2 * 3  # two pick_place episodes of horizon 3
    assert bc["env_steps"] == 0 and bc["gradient_updates"] == 3 * int(np.ceil(n / 4))
    lines = (tmp_path / "docs" / "results" / "bcs.md").read_text().splitlines()  # the appendix: every column
    head = [c.strip() for c in next(l for l in lines if l.startswith("| agent |")).split("|")]
    cols = [c.strip() for c in next(l for l in lines if l.startswith("| bc |")).split("|")]
    budget = [cols[head.index(k)] for k in ("env steps", "gradient updates", "demo transitions")]
    assert budget == ["0", str(3 * int(np.ceil(n / 4))), str(n)]  # found by name: metric columns may come first
    assert 0.5 < bc["demo_performance"] <= 1.0  # the expert's demonstrations, mean final p̂
    assert f"bc: {bc['demo_performance']:.3f} (expert)" in next(l for l in lines if l.startswith("Demonstrations"))

    h5[0].write_bytes(h5[0].read_bytes()[:200])  # a kill while Minari wrote the file
    key = h5[0].relative_to(cache).parts[0]
    abandoned = cache / f".{key}.tmp-999999999-dead"  # left by a collection that was killed
    abandoned.mkdir()
    with pytest.warns(UserWarning, match=re.escape(str(h5[0].parent.parent.parent))):
        assert bench.main(_args(suite, tmp_path, "--force")) == 0
    assert json.loads((tmp_path / "res" / "bcs" / "ThreeBoxes-v0__pp" / "bc" / "seed0.json").read_text())[
        "demo_transitions"] == n
    assert not abandoned.exists()
    # the demonstration cache's Minari metadata.json files are not results
    from lfd_bench.leaderboard import write_leaderboard

    assert list(cache.rglob("metadata.json"))
    write_leaderboard(tmp_path / "res", tmp_path / "all.md", command="x", suite=None)
    assert "ThreeBoxes-v0 (pp)" in (tmp_path / "all.md").read_text()


def test_demo_agents_select_the_best_checkpoint_and_count_its_steps(tmp_path):
    suite = {"name": "sel", "seeds": [0], "eval_episodes": 2, "budget": 4, "curve_points": 2,
             "cells": [{"env": "ThreeBoxes-v0", "env_kwargs": THREE_BOXES, "label": "pp",
                        "agents": {"bc": {"demo_episodes": 2, "n_epochs": 2, "batch_size": 4, "select_episodes": 3}}}]}
    path = tmp_path / "sel.json"
    path.write_text(json.dumps(suite))
    assert bench.main(_args(path, tmp_path)) == 0
    bc = json.loads((tmp_path / "res" / "sel" / "ThreeBoxes-v0__pp" / "bc" / "seed0.json").read_text())
    # 2 chunks x 3 validation episodes of horizon 3; BC itself takes no env step
    assert bc["env_steps"] == 2 * 3 * 3
    # BC's 2 configured epochs x the batches in all (the second curve point's learn call trains
    # no more), counted once (not once more through the wrapper)
    assert bc["gradient_updates"] == 2 * int(np.ceil(bc["demo_transitions"] / 4))
    assert len(bc["learning_curve"]) == 2 and len(bc["validation_scores"]) == 2  # one score per chunk


def test_corrupt_cell_json_is_named_and_rerun(tmp_path, capsys):
    suite = _suite(tmp_path)
    args = ["--suite", str(suite), "--out", str(tmp_path / "res"), "--leaderboard", str(tmp_path / "lb.md"),
            "--no-progress"]
    assert bench.main(args) == 0
    victim = next((tmp_path / "res").rglob("random/seed0.json"))
    victim.write_text(victim.read_text()[:40])  # truncated by a kill
    capsys.readouterr()
    assert bench.main(args) == 0
    err = capsys.readouterr().err
    assert str(victim) in err and "running the cell again" in err
    assert len(json.loads(victim.read_text())["final_normalized_performance"]) == 6
    # the leaderboard step names a corrupt file instead of crashing
    victim.write_text("{")
    from lfd_bench.leaderboard import load_results

    assert len(load_results(tmp_path / "res", "tiny")) == 1
    assert str(victim) in capsys.readouterr().err


def test_unwritable_out_refused_before_training(tmp_path, capsys, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    monkeypatch.setattr("lfd_bench.cell.run_cell", lambda *a, **k: pytest.fail("trained despite an unwritable --out"))
    assert bench.main(["--suite", str(_suite(tmp_path)), "--out", str(blocker / "res"), "--no-progress",
                       "--leaderboard", str(tmp_path / "lb.md")]) == 2
    assert f"cannot write to {blocker / 'res'}" in capsys.readouterr().err


def test_leaderboard_written_atomically(tmp_path, monkeypatch):
    from lfd_bench import leaderboard

    suite = _suite(tmp_path)
    args = ["--suite", str(suite), "--out", str(tmp_path / "res"), "--leaderboard", str(tmp_path / "lb.md"),
            "--no-progress"]
    assert bench.main(args) == 0
    before = (tmp_path / "lb.md").read_text()

    def killed(*a, **k):
        raise KeyboardInterrupt  # a kill while the document is produced

    monkeypatch.setattr(leaderboard, "render_markdown", killed)
    with pytest.raises(KeyboardInterrupt):
        leaderboard.write_leaderboard(tmp_path / "res", tmp_path / "lb.md", command="x", suite="tiny")
    assert (tmp_path / "lb.md").read_text() == before
    monkeypatch.undo()
    from lfd_bench.storage import atomic_write_text

    def half_written(tmp):
        tmp.write_text("half")
        raise KeyboardInterrupt

    from lfd_bench.storage import atomic_write

    with pytest.raises(KeyboardInterrupt):
        atomic_write(tmp_path / "lb.md", half_written)
    assert (tmp_path / "lb.md").read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []
    atomic_write_text(tmp_path / "lb.md", "new")
    assert (tmp_path / "lb.md").read_text() == "new"


def test_reference_rows_and_notes(tmp_path):
    suite = json.loads(_suite(tmp_path).read_text())
    suite["notes"] = "Widths cut to 64 for a CPU."
    suite["cells"][0]["notes"] = "budget 20 steps instead of 1M"
    suite["reference"] = {"lfd_test/PointReach-v0": {"source": "thesis Table 4.1", "rows": {
        "random": {"mean": 0.111, "std": 0.022, "p25": 0.05, "median": 0.1, "p75": 0.2},
        "dmfd": {"mean": 0.9}}}}
    path = tmp_path / "ref.json"
    path.write_text(json.dumps(suite))
    assert bench.main(["--suite", str(path), "--out", str(tmp_path / "res"), "--leaderboard",
                       str(tmp_path / "lb.md"), "--no-progress"]) == 0
    headline = (tmp_path / "lb.md").read_text().splitlines()
    i = next(k for k, l in enumerate(headline) if l.startswith("| random |"))
    assert headline[i + 1].startswith("| *thesis: random* | 0.111 |")  # the thesis under ours in the headline
    assert any(l.startswith("- toy_env:lfd_test/PointReach-v0:") for l in headline)  # one verdict line per task
    lines = (tmp_path / "docs" / "results" / "tiny.md").read_text().splitlines()
    i = next(k for k, l in enumerate(lines) if l.startswith("| random |"))
    assert lines[i + 1].startswith("| *thesis: random* |") and "0.111 ± 0.022" in lines[i + 1]
    assert "| 0.050 |" in lines[i + 1] and "| 0.200 |" in lines[i + 1]
    assert any(l.startswith("| *thesis: dmfd* |") and "0.900" in l for l in lines)
    assert "Reference rows: thesis Table 4.1." in lines
    assert "Widths cut to 64 for a CPU." in lines and "Note: budget 20 steps instead of 1M" in lines


def test_malformed_suite_refused_before_training(tmp_path, capsys):
    suite = json.loads(_suite(tmp_path).read_text())
    suite["reference"] = {"lfd_test/PointReach-v0": {"source": "thesis", "rows": {"random": {"average": 0.1}}}}
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(suite))
    assert bench.main(["--suite", str(path), "--out", str(tmp_path / "res"), "--no-progress"]) == 2
    assert "unknown keys ['average']" in capsys.readouterr().err and not (tmp_path / "res").exists()
    path.write_text("{")
    assert bench.main(["--suite", str(path), "--out", str(tmp_path / "res"), "--no-progress"]) == 2
    assert "not valid JSON" in capsys.readouterr().err


def test_readme_suite_example_is_a_valid_suite():
    text = README.read_text()
    example = json.loads(re.search(r"```json\n(.*?)```", text, re.S).group(1))
    bench.check_suite(example, "README example")
    cells = bench.expand_cells({"name": "readme", **example})
    assert cells[0].cpus == 2 and cells[0].tags["notes"]


def broken_factory(env, seed, **kwargs):
    """A third-party agent that cannot be built (like a wrong keyword in a suite)."""
    raise TypeError("broken_factory() got an unexpected keyword argument 'widht'")


def test_preflight_runs_every_pair_tiny_and_names_crashes(tmp_path, capsys):
    suite = _suite(tmp_path)
    out = tmp_path / "res"
    assert bench.main(["--suite", str(suite), "--out", str(out), "--no-progress", "--preflight"]) == 0
    assert "preflight: all 2 (env, agent) pairs ran" in capsys.readouterr().out
    assert not list(out.rglob("*.json")), "preflight results are not results"
    assert bench.main(["--suite", str(suite), "--out", str(out), "--no-progress", "--preflight",
                       "--agent", f"{__name__}:broken_factory"]) == 1
    assert "broken_factory" in capsys.readouterr().err


def test_leaderboard_shows_reported_success_in_reference_rows_and_the_coverage_picture(tmp_path):
    from lfd_bench.leaderboard import render_markdown

    rng = np.random.default_rng(0)

    def result(agent, seed, success):
        pts = rng.uniform(-0.4, 0.4, (30, 2)).round(4).tolist()
        return {"cell": {"suite": "s", "env_id": "Push2DObstacle-v0", "agent": agent, "seed": seed, "tags": {}},
                "final_normalized_performance": [0.1, 0.2], "final_metrics": {"is_success": [success, 0.0]},
                "learning_curve": [{"steps": 10, "mean_normalized_performance": 0.1}], "train_wall_time_s": 1.0,
                "env_steps": 10, "gradient_updates": 5, "demo_transitions": 0,
                "coverage": {"steps": 30, "cell": 0.02, "visited_cells": 17 + seed, "every": 1, "points": pts}}

    results = [result("mopa_sac", 0, 1.0), result("sac", 0, 0.0)]
    results[0]["environment"] = {"cpu": "CPU A", "cpu_count": 2, "python": "3.11.7"}
    results[1]["environment"] = {"cpu": "CPU B", "cpu_count": 4, "python": "3.11.7"}
    config = {"reference": {"Push2DObstacle-v0": {"source": "thesis Fig. 3.5", "rows": {
        "mopa_sac": {"mean": 0.5, "is_success": 0.97}}}}}
    md = render_markdown(results, command="x", suite="s", plot_dir=tmp_path / "plots", relative_to=tmp_path,
                         suite_config=config)
    ref = next(line for line in md.splitlines() if line.startswith("| *thesis: mopa_sac*"))
    assert " 0.970 |" in ref  # the reported success rate sits in the success column
    assert "Hardware: CPU A (2 cores), CPU B (4 cores); Python 3.11.7." in md  # every machine the cells ran on
    assert "coverage" in md and "| mopa_sac | 30 | 17 | 17 |" in md
    assert any(p.suffix == ".png" and "coverage" in p.name for p in (tmp_path / "plots").rglob("*"))


def test_leaderboard_keeps_other_suites_sections():
    from lfd_bench.leaderboard import merge_suite_section

    doc = merge_suite_section("", "a", "# Leaderboard\n\ncommand a\n\n## Env-v0\n\n| row a1 |")
    doc = merge_suite_section(doc, "b", "# Leaderboard\n\ncommand b\n\n## Env-v0\n\n| row b |")
    doc = merge_suite_section(doc, "a", "# Leaderboard\n\ncommand a2\n\n## Env-v0\n\n| row a2 |")
    assert doc.startswith("# Leaderboard\n") and doc.count("# Leaderboard") == 1
    assert "| row b |" in doc and "| row a2 |" in doc and "row a1" not in doc
    assert doc.index("## Suite `a`") < doc.index("## Suite `b`")  # order kept, a replaced in place
    assert "### Env-v0" in doc and "Suites: `a`, `b`." in doc
    # an older single-suite file is replaced by the sectioned layout
    assert "old" not in merge_suite_section("# Leaderboard\n\nold\n", "a", "# Leaderboard\n\nnew")


def test_reference_rows_keyed_by_label_are_not_shown_under_other_labels_of_the_env():
    from lfd_bench.leaderboard import references_for

    ref = {"source": "s", "rows": {"bc": {"mean": 0.9}}}
    config = {"reference": {"E-v0 (state)": ref}}
    assert references_for(config, "E-v0 (state)", "E-v0") is ref
    assert references_for(config, "E-v0 (noisy demos, state)", "E-v0") is None
    assert references_for({"reference": {"E-v0": ref}}, "E-v0 (any)", "E-v0") is ref  # env id: every label


def test_agents_filter_keeps_each_cell_to_the_agents_it_lists():
    """``--agents`` never gives a cell an agent that another cell of the suite lists (with that
    cell's settings) — only names no cell lists (e.g. a third-party factory) go everywhere."""
    suite = {"name": "filter", "cells": [
        {"env": "StraightenRope-v0", "label": "a", "agents": {"zero": {}, "bc": {"demo_episodes": 3}}},
        {"env": "StraightenRope-v0", "label": "b", "agents": {"random": {}}}]}
    cells = bench.expand_cells(suite, agents=["bc", "random", f"{__name__}:broken_factory"])
    got = {(c.tags["label"], c.agent) for c in cells}
    assert got == {("a", "bc"), ("a", f"{__name__}:broken_factory"), ("b", f"{__name__}:broken_factory"),
                   ("b", "random")}
    assert next(c for c in cells if c.agent == "bc").agent_kwargs == {"demo_episodes": 3}
    two_envs = {"name": "filter2", "cells": [{"env": "StraightenRope-v0", "agents": {"bc": {}}},
                                             {"env": "ClothFold-v0", "agents": {"random": {}}}]}
    with pytest.raises(ValueError, match="lists agent"):  # nothing to run: said, not an empty leaderboard
        bench.expand_cells(two_envs, agents=["bc"], envs=["ClothFold-v0"])


def test_report_rewrites_the_leaderboard_from_finished_cells_and_trains_nothing(tmp_path, monkeypatch, capsys):
    suite = _suite(tmp_path)
    out, board = tmp_path / "res", tmp_path / "lb.md"
    args = ["--suite", str(suite), "--out", str(out), "--leaderboard", str(board), "--no-progress"]
    assert bench.main(args + ["--report"]) == 1  # nothing finished yet: nothing to report
    assert "error" in capsys.readouterr().err and not board.exists()
    assert bench.main(args + ["--agents", "random"]) == 0  # one of the two agents
    board.write_text("stale")
    monkeypatch.setattr("lfd_bench.cell.run_cell", lambda *a, **k: pytest.fail("--report trained a cell"))
    assert bench.main(args + ["--report"]) == 0
    text = board.read_text()
    assert "| random |" in text and "third_party_factory" not in text
    assert "--report" not in text and f"python -m lfd_bench.run --suite {suite}" in text


def test_the_regenerate_command_drops_the_options_that_only_scope_this_run():
    """The leaderboard shows every finished cell of the suite, so the command it prints must
    regenerate all of them, not the slice this invocation trained."""
    argv = ["--suite", "s", "--envs", "A-v1", "B-v1", "--agents", "dmfd", "curl", "--jobs=2", "--seeds", "0", "1",
            "--no-progress", "--executor", "local", "--force", "--report", "--budget", "100", "--agent", "m:f"]
    assert bench.regenerate_command(argv) == "python -m lfd_bench.run --suite s --seeds 0 1 --budget 100 --agent m:f"


def test_train_speed_matmul_floor_is_part_of_the_update_and_sets_max_vs_sac():
    """The replayed matrix products of an update take less time than the whole update, and
    ``max_vs_sac`` is SB3 SAC's update time over the agent's matmul time (same run)."""
    import torch as th

    from benchmarks.train_speed import agent_rows

    threads = th.get_num_threads()
    th.set_num_threads(1)
    try:
        rows = agent_rows("ClothFold-v0", widths=[64], agents=["dmfd", "bc", "sac"], rounds=1, updates=20,
                          learn_steps=10, batch_size=64, buffer_rows=500)
    finally:
        th.set_num_threads(threads)
    by = {r["agent"]: r for r in rows}
    assert by["BC"]["matmul_ms"] is None and by["BC"]["max_vs_sac"] is None
    for name in ("DMfD", "SB3 SAC"):
        r = by[name]
        assert 0 < r["matmul_ms"] < r["update_ms"], r
        assert 0 < r["matmul_share"] < 1, r
    expected = by["SB3 SAC"]["update_ms"] / by["DMfD"]["matmul_ms"]
    assert by["DMfD"]["max_vs_sac"] == pytest.approx(expected, rel=0.05)


def test_cells_evaluate_with_sampled_actions_where_deterministic_is_false(tmp_path):
    """``"deterministic": false`` reaches the agent's predict in the evaluation; a non-bool is refused."""
    import gymnasium as gym

    from lfd_bench.cell import evaluate_episodes

    class Recorder:
        def __init__(self, env):
            self.space, self.flags = env.action_space, set()

        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            self.flags.add(deterministic)
            return np.zeros(self.space.shape, self.space.dtype), None

    env = gym.make("Push2DObstacle-v0")
    for deterministic in (True, False):
        agent = Recorder(env)
        evaluate_episodes(agent, env, 1, seed=0, deterministic=deterministic)
        assert agent.flags == {deterministic}
    suite = {"name": "t", "cells": [{"env": "Push2DObstacle-v0", "deterministic": False, "agents": {"zero": {}}}]}
    bench.check_suite(suite)
    assert [c.deterministic for c in bench.expand_cells(suite)] == [False]
    with pytest.raises(ValueError, match="deterministic must be true or false"):
        bench.check_suite({"name": "t", "cells": [{"env": "Push2DObstacle-v0", "deterministic": "no"}]})


def test_leaderboard_notes_come_from_the_suite_config_when_it_has_them():
    from lfd_bench.leaderboard import cell_notes

    recorded = {"zero": [{"cell": {"env_id": "Push2DObstacle-v0", "tags": {"label": "a", "notes": "old"}}}]}
    suite = {"cells": [{"env": "Push2DObstacle-v0", "label": "a", "notes": "new"},
                       {"env": "Push2DObstacle-v0", "label": "b", "notes": "other"}]}
    assert cell_notes(suite, "Push2DObstacle-v0 (a)", recorded) == ["new"]
    assert cell_notes({"cells": [{"env": "Push2DObstacle-v0", "label": "a"}]}, "Push2DObstacle-v0 (a)",
                      recorded) == ["old"]
    assert cell_notes(None, "Push2DObstacle-v0 (a)", recorded) == ["old"]


def test_aggregate_compares_agents_on_each_envs_main_cell():
    """Ablation cells that run a few agents do not shrink the across-environment comparison to the
    agents they share: per env id, the cell with the most agents is aggregated."""
    from lfd_bench.leaderboard import group_by_env, main_cells, render_markdown, seed_matrix

    def result(env, label, agent, seed, score):
        return {"cell": {"suite": "s", "env_id": env, "agent": agent, "seed": seed, "tags": {"label": label}},
                "final_normalized_performance": [score, score], "learning_curve": [], "train_wall_time_s": 1.0,
                "env_steps": 10, "gradient_updates": 5, "demo_transitions": 0}

    results = [result(env, "main", agent, seed, 0.1 * seed + (0.5 if agent == "dmfd" else 0.2))
               for env in ("A-v0", "B-v0") for agent in ("bc", "dmfd") for seed in range(3)]
    results += [result("A-v0", "ablation", "dmfd", seed, 0.9) for seed in range(3)]
    table = group_by_env(results)
    assert sorted(main_cells(table)) == ["A-v0 (main)", "B-v0 (main)"]
    scores = seed_matrix(main_cells(table))
    assert sorted(scores) == ["bc", "dmfd"] and scores["dmfd"].shape == (3, 2)
    md = render_markdown(results, command="x", suite="s", plot_dir=None, relative_to=Path("."))
    assert ("Agents run on all 2 environments; per env, its cell with the most agents (1 cell with fewer left out; "
            "ties go to the first label): A-v0 (main); B-v0 (main)") in md
    assert "| bc | 3 × 2 |" in md and "| dmfd | 3 × 2 |" in md


def test_sb3_agents_train_on_scaled_rewards_when_asked():
    from toy_env import PointReachEnv

    model = resolve_agent("sac")(PointReachEnv(), seed=0, reward_scale=10.0, learning_starts=10)
    plain = PointReachEnv()
    venv = model.get_env()
    venv.seed(3)
    venv.reset()
    plain.reset(seed=3)
    action = np.full((1, 2), 0.5, np.float32)
    reward = float(venv.step(action)[1][0])
    assert reward != 0.0 and reward == pytest.approx(10.0 * float(plain.step(action[0])[1]), rel=1e-5)
    with pytest.raises(ValueError, match="reward_scale"):
        resolve_agent("sac")(PointReachEnv(), reward_scale=-1.0)


@pytest.mark.parametrize("name", bench.available_suites())
def test_every_shipped_suite_fits_the_schema(name):
    bench.load_suite(name)  # schema, agents and their kwargs


@pytest.mark.parametrize("change,match", [
    (lambda s: s.update(budgte=5), r"unknown key\(s\) 'budgte' \(did you mean 'budget'\?\) in the top level"),
    (lambda s: s.update(eval_epsiodes=5), r"'eval_epsiodes' \(did you mean 'eval_episodes'\?\)"),
    (lambda s: s["cells"][0].update(env_kwarg={}), r"'env_kwarg' .* in cells\[0\]"),
    (lambda s: s["cells"][0].update(agent=s["cells"][0].pop("agents")), r"'agent' \(did you mean 'agents'\?\)"),
    (lambda s: s.update(budget=-5), r"budget must be an integer >= 1.*got -5"),
    (lambda s: s.update(eval_episodes=0), r"eval_episodes must be an integer >= 1.*got 0"),
    (lambda s: s.update(seeds="abc"), r"seeds must be a non-empty list .*got 'abc'"),
    (lambda s: s.update(seeds=[0, "1"]), r"seeds\[1\] must be a non-negative integer"),
    (lambda s: s["cells"][0].update(budget=2.5), r"cells\[0\].budget must be an integer"),
    (lambda s: s["cells"][0]["agents"].update(sac={"learnig_starts": 5}),
     r"cells\[0\].agents.sac: unknown keyword\(s\) \['learnig_starts'\] for agent 'sac'"),
    (lambda s: s["cells"][0]["agents"].update(bc={"n_epoch": 5}), r"unknown keyword\(s\) \['n_epoch'\]"),
    (lambda s: s["cells"][0]["agents"].update(random={"x": 1}), r"unknown keyword\(s\) \['x'\] for agent 'random'"),
    (lambda s: s["cells"][0]["agents"].update(nope={}), r"cells\[0\].agents: unknown agent 'nope'"),
])
def test_suite_mistakes_are_refused_naming_key_and_file(tmp_path, capsys, change, match):
    suite = {"seeds": [0], "budget": 20, "eval_episodes": 2,
             "cells": [{"env": "Push2DObstacle-v0", "agents": {"random": {}, "sac": {"learning_starts": 1}}}]}
    change(suite)
    path = tmp_path / "typo.json"
    path.write_text(json.dumps(suite))
    assert bench.main(["--suite", str(path), "--out", str(tmp_path / "res"), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and re.search(match, err), err
    assert not (tmp_path / "res").exists()  # nothing trained


def test_bad_env_kwargs_and_agent_specs_fail_before_training(tmp_path, capsys):
    suite = {"name": "bad-env", "cells": [{"env": "Push2DObstacle-v0", "env_kwargs": {"horizon": -3},
                                            "agents": {"random": {}}}]}
    bench.check_suite(suite)  # the schema cannot tell: the env can
    with pytest.raises(ValueError, match=r"'bad-env', env 'Push2DObstacle-v0'.*env_kwargs.*horizon"):
        bench.expand_cells(suite)
    with pytest.raises(ValueError, match="must be 'package.module:factory' with both parts"):
        resolve_agent(":factory")
    path = _suite(tmp_path)
    assert bench.main(["--suite", str(path), "--agent", ":factory", "--out", str(tmp_path / "res")]) == 2
    assert "both parts" in capsys.readouterr().err
    for override in (["--budget", "-5"], ["--seeds", "-1"]):
        assert bench.main(["--suite", str(path), *override, "--out", str(tmp_path / "res")]) == 2
        assert "must be" in capsys.readouterr().err
    assert not (tmp_path / "res").exists()


def test_performance_profile_figure_has_a_title():
    from lfd_bench.plots import PROFILES_TITLE, profiles_figure

    taus = np.linspace(0, 1, 5)
    fig = profiles_figure({"dmfd": np.linspace(1, 0, 5)}, {"dmfd": np.stack([np.linspace(0.9, 0, 5),
                                                                          np.linspace(1, 0.1, 5)])}, taus)
    assert fig.axes[0].get_title() == PROFILES_TITLE


def test_committed_leaderboard_is_a_page_a_reader_can_use():
    """``leaderboard.md`` holds one short section per suite with committed results (its headline
    table), every other cell on the suite's appendix page, and no line too long to read; configs hold
    settings, so no suite or cell note runs to an investigation."""
    root = README.parent
    board = (root / "leaderboard.md").read_text()
    lines = board.splitlines()
    assert len(lines) <= 400 and max(map(len, lines)) <= 600
    for results in sorted(p for p in (root / "results").iterdir()
                          if p.is_dir() and not p.name.startswith("_")):
        assert f"<!-- leaderboard:suite={results.name} -->" in board, results.name
        page = root / "docs" / "results" / f"{results.name}.md"
        assert f"(docs/results/{results.name}.md)" in board and page.exists()
        suite = bench.load_suite(results.name)
        assert suite.get("budget_cut"), results.name
        for notes in [suite.get("notes", "")] + [c.get("notes", "") for c in suite["cells"]]:
            assert len(notes) <= 800, (results.name, notes[:80])


def test_headline_shows_success_where_the_suite_says_so():
    """A suite whose thesis reports success rates (``"headline_metric": "is_success"``) gets them in its
    headline table and verdicts, seeds as runs, beside the reported rate."""
    from lfd_bench.leaderboard import render_headline

    def result(seed, success):
        return {"cell": {"suite": "s", "env_id": "Push2DObstacle-v0", "agent": "mopa_sac", "seed": seed, "tags": {}},
                "final_normalized_performance": [0.1, 0.2], "final_metrics": {"is_success": success},
                "learning_curve": [], "train_wall_time_s": 1.0}

    results = [result(0, [1.0, 1.0]), result(1, [1.0, 0.0]), result(2, [0.0, 0.0])]
    config = {"headline_metric": "is_success", "reference": {"Push2DObstacle-v0": {
        "source": "thesis", "rows": {"mopa_sac": {"mean": 0.9, "is_success": 0.4}}}}}
    md = render_headline(results, suite="s", suite_config=config, command="x", page="p.md")
    row = next(line for line in md.splitlines() if line.startswith("| mopa_sac |"))
    assert row.startswith("| mopa_sac | 0.500 [")  # mean of the seeds' rates 1, 0.5, 0
    assert "| *thesis: mopa_sac* | 0.400 |" in md and "mopa_sac 0.500 vs 0.400: met (+0.100)" in md
    assert "Success rate over seeds" in md
    plain = render_headline(results, suite="s", suite_config={**config, "headline_metric": "normalized_performance"},
                            command="x", page="p.md")
    assert "| mopa_sac | 0.150 [" in plain and "| *thesis: mopa_sac* | 0.900 |" in plain


def test_headline_puts_fold_quality_beside_the_score_and_keeps_thesis_rows_of_agents_not_run_yet():
    """A task's reported quality measure sits beside p̂ (mean over seeds), and an agent the thesis
    reports but no cell has run yet keeps its rows, so the reader sees what is missing."""
    from lfd_bench.leaderboard import render_headline

    def result(seed, quality):
        return {"cell": {"suite": "s", "env_id": "ClothFoldDiagonalPinned-v1", "agent": "dmfd", "seed": seed,
                         "tags": {}},
                "final_normalized_performance": [0.8, 0.9], "final_metrics": {"fold_quality": quality},
                "learning_curve": [], "train_wall_time_s": 1.0}

    results = [result(0, [0.5, 0.7]), result(1, [0.9, 0.9]), result(2, [-0.0001, 0.0])]
    config = {"reference": {"ClothFoldDiagonalPinned-v1": {"source": "thesis", "rows": {
        "dmfd": {"mean": 0.895}, "curl": {"mean": 0.679}}}}}
    md = render_headline(results, suite="s", suite_config=config, command="x", page="p.md")
    row = next(line for line in md.splitlines() if line.startswith("| dmfd |"))
    assert row.startswith("| dmfd | 0.850 [") and row.endswith(" · fold quality 0.500 |")  # (0.6 + 0.9 + 0) / 3
    assert "| curl | — |" in md and "| *thesis: curl* | 0.679 |" in md
    assert "Beside it: the mean over seeds of fold quality" in md and "-0.000" not in md


def test_every_cell_table_never_prints_negative_zero_for_a_reported_metric():
    """A metric whose episodes round to zero reads 0.000 ± 0.000 in the per-cell table, not -0.000."""
    from lfd_bench.leaderboard import agent_row

    run = {"cell": {"seed": 0}, "final_normalized_performance": [0.0, 0.0],
           "final_metrics": {"fold_quality": [-1e-5, -2e-5]}, "train_wall_time_s": 0.0}
    row, _ = agent_row("zero", [run], ["fold_quality"])
    assert "| 0.000 ± 0.000 |" in row and "-0.000" not in row
