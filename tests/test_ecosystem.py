"""Standard tools work on every id without tricks: spec horizons, SB3 check_env, GoalEnv + HER."""

import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium_robotics.core import GoalEnv
from stable_baselines3.common.env_checker import check_env

import lfd_envs
from lfd_agents.threads import torch_threads
from lfd_envs.mujoco.nist import instruction_from_tokens

GOAL_IDS = ("Push2DObstacle-v0", "SawyerPushObstacle-v0", "SawyerLiftObstacle-v0", "SawyerAssemblyObstacle-v0")
README = (Path(__file__).resolve().parent.parent / "README.md").read_text()


def time_limit(env):
    while not isinstance(env, gym.wrappers.TimeLimit):
        env = env.env
    return env._max_episode_steps


def default_horizons(base):
    """Every default horizon of the env's task (particle tasks: one per action mode)."""
    task = getattr(base, "task", None)
    return [task.horizon(m) for m in ("delta", "pick_place")] if hasattr(task, "horizons") else [base.horizon]


@pytest.mark.parametrize("env_id", sorted(lfd_envs.ENV_SPECS))
def test_default_config_passes_check_env_and_has_max_episode_steps(env_id):
    env = gym.make(env_id)
    limit = gym.spec(env_id).max_episode_steps
    assert limit == env.spec.max_episode_steps == time_limit(env)
    if env_id in lfd_envs.MUJOCO_ENV_IDS:
        assert limit == env.unwrapped.horizon
    else:  # the TimeLimit never cuts a default-horizon episode in any action mode
        assert limit == max(default_horizons(env.unwrapped)) >= env.unwrapped.horizon
    assert hasattr(env.unwrapped, "compute_reward") == isinstance(env.unwrapped, GoalEnv) == False  # noqa: E712
    check_env(env, skip_render_check=True)
    env.close()


def test_time_limit_follows_the_configured_horizon():
    env = gym.make("DryCloth-v0", action_mode="delta", resolution=20, obs_mode="state")
    assert env.unwrapped.horizon == 75 and time_limit(env) == 75
    env = gym.make("ThreeBoxes-v0", action_mode="delta", obs_mode="state")
    assert env.unwrapped.horizon == 75 and time_limit(env) == 75
    env = gym.make("Push2DObstacle-v0", horizon=450)
    assert time_limit(env) == 450 and env.spec.max_episode_steps == 450
    env = gym.make("Push2DObstacle-v0", horizon=9, max_episode_steps=5)  # an explicit limit is kept
    assert time_limit(env) == 5
    env = gym.make("Push2DObstacle-v0", horizon=7)
    env.reset(seed=0)
    flags = [env.step(np.zeros(4))[3] for _ in range(7)]
    assert flags == [False] * 6 + [True]


@pytest.mark.parametrize("env_id", GOAL_IDS)
def test_goal_envs_are_goal_env_instances_through_wrappers(env_id):
    env = gym.make(env_id, goal_conditioned=True)
    assert isinstance(env.unwrapped, GoalEnv)
    obs, info = env.reset(seed=0)
    obs, reward, *_, info = env.step(env.action_space.sample())
    assert env.compute_reward(obs["achieved_goal"], obs["desired_goal"], info) == pytest.approx(reward, abs=1e-5)
    if env_id == "Push2DObstacle-v0":
        check_env(env, skip_render_check=True)  # on the wrapped env, not only env.unwrapped


def test_nist_instruction_tokens_by_default_and_text_on_request():
    env = gym.make("NistBoardInsert-v0", obs_mode="state+image", image_size=16)
    obs, _ = env.reset(seed=0)
    assert "instruction" not in obs and env.observation_space.contains(obs)
    assert instruction_from_tokens(obs["instruction_tokens"]) == env.unwrapped.instruction
    text = gym.make("NistBoardInsert-v0", obs_mode="state+image", image_size=16, instruction_encoding="text")
    obs, _ = text.reset(seed=0)
    assert obs["instruction"] == text.unwrapped.instruction and "instruction_tokens" not in obs
    with pytest.raises(ValueError, match="instruction_encoding"):
        gym.make("NistBoardInsert-v0", instruction_encoding="words")


def test_readme_her_example_runs():
    code = next(c for c in re.findall(r"```python\n(.*?)```", README, re.S)
                if c.startswith("from stable_baselines3 import SAC, HerReplayBuffer"))
    scope: dict = {}
    with torch_threads(1):  # a shared 2-core machine: more threads only contend
        exec(compile(code, "README-her", "exec"), scope)
    assert scope["model"].num_timesteps == 300 and scope["model"].replay_buffer.size() > 0


def test_vector_entry_point_still_works_with_max_episode_steps():
    venv = gym.make_vec("DryCloth-v0", num_envs=2, vectorization_mode="vector_entry_point", resolution=20,
                        obs_mode="state")
    assert venv.unwrapped.horizon == 3  # make_vec's max_episode_steps (75) is an upper bound only
    venv = gym.make_vec("ClothFold-v0", num_envs=2, vectorization_mode="vector_entry_point", resolution=8,
                        obs_mode="state", max_episode_steps=5)
    assert venv.unwrapped.horizon == 5
    venv.reset(seed=0)
    flags = [venv.step(np.zeros(venv.action_space.shape))[3] for _ in range(5)]
    assert not any(f.any() for f in flags[:4]) and flags[4].all()
