"""Baselines: BC, SAC-LfD, AWAC, and plain SB3 algorithms on lfd envs."""

from __future__ import annotations

import numpy as np
import pytest
import torch as th

from dmfd_toy_env import ToyPickPlaceEnv, collect_episodes, evaluate
from lfd_agents import AWAC, BC, ImageEncoder, SACLfD

th.set_num_threads(1)
def tiny() -> dict:
    return dict(net_arch=[32, 32])  # fresh each time: SB3 adds keys to policy_kwargs in place


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_bc_beats_untrained_policy(seed):
    eps = collect_episodes(30)
    env = ToyPickPlaceEnv()
    model = BC("MlpPolicy", env, demonstrations=eps, batch_size=64, policy_kwargs=dict(net_arch=[64, 64]), seed=seed)
    untrained = evaluate(model)
    model.learn(epochs=40)
    trained = evaluate(model)
    assert trained > 0.4 and trained > untrained + 0.3, (trained, untrained)


@pytest.mark.parametrize("obs_mode,policy", [("image", "CnnPolicy"), ("state+image", "MultiInputPolicy")])
def test_bc_image_inputs_train_and_round_trip(tmp_path, obs_mode, policy):
    eps = collect_episodes(2, obs_mode=obs_mode)
    env = ToyPickPlaceEnv(obs_mode=obs_mode)
    model = BC(policy, env, demonstrations=eps, batch_size=16, policy_kwargs=tiny(), seed=0)
    obs, _ = env.reset(seed=0)
    before = model.predict(obs)[0]
    model.learn(epochs=2)
    after = model.predict(obs)[0]
    assert after.shape == (3,) and not np.allclose(before, after)
    model.save(tmp_path / "bc.zip")
    loaded = BC.load(tmp_path / "bc.zip", env=env)
    np.testing.assert_array_equal(loaded.predict(obs)[0], after)


def test_bc_without_demonstrations_explains():
    with pytest.raises(RuntimeError, match="demonstrations"):
        BC("MlpPolicy", ToyPickPlaceEnv()).learn()


def test_sac_lfd_prefills_buffer_and_trains(tmp_path):
    eps = collect_episodes(3)
    model = SACLfD("MlpPolicy", ToyPickPlaceEnv(), demonstrations=eps, buffer_size=500, batch_size=32,
                   policy_kwargs=tiny(), seed=0)
    assert model.replay_buffer.size() == 90 and model.learning_starts == 0
    model.learn(20)
    assert model.replay_buffer.size() == 110 and model._n_updates > 0
    model.save(tmp_path / "sac_lfd.zip")
    SACLfD.load(tmp_path / "sac_lfd.zip", env=ToyPickPlaceEnv())


def test_sac_lfd_reward_scale_is_a_factor_on_the_stored_rewards():
    """Training with reward_scale 3 equals training on rewards stored 3x larger, update for update."""
    from stable_baselines3.common.logger import configure

    eps = collect_episodes(3)
    critics = []
    for scale, stored in ((3.0, 1.0), (1.0, 3.0), (1.0, 1.0)):  # each built and trained in turn (global RNG)
        m = SACLfD("MlpPolicy", ToyPickPlaceEnv(), demonstrations=eps, buffer_size=500, batch_size=32,
                   policy_kwargs=tiny(), seed=0, reward_scale=scale)
        m.set_logger(configure(None, []))
        m.replay_buffer.rewards *= stored
        m.train(gradient_steps=5, batch_size=32)
        critics.append(th.cat([p.detach().flatten() for p in m.critic.parameters()]))
    assert th.allclose(critics[0], critics[1], atol=1e-6)
    assert not th.allclose(critics[0], critics[2], atol=1e-4)  # the scale does change training
    with pytest.raises(ValueError, match="reward_scale"):
        SACLfD("MlpPolicy", ToyPickPlaceEnv(), reward_scale=0.0)


def test_awac_trains_offline_then_online():
    eps = collect_episodes(3)
    model = AWAC("MlpPolicy", ToyPickPlaceEnv(), demonstrations=eps, buffer_size=500, batch_size=32,
                 offline_steps=25, policy_kwargs=tiny(), seed=0)
    assert model.entropy_weight == 0.0 and model.rsi_prob == 0.0 and model.gamma == 0.99
    model.learn(10)
    assert model._n_updates == 25 + 10 and model.num_timesteps == 10
    model.learn(5, reset_num_timesteps=False)
    assert model._n_updates == 25 + 15  # offline phase runs once


@pytest.mark.parametrize("algo_name", ["SAC", "TD3", "PPO"])
@pytest.mark.parametrize("obs_mode", ["state", "image", "state+image"])
def test_plain_sb3_algorithms_run_on_toy_env(algo_name, obs_mode):
    import stable_baselines3 as sb3

    from lfd_agents.networks import KeySubsetExtractor

    policy = {"state": "MlpPolicy", "image": "CnnPolicy", "state+image": "MultiInputPolicy"}[obs_mode]
    kwargs: dict = dict(policy_kwargs=dict(net_arch=[16, 16]), seed=0)
    if obs_mode == "image":  # SB3's NatureCNN needs >= 36x36 pixels
        kwargs["policy_kwargs"]["features_extractor_class"] = ImageEncoder
    if obs_mode == "state+image":
        kwargs["policy_kwargs"]["features_extractor_class"] = KeySubsetExtractor
    if algo_name == "PPO":
        kwargs.update(n_steps=16, batch_size=16, n_epochs=1)
    else:
        kwargs.update(buffer_size=200, learning_starts=5, batch_size=8)
    getattr(sb3, algo_name)(policy, ToyPickPlaceEnv(obs_mode=obs_mode), **kwargs).learn(20)


@pytest.mark.parametrize("algo_name", ["SAC", "TD3", "PPO"])
def test_plain_sb3_algorithms_run_on_particle_task(algo_name):
    import gymnasium as gym
    import stable_baselines3 as sb3

    env = gym.make("ClothFoldDiagonalPinned-v0", obs_mode="state", action_mode="pick_place", resolution=6)
    kwargs: dict = dict(policy_kwargs=dict(net_arch=[16, 16]), seed=0)
    kwargs.update(n_steps=6, batch_size=6, n_epochs=1) if algo_name == "PPO" else kwargs.update(
        buffer_size=50, learning_starts=2, batch_size=4)
    getattr(sb3, algo_name)("MlpPolicy", env, **kwargs).learn(6)


def test_bc_default_training_is_a_fixed_number_of_updates():
    """Without ``n_epochs`` one ``learn`` runs about ``default_updates`` gradient steps, whatever the
    dataset size (a few epochs of a small dataset leave the policy near the mean action)."""
    eps = collect_episodes(3)
    n = sum(len(ep["actions"]) for ep in eps)
    model = BC("MlpPolicy", ToyPickPlaceEnv(), demonstrations=eps, batch_size=16, default_updates=200,
               policy_kwargs=tiny(), seed=0)
    model.learn()
    batches = -(-n // 16)
    assert model._n_updates == batches * -(-200 // batches) and 200 <= model._n_updates < 200 + batches
    with pytest.raises(ValueError):
        BC("MlpPolicy", ToyPickPlaceEnv(), demonstrations=eps, default_updates=0)
