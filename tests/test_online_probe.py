"""tools.online_probe: every variant starts from the same cached offline policy."""

import json

import numpy as np
import pytest
from picker_moves import steer_picker

from tools import online_probe as probe

SUITE = {"name": "probe", "cells": [
    {"env": "ClothFoldDiagonalPinned-v0", "label": "pp",
     "env_kwargs": {"action_mode": "pick_place", "obs_mode": "state", "resolution": 12},
     "agents": {"dmfd": {"demo_episodes": 3, "offline_steps": 30, "demo_ratio": 0.5, "batch_size": 16,
                         "policy_kwargs": {"net_arch": [16, 16]}},
                "bc": {"demo_episodes": 3}}}]}


def test_variants_share_the_offline_start_and_the_cache_is_reused(tmp_path):
    cell = probe.find_cell(SUITE, "ClothFoldDiagonalPinned-v0", "dmfd")
    kw = dict(seed=0, online_steps=6, eval_every=3, eval_episodes=2, cache=tmp_path / "cache",
              demo_cache=tmp_path / "demos")
    out = probe.probe_cell(cell, {"base": {}, "ratio": {"demo_ratio": 0.9}}, **kw)
    (cached,) = list((tmp_path / "cache").glob("offline_*.pt"))
    stamp = cached.stat().st_mtime_ns
    for name in ("base", "ratio"):
        evals = [r for r in out[name] if "online_steps" in r]
        assert [r["online_steps"] for r in evals] == [0, 3, 6]
        assert len(out[name][-1]["mean_action_drift_online_states"]) == 6  # pick-and-place action size
    assert all(0.0 <= r["held_rate"] <= 1.0 for r in evals)  # pick-and-place steps end released: 0
    start = [out[n][0] for n in ("base", "ratio")]
    assert start[0]["mean_p"] == start[1]["mean_p"] and start[0]["log_std"] == start[1]["log_std"]
    again = probe.probe_cell(cell, {"base": {}}, **{**kw, "online_steps": 3})
    assert cached.stat().st_mtime_ns == stamp, "the offline phase ran again instead of loading the cache"
    assert again["base"][0]["mean_p"] == start[0]["mean_p"]


def test_bad_requests_are_refused(tmp_path, capsys):
    with pytest.raises(ValueError, match="cells with that agent"):
        probe.find_cell(SUITE, "ClothFoldDiagonalPinned-v0", "dmfd", label="other")
    cell = probe.find_cell(SUITE, "ClothFoldDiagonalPinned-v0", "bc")
    with pytest.raises(ValueError, match="no offline_steps"):
        probe.probe_cell(cell, {"base": {}}, agent_name="bc", cache=tmp_path)
    path = tmp_path / "s.json"
    path.write_text(json.dumps(SUITE))
    assert probe.main(["--suite", str(path), "--env", "ClothFoldDiagonalPinned-v0", "--variant", "x", "[1]"]) == 2
    assert "must be an object" in capsys.readouterr().err
    assert not list(tmp_path.glob("offline_*"))


def test_a_recipe_cell_is_found_with_the_recipe_settings():
    suite = {"name": "r", "cells": [{"env": "StraightenRope-v1", "env_kwargs": {"obs_mode": "state"},
                                     "agents": {"bc": {"recipe": "bc/state-v1", "demo_episodes": 7}}}]}
    cell = probe.find_cell(suite, "StraightenRope-v1", "bc")
    assert "recipe" not in cell["agent_kwargs"]
    assert cell["agent_kwargs"]["n_epochs"] == 100 and cell["agent_kwargs"]["demo_episodes"] == 7
    assert cell["agent_kwargs"]["demo_policy_kwargs"]["hold_speed"] == 0.5


def test_held_rate_counts_episodes_in_which_a_picker_held_the_cloth():
    import gymnasium as gym

    env = probe.HeldRate(gym.make("ClothFoldDiagonalUnpinned-v0", resolution=12))

    class Hover:  # flag on, 0.1 m above the cloth: never holds anything
        def predict(self, obs, deterministic=True):
            return np.array([0.0, 0.0, 0.3, 1.0], np.float32), None

    from lfd_bench.cell import evaluate

    evaluate(Hover(), env, 2, seed=0)
    assert env.rate() == {"held_rate": 0.0} and env.rate() == {}
    env.reset(seed=0)
    u = env.unwrapped
    corner = u.particle_positions[np.argmin(u.particle_positions[:, :2].sum(axis=1))]
    steer_picker(env, corner, 15)  # onto a corner with the flag on: grasps on contact
    env.reset(seed=1)
    assert env.rate() == {"held_rate": 0.5}


def test_held_rate_passes_through_an_env_without_held_particles():
    import gymnasium as gym

    env = probe.HeldRate(gym.make("CartPole-v1"))
    env.reset(seed=0)
    obs, reward, *_ = env.step(0)
    assert obs.shape == (4,) and reward == 1.0
    assert env.rate() == {}
