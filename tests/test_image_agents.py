"""Learning from pixels: DrQ's averaged targets and losses, CURL's contrastive loss and momentum key
encoder, the shared image encoder, DMfD's and BC's image paths, and plain SB3 on the default
32×32 image env."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch as th
from torch.distributions import Normal

from dmfd_toy_env import ToyPickPlaceEnv, collect_episodes
from lfd_agents import BC, CURL, DMfD, DrQ, ImageEncoder
from lfd_agents.augment import random_shift
from lfd_agents.curl import contrastive_logits, contrastive_loss
from lfd_agents.networks import THESIS_ENCODER, DetachedExtractor

def tiny() -> dict:
    """Small networks (a new dict each time: SB3 writes into the policy_kwargs it is given)."""
    return dict(net_arch=[32, 32])


def _filled(cls, obs_mode="image", steps=40, **kwargs):
    """A model whose replay buffer holds ``steps`` random transitions and that took no update."""
    policy = "CnnPolicy" if obs_mode == "image" else "MultiInputPolicy"
    model = cls(policy, ToyPickPlaceEnv(obs_mode=obs_mode), batch_size=8, buffer_size=200,
                learning_starts=10_000, policy_kwargs=tiny(), seed=0, **kwargs)
    model.learn(steps)
    return model


def _sample(model, n=8):
    data = model.replay_buffer.sample(n)
    return data


# ------------------------------------------------------------------------------ DrQ
def test_drq_target_is_the_mean_over_k_shifted_next_observations():
    model = _filled(DrQ, n_target_augs=2)
    data = _sample(model)
    alpha = th.tensor(0.3)
    gen_state = model.aug_generator.get_state()
    th.manual_seed(5)
    target = model.target_q(data, alpha)
    # by hand: the same two shifts (replayed from the generator), the same policy noise
    model.aug_generator.set_state(gen_state)
    next_obs = data.next_observations
    shifted = [random_shift(next_obs, 2, model.aug_generator) for _ in range(2)]
    assert not th.equal(shifted[0], shifted[1])
    th.manual_seed(5)
    noise = th.randn(16, 3).split(8)
    ys = []
    with th.no_grad():
        for aug, eps in zip(shifted, noise):
            features = model.critic.features_extractor(aug / 255.0)
            latent = model.actor.latent_pi(features)
            mean, std = model.actor.mu(latent), model.actor.log_std(latent).clamp(-20, 2).exp()
            g = mean + eps * std
            a = th.tanh(g)
            logp = Normal(mean, std).log_prob(g).sum(-1) - th.log(1 - a ** 2 + 1e-6).sum(-1)
            q1, q2 = model.critic_target(aug, a)
            next_v = th.min(q1, q2).flatten() - alpha * logp
            ys.append(data.rewards.flatten() + model.gamma * (1 - data.dones.flatten()) * next_v)
    th.testing.assert_close(target, (ys[0] + ys[1]) / 2, rtol=1e-5, atol=1e-5)
    assert not th.allclose(ys[0], ys[1])  # the two shifts give different targets: the mean is not either one


def test_drq_q_loss_is_the_mean_over_m_shifted_observations():
    model = _filled(DrQ, n_q_augs=2)
    data = _sample(model)
    target = th.randn(8)
    obs_augs = model.augment(data.observations, 2)
    loss = model.critic_loss(data, target, obs_augs)
    by_hand = []
    for m in range(2):
        q1, q2 = model.critic(obs_augs[8 * m:8 * (m + 1)], data.actions)
        by_hand.append(0.5 * (((q1.flatten() - target) ** 2).mean() + ((q2.flatten() - target) ** 2).mean()))
    th.testing.assert_close(loss, (by_hand[0] + by_hand[1]) / 2)


def test_drq_actor_reads_the_critics_encoder_without_training_it():
    model = _filled(DrQ)
    encoder = model.critic.features_extractor
    assert isinstance(model.actor.features_extractor, DetachedExtractor)
    assert model.actor.features_extractor.encoder is encoder
    actor_params = {id(p) for g in model.actor.optimizer.param_groups for p in g["params"]}
    critic_params = {id(p) for g in model.critic.optimizer.param_groups for p in g["params"]}
    assert not actor_params & {id(p) for p in encoder.parameters()}
    assert {id(p) for p in encoder.parameters()} <= critic_params
    obs = _sample(model).observations
    model.actor.action_log_prob(obs)[1].sum().backward()
    assert all(p.grad is None for p in encoder.parameters())


def test_image_learners_need_images():
    with pytest.raises(ValueError, match="n_target_augs"):
        DrQ("CnnPolicy", ToyPickPlaceEnv(obs_mode="image"), n_target_augs=0)
    with pytest.raises(ValueError, match="has none"):
        DrQ("MultiInputPolicy", gym.wrappers.TransformObservation(
            ToyPickPlaceEnv(obs_mode="state"), lambda o: {"state": o},
            gym.spaces.Dict({"state": ToyPickPlaceEnv().observation_space})))


# ------------------------------------------------------------------------------ CURL
def test_contrastive_logits_put_the_positive_pairs_on_the_diagonal():
    z = th.nn.functional.normalize(th.randn(6, 5), dim=1) * 3
    logits = contrastive_logits(z, z, th.eye(5))
    assert (logits.argmax(dim=1) == th.arange(6)).all()  # q_i·k_i is row i's largest (Cauchy-Schwarz)
    assert th.allclose(logits.max(dim=1).values, th.zeros(6))
    w = th.randn(5, 5)
    by_hand = -th.log_softmax(z @ w @ z.t(), dim=1).diagonal().mean()
    th.testing.assert_close(contrastive_loss(z, z, w), by_hand)
    assert contrastive_loss(z, z, th.eye(5)) < contrastive_loss(z, z.roll(1, dims=0), th.eye(5))


def test_curl_key_encoder_moves_by_exactly_tau_towards_the_query_encoder_and_takes_no_gradient():
    model = _filled(CURL, encoder_tau=0.05)
    key = model.critic_target.features_extractor
    key_before = [p.detach().clone() for p in key.parameters()]
    query_before = [p.detach().clone() for p in model.critic.features_extractor.parameters()]
    w_before = model.policy.contrastive_w.detach().clone()
    model.train(1, batch_size=8)
    query_after = [p.detach() for p in model.critic.features_extractor.parameters()]
    for k0, k1, q1 in zip(key_before, key.parameters(), query_after):
        th.testing.assert_close(k1.detach(), 0.95 * k0 + 0.05 * q1)
    assert all(p.grad is None for p in key.parameters())
    assert any(not th.equal(a, b) for a, b in zip(query_before, query_after))
    assert not th.equal(w_before, model.policy.contrastive_w)  # W is trained by the contrastive step
    assert "train/contrastive_loss" in model.logger.name_to_value


def test_curl_contrastive_step_trains_the_query_encoder_on_the_anchor_crop():
    model = _filled(CURL)
    obs = _sample(model).observations
    loss = model.contrastive_loss(model.augment(obs, 1), model.augment(obs, 1))
    loss.backward()
    assert all(p.grad is not None for p in model.critic.features_extractor.parameters())
    assert model.policy.contrastive_w.grad is not None


@pytest.mark.parametrize("cls,obs_mode", [(DrQ, "image"), (CURL, "state+image")])
def test_image_learners_train_and_round_trip(tmp_path, cls, obs_mode):
    policy = "CnnPolicy" if obs_mode == "image" else "MultiInputPolicy"
    model = cls(policy, ToyPickPlaceEnv(obs_mode=obs_mode), batch_size=8, buffer_size=200, learning_starts=10,
                policy_kwargs=tiny(), seed=0)
    model.learn(20)
    assert model._n_updates == 10
    env = ToyPickPlaceEnv(obs_mode=obs_mode)
    obs, _ = env.reset(seed=3)
    action, _ = model.predict(obs, deterministic=True)
    assert action.shape == (3,) and np.all(np.abs(action) <= 1)
    model.save(tmp_path / "m")
    loaded = cls.load(tmp_path / "m", env=env)
    np.testing.assert_allclose(loaded.predict(obs, deterministic=True)[0], action, atol=1e-6)
    loaded.learn(5, reset_num_timesteps=False)


# ------------------------------------------------------------------------------ encoders, DMfD, BC
def test_default_encoder_is_lean_and_the_thesis_encoder_is_an_option():
    space = ToyPickPlaceEnv(obs_mode="image").observation_space
    space = gym.spaces.Box(0, 255, (3, 32, 32), np.uint8) if space.shape[-1] == 3 else space
    lean, thesis = ImageEncoder(space), ImageEncoder(space, **THESIS_ENCODER)
    convs = [[m for m in e.convs if isinstance(m, th.nn.Conv2d)] for e in (lean, thesis)]
    assert [(c.out_channels, c.stride[0]) for c in convs[0]] == [(16, 2), (16, 2), (16, 1)]
    assert [(c.out_channels, c.stride[0]) for c in convs[1]] == [(32, 2), (32, 1), (32, 1), (32, 1)]
    assert lean.head[0].in_features == 16 * 5 * 5 and thesis.head[0].in_features == 32 * 9 * 9
    x = th.rand(4, 3, 32, 32)
    assert lean(x).shape == thesis(x).shape == (4, 50)
    with pytest.raises(ValueError, match="strides"):
        ImageEncoder(gym.spaces.Box(0, 255, (3, 16, 16), np.uint8), strides=(2, 2, 2, 2))


def test_dmfd_image_path_asymmetric_critic_shared_encoder_and_thesis_option():
    eps = collect_episodes(2, obs_mode="state+image")
    env = ToyPickPlaceEnv(obs_mode="state+image")
    model = DMfD("MultiInputPolicy", env, demonstrations=eps, buffer_size=500, batch_size=8, policy_kwargs=tiny(),
                 seed=0)
    assert model.rsi_prob == 0.3 and model._aug_keys == ["image"] and model.aug_pad == 2
    actor_fe, critic_fe = model.actor.features_extractor, model.critic.features_extractor
    assert actor_fe.keys == ["image"] and critic_fe.keys == ["image", "state"]  # actor on image, critic on both
    assert actor_fe.extractors["image"] is critic_fe.extractors["image"]  # one encoder
    encoder_ids = {id(p) for p in critic_fe.extractors["image"].parameters()}
    assert not encoder_ids & {id(p) for g in model.actor.optimizer.param_groups for p in g["params"]}
    model.learn(10)
    thesis = DMfD("MultiInputPolicy", env, demonstrations=eps, buffer_size=500, batch_size=8, seed=0,
                  policy_kwargs=dict(tiny(), share_encoder=False,
                                     features_extractor_kwargs=dict(image_encoder_kwargs=THESIS_ENCODER)))
    t_actor, t_critic = thesis.actor.features_extractor, thesis.critic.features_extractor
    assert t_actor.extractors["image"] is not t_critic.extractors["image"]
    assert t_actor.extractors["image"].channels == 32 and t_actor.extractors["image"].strides == (2, 1, 1, 1)
    thesis.learn(10)


def test_dmfd_shared_encoder_is_trained_by_both_losses_and_the_heads_by_their_own():
    eps = collect_episodes(2, obs_mode="image")
    model = DMfD("CnnPolicy", ToyPickPlaceEnv(obs_mode="image"), demonstrations=eps, buffer_size=500, batch_size=8,
                 policy_kwargs=tiny(), seed=0)
    assert model.actor.features_extractor is model.critic.features_extractor
    data = model.augment_batch(model.sample_batch(8))
    features = model.critic.features(data.observations)
    critic, actor = model.critic_loss(data, features), model.actor_loss(data, features)
    encoder = list(model.critic.features_extractor.parameters())
    heads = [p for n, p in model.critic.named_parameters() if not n.startswith("features_extractor.")]
    for loss in (critic["loss"], actor["loss"]):
        assert all(g.abs().sum() > 0 for g in th.autograd.grad(loss, encoder, retain_graph=True))
    assert all(g is None for g in th.autograd.grad(actor["loss"], heads, retain_graph=True, allow_unused=True))
    # the losses from shared features are those of encoding the batch separately for each
    for loss in (model.critic_loss, model.actor_loss):
        th.manual_seed(2)
        shared = loss(data, features)["loss"]
        th.manual_seed(2)
        th.testing.assert_close(shared, loss(data)["loss"])


def test_dmfd_image_actor_fits_its_demonstrations_with_the_default_network():
    """Offline phase only: the lean shared encoder, trained by both losses, lets the actor imitate
    the demonstrations' actions far better than their mean action."""
    demos = collect_episodes(10, obs_mode="image")
    obs = np.concatenate([e["observations"][:-1] for e in demos])
    actions = np.concatenate([e["actions"] for e in demos])
    model = DMfD("CnnPolicy", ToyPickPlaceEnv(obs_mode="image"), demonstrations=demos, offline_steps=300,
                 batch_size=64, learning_rate=1e-3, buffer_size=1000, seed=0, policy_kwargs=dict(net_arch=[64, 64]))
    model.learn(1)
    error = ((model.predict(obs, deterministic=True)[0] - actions) ** 2).mean()
    assert error < 0.1 * ((actions.mean(axis=0) - actions) ** 2).mean()


def test_bc_from_images_fits_the_demonstrated_actions_far_better_than_their_mean():
    demos = collect_episodes(10, obs_mode="image")
    model = BC("CnnPolicy", ToyPickPlaceEnv(obs_mode="image"), demonstrations=demos, n_epochs=20, batch_size=64,
               seed=0)
    assert model._aug_keys == [None]  # trained on pad-and-crop shifted images
    model.learn()
    obs = np.concatenate([e["observations"][:-1] for e in demos])
    actions = np.concatenate([e["actions"] for e in demos])
    error = ((model.predict(obs, deterministic=True)[0] - actions) ** 2).mean()
    baseline = ((actions.mean(axis=0) - actions) ** 2).mean()
    assert error < 0.2 * baseline, (error, baseline)


# ------------------------------------------------------------------------------ plain SB3
@pytest.mark.parametrize("algo", ["SAC", "PPO"])
def test_plain_sb3_cnn_policy_runs_on_the_default_image_env_as_the_readme_shows(algo):
    """The README's one line (``policy_kwargs=dict(features_extractor_class=ImageEncoder)``), run
    with a small buffer and a few steps."""
    from pathlib import Path

    import stable_baselines3 as sb3

    readme = (Path(__file__).resolve().parent.parent / "README.md").read_text()
    assert 'SAC("CnnPolicy", env, policy_kwargs=dict(features_extractor_class=ImageEncoder))' in readme
    assert 'gym.make("lfd_envs:ClothFoldDiagonal-v0")' in readme
    env = gym.make("lfd_envs:ClothFoldDiagonal-v0", max_episode_steps=8)
    assert env.observation_space.shape == (32, 32, 3)
    kwargs = dict(learning_starts=4, batch_size=4, buffer_size=100) if algo == "SAC" else dict(n_steps=8,
                                                                                                 batch_size=4)
    model = getattr(sb3, algo)("CnnPolicy", env, policy_kwargs=dict(features_extractor_class=ImageEncoder),
                               seed=0, device="cpu", **kwargs)
    model.learn(8)
    obs, _ = env.reset(seed=0)
    assert env.action_space.contains(model.predict(obs, deterministic=True)[0])


def test_train_speed_image_rows_compare_each_update_with_its_state_counterpart(one_torch_thread):
    from benchmarks.train_speed import agent_rows

    rows = agent_rows("ClothFold-v0", widths=[32], agents=[], image_agents=["drq"], rounds=1,
                      updates=10, learn_steps=10, batch_size=16, buffer_rows=200, matmul_floor=False)
    by = {(r["agent"], r["obs"]): r for r in rows}
    assert set(by) == {("SAC-LfD", "state"), ("DrQ", "image")}  # DrQ runs SAC-LfD's update machinery
    image, state = by[("DrQ", "image")], by[("SAC-LfD", "state")]
    assert image["vs_state"] == pytest.approx(state["updates_per_cpu_s"] / image["updates_per_cpu_s"], rel=0.05)
    assert image["vs_state"] > 1  # encoding 32x32 images costs more than a 32-wide state MLP
    assert state["vs_state"] is None
