"""ThreeBoxes-v0: rigid-box physics (no interpenetration, carrying, stacking), performance,
env contract, experts for 3/2/1 pickers and random-action data."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import lfd_envs  # noqa: F401
from lfd_envs.core.rollout import episode_steps
from lfd_envs.experts import make_expert
from lfd_envs.tasks.three_boxes import BOX_HALF_EXTENTS, matrix_to_quaternion

PARTICLE_RADIUS = 0.005


def _overlap_violations(env) -> int:
    """Particles of one box deeper than 2 mm inside another box, or below the table."""
    base = env.unwrapped
    task, pos = base.task, base.particle_positions.astype(np.float64)
    centers, rots = task.poses(pos[None], base.batch.ctx)
    bad = int((pos[:, 2] < PARTICLE_RADIUS - 1e-3).sum())
    for i, si in enumerate(task.box_slices):
        for j in range(3):
            if i != j:
                local = (pos[si] - centers[0, j]) @ rots[0, j]
                bad += int(np.all(np.abs(local) < BOX_HALF_EXTENTS[j] - 0.002, axis=1).sum())
    return bad


def _run(env, policy, variant: int, check=None) -> float:
    obs, _ = env.reset(seed=0, options={"variant": variant, "split": "eval"})
    policy.reset()
    for step in episode_steps(env, policy, obs):
        if check is not None:
            check(env)
    return float(step.info["normalized_performance"])


def _no_overlap(env) -> None:
    assert _overlap_violations(env) == 0


def test_experts_solve_every_picker_count_and_boxes_never_interpenetrate():
    from lfd_envs.experts.random_pick_place import RandomPickPlacePolicy

    for pickers in (3, 2, 1):
        for mode in ("pick_place", "delta"):
            env = gym.make("ThreeBoxes-v0", num_pickers=pickers, action_mode=mode)
            expert = make_expert(env)
            score = _run(env, expert, 0, check=_no_overlap)
            assert score > 0.95, (pickers, mode, score)
            if mode == "pick_place":
                assert expert.moves_done == {3: 1, 2: 2, 1: 3}[pickers]
                rand = [_run(env, RandomPickPlacePolicy(env, seed=s), 1, check=_no_overlap) for s in (0, 1)]
                assert score > np.mean(rand) + 0.5, (pickers, rand)


def test_box_can_be_carried_and_stacked():
    env = gym.make("ThreeBoxes-v0", num_pickers=1)
    base = env.unwrapped
    task = base.task
    env.reset(seed=0, options={"variant": 3, "split": "eval"})
    centers = task.box_centers(base.particle_positions[None])[0]
    # put the narrow box 3 on top of box 1
    target = centers[0] + np.array([0.0, 0.0, BOX_HALF_EXTENTS[0, 2] + BOX_HALF_EXTENTS[2, 2] + 0.003])
    action = base.batch.action_mode.join(task.grasp_point(centers[2], 2)[None], task.grasp_point(target, 2)[None])
    env.step(action)
    after = task.box_centers(base.particle_positions[None])[0]
    np.testing.assert_allclose(after[2], target - [0, 0, 0.003], atol=0.01)  # resting on box 1
    np.testing.assert_allclose(after[0], centers[0], atol=0.005)  # box 1 did not move
    assert _overlap_violations(env) == 0
    for _ in range(2):  # the stack stays (boxes neither sink into each other nor into the table)
        env.step(base.batch.action_mode.join(np.array([[0.5, 0.2, 0.9]]), np.array([[0.5, 0.2, 0.9]])))
    final = task.box_centers(base.particle_positions[None])[0]
    np.testing.assert_allclose(final, after, atol=0.005)
    assert _overlap_violations(env) == 0


def test_performance_is_zero_at_goals():
    env = gym.make("ThreeBoxes-v0")
    base = env.unwrapped
    task = base.task
    env.reset(seed=0, options={"variant": 0, "split": "train"})
    pos = base.particle_positions.astype(np.float64).copy()
    goals = base.batch.ctx["goals"][0]
    local = base.batch.ctx["box_local"][0]
    for b, sl in enumerate(task.box_slices):
        pos[sl] = goals[b] + local[sl]
    ev = task.evaluate(pos[None], base.batch.ctx)
    assert abs(ev["performance"][0]) < 1e-6
    shifted = pos.copy()
    shifted[task.box_slices[1]] += [0.1, 0.0, 0.0]
    assert task.evaluate(shifted[None], base.batch.ctx)["performance"][0] == pytest.approx(-0.1)
    assert task.success(np.array([0.0]), np.array([1.0]))[0]


def test_contract_state_and_round_trip():
    from gymnasium.utils.env_checker import check_env

    env = gym.make("ThreeBoxes-v0")
    base = env.unwrapped
    assert base.action_mode == "pick_place" and base.horizon == 3 and base.num_pickers == 1
    check_env(base, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (33,)
    quats = obs[:21].reshape(3, 7)[:, 3:]
    np.testing.assert_allclose(quats, np.tile([0, 0, 0, 1.0], (3, 1)), atol=1e-3)
    np.testing.assert_allclose(matrix_to_quaternion(np.eye(3)), [0, 0, 0, 1])
    delta = gym.make("ThreeBoxes-v0", action_mode="delta", num_pickers=4, obs_mode="particles", resolution=3)
    assert delta.unwrapped.horizon == 75 and delta.action_space.shape == (16,)
    n = delta.unwrapped.num_particles
    assert delta.reset(seed=0)[0].shape == (n + 4, 3)
    img = gym.make("ThreeBoxes-v0", obs_mode="state+image", image_size=20).reset(seed=0)[0]
    assert img["image"].shape == (20, 20, 3) and img["image"].std() > 5
    state = base.get_state()
    a = env.action_space.sample()
    o1 = env.step(a)[0]
    base.set_state(state)
    np.testing.assert_array_equal(o1, env.step(a)[0])


def test_vector_env_equals_single_envs():
    vec = gym.make_vec("ThreeBoxes-v0", num_envs=2, vectorization_mode="vector_entry_point", num_pickers=2)
    obs, _ = vec.reset(seed=7)
    actions = np.random.default_rng(1).uniform(-1, 1, (2,) + vec.single_action_space.shape).astype(np.float32)
    vobs, vrew, *_ = vec.step(actions)
    for i in range(2):
        env = gym.make("ThreeBoxes-v0", num_pickers=2)
        o, _ = env.reset(seed=7 + i)
        np.testing.assert_array_equal(o, obs[i])
        o, r, *_ = env.step(actions[i])
        np.testing.assert_array_equal(o, vobs[i])
        assert r == pytest.approx(vrew[i])


def test_random_pick_place_dataset_is_reproducible(tmp_path):
    from lfd_envs import datasets

    kwargs = {"obs_mode": "particles"}
    a = datasets.load(datasets.collect("ThreeBoxes-v0", 2, tmp_path / "a", policy="random_pick_place",
                                       progress=False, env_kwargs=kwargs))
    b = datasets.load(datasets.collect("ThreeBoxes-v0", 2, tmp_path / "b", policy="random_pick_place",
                                       progress=False, env_kwargs=kwargs))
    eps_a, eps_b = list(a.iterate_episodes()), list(b.iterate_episodes())
    assert a.total_steps == 6
    for ea, eb in zip(eps_a, eps_b):
        np.testing.assert_array_equal(ea.actions, eb.actions)
    assert not np.allclose(eps_a[0].actions, eps_a[1].actions)
    # every step moved one box somewhere on the line
    obs = eps_a[0].observations
    assert np.abs(obs[1:] - obs[:-1]).max() > 0.01
