"""Push2DObstacle-v0: contract, physics of the scene, planning interface, expert, goal-conditioned HER."""

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from lfd_envs.experts import make_expert
from lfd_envs.mujoco.planning import interpolate, plan_path
from lfd_envs.mujoco.push2d import Push2DObstacleEnv

pytestmark = pytest.mark.filterwarnings("ignore:.*(infinity|Box observation space).*")


def rollout(env, policy, seed, split="eval"):
    obs, info = env.reset(seed=seed, options={"split": split})
    total = 0.0
    for _ in range(env.unwrapped.horizon):
        obs, r, term, trunc, info = env.step(policy(obs))
        total += r
        if term or trunc:
            break
    return total, info


def test_make_and_check_env():
    env = gym.make("lfd_envs:Push2DObstacle-v0")
    assert env.unwrapped.horizon == 400 and env.observation_space.shape == (20,)
    check_env(env.unwrapped, skip_render_check=True)
    check_env(Push2DObstacleEnv(goal_conditioned=True), skip_render_check=True)
    img = Push2DObstacleEnv(obs_mode="state+image")
    obs, _ = img.reset(seed=0)
    assert obs["image"].shape == (84, 84, 3) and obs["image"].dtype == np.uint8 and obs["state"].shape == (20,)
    img.close()


def test_variants_and_observation_layout():
    env = Push2DObstacleEnv()
    for seed in range(5):
        obs, info = env.reset(seed=seed, options={"split": "train" if seed % 2 else "eval"})
        box, goal = env.box_xy(), env.goal
        assert -0.35 <= box[0] <= -0.24 and 0.13 <= box[1] <= 0.2 and goal[0] <= box[0]
        assert np.linalg.norm(box - goal) > 0.1 and not info["is_success"]
        q = env.arm_qpos()
        assert np.abs(q).max() <= 0.02 + 1e-12
        assert np.allclose(obs[:4], np.cos(q), atol=1e-6) and np.allclose(obs[4:8], np.sin(q), atol=1e-6)
        assert np.allclose(obs[8:10], box) and np.allclose(obs[16:18], env.fingertip_xy())
        assert np.allclose(obs[18:20], goal)
        assert env.data.ncon == 0


def test_reward_follows_thesis_b1():
    env = Push2DObstacleEnv()
    env.reset(seed=0)
    assert env._task_reward() == 0.0  # far from the box, box far from the goal
    state = env.get_state()
    state["sim/qpos"][4:6] = env.goal + [0.08, 0.0]
    env.set_state(state)
    assert np.isclose(env._task_reward(), 0.3 * (1 - np.tanh(5 * 0.08)))
    state["sim/qpos"][4:6] = env.goal + [0.03, 0.0]
    env.set_state(state)
    assert env._is_success() and env._task_reward() > 150
    _, r, term, trunc, info = env.step(np.zeros(4))
    assert term and not trunc and info["is_success"] and info["normalized_performance"] == 1.0


def test_is_valid_agrees_with_simulator_and_leaves_data_untouched():
    env = Push2DObstacleEnv()
    env.reset(seed=0)
    env.step(np.array([0.5, -0.5, 0.2, 0.1]))
    before = {k: getattr(env.data, k).copy() for k in ("qpos", "qvel", "act", "ctrl", "qacc_warmstart")}
    t = env.data.time
    assert env.is_valid(env.arm_qpos())
    inside = np.array([1.0, 0.0, 0.0, 0.0])  # arm through obstacle1
    assert not env.is_valid(inside)
    assert {"obstacle1"} <= {name for pair in env.colliding_pairs(inside) for name in pair[:2]}
    rng = np.random.default_rng(0)
    probe = mujoco.MjData(env.model)
    for _ in range(200):
        q = rng.uniform(env.joint_limits[:, 0], env.joint_limits[:, 1])
        probe.qpos[:] = env.data.qpos
        probe.qpos[:4] = q
        mujoco.mj_forward(env.model, probe)
        assert env.is_valid(q) == all(c.dist > -0.002 for c in probe.contact)
    for k, v in before.items():
        assert np.array_equal(getattr(env.data, k), v), k
    assert env.data.time == t
    # the simulator agrees: driving the arm into obstacle1 is blocked
    env.reset(seed=0)
    for _ in range(15):
        env.step(np.array([1.0, 0.0, 0.0, 0.0]))
    assert env.arm_qpos()[0] < 0.6 and env.is_valid(env.arm_qpos())


def test_execute_joint_path_reaches_end_configuration():
    env = Push2DObstacleEnv()
    env.reset(seed=1)
    goal = np.array([-1.2, 0.8, -0.6, 0.4])
    path = plan_path(env, goal)
    assert path is not None
    res = env.execute_path(path)
    assert res.steps == len(path) - 1 and not res.terminated
    assert np.abs(env.arm_qpos() - goal).max() < 0.01
    with pytest.raises(ValueError, match="dq_step"):
        env.execute_path([env.arm_qpos(), env.arm_qpos() + 0.3])
    env.step(np.zeros(4))  # still usable


def test_determinism_per_seed_and_state_round_trip():
    actions = np.random.default_rng(0).uniform(-1, 1, (30, 4))
    runs = []
    for _ in range(2):
        env = Push2DObstacleEnv()
        env.reset(seed=11)
        runs.append(np.stack([env.step(a)[0] for a in actions]))
    assert np.array_equal(runs[0], runs[1])
    env = Push2DObstacleEnv()
    env.reset(seed=11)
    for a in actions[:10]:
        env.step(a)
    state = env.get_state()
    tail = np.stack([env.step(a)[0] for a in actions[10:]])
    env.reset(seed=99)
    env.set_state(state)
    assert np.array_equal(np.stack([env.step(a)[0] for a in actions[10:]]), tail)
    assert np.array_equal(tail, runs[0][10:])


def test_bad_actions_raise_and_env_keeps_working():
    env = Push2DObstacleEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(4,\)"):
        env.step(np.zeros(3))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([np.nan, 0, 0, 0]))
    with pytest.raises(TypeError, match="valid arguments"):
        Push2DObstacleEnv(horizn=3)
    with pytest.raises(ValueError, match="goal_conditioned"):
        Push2DObstacleEnv(obs_mode="image", goal_conditioned=True)
    obs, r, *_ = env.step(np.full(4, 5.0))  # clipped
    assert np.all(np.isfinite(obs))


def test_expert_beats_random_by_a_wide_margin():
    env = Push2DObstacleEnv()
    expert = make_expert(env)
    rng = np.random.default_rng(0)
    exp_success, rand_success, exp_return, rand_return = 0, 0, 0.0, 0.0
    for seed in (0, 1, 2):
        expert.reset()
        ret, info = rollout(env, lambda o: expert.predict(o)[0], seed)
        exp_success += info["is_success"]
        exp_return += ret
        ret, info = rollout(env, lambda o: rng.uniform(-1, 1, 4), seed)
        rand_success += info["is_success"]
        rand_return += ret
    assert exp_success >= 2 and rand_success == 0
    assert exp_return > rand_return + 250


def test_goal_conditioned_reward_matches_and_her_trains():
    from stable_baselines3 import SAC, HerReplayBuffer

    env = Push2DObstacleEnv(goal_conditioned=True, horizon=20)
    obs, info = env.reset(seed=0)
    assert set(obs) == {"observation", "achieved_goal", "desired_goal"}
    for a in np.random.default_rng(0).uniform(-1, 1, (5, 4)):
        obs, r, term, trunc, info = env.step(a)
        assert np.isclose(env.compute_reward(obs["achieved_goal"], obs["desired_goal"], info), r)
    batch_ag = np.stack([obs["achieved_goal"], obs["desired_goal"]])
    batch_dg = np.stack([obs["desired_goal"], obs["desired_goal"]])
    rewards = env.compute_reward(batch_ag, batch_dg, np.array([{}, {}]))  # SB3 passes empty infos
    assert rewards.shape == (2,) and rewards[1] > 150
    model = SAC("MultiInputPolicy", env, replay_buffer_class=HerReplayBuffer,
                replay_buffer_kwargs={"n_sampled_goal": 2, "goal_selection_strategy": "future"},
                learning_starts=40, batch_size=32, policy_kwargs={"net_arch": [32, 32]}, seed=0, device="cpu")
    model.learn(60)
    assert model.replay_buffer.size() > 0
