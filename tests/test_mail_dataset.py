"""lfd_bench.mail_dataset: the CEM-converted teacher solution of each eval episode, played by
the student, solves ThreeBoxes 3 -> 1 far better than random actions."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import lfd_envs  # noqa: F401
from lfd_bench.agents import resolve_agent
from lfd_bench.mail_dataset import MAILDatasetAgent
from lfd_envs.core.rollout import play_episode

KW = {"num_pickers": 1, "action_mode": "pick_place", "obs_mode": "state"}


def test_converted_teacher_solution_beats_random_on_eval_episodes(tmp_path):
    env = gym.make("ThreeBoxes-v0", **KW)
    agent = resolve_agent("mail_dataset")(env, 0, teacher_pickers=3, population=12,
                                                                   simulator_worlds=12, workdir=tmp_path)
    assert isinstance(agent, MAILDatasetAgent) and agent.needs_training is False
    agent.learn(10)  # nothing to train
    agent.bind(env)
    options = [{"split": "eval", "variant": k} for k in range(2)]
    p_data = [play_episode(env, agent, seed=k, options=o)["normalized_performance"] for k, o in enumerate(options)]
    rand = resolve_agent("random")(env, 0)
    p_rand = [play_episode(env, rand, seed=k, options=o)["normalized_performance"] for k, o in enumerate(options)]
    # the 3-picker teacher solved the same starts; one CEM plan was made per episode
    assert agent.episodes == 2 and min(agent.teacher_finals) > 0.9
    assert np.mean(p_data) > np.mean(p_rand) + 0.3, (p_data, p_rand)


def test_bad_input():
    env = gym.make("ThreeBoxes-v0", **KW)
    with pytest.raises(ValueError, match="teacher_pickers"):
        MAILDatasetAgent(env, teacher_pickers=0)
    with pytest.raises(ValueError, match="pick_place"):
        MAILDatasetAgent(gym.make("ThreeBoxes-v0", num_pickers=1, action_mode="delta", obs_mode="state"))
    agent = MAILDatasetAgent(env, teacher_pickers=3)
    obs, _ = env.reset(seed=0)
    with pytest.raises(RuntimeError, match="bind"):
        agent.predict(obs)
