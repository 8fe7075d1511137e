"""Particle tasks (rope, cloth fold, diagonal fold): env contract, spaces, scoring, states.

Small resolutions keep these fast; the physics itself is tested in the engine's tests.
"""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import lfd_envs  # noqa: F401
from lfd_envs.tasks.cloth_fold import fold_distances, group_b
from lfd_envs.tasks.cloth_fold_diagonal import diagonal_edge_distance
from lfd_envs.tasks.picker_actions import DeltaActions, PickPlaceActions, PickPlaceSchedule, Workspace
from lfd_envs.tasks.rope import rope_keypoint_indices
from picker_moves import steer_picker

RES = {"StraightenRope-v0": 15, "ClothFold-v0": 12, "ClothFoldDiagonal-v0": 12,
       "ClothFoldDiagonalPinned-v0": 12, "ClothFoldDiagonalUnpinned-v0": 12}
IDS = list(RES)


def make(env_id, **kw):
    kw.setdefault("resolution", RES[env_id])
    return gym.make(env_id, **kw)


# ----------------------------------------------------------------------------- scoring (pure numpy)
def _flat_grid(n, size=0.5):
    s = np.linspace(-size / 2, size / 2, n)
    y, x = np.meshgrid(s, s, indexing="ij")
    return np.stack([x, y, np.zeros_like(x)], -1)[None]


def test_fold_metric_zero_for_perfect_fold_and_positive_when_flat():
    grid = _flat_grid(10)
    b0 = group_b(grid)
    group, fix = fold_distances(grid, b0)
    assert group[0] > 0.2 and fix[0] == 0.0
    folded = grid.copy()
    folded[:, :, :5] = grid[:, :, ::-1][:, :, :5]  # left half exactly on its mirror partners
    group, fix = fold_distances(folded, b0)
    assert group[0] == pytest.approx(0.0) and fix[0] == pytest.approx(0.0)


def test_diagonal_metric_zero_for_diagonal_fold():
    grid = _flat_grid(8)[0]
    n = 8
    folded = grid.copy()
    for r in range(n):
        for c in range(n):
            if r + c < n - 1:  # bottom-left half lands on its mirror (n-1-c, n-1-r)
                folded[r, c] = grid[n - 1 - c, n - 1 - r]
    assert diagonal_edge_distance(grid[None])[0] > 1.0
    assert diagonal_edge_distance(folded[None])[0] == pytest.approx(0.0, abs=1e-12)


def test_rope_keypoints_and_absolute_normalisation():
    assert rope_keypoint_indices(41).tolist() == [0, 4, 8, 12, 16, 20, 24, 28, 32, 40]
    env = make("StraightenRope-v0")
    task = env.unwrapped.task
    straight = np.zeros((1, 15, 3))
    straight[0, :, 0] = np.linspace(0, 0.5, 15)
    p = task.performance(straight, {"length": np.array([0.5])})
    assert task.normalized_performance(p, np.array([-0.3]))[0] == pytest.approx(1.0)
    env.close()


# ----------------------------------------------------------------------------- action modes
def test_delta_plan_clips_to_workspace():
    ws = Workspace((-0.1, -0.1, 0.0), (0.1, 0.1, 0.2), margin=0.02)
    mode = DeltaActions(2, ws)
    start = np.zeros((1, 2, 3)) + [0.0, 0.0, 0.1]
    targets, grasp = mode.plan(np.array([[1, 0, 0, 1, -1, 0, -1, -1]], np.float32), start)
    assert targets.shape == (8, 1, 2, 3) and grasp.shape == (8, 1, 2)
    assert np.allclose(targets[-1, 0, 0], [0.08, 0.0, 0.1])  # clipped at high - margin
    assert np.allclose(targets[-1, 0, 1], [-0.08, 0.0, 0.02])
    assert grasp[:, 0, 0].all() and not grasp[:, 0, 1].any()


def test_pick_place_plan_has_fixed_length_and_grasps_in_between():
    ws = Workspace((-0.5, -0.5, 0.0), (0.5, 0.5, 0.5), margin=0.05)
    mode = PickPlaceActions(1, ws, PickPlaceSchedule(arc_ratio=0.5))
    start = np.array([[[0.0, 0.0, 0.3]], [[0.2, 0.2, 0.3]]])
    pick = np.array([[[-0.3, 0.0, 0.0]], [[0.1, 0.1, 0.0]]])
    place = np.array([[[0.3, 0.0, 0.0]], [[0.1, 0.2, 0.0]]])
    actions = mode.join(pick, place).reshape(2, -1)
    targets, grasp = mode.plan(actions, start)
    assert targets.shape[0] == mode.frames_per_step == mode.schedule.total_frames
    for w in range(2):
        g = grasp[:, w, 0]
        first, last = np.argmax(g), len(g) - 1 - np.argmax(g[::-1])
        assert g[first:last + 1].all() and not g[last + 1:].any()
        assert np.allclose(targets[first, w, 0, :2], pick[w, 0, :2])
        assert np.allclose(targets[last, w, 0, :2], place[w, 0, :2])
    assert targets[:, 0, 0, 2].max() > 0.25  # the long carry arcs up (fold motion)
    assert np.all(targets >= ws.lo + ws.margin - 1e-9) and np.all(targets <= ws.hi - ws.margin + 1e-9)


# ----------------------------------------------------------------------------- env contract
@pytest.mark.parametrize("env_id", ["StraightenRope-v0", "ClothFold-v0", "ClothFoldDiagonalPinned-v0"])
def test_check_env(env_id):
    env = make(env_id, obs_mode="state")
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_check_env_image_particles_and_pick_place():
    check_env(make("ClothFoldDiagonal-v0", obs_mode="image").unwrapped, skip_render_check=True)
    check_env(make("StraightenRope-v0", obs_mode="particles", action_mode="pick_place").unwrapped,
              skip_render_check=True)


def test_default_diagonal_is_dmfd_setting():
    env = gym.make("lfd_envs:ClothFoldDiagonal-v0")
    base = env.unwrapped
    assert base.num_pickers == 1 and base.action_mode == "delta" and not base.task.pinned
    assert env.observation_space.shape == (32, 32, 3) and env.observation_space.dtype == np.uint8
    assert env.action_space.shape == (4,)
    assert base.horizon == 100 and base.task.resolution == 40
    obs, info = env.reset(seed=0)
    assert obs.shape == (32, 32, 3) and obs.dtype == np.uint8
    assert {"performance", "normalized_performance", "variant", "corner_distance"} <= set(info)
    env.close()


@pytest.mark.parametrize("env_id,state0", [("StraightenRope-v0", 30), ("ClothFold-v0", 12),
                                          ("ClothFoldDiagonalPinned-v0", 12)])
def test_spaces_follow_arguments(env_id, state0):
    for mode, per in (("delta", 4), ("pick_place", 6)):
        for p in (1, 2, 3, 4):
            env = make(env_id, num_pickers=p, action_mode=mode, obs_mode="state")
            assert env.action_space.shape == (per * p,)
            assert env.observation_space.shape == (state0 + 3 * p,)
            assert env.unwrapped.horizon == env.unwrapped.task.horizons[mode]
            env.close()
    env = make(env_id, num_pickers=2, obs_mode="particles")
    n = env.unwrapped.num_particles
    assert env.observation_space.shape == (n + 2, 3)
    env = make(env_id, obs_mode="state+image", image_size=(24, 16), horizon=7)
    assert env.observation_space["image"].shape == (24, 16, 3)
    assert env.unwrapped.horizon == 7
    obs, _ = env.reset(seed=3)
    assert env.observation_space.contains(obs)


def test_bad_arguments_have_clear_errors():
    with pytest.raises(ValueError, match="num_pickers"):
        make("ClothFold-v0", num_pickers=5)
    with pytest.raises(ValueError, match="action_mode"):
        make("ClothFold-v0", action_mode="teleport")
    with pytest.raises(ValueError, match="obs_mode"):
        make("ClothFold-v0", obs_mode="depth")
    with pytest.raises(ValueError, match="resolution"):
        make("ClothFold-v0", resolution=2)
    with pytest.raises(TypeError, match="valid arguments"):
        make("ClothFold-v0", pinned=True)
    with pytest.raises(ValueError, match="pinned"):
        make("ClothFoldDiagonal-v0", pinned="yes")


def test_bad_actions_raise_and_env_keeps_working():
    env = make("ClothFold-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"\(8,\)"):
        env.step(np.zeros(5))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.full(8, np.nan))
    obs, reward, term, trunc, info = env.step(np.full(8, 3.0))  # clipped to [-1, 1]
    assert np.all(np.isfinite(obs)) and np.isfinite(reward)
    assert env.unwrapped.elapsed_steps == 1


def test_train_and_eval_variants_differ():
    env = make("ClothFold-v0")
    ids, sizes = set(), set()
    for split in ("train", "eval"):
        for k in range(3):
            _, info = env.reset(seed=0, options={"variant": k, "split": split})
            ids.add(info["variant"])
            sizes.add(round(float(env.unwrapped.batch.ctx["size"][0]), 9))
    assert len(ids) == 6 and len(sizes) == 6
    assert env.unwrapped.variants.num_train <= min(i for i in ids if i >= 800)


def test_seed_determinism_and_state_round_trip():
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(6, 8)).astype(np.float32)
    runs = []
    for _ in range(2):
        env = make("ClothFold-v0", obs_mode="particles")
        obs, _ = env.reset(seed=11)
        traj = [obs]
        for a in actions:
            traj.append(env.step(a)[0])
        runs.append(np.stack(traj))
    assert np.array_equal(runs[0], runs[1])

    env = make("ClothFold-v0", obs_mode="particles")
    env.reset(seed=11)
    for a in actions[:3]:
        env.step(a)
    state = env.unwrapped.get_state()
    future = [env.step(a) for a in actions[3:]]
    env.reset(seed=99, options={"variant": 5, "split": "eval"})  # somewhere else entirely
    env.unwrapped.set_state(state)
    assert np.array_equal(env.unwrapped.current_observation(), runs[0][3])
    again = [env.step(a) for a in actions[3:]]
    for (o1, r1, _, t1, i1), (o2, r2, _, t2, i2) in zip(future, again):
        assert np.array_equal(o1, o2) and r1 == r2 and t1 == t2 and i1 == i2


def test_rewards_sum_to_performance_change_and_truncation():
    env = make("StraightenRope-v0", horizon=4)
    _, info0 = env.reset(seed=1)
    total, done, steps = 0.0, False, 0
    while not done:
        _, r, term, trunc, info = env.step(env.action_space.sample())
        total += r
        steps += 1
        done = term or trunc
    assert steps == 4 and trunc and not term
    assert total == pytest.approx(info["performance"] - info0["performance"], abs=1e-6)
    assert info["normalized_performance"] == pytest.approx(1 - abs(info["end_point_distance"] - 0.5) / 0.5)


def test_render_and_image_observation():
    env = make("ClothFoldDiagonalPinned-v0", render_mode="rgb_array", obs_mode="image", image_size=16)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (16, 16, 3) and obs.dtype == np.uint8 and obs.std() > 5
    frame = env.render()
    assert frame.shape == (256, 256, 3) and frame.dtype == np.uint8


def test_held_particles_counts_what_a_picker_holds_not_its_flag():
    env = make("ClothFoldDiagonalUnpinned-v0")
    env.reset(seed=0)
    u = env.unwrapped
    corner = u.particle_positions[np.argmin(u.particle_positions[:, :2].sum(axis=1))]
    steer_picker(env, corner + [0.0, 0.0, 0.15], 20)  # above the corner, flag on: holds nothing
    assert u.grasped[0] and u.held_particles.tolist() == [0]
    steer_picker(env, corner, 10)  # lowered onto the corner with the flag still on: grasps on contact
    assert u.held_particles[0] >= 1
    env.step(np.array([0, 0, 0, -1], np.float32))  # flag off: released
    assert u.held_particles.tolist() == [0]


@pytest.mark.parametrize("env_id", ["ClothFoldDiagonalPinned-v0", "ClothFoldDiagonalPinned-v1"])
def test_pin_block_leaves_the_cloth_unstretched_at_rest(env_id):
    """The particles the pin block touches are all pinned, so none is pushed out of the block
    against a pinned neighbour (before: edges up to 238 % stretched at rest, -v0)."""
    from tools.cloth_bounds import edge_strain

    env = gym.make(env_id, obs_mode="state")
    for k in (0, 1):
        env.reset(seed=k, options={"split": "eval", "variant": k})
        base = env.unwrapped
        strain, _, _ = edge_strain(base.batch.sim.builders[0], base.particle_positions)
        assert strain.max() < 0.10, (k, strain.max())


# ----------------------------------------------------------------------------- grasp flags in the state
@pytest.mark.parametrize("env_id", ["StraightenRope-v0", "ClothFoldDiagonalUnpinned-v0"])
def test_observe_grasp_appends_one_flag_per_picker_that_follows_what_it_holds(env_id):
    from lfd_envs.experts import make_expert

    plain = make(env_id, obs_mode="state")
    env = make(env_id, obs_mode="state", observe_grasp=True)
    check_env(env.unwrapped, skip_render_check=True)
    p = env.unwrapped.num_pickers
    assert env.observation_space.shape[0] == plain.observation_space.shape[0] + p
    assert np.all(env.observation_space.low[-p:] == 0) and np.all(env.observation_space.high[-p:] == 1)
    obs, _ = env.reset(seed=3)
    ref, _ = plain.reset(seed=3)
    expert = make_expert(env)
    flags = set()
    for _ in range(30):
        action, _ = expert.predict(obs)
        obs, *_ = env.step(action)
        ref, *_ = plain.step(action)
        np.testing.assert_array_equal(obs[:-p], ref)  # the task's state is unchanged
        held = env.unwrapped.held_particles
        np.testing.assert_array_equal(obs[-p:], (held > 0).astype(np.float32))
        flags.add(bool(obs[-p:].any()))
    assert flags == {False, True}, "the expert grasps within 30 steps, so the flag must turn on"


def test_observe_grasp_draws_a_holding_picker_black_and_changes_nothing_else_in_the_image():
    from lfd_envs.experts import make_expert
    from lfd_envs.tasks.particle_batch import HOLDING_PICKER_COLOR

    kw = dict(obs_mode="state+image", image_size=64)
    plain = make("ClothFoldDiagonalUnpinned-v0", **kw)
    env = make("ClothFoldDiagonalUnpinned-v0", observe_grasp=True, **kw)
    obs, _ = env.reset(seed=3)
    ref, _ = plain.reset(seed=3)
    expert = make_expert(env)
    black = np.round(255 * np.asarray(HOLDING_PICKER_COLOR))
    seen = set()
    for _ in range(30):
        action, _ = expert.predict(obs)
        obs, *_ = env.step(action)
        ref, *_ = plain.step(action)
        holding = bool(obs["state"][-1])
        changed = (obs["image"] != ref["image"]).any(axis=-1)
        seen.add(holding)
        if not holding:
            assert not changed.any()
            continue
        assert changed.any(), "a picker that holds the cloth is drawn in another colour"
        assert np.all(np.abs(obs["image"][changed].astype(float) - black).max(axis=-1) < 40), "drawn dark"
    assert seen == {False, True}


def test_observe_grasp_in_the_vector_env_and_bad_values():
    vec = gym.make_vec("StraightenRope-v0", num_envs=2, vectorization_mode="vector_entry_point",
                       resolution=15, obs_mode="state", observe_grasp=True)
    obs, _ = vec.reset(seed=0)
    assert obs.shape == (2, make("StraightenRope-v0").observation_space.shape[0] + 2)
    assert np.all(obs[:, -2:] == 0)
    with pytest.raises(ValueError, match="observe_grasp"):
        make("StraightenRope-v0", observe_grasp="yes")
