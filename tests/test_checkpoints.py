"""Cells survive being killed: a re-run resumes from the newest checkpoint and ends with exactly the
result (and the trained weights) of a run that was never interrupted."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch

from lfd_bench import cell as bench
from lfd_bench.checkpoints import CHECKPOINT_DIRNAME, CheckpointStore

ROOT = Path(__file__).resolve().parent.parent
SMALL = {"batch_size": 32}
LEARNERS = {
    "dmfd": {"demo_episodes": 2, "learning_starts": 0, "policy_kwargs": {"net_arch": [32, 32]}, **SMALL},
    "awac": {"demo_episodes": 2, "learning_starts": 0, "offline_steps": 20, "policy_kwargs": {"net_arch": [32, 32]}, **SMALL},
    "sac_lfd": {"demo_episodes": 2, "learning_starts": 0, "policy_kwargs": {"net_arch": [32, 32]}, **SMALL},
    "bc": {"demo_episodes": 2, "default_updates": 40, **SMALL},
    "sac": {"learning_starts": 10, "policy_kwargs": {"net_arch": [32, 32]}, **SMALL},
    "mopa_sac": {"learning_starts": 10, "warmup_stored": 20, **SMALL},
}


REAL_BUILD, REAL_SAVE = bench._build_training, CheckpointStore.save


class Killed(Exception):
    """Stands for the process dying right after a checkpoint was written."""


def _cell(agent: str, **overrides) -> bench.Cell:
    settings = dict(suite="ckpt", env_id="Push2DObstacle-v0", env_kwargs={}, agent=agent,
                    agent_kwargs=LEARNERS[agent], seed=3, budget=60, eval_episodes=1, curve_points=2,
                    checkpoint_steps=20)
    settings.update(overrides)
    return bench.Cell(**settings)


def _run(cell, tmp_path, monkeypatch, checkpoints=None, kill_after_saves=None):
    """run_cell, returning the result and the final learner's parameters."""
    built = []

    def build(*args, **kwargs):
        built.append(REAL_BUILD(*args, **kwargs))
        return built[-1]

    saves = []

    def save(self, state):
        REAL_SAVE(self, state)
        saves.append(state["steps"])
        if kill_after_saves is not None and len(saves) >= kill_after_saves:
            raise Killed

    monkeypatch.setattr(bench, "_build_training", build)
    monkeypatch.setattr(CheckpointStore, "save", save)
    result = bench.run_cell(cell, progress=False, demo_cache=tmp_path / "_demos", checkpoints=checkpoints)
    policy = getattr(built[-1].agent, "model", built[-1].agent).policy
    return result, {k: v.clone() for k, v in policy.state_dict().items()}


@pytest.mark.parametrize("agent", sorted(LEARNERS))
def test_a_cell_killed_after_a_checkpoint_resumes_to_the_uninterrupted_result(agent, tmp_path, monkeypatch,
                                                                               one_torch_thread):
    cell = _cell(agent)
    plain, plain_params = _run(cell, tmp_path, monkeypatch)
    store = tmp_path / "ckpt" / cell.key
    with pytest.raises(Killed):
        _run(cell, tmp_path, monkeypatch, checkpoints=store, kill_after_saves=3)
    progress = json.loads((store / "progress.json").read_text())
    assert progress["steps"] == 40 and progress["budget"] == 60
    resumed, resumed_params = _run(cell, tmp_path, monkeypatch, checkpoints=store)
    assert resumed["resumed_at_steps"] == 40
    for key in ("final_normalized_performance", "learning_curve", "trained_steps", "env_steps",
                "gradient_updates", "demo_transitions"):
        assert resumed[key] == plain[key], key
    assert plain_params.keys() == resumed_params.keys()
    for name, value in plain_params.items():
        assert torch.equal(value, resumed_params[name]), name


def test_a_checkpoint_of_other_settings_is_not_resumed(tmp_path, monkeypatch, one_torch_thread):
    store = tmp_path / "ckpt"
    with pytest.raises(Killed):
        _run(_cell("sac"), tmp_path, monkeypatch, checkpoints=store, kill_after_saves=1)
    other = _cell("sac", agent_kwargs={**LEARNERS["sac"], "learning_rate": 1e-2})
    result, _ = _run(other, tmp_path, monkeypatch, checkpoints=store)
    assert "resumed_at_steps" not in result


def test_training_stops_are_curve_points_and_checkpoint_multiples():
    assert bench.training_stops(100, 2, 30) == [(30, False), (50, True), (60, False), (90, False), (100, True)]
    assert bench.training_stops(100, 4) == [(25, True), (50, True), (75, True), (100, True)]
    assert bench.training_stops(2, 4) == [(0, True), (1, True), (1, True), (2, True)]  # every curve point kept


def test_bc_trains_its_configured_updates_whatever_the_curve_points(tmp_path, monkeypatch, one_torch_thread):
    updates = {points: _run(_cell("bc", curve_points=points, checkpoint_steps=None), tmp_path,
                            monkeypatch)[0]["gradient_updates"] for points in (1, 3)}
    assert updates[1] == updates[3] > 0


@pytest.mark.timeout(300)
def test_benchmark_run_killed_mid_cell_resumes_and_cleans_up(tmp_path):
    """The real thing: ``python -m lfd_bench.run`` killed with SIGKILL once a checkpoint exists."""
    suite = {"name": "killed", "seeds": [1], "eval_episodes": 2, "curve_points": 2, "budget": 400,
             "checkpoint_steps": 100,
             "cells": [{"env": "Push2DObstacle-v0", "agents": {"sac": {"learning_starts": 50, "batch_size": 32}}}]}
    path = tmp_path / "killed.json"
    path.write_text(json.dumps(suite))
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}

    def command(out):
        return [sys.executable, "-m", "lfd_bench.run", "--suite", str(path), "--out", str(out),
                "--leaderboard", str(out / "leaderboard.md"), "--no-progress"]

    killed_out, plain_out = tmp_path / "killed", tmp_path / "plain"
    proc = subprocess.Popen(command(killed_out), cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    state = killed_out / CHECKPOINT_DIRNAME / "killed" / "Push2DObstacle-v0" / "sac" / "seed1" / "state.pt"
    deadline = time.time() + 200
    while not state.exists() and proc.poll() is None and time.time() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert state.exists(), "no checkpoint was written before the kill"
    result_path = Path("killed/Push2DObstacle-v0/sac/seed1.json")
    assert not (killed_out / result_path).exists()
    subprocess.run(command(killed_out), cwd=ROOT, env=env, check=True, capture_output=True)
    subprocess.run(command(plain_out), cwd=ROOT, env=env, check=True, capture_output=True)
    resumed, plain = (json.loads((o / result_path).read_text()) for o in (killed_out, plain_out))
    assert resumed["resumed_at_steps"] > 0 and "resumed_at_steps" not in plain
    assert resumed["final_normalized_performance"] == plain["final_normalized_performance"]
    assert resumed["learning_curve"] == plain["learning_curve"]
    assert resumed["gradient_updates"] == plain["gradient_updates"]
    assert not (killed_out / CHECKPOINT_DIRNAME).exists()  # removed once the result is written
    assert np.isfinite(resumed["final_normalized_performance"]).all()


def _gradient_steps(agent, seed: int = 0) -> dict:
    """A few updates on batches drawn with fixed generators; the resulting parameters."""
    from stable_baselines3.common.logger import configure

    model = getattr(agent, "model", agent)
    model.set_logger(configure(None, []))
    torch.manual_seed(seed)
    np.random.seed(seed)
    if hasattr(model, "replay_buffer"):
        model.train(gradient_steps=3, batch_size=16)
    else:  # BC: one more epoch over its demonstrations
        model.learn(0, epochs=1, reset_num_timesteps=False)
    return {k: v.clone() for k, v in model.policy.state_dict().items()}


def _trained_restored_and_unloaded(build, steps: int):
    """A learner trained ``steps`` steps, a fresh one loaded with its training state (through bytes, as
    from a checkpoint file) and a fresh one left as built."""
    import io

    from lfd_agents.training_state import get_training_state, set_training_state

    original = build()
    original.learn(steps)
    buffer = io.BytesIO()
    torch.save(get_training_state(original), buffer)
    buffer.seek(0)
    restored, unloaded = build(), build()
    set_training_state(restored, torch.load(buffer, weights_only=False))
    return original, restored, unloaded


@pytest.mark.parametrize("agent", sorted(LEARNERS))
def test_a_restored_learner_trains_on_exactly_as_the_original(agent, tmp_path, one_torch_thread):
    """What a checkpoint carries is complete: the same updates from the original learner and from a
    freshly built one loaded with its training state give the same weights (and an unloaded one not)."""
    import gymnasium as gym

    from lfd_bench.agents import resolve_agent

    kwargs = {**LEARNERS[agent], "demo_cache": str(tmp_path)} if "demo_episodes" in LEARNERS[agent] else LEARNERS[agent]

    def build():
        return resolve_agent(agent)(gym.make("lfd_envs:Push2DObstacle-v0"), 5, **kwargs)

    original, restored, unloaded = _trained_restored_and_unloaded(build, 40)
    counters = ("num_timesteps", "_n_updates", "_episode_num", "_epochs_done", "_offline_done")
    models = [getattr(a, "model", a) for a in (original, restored)]
    for name in counters:
        assert getattr(models[0], name, None) == getattr(models[1], name, None), name
    assert models[0].num_timesteps > 0 or agent == "bc"
    expected = _gradient_steps(original)
    got = _gradient_steps(restored)
    assert all(torch.equal(expected[k], got[k]) for k in expected)
    try:
        other = _gradient_steps(unloaded)
    except (ValueError, RuntimeError):  # nothing to sample from: as different as it gets
        return
    assert not all(torch.equal(expected[k], other[k]) for k in expected)


@pytest.mark.parametrize("name,obs_mode", [("DrQ", "image"), ("CURL", "state+image")])
def test_a_restored_image_learner_trains_on_exactly_as_the_original(name, obs_mode, one_torch_thread):
    """The image learners' state includes their augmentation generator: the same shifted batches follow."""
    import lfd_agents
    from dmfd_toy_env import ToyPickPlaceEnv

    def build():
        policy = "CnnPolicy" if obs_mode == "image" else "MultiInputPolicy"
        return getattr(lfd_agents, name)(policy, ToyPickPlaceEnv(obs_mode=obs_mode), batch_size=8, buffer_size=200,
                                         learning_starts=10, seed=5)

    original, restored, unloaded = _trained_restored_and_unloaded(build, 30)
    assert torch.equal(original.aug_generator.get_state(), restored.aug_generator.get_state())
    expected, got = _gradient_steps(original), _gradient_steps(restored)
    assert all(torch.equal(expected[k], got[k]) for k in expected)
    with pytest.raises(ValueError):  # a learner without the state has no transitions to sample
        _gradient_steps(unloaded)
