"""NistBC: RT-1-style multi-task visual behaviour cloning on NistBoardInsert-v0 (small images, CPU)."""

from __future__ import annotations

import numpy as np
import pytest

from lfd_agents.nist_bc import NistBC, collect_demonstrations, evaluate, instruction_ids, nist_bc_1cam, nist_bc_h6
from lfd_envs.mujoco.nist import TRAIN_TASKS, NistBoardInsertEnv

SIZE = (32, 40)


@pytest.fixture(scope="module")
def demos():
    return collect_demonstrations({"image_size": SIZE, "horizon": 60, "instruction": TRAIN_TASKS}, 12, seed=0)


def test_bc_beats_untrained_policy(demos):
    env = NistBoardInsertEnv(instruction="insert medium peg in large hole", image_size=SIZE, horizon=40)
    agent = NistBC(env, demos, history=2, seed=0, learning_rate=1e-3)
    untrained = evaluate(agent, env, episodes=6, seed=0)
    agent.learn(total_timesteps=400)
    trained = evaluate(agent, env, episodes=6, seed=0)
    # trained: the peg ends much closer to the hole (laterally, from images alone) and deeper
    p0, p1 = untrained["mean_normalized_performance"], trained["mean_normalized_performance"]
    assert p1 > 0.3 and p1 - p0 > 0.4, (untrained, trained)
    assert trained["mean_lateral_error"] < 0.6 * untrained["mean_lateral_error"], (untrained, trained)


def test_api_ablations_and_save_load(demos, tmp_path):
    env = NistBoardInsertEnv(image_size=SIZE, action_mode="tokens")
    for factory, hist, cams in [(nist_bc_h6, 6, 2), (nist_bc_1cam, 2, 1)]:
        agent = factory(env, seed=1)
        assert agent.config["history"] == hist and len(agent.config["cameras"]) == cams
    with pytest.raises(ValueError, match="cameras"):
        NistBC(env, cameras=("top",))
    # continuous demos drive a tokens env through the same 0.3 mm bins
    agent = NistBC(env, demos[:2], history=6, seed=0, policy_image_size=(16, 20)).learn(total_timesteps=2)
    obs, _ = env.reset(seed=0)
    agent.reset()
    actions = []
    for _ in range(3):
        action, state = agent.predict(obs, deterministic=True)
        assert state is None and env.action_space.contains(action)
        actions.append(action)
        obs, *_ = env.step(action)
    path = tmp_path / "bc.pt"
    agent.save(path)
    loaded = NistBC.load(path, env)
    assert loaded.config["policy_image_size"] == (16, 20) and loaded.config["history"] == 6
    obs, _ = env.reset(seed=0)
    agent.reset()
    loaded.reset()
    for _ in range(3):
        a1, _ = agent.predict(obs)
        a2, _ = loaded.predict(obs)
        assert np.array_equal(a1, a2)
        obs, *_ = env.step(a1)


def test_instruction_features_are_order_sensitive():
    a = instruction_ids("insert small peg in large hole", 512)
    b = instruction_ids("insert large peg in small hole", 512)
    assert sorted(a) != sorted(b)


def test_learns_from_minari_dataset(tmp_path):
    from lfd_envs import datasets

    kwargs = {"image_size": (24, 32), "horizon": 60, "instruction_encoding": "text"}  # NistBC reads text
    path = datasets.collect("NistBoardInsert-v0", 2, tmp_path, env_kwargs=kwargs, progress=False)
    env = NistBoardInsertEnv(image_size=(24, 32))
    agent = NistBC(env, path, seed=0).learn(total_timesteps=2)
    assert np.isfinite(agent.last_loss)


def test_cosine_schedule_and_weight_average(demos, tmp_path):
    env = NistBoardInsertEnv(image_size=SIZE)
    with pytest.raises(ValueError, match="ema_decay"):
        NistBC(env, ema_decay=1.0)
    with pytest.raises(ValueError, match="lr_decay_steps"):
        NistBC(env, lr_decay_steps=0)
    agent = NistBC(env, demos[:2], seed=0, policy_image_size=(16, 20), learning_rate=1e-3,
                   lr_decay_steps=4, ema_decay=0.5)
    agent.learn(total_timesteps=3)  # the third step (index 2) is half-way through the cosine
    assert agent.optimizer.param_groups[0]["lr"] == pytest.approx(0.5e-3)
    agent.learn(total_timesteps=3, reset_num_timesteps=False)
    assert agent.optimizer.param_groups[0]["lr"] == 0.0  # past the horizon: stays at 0
    # the average lags the raw weights and is what acts
    raw = dict(agent.policy.named_parameters())
    avg = dict(agent.acting_policy.named_parameters())
    assert agent.acting_policy is not agent.policy
    assert any(not np.allclose(raw[k].detach(), avg[k].detach()) for k in raw)
    path = tmp_path / "bc.pt"
    agent.save(path)
    loaded = NistBC.load(path, env)
    for k, v in loaded.acting_policy.state_dict().items():
        assert np.array_equal(v.numpy(), agent.acting_policy.state_dict()[k].numpy()), k
