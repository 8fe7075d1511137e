"""SoftGym's reward convention (lfd_envs.core.performance_reward)."""

import gymnasium as gym
import numpy as np
import pytest

import lfd_envs  # noqa: F401
from lfd_envs import datasets
from lfd_envs.core.performance_reward import PerformanceReward, performance_rewards

KW = {"obs_mode": "state", "action_mode": "delta"}


def test_reward_is_scaled_performance_and_the_rest_is_unchanged():
    plain = gym.make("StraightenRope-v0", **KW)
    wrapped = PerformanceReward(gym.make("StraightenRope-v0", **KW), scale=50)
    plain.reset(seed=3)
    wrapped.reset(seed=3)
    rng = np.random.default_rng(0)
    p_prev = None
    for _ in range(5):
        a = rng.uniform(-1, 1, plain.action_space.shape).astype(np.float32)
        o1, r1, t1, u1, i1 = plain.step(a)
        o2, r2, t2, u2, i2 = wrapped.step(a)
        assert np.array_equal(o1, o2) and (t1, u1) == (t2, u2)
        assert r2 == pytest.approx(50 * i2["performance"])
        # the suite's own reward is the change of performance: the two conventions differ
        if p_prev is not None:
            assert r1 == pytest.approx(i1["performance"] - p_prev)
        p_prev = i1["performance"]


def test_demonstration_rewards_match_the_wrapper(tmp_path):
    kw = {**KW, "num_pickers": 2}
    path = datasets.collect("StraightenRope-v0", 1, tmp_path / "demo", env_kwargs=kw, seed=4, progress=False)
    episode = next(iter(datasets.load(path).iterate_episodes()))
    rewards = performance_rewards(episode.infos["performance"], scale=50)
    env = PerformanceReward(gym.make("StraightenRope-v0", **kw), scale=50)
    env.reset(seed=4)
    replayed = [env.step(a)[1] for a in episode.actions]
    assert len(rewards) == len(episode.actions)
    np.testing.assert_allclose(rewards, replayed, rtol=1e-6, atol=1e-9)


def test_bad_input():
    env = gym.make("StraightenRope-v0", **KW)
    for scale in (0, -1, float("nan"), True, "50"):
        with pytest.raises(ValueError, match="scale"):
            PerformanceReward(env, scale=scale)
    with pytest.raises(ValueError, match="T\\+1"):
        performance_rewards(np.array([1.0]))
