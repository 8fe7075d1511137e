"""Executors: local processes and a Ray instance run cells into the same layout, resume, retry dead workers."""

import json
import os
from pathlib import Path

import numpy as np
import pytest

from lfd_bench import run as bench
from lfd_bench.storage import read_result, result_files


class GoalAgent:
    """Moves straight to the toy env's goal (reads its state observation)."""

    def learn(self, total_timesteps, **_):
        return self

    def predict(self, obs, deterministic=True):
        return np.clip((obs[2:] - obs[:2]) / 0.1, -1, 1), None


def dies_once(env, seed, marker, **kwargs):
    """A factory whose worker process dies the first time (``marker`` file records the attempt)."""
    path = Path(marker)
    if not path.exists():
        path.write_text("died once")
        os._exit(3)  # like an OOM kill: no exception, the process is gone
    return GoalAgent()


def _suite(tmp_path, marker):
    suite = {"name": "exec", "seeds": [0], "eval_episodes": 2, "budget": 4, "curve_points": 1,
             "cells": [{"env": "toy_env:lfd_test/PointReach-v0", "cpus": 1,
                        "agents": {"random": {}, f"{__name__}:dies_once": {"marker": str(marker)}}}]}
    return bench.expand_cells(suite)


def _check_layout(out, cells):
    files = result_files(out, "exec")
    assert sorted(f.relative_to(out).as_posix() for f in files) == sorted(f"{c.key}.json" for c in cells)
    for f in files:
        r = read_result(f)
        assert len(r["final_normalized_performance"]) == 2
        assert r["env_steps"] == 0 and r["gradient_updates"] == 0
    return files


def test_local_processes_run_resume_and_retry_dead_worker(tmp_path):
    cells = _suite(tmp_path, tmp_path / "marker")
    out = tmp_path / "res"
    bench.run_grid(cells, out, progress=False, executor="local", jobs=2)
    assert (tmp_path / "marker").exists()  # a worker died once, its cell was retried
    files = _check_layout(out, cells)
    mtimes = [f.stat().st_mtime_ns for f in files]
    bench.run_grid(cells, out, progress=False, executor="local", jobs=2)  # resume: nothing re-run
    assert [f.stat().st_mtime_ns for f in files] == mtimes


def test_ray_executor_runs_a_tiny_suite(tmp_path):
    import ray  # installed by the test extra
    cells = _suite(tmp_path, tmp_path / "marker")
    out = tmp_path / "res"
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
             runtime_env={"env_vars": {"PYTHONPATH": os.pathsep.join([str(Path(__file__).parent),
                                                                       os.environ.get("PYTHONPATH", "")])}})
    try:
        bench.run_grid(cells, out, progress=False, executor="ray")
        assert (tmp_path / "marker").exists()  # the dead worker's task was retried by Ray
        files = _check_layout(out, cells)
        json.loads(files[0].read_text())
        mtimes = [f.stat().st_mtime_ns for f in files]
        bench.run_grid(cells, out, progress=False, executor="ray")  # resume
        assert [f.stat().st_mtime_ns for f in files] == mtimes
    finally:
        ray.shutdown()


def sac_dies_once_after_a_checkpoint(env, seed, marker, **kwargs):
    """SB3 SAC whose process dies (once, ``marker`` records it) when it goes on from a checkpoint."""
    import functools

    from lfd_bench.agents import resolve_agent

    model = resolve_agent("sac")(env, seed, **kwargs)
    learn = model.learn

    @functools.wraps(learn)
    def dying_learn(*args, **kw):
        if model.num_timesteps > 0 and not Path(marker).exists():
            Path(marker).write_text("died once")
            os._exit(3)
        return learn(*args, **kw)

    model.learn = dying_learn
    return model


def test_ray_task_killed_after_a_checkpoint_resumes_to_the_uninterrupted_result(tmp_path):
    import ray

    def cells(marker):
        suite = {"name": "exec", "seeds": [1], "eval_episodes": 3, "budget": 60, "curve_points": 2,
                 "checkpoint_steps": 20,
                 "cells": [{"env": "toy_env:lfd_test/PointReach-v0", "agents": {
                     f"{__name__}:sac_dies_once_after_a_checkpoint": {
                         "marker": str(marker), "learning_starts": 10, "batch_size": 16,
                         "policy_kwargs": {"net_arch": [16, 16]}}}}]}
        return bench.expand_cells(suite)

    (tmp_path / "never").write_text("the plain run does not die")
    plain = tmp_path / "plain"
    bench.run_grid(cells(tmp_path / "never"), plain, progress=False)
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False,
             runtime_env={"env_vars": {"PYTHONPATH": os.pathsep.join([str(Path(__file__).parent),
                                                                       os.environ.get("PYTHONPATH", "")])}})
    try:
        killed = tmp_path / "killed"
        bench.run_grid(cells(tmp_path / "marker"), killed, progress=False, executor="ray")
    finally:
        ray.shutdown()
    assert (tmp_path / "marker").exists()  # the task died after its first checkpoint; Ray ran it again
    (a,), (b,) = result_files(plain), result_files(killed)
    resumed, expected = read_result(b), read_result(a)
    assert resumed["resumed_at_steps"] == 20 and "resumed_at_steps" not in expected
    for key in ("final_normalized_performance", "learning_curve", "gradient_updates", "env_steps"):
        assert resumed[key] == expected[key], key
    assert not (killed / "_checkpoints").exists()


def test_serial_cells_run_on_their_own_core_count(monkeypatch):
    """Each serial cell runs with as many torch threads as it asks cores for (default 1; more
    threads than cores on a shared machine make small networks many times slower) and with float
    subnormals flushed to zero; both settings are restored afterwards."""
    import torch

    from lfd_bench import cell as cell_module
    from lfd_bench import executors

    seen = []

    def fake_run_cell(cell, **_):
        seen.append((torch.get_num_threads(), executors.flush_denormals_enabled()))
        return {}

    monkeypatch.setattr(cell_module, "run_cell", fake_run_cell)
    cells = [bench.Cell(suite="t", env_id="ThreeBoxes-v0", env_kwargs={}, agent="zero", agent_kwargs={}, seed=0,
                        budget=1, eval_episodes=1, cpus=c) for c in (1, 2)]
    before = torch.get_num_threads(), executors.flush_denormals_enabled()
    executors.run_serial(cells, lambda cell, result: None, demo_cache=None, progress=False)
    assert seen == [(1, True), (2, True)]  # subnormals flushed while cells train
    assert (torch.get_num_threads(), executors.flush_denormals_enabled()) == before


def test_flushing_subnormals_leaves_numpy_limits_right_and_quiet():
    """numpy computes float limits on first use; with subnormals already flushed it warned that the
    smallest subnormal is zero on every harness run. The harness computes them before flushing."""
    import subprocess
    import sys

    code = ("import warnings, numpy as np, torch\n"
            "from lfd_bench.executors import flush_denormals, flush_denormals_enabled\n"
            "flush_denormals(True)\n"
            "assert flush_denormals_enabled()\n"
            "warnings.simplefilter('error')\n"
            "tiny = np.finfo(np.float64).smallest_subnormal\n"
            "assert tiny.tobytes() != bytes(8)\n")  # compared as a number it reads 0 while flushing
    root = Path(__file__).resolve().parent.parent
    done = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr


def test_missing_ray_names_this_distribution(monkeypatch):
    import sys

    from lfd_bench.executors import run_ray

    monkeypatch.setitem(sys.modules, "ray", None)  # as if Ray were not installed
    with pytest.raises(ValueError, match=r"lfd-suite") as info:
        run_ray([], lambda cell, result: None, address=None, demo_cache=None)
    assert "lfd[cluster]" not in str(info.value)
