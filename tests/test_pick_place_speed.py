"""Pick-and-place with a speed limit on held pickers (``pick_place_speed``): per-world step lengths."""

import gymnasium as gym
import numpy as np
import pytest

import lfd_envs  # noqa: F401
from lfd_envs.tasks.picker_actions import PickPlaceActions, PickPlaceSchedule, Workspace

WS = Workspace((-0.6, -0.6, 0.0), (0.6, 0.6, 0.7), margin=0.02)


def _plan(schedule: PickPlaceSchedule):
    mode = PickPlaceActions(1, WS, schedule)
    start = np.array([[[0.0, 0.0, 0.3]], [[0.0, 0.0, 0.3]]])
    pick = np.array([[[-0.5, -0.5, 0.02]], [[0.1, 0.1, 0.02]]])  # a long and a short carry
    place = np.array([[[0.5, 0.5, 0.02]], [[0.15, 0.1, 0.02]]])
    return mode, mode.plan_motion(mode.join(pick, place).reshape(2, -1), start)


def test_held_pickers_never_exceed_the_limit_and_each_world_gets_its_own_length():
    limit = 0.01
    mode, motion = _plan(PickPlaceSchedule(arc_ratio=0.45, arc_max=0.5, carry_frames=48, max_speed=limit))
    _, fixed = _plan(PickPlaceSchedule(arc_ratio=0.45, arc_max=0.5, carry_frames=48))
    assert motion.targets.shape[0] == motion.frames.max() <= mode.frames_per_step
    assert motion.frames[0] > fixed.targets.shape[0] == motion.frames[1]  # long carry: longer; short: as before
    assert (fixed.frames == fixed.targets.shape[0]).all()
    for w in range(2):
        n = motion.frames[w]
        path = np.concatenate([[[0.0, 0.0, 0.3]], motion.targets[:n, w, 0]])
        held = motion.grasp[:n, w, 0]
        step = np.linalg.norm(np.diff(path, axis=0), axis=-1)
        assert step[held].max() <= limit + 1e-9
    # the default schedule carries the long fold far faster than 1 m/s
    fixed_path = np.concatenate([[[0.0, 0.0, 0.3]], fixed.targets[:, 0, 0]])
    assert np.linalg.norm(np.diff(fixed_path, axis=0), axis=-1)[fixed.grasp[:, 0, 0]].max() > 3 * limit


def test_bad_speed_is_a_clear_error():
    with pytest.raises(ValueError, match="max_speed"):
        PickPlaceSchedule(max_speed=0.0)
    for bad in (0.0, -1.0, float("nan"), "fast"):
        with pytest.raises(ValueError, match="pick_place_speed"):
            gym.make("lfd_envs:ClothFold-v0", action_mode="pick_place", resolution=10, pick_place_speed=bad)


def test_vector_env_with_per_world_lengths_equals_single_envs():
    kw = dict(action_mode="pick_place", num_pickers=1, resolution=12, obs_mode="particles", pick_place_speed=1.0)
    n = 3
    venv = gym.make_vec("ClothFold-v0", num_envs=n, vectorization_mode="vector_entry_point", **kw)
    singles = [gym.make("ClothFold-v0", **kw) for _ in range(n)]
    venv.reset(seed=3)
    for i, env in enumerate(singles):
        env.reset(seed=3 + i)
    rng = np.random.default_rng(1)
    lengths = set()
    for _ in range(2):
        actions = rng.uniform(-1, 1, (n,) + venv.single_action_space.shape).astype(np.float32)
        motion = venv.unwrapped.batch.action_mode.plan_motion(actions, venv.unwrapped.batch.pickers)
        lengths.update(motion.frames.tolist())
        vobs, vrew, *_ = venv.step(actions)
        for i, env in enumerate(singles):
            obs, rew, *_ = env.step(actions[i])
            assert np.array_equal(vobs[i], obs) and rew == vrew[i]
    assert len(lengths) > 1  # the worlds really ran different numbers of frames


def test_random_pick_and_place_at_one_metre_per_second_throws_nothing():
    """Uniform-random pick-and-place on ClothFold: the default schedule carries at several m/s and
    leaves particles flying; at 1 m/s nothing moves fast when a step ends and the cloth stays closer."""
    out = {}
    for speed in (None, 1.0):
        env = gym.make("lfd_envs:ClothFold-v0", action_mode="pick_place", num_pickers=1, resolution=20,
                       obs_mode="state", pick_place_speed=speed)
        rng = np.random.default_rng(0)
        fastest, farthest = 0.0, 0.0
        for v in range(4):
            env.reset(seed=v, options={"variant": 17 + v, "split": "train"})
            for _ in range(3):
                env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
                sim = env.unwrapped.batch.sim
                fastest = max(fastest, float(np.linalg.norm(sim.velocities[0], axis=-1).max()))
                farthest = max(farthest, float(np.abs(env.unwrapped.particle_positions[:, :2]).max()))
        out[speed] = fastest, farthest
    assert out[None][0] > 3.0 and out[1.0][0] < 2.0
    assert out[1.0][1] < out[None][1] - 0.2


def test_bad_world_frames_raise_and_change_nothing():
    env = gym.make("lfd_envs:ClothFold-v0", action_mode="pick_place", num_pickers=1, resolution=10)
    env.reset(seed=0)
    sim = env.unwrapped.batch.sim
    before = sim.get_state()
    targets = np.repeat(sim.picker_positions[None], 4, axis=0)
    for bad in ([5], [-1], [1, 2], [1.5]):
        with pytest.raises(ValueError, match="world_frames"):
            sim.step_frames(targets, None, np.array(bad))
    after = sim.get_state()
    assert all(np.array_equal(before[k], after[k]) for k in before)
    sim.step_frames(targets, None, np.array([2]))  # a world stopped after 2 of 4 frames ...
    two = sim.get_state()
    sim.set_state(before)
    sim.step_frames(targets[:2])  # ... is where 2 frames take it
    assert all(np.array_equal(two[k], sim.get_state()[k]) for k in two)


def test_free_speed_limit_slows_empty_pickers_for_colliding_pickers():
    limit = 0.01
    _, motion = _plan(PickPlaceSchedule(max_speed=limit, max_free_speed=limit))
    for w in range(2):
        n = motion.frames[w]
        path = np.concatenate([[[0.0, 0.0, 0.3]], motion.targets[:n, w, 0]])
        assert np.linalg.norm(np.diff(path, axis=0), axis=-1).max() <= limit + 1e-9
    env = gym.make("lfd_envs:ClothFold-v0", action_mode="pick_place", resolution=10, pick_place_speed=1.0,
                   sim_options={"picker_collision": True})
    schedule = env.unwrapped.picker_actions.schedule
    assert schedule.max_free_speed == schedule.max_speed == pytest.approx(0.01)
    plain = gym.make("lfd_envs:ClothFold-v0", action_mode="pick_place", resolution=10, pick_place_speed=1.0)
    assert plain.unwrapped.picker_actions.schedule.max_free_speed is None
