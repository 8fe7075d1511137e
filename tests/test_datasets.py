"""Minari demonstration datasets: write, load, restore states, replay."""

import numpy as np
import pytest

from lfd_envs import datasets
import gymnasium as gym
from toy_env import TOY_ID, PointReachExpert


def test_collect_load_replay_round_trip(tmp_path):
    path = datasets.collect(TOY_ID, 3, tmp_path, policy=PointReachExpert, seed=10, progress=False)
    ds = datasets.load(path)
    assert ds.total_episodes == 3
    env = datasets.make_env(ds)
    for ep in ds.iterate_episodes():
        finals = datasets.replay(env, ep)
        assert finals[-1] == pytest.approx(float(ep.infos["normalized_performance"][-1]))
        states = datasets.episode_states(ep, env)
        assert len(states) == len(ep.actions) + 1
        env.unwrapped.set_state(states[2])
        assert np.allclose(env.unwrapped.current_observation(), ep.observations[2])
    assert np.mean([ep.infos["normalized_performance"][-1] for ep in ds.iterate_episodes()]) > 0.9


def test_cli_and_bad_policy(tmp_path, capsys):
    assert datasets.main(["collect", "--env", TOY_ID, "--episodes", "2", "--out", str(tmp_path), "--policy", "random"]) == 0
    assert "2 episodes" in capsys.readouterr().out
    with pytest.raises(ValueError, match="unknown policy"):
        datasets.collect(TOY_ID, 1, tmp_path, policy="oracle")
    with pytest.raises(FileNotFoundError):
        datasets.load(tmp_path / "nothing")
