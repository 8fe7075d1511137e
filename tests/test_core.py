"""The env contract of lfd_envs.core, on a tiny toy env."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import lfd_envs
from lfd_envs.core import VariantSplit
from toy_env import TOY_ID, PointReachEnv


def test_check_env_all_obs_modes():
    for mode in ("state", "image", "state+image"):
        check_env(PointReachEnv(obs_mode=mode), skip_render_check=True)


def test_unknown_kwarg_lists_valid_ones():
    with pytest.raises(TypeError, match="valid arguments are .*obs_mode"):
        PointReachEnv(obs_mod="state")
    with pytest.raises(ValueError, match="obs_mode must be one of"):
        PointReachEnv(obs_mode="pixels")


def test_bad_actions_raise_and_env_stays_usable():
    env = PointReachEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(2,\)"):
        env.step(np.zeros(3))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([np.nan, 0.0]))
    obs, r, term, trunc, info = env.step(np.array([5.0, -5.0]))  # clipped
    assert np.isfinite(r) and {"performance", "normalized_performance", "variant", "is_success"} <= set(info)


def test_variant_splits_never_overlap_and_are_reproducible():
    vs = VariantSplit("PointReach", 50, 20)
    train = {tuple(vs.rng("train", k).uniform(size=3)) for k in range(50)}
    evals = {tuple(vs.rng("eval", k).uniform(size=3)) for k in range(20)}
    assert not train & evals
    assert np.array_equal(vs.rng("eval", 3).uniform(size=3), vs.rng("eval", 3).uniform(size=3))
    with pytest.raises(ValueError):
        vs.rng("eval", 20)
    with pytest.raises(ValueError):
        vs.rng("test", 0)


def test_reset_seed_determinism_and_options():
    env = PointReachEnv()
    o1, i1 = env.reset(seed=3)
    o2, i2 = env.reset(seed=3)
    assert np.array_equal(o1, o2) and i1["variant"] == i2["variant"]
    _, info = env.reset(options={"split": "eval", "variant": 5})
    assert info["variant"] == 805 and env.variant == ("eval", 5)
    with pytest.raises(ValueError, match="unknown reset options"):
        env.reset(options={"varaint": 1})


def test_get_set_state_round_trip_gives_identical_future():
    env = PointReachEnv()
    env.reset(seed=1)
    env.step(np.array([0.3, 0.1]))
    state = env.get_state()
    actions = np.random.default_rng(0).uniform(-1, 1, (5, 2))
    a = [env.step(u)[0] for u in actions]
    env.reset(seed=99)  # different variant
    env.set_state(state)
    b = [env.step(u)[0] for u in actions]
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    with pytest.raises(ValueError, match="missing keys"):
        env.set_state({"sim/pos": np.zeros(2)})


def test_normalized_performance_is_relative_to_start():
    env = PointReachEnv(horizon=40)
    _, info = env.reset(seed=0)
    assert info["normalized_performance"] == pytest.approx(0.0)
    base = env.unwrapped
    for _ in range(40):
        d = np.clip((base._goal - base._pos) / base.step_size, -1, 1)
        *_, term, trunc, info = env.step(d)
    assert info["normalized_performance"] == pytest.approx(1.0, abs=1e-6) and trunc


def test_registration_without_prior_import():
    assert "ClothFoldDiagonal-v0" in gym.registry and "Push2DObstacle-v0" in gym.registry
    assert set(lfd_envs.PARTICLE_ENV_IDS) | set(lfd_envs.MUJOCO_ENV_IDS) == set(lfd_envs.ENV_SPECS)
