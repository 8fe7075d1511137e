"""Demonstrators of controlled quality (the ε-noisy expert) and their demonstration cache entries."""

import gymnasium as gym
import numpy as np
import pytest

import lfd_envs  # noqa: F401
from lfd_bench.demo_cache import cache_key, demonstrations_for
from lfd_envs import datasets
from lfd_envs.experts import make_expert
from lfd_envs.experts.noisy import EpsilonNoisyPolicy, noisy_expert_policy

ROPE = dict(obs_mode="state", action_mode="delta")


class _Constant:
    """A policy that always returns the same action, counting its calls."""

    def __init__(self, action):
        self.action, self.calls = np.asarray(action, dtype=np.float32), 0

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        self.calls += 1
        return self.action, None


def test_slip_rate_and_bounds():
    space = gym.spaces.Box(-1.0, 1.0, (4,), np.float32)
    inner = _Constant(np.full(4, 0.5))
    policy = EpsilonNoisyPolicy(inner, space, epsilon=0.25, seed=3)
    actions = np.array([policy.predict(None)[0] for _ in range(4000)])
    slipped = ~np.all(actions == 0.5, axis=1)
    assert inner.calls == 4000  # the wrapped policy sees every step, slip or not
    assert slipped.mean() == pytest.approx(0.25, abs=0.03)
    assert np.all(np.abs(actions) <= 1.0) and actions.dtype == np.float32
    assert not np.any(EpsilonNoisyPolicy(_Constant(np.zeros(4)), space, 0.0).predict(None)[0])


def test_gaussian_action_noise_is_zero_mean_scaled_to_the_range_and_clipped():
    space = gym.spaces.Box(np.array([-1.0, 0.0]), np.array([1.0, 4.0]), dtype=np.float32)
    inner = _Constant([0.0, 2.0])
    policy = EpsilonNoisyPolicy(inner, space, epsilon=0.0, seed=1, action_noise=0.1)
    actions = np.array([policy.predict(None)[0] for _ in range(4000)])
    assert inner.calls == 4000
    assert np.allclose(actions.mean(axis=0), [0.0, 2.0], atol=0.01)  # zero mean: a regression still fits the expert
    assert np.allclose(actions.std(axis=0), [0.1, 0.2], rtol=0.05)  # 0.1 half-ranges in each dimension
    at_bound = EpsilonNoisyPolicy(_Constant([1.0, 4.0]), space, epsilon=0.0, seed=1, action_noise=0.5)
    clipped = np.array([at_bound.predict(None)[0] for _ in range(200)])
    assert np.all(clipped <= space.high) and np.all(clipped >= space.low) and clipped.dtype == np.float32
    for bad in (-0.1, float("nan")):
        with pytest.raises(ValueError, match="action_noise"):
            EpsilonNoisyPolicy(inner, space, 0.0, action_noise=bad)


def test_bad_epsilon_and_space_rejected():
    space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
    for eps in (-0.1, 1.5):
        with pytest.raises(ValueError, match="epsilon"):
            EpsilonNoisyPolicy(_Constant(np.zeros(2)), space, eps)
    with pytest.raises(ValueError, match="bounded Box"):
        EpsilonNoisyPolicy(_Constant(np.zeros(2)), gym.spaces.Box(-np.inf, np.inf, (2,)), 0.1)


def _final(env, policy, seed):
    obs, _ = env.reset(seed=seed)
    done = False
    while not done:
        obs, _, term, trunc, info = env.step(policy.predict(obs)[0])
        done = term or trunc
    return info["normalized_performance"]


def test_noise_lowers_the_experts_score_on_the_rope():
    env = gym.make("StraightenRope-v0", **ROPE)
    expert = [_final(env, make_expert(env), 100 + k) for k in range(3)]
    noisy = [_final(env, noisy_expert_policy(env, epsilon=0.6, seed=k), 100 + k) for k in range(3)]
    env.close()
    assert np.mean(expert) > 0.95
    assert np.mean(noisy) < np.mean(expert) - 0.15


def test_collect_records_policy_kwargs_and_rejects_unknown_ones(tmp_path):
    path = datasets.collect("StraightenRope-v0", 1, tmp_path, env_kwargs=ROPE, policy="noisy_expert",
                            policy_kwargs={"epsilon": 0.3}, progress=False)
    ds = datasets.load(path)
    assert ds.total_episodes == 1
    cfg = datasets.dataset_config(ds)
    assert cfg["policy"] == "noisy_expert" and cfg["policy_kwargs"] == {"epsilon": 0.3}
    with pytest.raises(ValueError, match="does not take"):
        datasets.collect("StraightenRope-v0", 1, tmp_path / "b", env_kwargs=ROPE, policy="noisy_expert",
                         policy_kwargs={"sigma": 0.3}, progress=False)
    # the expert's own options pass through both named expert policies
    path = datasets.collect("StraightenRope-v0", 1, tmp_path / "c", env_kwargs=ROPE, policy="expert",
                            policy_kwargs={"direct_approach": True}, progress=False)
    assert datasets.dataset_config(datasets.load(path))["policy_kwargs"] == {"direct_approach": True}


def test_cache_keys_keep_the_experts_and_separate_demonstrators(tmp_path):
    base = cache_key("StraightenRope-v0", ROPE, 10, 0)
    assert cache_key("StraightenRope-v0", ROPE, 10, 0, "expert", None) == base  # old caches stay valid
    noisy = cache_key("StraightenRope-v0", ROPE, 10, 0, "noisy_expert", {"epsilon": 0.2})
    assert noisy != base != cache_key("StraightenRope-v0", ROPE, 10, 0, "noisy_expert", {"epsilon": 0.3})
    env = gym.make("StraightenRope-v0", **ROPE)
    with pytest.raises(ValueError, match="unknown demonstration policy"):
        demonstrations_for(env, 1, tmp_path, policy="oracle")
    demos = demonstrations_for(env, 2, tmp_path, policy="noisy_expert", policy_kwargs={"epsilon": 0.3})
    env.close()
    assert demos.episodes == 2 and demos.transitions == 2 * 75
    assert -1.0 < demos.mean_final_performance <= 1.0
    assert (tmp_path / cache_key("StraightenRope-v0", ROPE, 2, 0, "noisy_expert", {"epsilon": 0.3})).is_dir()


def test_cli_takes_policy_kwargs(tmp_path, capsys):
    assert datasets.main(["collect", "--env", "StraightenRope-v0", "--episodes", "1", "--out", str(tmp_path),
                          "--obs-mode", "state", "--action-mode", "delta", "--policy", "noisy_expert",
                          "--policy-kwargs", '{"epsilon": 0.1}']) == 0
    assert "1 episodes" in capsys.readouterr().out
