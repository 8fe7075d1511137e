"""DMfD: loss terms, demonstration loading, RSI, augmentation, save/load, learning signal."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch as th
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.type_aliases import ReplayBufferSamples

from dmfd_toy_env import ToyPickPlaceEnv, collect_episodes, evaluate
from lfd_agents import BC, DMfD, ReferenceStateInit
from lfd_agents.augment import random_shift
from lfd_agents.demos import fill_replay_buffer, load_episodes
from lfd_agents.dmfd import awr_log_prob, awr_weights, dmfd_actor_loss, td_target
from lfd_agents.networks import log_prob, normal_log_prob

th.set_num_threads(1)  # 2 shared cores: threads only add contention
def tiny() -> dict:
    return dict(net_arch=[32, 32])  # fresh each time: SB3 adds keys to policy_kwargs in place


@pytest.fixture(scope="module")
def demos():
    return collect_episodes(4)


# ------------------------------------------------------------------------------ loss terms
def test_actor_loss_matches_hand_computed_values():
    adv = th.tensor([0.0, 2.0 * math.log(3.0)])  # λ = 2 → softmax([0, ln 3]) = [1/4, 3/4]
    w = awr_weights(adv, temperature=2.0)
    assert th.allclose(w, th.tensor([0.5, 1.5]))
    out = dmfd_actor_loss(th.tensor([-1.0, -2.0]), adv, th.tensor([0.2, -0.4]), th.tensor([1.0, 3.0]),
                          temperature=2.0, ent_coef=0.5, entropy_weight=0.1)
    # L_A = -mean(-1*0.5, -2*1.5) = 1.75; L_E = mean(0.1-1, -0.2-3) = -2.05
    assert out["awr_loss"].item() == pytest.approx(1.75)
    assert out["entropy_loss"].item() == pytest.approx(-2.05)
    assert out["loss"].item() == pytest.approx(0.9 * 1.75 + 0.1 * -2.05)


def test_binary_weighting_imitates_only_actions_rated_above_the_policys():
    adv = th.tensor([-0.5, 0.0, 1e-3, 4.0])
    assert awr_weights(adv, temperature=2.0, weighting="binary").tolist() == [0.0, 0.0, 1.0, 1.0]
    out = dmfd_actor_loss(th.tensor([-1.0, -2.0, -3.0, -4.0]), adv, th.zeros(4), th.zeros(4),
                          temperature=2.0, ent_coef=0.5, entropy_weight=0.0, weighting="binary")
    assert out["awr_loss"].item() == pytest.approx((3.0 + 4.0) / 4)
    with pytest.raises(ValueError, match="weighting must be one of"):
        awr_weights(adv, temperature=2.0, weighting="exp")
    with pytest.raises(ValueError, match="awr_weighting"):
        DMfD("MlpPolicy", ToyPickPlaceEnv(), buffer_size=100, policy_kwargs=tiny(), awr_weighting="hard")


def _fit_grads(fit: str) -> tuple[th.Tensor, th.Tensor]:
    actions = th.tensor([[0.1, 0.1, 0.1]])
    mean = th.zeros(1, 3, requires_grad=True)
    log_std = th.tensor([-5.0, -2.0, -0.5], requires_grad=True)  # a tight, a medium and a loose dimension
    awr_log_prob(actions, mean, log_std.exp(), fit).sum().backward()
    return mean.grad[0], log_std.grad


def test_isotropic_fit_pulls_every_action_dimension_alike_and_fits_each_std():
    """The likelihood fit weights a dimension's error by 1/sigma^2: with the same error of 0.1 the
    tight dimension is pulled e^9 (about 8100) times harder than the loose one. The isotropic
    fit pulls all three alike, and its std gradient is the likelihood's."""
    mean_grad, std_grad = _fit_grads("likelihood")
    assert (mean_grad[0] / mean_grad[2]).item() == pytest.approx(math.exp(9.0), rel=1e-4)
    iso_mean_grad, iso_std_grad = _fit_grads("isotropic")
    assert th.allclose(iso_mean_grad, iso_mean_grad[0].expand(3))
    assert iso_mean_grad[0].item() == pytest.approx(0.1 / math.exp(2 * -2.5), rel=1e-4)  # one sigma: e^mean(log sigma)
    assert th.allclose(iso_std_grad, std_grad)
    a, m, sd = th.randn(4, 3), th.randn(4, 3), th.rand(3) + 0.1
    assert th.equal(awr_log_prob(a, m, sd, "likelihood"), normal_log_prob(a, m, sd))
    with pytest.raises(ValueError, match="fit must be one of"):
        awr_log_prob(a, m, sd, "mse")
    with pytest.raises(ValueError, match="awr_fit"):
        DMfD("MlpPolicy", ToyPickPlaceEnv(), buffer_size=100, policy_kwargs=tiny(), awr_fit="mse")


def test_td_target_hand_computed():
    y = td_target(th.tensor([1.0, 2.0]), th.tensor([0.0, 1.0]), th.tensor([3.0, 4.0]), th.tensor([-1.0, 0.0]),
                  gamma=0.9, target_ent_coef=0.5)
    assert th.allclose(y, th.tensor([1.0 + 0.9 * 3.5, 2.0]))


def _tiny_batch(model: DMfD) -> ReplayBufferSamples:
    g = th.Generator().manual_seed(0)
    obs, next_obs = th.randn(3, 7, generator=g), th.randn(3, 7, generator=g)
    actions = th.rand(3, 3, generator=g) * 2 - 1
    return ReplayBufferSamples(obs, actions, next_obs, th.tensor([[0.5], [-1.0], [2.0]]),
                               th.tensor([[0.0], [1.0], [0.0]]), None)


def test_model_losses_match_manual_computation():
    model = DMfD("MlpPolicy", ToyPickPlaceEnv(), buffer_size=100, policy_kwargs=tiny(), seed=0, reward_scale=2.0)
    data = _tiny_batch(model)
    th.manual_seed(1)
    critic = model.critic_loss(data)
    th.manual_seed(1)
    with th.no_grad():
        dist = model.actor.distribution(data.next_observations)
        a2 = dist.sample()
        q_next = th.min(*[q.flatten() for q in model.critic_target(data.next_observations, a2)])
        y = 2.0 * data.rewards.flatten() + (1 - data.dones.flatten()) * 0.9 * q_next  # α_target = 0
        q1, q2 = (q.flatten() for q in model.critic(data.observations, data.actions))
        expected = ((q1 - y) ** 2).mean() + ((q2 - y) ** 2).mean()
    assert critic["loss"].item() == pytest.approx(expected.item(), rel=1e-5)

    th.manual_seed(2)
    actor = model.actor_loss(data)
    th.manual_seed(2)
    with th.no_grad():
        dist = model.actor.distribution(data.observations)
        a_pi = dist.rsample()
        q_pi = th.min(*[q.flatten() for q in model.critic(data.observations, a_pi)])
        q_b = th.min(*[q.flatten() for q in model.critic(data.observations, data.actions)])
        w = th.exp((q_b - q_pi) / 2.0)
        w = w / w.sum() * 3
        l_a = -(log_prob(dist, data.actions) * w).mean()
        l_e = (0.5 * log_prob(dist, a_pi) - q_pi).mean()
    assert actor["awr_loss"].item() == pytest.approx(l_a.item(), rel=1e-5)
    assert actor["entropy_loss"].item() == pytest.approx(l_e.item(), rel=1e-5)
    assert actor["loss"].item() == pytest.approx(0.9 * l_a.item() + 0.1 * l_e.item(), rel=1e-5)


def test_bad_hyperparameters_are_rejected():
    with pytest.raises(ValueError, match="entropy_weight"):
        DMfD("MlpPolicy", ToyPickPlaceEnv(), entropy_weight=1.5)
    with pytest.raises(ValueError, match="rsi_prob"):
        DMfD("MlpPolicy", ToyPickPlaceEnv(), demonstrations=collect_episodes(1), rsi_prob=2.0)


# ------------------------------------------------------------------------------ demonstrations
def test_buffer_prefill_counts_layout_and_duplication(demos):
    env = ToyPickPlaceEnv(obs_mode="image")
    eps = collect_episodes(2, obs_mode="image")
    model = DMfD("CnnPolicy", env, demonstrations=eps, buffer_size=500, policy_kwargs=tiny(), seed=0)
    buf = model.replay_buffer
    assert buf.size() == 60 and buf.observations.shape[2:] == (3, 32, 32)  # HWC demos → CHW buffer
    np.testing.assert_array_equal(buf.observations[0, 0], np.moveaxis(eps[0]["observations"][0], -1, 0))
    np.testing.assert_array_equal(buf.next_observations[29, 0], np.moveaxis(eps[0]["observations"][30], -1, 0))
    assert buf.dones[29, 0] == 1 and buf.timeouts[29, 0] == 1 and buf.dones[28, 0] == 0
    full = ReplayBuffer(200, ToyPickPlaceEnv().observation_space, ToyPickPlaceEnv().action_space, n_envs=2)
    assert fill_replay_buffer(full, demos, duplicate=True) == 200 and full.full
    with pytest.raises(ValueError, match="obs_mode"):
        fill_replay_buffer(ReplayBuffer(50, env.observation_space, env.action_space), demos)


def test_minari_dataset_round_trip(tmp_path):
    from lfd_envs import datasets

    path = datasets.collect("ClothFoldDiagonalPinned-v0", 1, tmp_path,
                            env_kwargs=dict(obs_mode="state", action_mode="pick_place", resolution=6), progress=False)
    (ep,) = load_episodes(path)
    assert len(ep) == 3 and ep.observations.shape == (4, 15) and len(ep.states) == 4
    import gymnasium as gym

    env = ReferenceStateInit(gym.make("ClothFoldDiagonalPinned-v0", obs_mode="state", action_mode="pick_place",
                                      resolution=6), path, probability=1.0, seed=0)
    obs, info = env.reset(seed=3)
    np.testing.assert_allclose(obs, ep.observations[info["rsi_step"]], atol=1e-6)


# ------------------------------------------------------------------------------ RSI
def test_rsi_resets_land_on_demonstration_states(demos):
    env = ReferenceStateInit(ToyPickPlaceEnv(), demos, probability=1.0, seed=0)
    eps = load_episodes(demos)
    for k in range(5):
        obs, info = env.reset(seed=k)
        assert info["rsi"]
        t = info["rsi_step"]
        matches = [j for j, ep in enumerate(eps) if np.array_equal(obs, ep.observations[t])]
        assert matches, "reset observation is not a demonstration state"
        j = matches[0]
        state = env.unwrapped.get_state()
        assert int(state["episode/step"]) == t
        np.testing.assert_array_equal(state["sim/block"], eps[j].states[t]["sim/block"])
        # replaying the demonstration's next action reproduces its next state: maximal imitation reward 0.5
        _, reward, *_, step_info = env.step(eps[j].actions[t])
        assert step_info["imitation_reward"] == pytest.approx(0.5)
        assert reward == pytest.approx(eps[j].rewards[t] + 0.5, abs=1e-6)


def test_rsi_probability_zero_and_eval_split_are_untouched(demos):
    never = ReferenceStateInit(ToyPickPlaceEnv(), demos, probability=0.0, seed=0)
    always = ReferenceStateInit(ToyPickPlaceEnv(), demos, probability=1.0, seed=0)
    plain = ToyPickPlaceEnv()
    for k in range(3):
        obs, info = never.reset(seed=k)
        np.testing.assert_array_equal(obs, plain.reset(seed=k)[0])
        assert not info["rsi"] and never.step(np.zeros(3))[4]["imitation_reward"] == 0.0
        assert not always.reset(seed=k, options={"split": "eval"})[1]["rsi"]
    frac = np.mean([ReferenceStateInit(ToyPickPlaceEnv(), demos, 0.3, seed=0).reset(seed=k)[1]["rsi"]
                    for k in range(200)])
    assert 0.2 < frac < 0.4


def test_rsi_needs_states():
    eps = collect_episodes(1)
    del eps[0]["infos"]
    with pytest.raises(ValueError, match="states"):
        ReferenceStateInit(ToyPickPlaceEnv(), eps)


# ------------------------------------------------------------------------------ images
def test_random_shift_shapes_and_content():
    imgs = th.randint(0, 256, (5, 3, 32, 32), dtype=th.uint8)
    out = random_shift(imgs, pad=2)
    assert out.shape == imgs.shape and out.dtype == imgs.dtype
    padded = th.nn.functional.pad(imgs.float(), (2, 2, 2, 2), mode="replicate")
    for i in range(5):  # every output is a 32x32 window of the padded image
        windows = [(dy, dx) for dy in range(5) for dx in range(5)
                   if th.equal(padded[i, :, dy:dy + 32, dx:dx + 32], out[i].float())]
        assert windows
    assert th.equal(random_shift(imgs, pad=0), imgs)


def test_asymmetric_actor_critic_and_augmented_batches():
    eps = collect_episodes(2, obs_mode="state+image")
    model = DMfD("MultiInputPolicy", ToyPickPlaceEnv(obs_mode="state+image"), demonstrations=eps,
                 buffer_size=200, batch_size=8, policy_kwargs=tiny(), seed=0)
    assert model.actor.features_extractor.keys == ["image"]
    assert model.critic.features_extractor.keys == ["image", "state"]
    assert model.rsi_prob == 0.3  # image default
    data = model.augment_batch(model.replay_buffer.sample(8))
    assert data.observations["image"].shape == (8, 3, 32, 32) and data.observations["state"].shape == (8, 7)
    model.learn(10)


# ------------------------------------------------------------------------------ save / load
@pytest.mark.parametrize("obs_mode,policy", [("state", "MlpPolicy"), ("image", "CnnPolicy")])
def test_save_load_round_trip_predicts_identically(tmp_path, obs_mode, policy):
    env = ToyPickPlaceEnv(obs_mode=obs_mode)
    model = DMfD(policy, env, demonstrations=collect_episodes(2, obs_mode=obs_mode), buffer_size=200,
                 batch_size=16, policy_kwargs=tiny(), seed=0)
    model.learn(20)
    model.save(tmp_path / "dmfd.zip")
    loaded = DMfD.load(tmp_path / "dmfd.zip", env=ToyPickPlaceEnv(obs_mode=obs_mode))
    for k in range(3):
        obs, _ = env.reset(seed=k)
        np.testing.assert_array_equal(model.predict(obs, deterministic=True)[0],
                                      loaded.predict(obs, deterministic=True)[0])
    assert loaded.entropy_weight == 0.1 and loaded.gamma == 0.9 and loaded.replay_buffer.size() == 0


# ------------------------------------------------------------------------------ learning signal
def test_dmfd_beats_sac_and_random_on_cloth_fold_diagonal_pinned(tmp_path):
    """Pick-and-place ClothFoldDiagonalPinned (state, 16x16 cloth), fixed seeds, 30 env steps.

    Random pick-and-place and SAC without demonstrations score p̂ = 0 here (picks miss the
    corner); DMfD with 10 expert demonstrations learns the fold.
    """
    import gymnasium as gym
    from stable_baselines3 import SAC

    from lfd_envs import datasets

    kw = dict(obs_mode="state", action_mode="pick_place", resolution=16)
    path = datasets.collect("ClothFoldDiagonalPinned-v0", 10, tmp_path, env_kwargs=kw, progress=False)

    def score(model, n=6, seed=500):
        env = gym.make("ClothFoldDiagonalPinned-v0", **kw)
        rng = np.random.default_rng(seed)
        scores = []
        for i in range(n):
            obs, info = env.reset(seed=seed + i, options={"split": "eval"})
            done = False
            while not done:
                action = (rng.uniform(-1, 1, env.action_space.shape) if model is None
                          else model.predict(obs, deterministic=True)[0])
                obs, _, term, trunc, info = env.step(action)
                done = term or trunc
            scores.append(info["normalized_performance"])
        return float(np.mean(scores))

    common = dict(buffer_size=2000, batch_size=64, gradient_steps=20, learning_rate=1e-3,
                  policy_kwargs=dict(net_arch=[64, 64]), seed=0)
    dmfd = DMfD("MlpPolicy", gym.make("ClothFoldDiagonalPinned-v0", **kw), demonstrations=path, **common)
    assert dmfd.rsi_prob == 0.2 and dmfd.replay_buffer.size() == 30
    dmfd.learn(30)
    sac = SAC("MlpPolicy", gym.make("ClothFoldDiagonalPinned-v0", **kw), learning_starts=10, **common)
    sac.learn(30)
    p_dmfd, p_sac, p_random = score(dmfd), score(sac), score(None)
    print("p_dmfd, p_sac, p_random", p_dmfd, p_sac, p_random)
    assert p_dmfd > 0.6, (p_dmfd, p_sac, p_random)
    assert p_dmfd > p_sac + 0.4 and p_dmfd > p_random + 0.4, (p_dmfd, p_sac, p_random)


def test_dmfd_beats_bc_with_the_same_mixed_quality_demos_and_updates():
    """Half of the 40 toy demonstrations carry the block to a wrong place 0.6 from the goal.

    BC averages the two behaviours and lands between them; DMfD's advantage weighting prefers
    the actions that reach the goal. Both get the same demonstrations and ~6,000 gradient steps
    (DMfD: 3,000 on the demonstrations, then 3,000 env steps with one update each), on seeds
    0, 1, 2; the median of the paired differences must be clearly positive. Measured: DMfD − BC
    = +0.18, −0.06, +0.07 (with 20 demonstrations +0.05, +0.07, −0.04): one seed of three can
    lose, the critic behind the weights is small and young.
    """
    eps = collect_episodes(40, wrong_goal_fraction=0.5)
    n = sum(len(ep["actions"]) for ep in eps)
    diffs = []
    for seed in range(3):
        common = dict(batch_size=64, policy_kwargs=dict(net_arch=[64, 64]), seed=seed)
        bc = BC("MlpPolicy", ToyPickPlaceEnv(), demonstrations=eps, n_epochs=round(6000 * 64 / n),
                learning_rate=3e-4, **common)
        bc.learn()
        dmfd = DMfD("MlpPolicy", ToyPickPlaceEnv(), demonstrations=eps, offline_steps=3000, demo_ratio=0.5,
                    reward_scale=50, buffer_size=10_000, **common)
        dmfd.learn(3000)
        assert abs(bc._n_updates - dmfd._n_updates) < 0.1 * dmfd._n_updates
        diffs.append(evaluate(dmfd) - evaluate(bc))
    print("DMfD - BC per seed", np.round(diffs, 3))
    assert np.median(diffs) > 0.04 and np.mean(diffs) > 0.03, diffs


def test_demo_ratio_keeps_demonstrations_in_every_batch(demos):
    """With ``demo_ratio`` the demonstrations live in their own buffer and make up that share of
    each batch; the online replay buffer starts empty (the whole batch is demos until it fills)."""
    n_demo = sum(len(ep["actions"]) for ep in demos)
    model = DMfD("MlpPolicy", ToyPickPlaceEnv(), demonstrations=demos, demo_ratio=0.25, batch_size=64,
                 policy_kwargs=tiny(), seed=0)
    assert model.replay_buffer.size() == 0 and model.demo_buffer.size() == n_demo
    demo_obs = np.concatenate([np.asarray(ep["observations"][:-1], np.float32) for ep in demos])

    def demo_share(batch) -> float:
        obs = batch.observations.numpy()
        return float(np.mean(np.abs(obs[:, None] - demo_obs[None]).max(-1).min(1) < 1e-6))

    assert demo_share(model.sample_batch(64)) == 1.0
    assert float(model.demo_buffer.sample(512).dones.sum()) == 0.0  # time-limit ends are not terminal
    model.learn(200)
    assert model.replay_buffer.size() == 200
    batch = model.sample_batch(64)
    assert len(batch.actions) == 64 and demo_share(batch) == pytest.approx(0.25, abs=0.03)
    with pytest.raises(ValueError, match="demo_ratio"):
        DMfD("MlpPolicy", ToyPickPlaceEnv(), demonstrations=demos, demo_ratio=1.0, policy_kwargs=tiny())


def test_pretrain_runs_the_offline_phase_once_and_learn_goes_on_online(demos):
    """``pretrain()`` takes the offline steps and no env step; ``learn`` then only goes online,
    and the result equals a ``learn`` that ran the offline phase itself."""
    def make():
        return DMfD("MlpPolicy", ToyPickPlaceEnv(), demonstrations=demos, offline_steps=40, batch_size=16,
                    policy_kwargs=tiny(), seed=3)

    model = make()
    assert model.offline_pending
    model.pretrain()
    assert not model.offline_pending and model._n_updates == 40 and model.num_timesteps == 0
    model.pretrain()  # nothing left to do
    assert model._n_updates == 40
    model.learn(30)
    plain = make()
    plain.learn(30)
    assert model.num_timesteps == plain.num_timesteps == 30 and model._n_updates == plain._n_updates
    for a, b in zip(model.policy.parameters(), plain.policy.parameters()):
        th.testing.assert_close(a, b)
    assert not DMfD("MlpPolicy", ToyPickPlaceEnv(), demonstrations=demos, policy_kwargs=tiny()).offline_pending
