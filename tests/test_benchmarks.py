"""Benchmark harness: statistics, an end-to-end tiny suite, resume, and clear errors."""

import json
import re
from pathlib import Path

import numpy as np
import pytest

from benchmarks import run as bench
from benchmarks.agents import resolve_agent
from benchmarks.stats import bootstrap_ci, iqm, summarize

README = Path(__file__).resolve().parent.parent / "README.md"


def third_party_factory(env, seed, **kwargs):
    """A third-party agent: always moves straight to the goal (reads the toy env's state)."""
    class Agent:
        def learn(self, total_timesteps):
            return self

        def predict(self, obs, deterministic=True):
            return np.clip((obs[2:] - obs[:2]) / 0.1, -1, 1), None

    return Agent()


def test_stats_match_numpy():
    x = np.arange(20, dtype=float)
    s = summarize(x)
    assert s.p25 == np.percentile(x, 25) and s.p75 == np.percentile(x, 75)
    assert s.mean == x.mean() and s.std == x.std() and s.median == np.median(x)
    assert iqm(x) == pytest.approx(np.mean(x[5:15]))
    assert iqm(np.arange(8.0)) == pytest.approx(3.5)
    lo, hi = bootstrap_ci(x)
    assert lo <= iqm(x) <= hi
    lo2, hi2 = bootstrap_ci(np.tile(x, 10))
    assert hi2 - lo2 < hi - lo


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
    text = board.read_text()
    for f in files:
        r = json.loads(f.read_text())
        finals = np.asarray(r["final_normalized_performance"])
        assert len(finals) == 6
        row = next(l for l in text.splitlines() if l.startswith(f"| {r['cell']['agent']} |"))
        assert f"{finals.mean():.3f} ± {finals.std():.3f}" in row
        assert f"{np.median(finals):.3f}" in row
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
        resolve_agent("benchmarks.stats:nothing_here")
    assert bench.main(["--suite", str(_suite(tmp_path)), "--envs", "Nope-v0", "--out", str(tmp_path)]) == 2
    assert "valid:" in capsys.readouterr().err
    with pytest.raises(ValueError, match="valid suites are"):
        bench.load_suite("no-such-suite")


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
