"""Experts notice a new episode by themselves: a loop that never calls ``expert.reset()`` works."""

import gymnasium as gym

import lfd_envs  # noqa: F401
from lfd_envs.core.rollout import finish_episode
from lfd_envs.experts import make_expert


def run_without_expert_reset(env, expert, variants):
    infos = []
    for k in variants:
        obs, _ = env.reset(seed=k, options={"split": "eval", "variant": k})
        infos.append(finish_episode(env, expert, obs))  # no expert.reset()
    return infos


def test_sawyer_expert_needs_no_reset():
    env = gym.make("SawyerLiftObstacle-v0")
    infos = run_without_expert_reset(env, make_expert(env), [0, 1, 2])
    assert all(info["is_success"] for info in infos)


def test_particle_expert_needs_no_reset_and_matches_reset_loop():
    env = gym.make("DryCloth-v0", resolution=20, obs_mode="state")  # its plan spans the episode
    expert = make_expert(env)
    auto = [i["normalized_performance"] for i in run_without_expert_reset(env, expert, [0, 1, 2])]
    manual = []
    for k in [0, 1, 2]:
        obs, _ = env.reset(seed=k, options={"split": "eval", "variant": k})
        expert.reset()  # still allowed, and changes nothing
        manual.append(finish_episode(env, expert, obs)["normalized_performance"])
    assert auto == manual and min(auto[1:]) > 0.2  # a stale plan scored 0.0 on these


def test_set_state_counts_as_a_new_episode():
    env = gym.make("ThreeBoxes-v0", action_mode="pick_place", obs_mode="state")
    env.reset(seed=0)
    base = env.unwrapped
    count = base.episode_count
    base.set_state(base.get_state())
    assert base.episode_count == count + 1
    env.reset(seed=1)
    assert base.episode_count == count + 2
