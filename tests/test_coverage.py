"""lfd_bench.coverage: the end-effector recorder sees every low-level step (MoPA's planned
waypoints included), suites pass ``coverage_steps`` to cells, and the picture/markdown are made."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest

import lfd_envs  # noqa: F401
from lfd_bench import run as bench
from lfd_bench.coverage import EndEffectorRecorder, coverage_markdown, coverage_of, load_coverage, plot_coverage
from lfd_envs.mujoco.ompl_planner import ompl_available


@pytest.mark.skipif(not ompl_available(), reason="ompl not installed")
def test_recorder_counts_planned_waypoints_and_records_the_fingertip():
    from lfd_agents.mopa import make_mopa_env

    env = gym.make("Push2DObstacle-v0")
    recorder = EndEffectorRecorder(env, max_steps=10_000, max_points=10_000)
    mopa = make_mopa_env(env, planner_kwargs={"seed": 0})
    mopa.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(12):
        _, _, term, trunc, info = mopa.step(rng.uniform(-1, 1, mopa.action_space.shape))
        assert np.allclose(recorder.points[-1], env.unwrapped.fingertip_xy(), atol=1e-4)
        if term or trunc:
            mopa.reset()
    # planned MoPA actions execute several waypoints, all stepped on the base env
    assert mopa.low_level_steps > 12 and recorder.steps == mopa.low_level_steps == len(recorder.points)
    summary = recorder.summary()
    assert summary["visited_cells"] == len({(int(np.floor(x / 0.02)), int(np.floor(y / 0.02)))
                                            for x, y in recorder.points})
    recorder.detach()
    mopa.step(np.zeros(mopa.action_space.shape))
    assert recorder.steps == summary["steps"]  # no longer recording


def test_recorder_stops_at_max_steps_and_thins_points():
    env = gym.make("Push2DObstacle-v0")
    recorder = EndEffectorRecorder(env, max_steps=30, max_points=10)
    env.reset(seed=0)
    for _ in range(40):
        env.step(env.action_space.sample())
    s = recorder.summary()
    assert s["steps"] == 30 and s["every"] == 3 and len(s["points"]) == 10
    assert json.loads(json.dumps(s)) == s


def test_recorder_rejects_bad_input():
    env = gym.make("Push2DObstacle-v0")
    with pytest.raises(ValueError, match="max_steps"):
        EndEffectorRecorder(env, 0)
    with pytest.raises(ValueError, match="cell"):
        EndEffectorRecorder(env, 10, cell=0.0)
    with pytest.raises(TypeError, match="end-effector"):
        EndEffectorRecorder(gym.make("Pendulum-v1"), 10)
    assert "step" not in env.unwrapped.__dict__  # nothing was hooked


def test_suite_coverage_steps_reach_the_cell_and_are_checked(tmp_path):
    suite = {"name": "t", "cells": [{"env": "Push2DObstacle-v0", "coverage_steps": 50, "agents": {"random": {}}}]}
    bench.check_suite(suite)
    (cell,) = bench.expand_cells(suite)
    assert cell.tags["coverage_steps"] == 50
    for bad in (0, "50", True):
        with pytest.raises(ValueError, match="coverage_steps"):
            bench.check_suite({"cells": [{"env": "Push2DObstacle-v0", "coverage_steps": bad}]})


def _fake_result(root, agent, seed, points, cells):
    path = root / "s" / "Push2DObstacle-v0" / agent / f"seed{seed}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    cov = {"steps": len(points), "cell": 0.02, "visited_cells": cells, "every": 1, "points": points}
    path.write_text(json.dumps({"cell": {"seed": seed}, "coverage": cov}))


def test_plot_and_markdown_from_results(tmp_path):
    rng = np.random.default_rng(0)
    _fake_result(tmp_path, "mopa_sac", 0, rng.uniform(-0.4, 0.4, (50, 2)).round(4).tolist(), 40)
    _fake_result(tmp_path, "mopa_sac", 1, rng.uniform(-0.4, 0.4, (50, 2)).round(4).tolist(), 44)
    _fake_result(tmp_path, "sac", 0, rng.uniform(0.3, 0.4, (50, 2)).round(4).tolist(), 6)
    data = load_coverage(tmp_path, "s", "Push2DObstacle-v0")
    assert [r["visited_cells"] for r in data["mopa_sac"]] == [40, 44] and len(data["sac"]) == 1
    assert coverage_of({"sac": [json.loads(p.read_text()) for p in (tmp_path / "s").rglob("sac/seed*.json")],
                        "random": [{"cell": {"seed": 0}}]}) == {"sac": data["sac"]}
    png = plot_coverage(data, tmp_path / "plots" / "c.png", "Push2DObstacle-v0", agents=["sac", "mopa_sac"])
    assert png is not None and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    md = coverage_markdown(data, tmp_path / "plots" / "c.png", tmp_path, "Push2DObstacle-v0")
    assert "![coverage](plots/c.png)" in md and "| mopa_sac | 50 | 40, 44 | 42 |" in md
    assert plot_coverage({}, tmp_path / "x.png") is None
    assert coverage_markdown(load_coverage(tmp_path, "other", "Push2DObstacle-v0"), tmp_path / "y.png", tmp_path) == ""


def test_coverage_picture_has_a_colour_bar_and_no_empty_panels(tmp_path):
    from lfd_bench.coverage import coverage_figure

    rng = np.random.default_rng(1)
    _fake_result(tmp_path, "mopa_sac", 0, rng.uniform(-0.4, 0.4, (50, 2)).round(4).tolist(), 40)
    _fake_result(tmp_path, "sac", 0, [], 0)  # recorded nothing (e.g. no env step before the first stop)
    data = load_coverage(tmp_path, "s", "Push2DObstacle-v0")
    fig = coverage_figure(data, "Push2DObstacle-v0")
    panels = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
    assert [ax.get_title().split(" ")[0] for ax in panels] == ["mopa_sac"]
    (bar,) = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
    assert bar.get_ylabel() == "training step" and bar.get_ylim()[1] == 50
    assert coverage_figure({"sac": data["sac"]}) is None
    assert coverage_markdown({"sac": data["sac"]}, tmp_path / "z.png", tmp_path) == ""
