"""Checkpoint selection on held-out training variants (lfd_agents.selection)."""

import gymnasium as gym
import numpy as np
import pytest

import lfd_envs  # noqa: F401
from lfd_agents.selection import BestCheckpoint
from lfd_envs.experts import make_expert
from lfd_envs.tasks.three_boxes import ThreeBoxesEnv

KW = {"num_pickers": 1, "action_mode": "pick_place", "obs_mode": "state"}


class _Fixed:
    """A stand-in SB3 policy: ``act(obs)`` decides; records training-mode switches."""

    def __init__(self, act):
        self.act = act
        self.training = True

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return self.act(obs), None

    def set_training_mode(self, mode):
        self.training = mode


def test_keeps_the_best_policy_and_counts_its_steps():
    env = gym.make("ThreeBoxes-v0", **KW)
    best = BestCheckpoint(env, episodes=3, first_variant=500)
    expert = make_expert(best.env)
    idle = np.zeros(env.action_space.shape, np.float32)
    good = _Fixed(lambda obs: expert.predict(obs)[0])
    bad = _Fixed(lambda obs: idle)
    scores = [best.update(p) for p in (bad, good, bad)]
    assert scores[1] > scores[0] + 0.5 and scores[2] == pytest.approx(scores[0])
    assert best.best_score == scores[1] and best.best_policy.training is False
    assert best.env_steps == 3 * 3 * env.unwrapped.horizon  # 3 scores x 3 episodes x the horizon
    # the kept copy acts like the expert, not like the last (bad) policy
    obs, _ = best.env.reset(seed=0, options={"split": "train", "variant": 500})
    expert.reset()
    assert not np.allclose(best.predict(obs)[0], idle)
    best.close()


def test_bad_input():
    env = gym.make("ThreeBoxes-v0", **KW)
    with pytest.raises(ValueError, match="episodes"):
        BestCheckpoint(env, episodes=0)
    with pytest.raises(ValueError, match="outside the 800 training variants"):
        BestCheckpoint(env, episodes=10, first_variant=795)
    with pytest.raises(RuntimeError, match="update"):
        BestCheckpoint(env, episodes=1).predict(env.reset(seed=0)[0])
    with pytest.raises(ValueError, match="gym.make"):
        BestCheckpoint(ThreeBoxesEnv(**KW), episodes=1)
