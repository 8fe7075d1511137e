"""tools.trace_policy: a cell's learner step by step beside its demonstrator."""

import json

import gymnasium as gym
import pytest

import lfd_envs  # noqa: F401
from tools import trace_policy
from lfd_envs.experts import make_expert

ROPE = {"obs_mode": "state", "action_mode": "delta"}


def test_trace_rows_follow_the_episode_and_report_pickers_and_held_particles():
    env = gym.make("StraightenRope-v0", **ROPE)
    rows = trace_policy.trace_episode(env, make_expert(env), variant=3, steps=12)
    assert [r["step"] for r in rows] == list(range(12))
    assert all(len(r["action"]) == 8 and len(r["picker"]) == 3 and r["held"] >= 0 for r in rows)
    assert any(r["held"] > 0 for r in rows)  # the expert grasps the rope within its first moves
    again = trace_policy.trace_episode(env, make_expert(env), variant=3, steps=12)
    assert again == rows  # same variant, same steps


def test_cli_traces_the_cells_learner_and_demonstrator(tmp_path, capsys, monkeypatch):
    suite = {"seeds": [0], "eval_episodes": 1, "budget": 10, "cells": [
        {"env": "StraightenRope-v0", "env_kwargs": ROPE,
         "agents": {"bc": {"demo_episodes": 1, "n_epochs": 1, "batch_size": 32,
                           "policy_kwargs": {"net_arch": [16]}}}}]}
    path = tmp_path / "tiny.json"
    path.write_text(json.dumps(suite))
    monkeypatch.setattr("lfd_bench.agents.DEFAULT_RESULTS", tmp_path)
    assert trace_policy.main(["--suite", str(path), "--env", "StraightenRope-v0", "--agent", "bc",
                              "--variants", "0", "--steps", "3"]) == 0
    out = capsys.readouterr().out
    assert "== eval variant 0: bc" in out and "== eval variant 0: demonstrator" in out
    assert out.count("action [") == 6


def test_cli_refuses_a_missing_cell_and_bad_steps(capsys):
    assert trace_policy.main(["--suite", "repro-cpu-v1", "--env", "NoSuchEnv-v0"]) == 2
    assert "error:" in capsys.readouterr().err
    assert trace_policy.main(["--suite", "repro-cpu-v1", "--env", "StraightenRope-v1", "--steps", "0"]) == 2
    with pytest.raises(ValueError, match="unknown policy"):
        trace_policy.demonstrator(gym.make("StraightenRope-v0", **ROPE), {"demo_policy": "nobody"})
    with pytest.raises(ValueError, match="does not take"):  # as collect says it
        trace_policy.demonstrator(gym.make("StraightenRope-v0", **ROPE),
                                  {"demo_policy": "noisy_expert", "demo_policy_kwargs": {"sigma": 0.3}})
