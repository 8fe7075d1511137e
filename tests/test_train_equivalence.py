"""The update step of DMfD, AWAC and SAC-LfD computes the same numbers as the reference code.

``REFERENCE`` holds the logged training values and parameter fingerprints of a few gradient
steps on a fixed seed, recorded with the straightforward implementation (separate critic
MLPs, one ``.item()`` per logged value and update, SB3's ``polyak_update``) before the
update step was made faster.  The fast implementation keeps the construction order of every
layer (so a seed gives the same initial weights) and the order of every random draw (so a
seed gives the same batches and the same sampled actions); any change to a loss, a target,
an optimiser step or the target-network update moves these numbers far beyond the float32
round-off that the tolerance allows for.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch as th
from stable_baselines3.common.logger import configure

from dmfd_toy_env import ToyPickPlaceEnv, collect_episodes
from lfd_agents import AWAC, BC, DMfD, SACLfD

th.set_num_threads(1)

REL = 1e-5  # float32 round-off of a few re-associated sums, compounded over 9 updates
ABS = 1e-6


def _online_rows(model, n: int, seed: int) -> None:
    """Add ``n`` random transitions to the online replay buffer (fixed generator)."""
    rng = np.random.default_rng(seed)
    obs_dim = model.observation_space.shape[0]
    act_dim = model.action_space.shape[0]
    for _ in range(n):
        model.replay_buffer.add(rng.normal(size=(1, obs_dim)).astype(np.float32),
                                rng.normal(size=(1, obs_dim)).astype(np.float32),
                                rng.uniform(-1, 1, (1, act_dim)).astype(np.float32),
                                rng.normal(size=1).astype(np.float32), (rng.random(1) < 0.1), [{}])


def _build(name: str):
    demos = collect_episodes(3, obs_mode="image" if name == "dmfd_image" else "state")
    kw = dict(buffer_size=400, batch_size=32, seed=0)
    arch = dict(net_arch=[64, 64])
    if name == "dmfd":
        return DMfD("MlpPolicy", ToyPickPlaceEnv(), demonstrations=demos, policy_kwargs=arch, **kw)
    if name == "dmfd_target_entropy_demo_ratio":
        model = DMfD("MlpPolicy", ToyPickPlaceEnv(), demonstrations=demos, policy_kwargs=arch, target_ent_coef=0.2,
                     demo_ratio=0.5, reward_scale=3.0, **kw)
        _online_rows(model, 100, seed=5)
        return model
    if name == "dmfd_image":  # the thesis's image network, with which the reference was recorded
        from lfd_agents.networks import THESIS_ENCODER

        return DMfD("CnnPolicy", ToyPickPlaceEnv(obs_mode="image"), demonstrations=demos,
                    policy_kwargs=dict(net_arch=[32, 32], share_encoder=False,
                                       features_extractor_kwargs=THESIS_ENCODER), **kw)
    if name == "awac":
        return AWAC("MlpPolicy", ToyPickPlaceEnv(), demonstrations=demos, offline_steps=0, policy_kwargs=arch, **kw)
    if name == "sac_lfd":
        model = SACLfD("MlpPolicy", ToyPickPlaceEnv(), demonstrations=demos, policy_kwargs=arch, **kw)
        _online_rows(model, 50, seed=6)
        return model
    raise KeyError(name)


def _fingerprint(module: th.nn.Module) -> list[float]:
    """Layout-independent summary of a module's parameters: sum, sum of squares, sum of |x|."""
    flat = th.cat([p.detach().double().flatten() for p in module.parameters()])
    return [float(flat.sum()), float((flat ** 2).sum()), float(flat.abs().sum())]


def _trace_bc() -> dict[str, list[float]]:
    """BC: the loss of each of 3 epochs (3 batches each) and the final fingerprint."""
    model = BC("MlpPolicy", ToyPickPlaceEnv(), demonstrations=collect_episodes(3), batch_size=32,
               policy_kwargs=dict(net_arch=[64, 64]), seed=0)
    th.manual_seed(11)
    np.random.seed(11)
    out: dict[str, list[float]] = {"train/bc_loss": []}
    for _ in range(3):
        model.learn(epochs=1, log_interval=0)
        out["train/bc_loss"].append(float(model.logger.name_to_value["train/bc_loss"]))
    out["fp/actor"] = _fingerprint(model.policy)
    return out


def trace(name: str) -> dict[str, list[float]]:
    """Logged values after each of 6 single updates and one 3-update call, and final fingerprints."""
    if name == "bc":
        return _trace_bc()
    model = _build(name)
    model.set_logger(configure(None, []))
    th.manual_seed(11)
    np.random.seed(11)
    out: dict[str, list[float]] = {}
    for n in (1, 1, 1, 1, 1, 1, 3):
        model.train(n, model.batch_size)
        for key, value in sorted(model.logger.name_to_value.items()):
            if key.startswith("train/") and key != "train/n_updates":
                out.setdefault(key, []).append(float(value))
    out["fp/actor"] = _fingerprint(model.actor)
    out["fp/critic"] = _fingerprint(model.critic)
    out["fp/critic_target"] = _fingerprint(model.critic_target)
    g = th.Generator().manual_seed(3)
    if name != "dmfd_image":
        x = th.randn(5, model.observation_space.shape[0], generator=g)
        a = th.rand(5, model.action_space.shape[0], generator=g) * 2 - 1
        with th.no_grad():
            out["q/critic"] = th.cat(model.critic(x, a), dim=1).flatten().tolist()
            out["q/critic_target"] = th.cat(model.critic_target(x, a), dim=1).flatten().tolist()
    return out


#: ``trace(name)`` of every case, recorded with the reference implementation (tests/data/train_reference.json)
REFERENCE: dict[str, dict[str, list[float]]] = json.loads(
    (Path(__file__).parent / "data" / "train_reference.json").read_text())


CASES = ["dmfd", "dmfd_target_entropy_demo_ratio", "dmfd_image", "awac", "sac_lfd", "bc"]


@pytest.mark.parametrize("name", CASES)
def test_update_step_reproduces_reference_values(name):
    got = trace(name)
    ref = REFERENCE[name]
    assert sorted(got) == sorted(ref)
    for key, values in ref.items():
        np.testing.assert_allclose(got[key], values, rtol=REL, atol=ABS, err_msg=f"{name} {key}")


if __name__ == "__main__":  # print the reference table (run with the reference implementation)
    import json

    print(json.dumps({n: trace(n) for n in CASES}, indent=1))


# ------------------------------------------------------------------------------ fused critics
def _critics(width: int = 16, n_critics: int = 2):
    from gymnasium import spaces
    from stable_baselines3.common.policies import ContinuousCritic
    from stable_baselines3.common.torch_layers import FlattenExtractor

    from lfd_agents.networks import EnsembleCritic

    obs_space, act_space = spaces.Box(-1, 1, (5,), np.float32), spaces.Box(-1, 1, (3,), np.float32)
    th.manual_seed(0)
    sb3 = ContinuousCritic(obs_space, act_space, [width, width], FlattenExtractor(obs_space), 5,
                           n_critics=n_critics, share_features_extractor=False)
    th.manual_seed(0)
    fused = EnsembleCritic(obs_space, act_space, [width, width], FlattenExtractor(obs_space), 5, n_critics=n_critics)
    return sb3, fused


def _batch(seed: int = 0):
    g = th.Generator().manual_seed(seed)
    return th.randn(64, 5, generator=g), th.rand(64, 3, generator=g) * 2 - 1, th.randn(64, 1, generator=g)


@pytest.mark.parametrize("n_critics", [1, 2, 3])
def test_ensemble_critic_has_sb3_initial_weights_outputs_and_gradients(n_critics):
    sb3, fused = _critics(n_critics=n_critics)
    obs, act, y = _batch()
    act_a, act_b = act.clone().requires_grad_(True), act.clone().requires_grad_(True)
    q_sb3, q_fused = sb3(obs, act_a), fused(obs, act_b)
    assert len(q_fused) == n_critics and q_fused[0].shape == (64, 1)
    for a, b in zip(q_sb3, q_fused):
        th.testing.assert_close(a, b, rtol=1e-6, atol=1e-6)
    th.testing.assert_close(sb3.q1_forward(obs, act), fused.q1_forward(obs, act), rtol=1e-6, atol=1e-6)
    sum(((q - y) ** 2).mean() for q in q_sb3).backward()
    sum(((q - y) ** 2).mean() for q in q_fused).backward()
    th.testing.assert_close(act_a.grad, act_b.grad, rtol=1e-5, atol=1e-7)
    for j, k in enumerate((0, 2, 4)):  # Linear layers of each SB3 Sequential
        for i in range(n_critics):
            lin = getattr(sb3, f"qf{i}")[k]
            th.testing.assert_close(lin.weight.grad.t(), getattr(fused, f"w{j}").grad[i], rtol=1e-5, atol=1e-7)
            th.testing.assert_close(lin.bias.grad, getattr(fused, f"b{j}").grad[i, 0], rtol=1e-5, atol=1e-7)


def test_sb3_critic_state_and_adam_state_load_into_the_ensemble_and_training_continues_identically():
    """Files saved when the critics were SB3 ``ContinuousCritic``s: weights (state-dict hook) and
    Adam moments (``_ensemble_optimizer_state``) are re-laid out, and the next steps agree."""
    from lfd_agents.dmfd import _ensemble_optimizer_state

    sb3, fused = _critics()
    opt_sb3 = th.optim.Adam(sb3.parameters(), lr=1e-2)

    def step(critic, opt, seed):
        obs, act, y = _batch(seed)
        opt.zero_grad()
        sum(((q - y) ** 2).mean() for q in critic(obs, act)).backward()
        opt.step()

    for seed in range(3):  # weights and moments move away from the shared initialisation
        step(sb3, opt_sb3, seed)
    fused.load_state_dict(sb3.state_dict())
    opt_fused = th.optim.Adam(fused.parameters(), lr=1e-2, fused=True)
    opt_fused.load_state_dict(_ensemble_optimizer_state(opt_sb3.state_dict(), fused, opt_fused.state_dict()))
    assert opt_fused.param_groups[0]["fused"] is True
    for seed in range(3, 6):
        step(sb3, opt_sb3, seed)
        step(fused, opt_fused, seed)
    obs, act, _ = _batch(9)
    for a, b in zip(sb3(obs, act), fused(obs, act)):
        th.testing.assert_close(a, b, rtol=1e-5, atol=1e-6)
