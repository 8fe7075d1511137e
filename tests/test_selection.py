"""Checkpoint selection on held-out training variants (lfd_agents.selection)."""

import gymnasium as gym
import numpy as np
import pytest

import lfd_envs  # noqa: F401
from lfd_agents.selection import BestCheckpoint, SelectBest
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


class _Swinging:
    """A stand-in learner whose policy after each ``learn`` is the next of ``policies``."""

    def __init__(self, policies):
        self.policies, self.calls, self.policy = list(policies), [], None

    def learn(self, total_timesteps, reset_num_timesteps=True):
        self.calls.append((total_timesteps, reset_num_timesteps))
        self.policy = self.policies[len(self.calls) - 1]
        return self

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        return self.policy.predict(obs, state, episode_start, deterministic)


def _good_and_bad(env):
    """The expert as a good policy and an idle one as a bad policy on ``env``."""
    expert = make_expert(env)
    idle = np.zeros(env.action_space.shape, np.float32)
    return expert, idle, _Fixed(lambda obs: expert.predict(obs)[0]), _Fixed(lambda obs: idle)


def test_select_best_acts_with_the_best_checkpoint_while_the_learner_moves_on():
    env = gym.make("ThreeBoxes-v0", **KW)
    expert, idle, good, bad = _good_and_bad(env)
    agent = SelectBest(_Swinging([bad, good, bad]), env, episodes=2, first_variant=600)
    obs, _ = env.reset(seed=0, options={"split": "train", "variant": 600})
    for i in range(3):
        agent.learn(10, reset_num_timesteps=i == 0)
    assert agent.model.calls == [(10, True), (10, False), (10, False)]
    assert agent.policy is bad  # the learner's current policy ...
    assert agent.selector.best_policy.act is good.act  # ... is not the one that acts
    expert.reset()
    assert not np.allclose(agent.predict(obs)[0], idle)
    assert agent.validation_env_steps == 3 * 2 * env.unwrapped.horizon
    agent.close()


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


class _Offline(_Swinging):
    """A stand-in learner with an offline phase: ``pretrain()`` sets its first policy."""

    def __init__(self, offline_policy, policies):
        super().__init__(policies)
        self.offline_policy, self.offline_pending = offline_policy, True

    def pretrain(self):
        self.policy, self.offline_pending = self.offline_policy, False


def test_the_policy_the_offline_phase_ends_with_is_the_first_candidate():
    env = gym.make("ThreeBoxes-v0", **KW)
    _, _, good, bad = _good_and_bad(env)
    agent = SelectBest(_Offline(good, [bad, bad]), env, episodes=2, first_variant=600)
    agent.learn(10)
    agent.learn(10, reset_num_timesteps=False)
    assert len(agent.selector.scores) == 3  # the offline policy, then one per learn
    assert agent.selector.best_policy.act is good.act  # online made it worse: the offline one acts
    agent.close()
