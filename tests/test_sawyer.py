"""Sawyer obstructed tasks (Push, Lift, Assembly): contract, planning interface, experts, HER."""

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from lfd_envs.experts import make_expert
from lfd_envs.mujoco.planning import densify_path
from lfd_envs.mujoco.sawyer_assembly import SawyerAssemblyObstacleEnv
from lfd_envs.mujoco.sawyer_lift import SawyerLiftObstacleEnv
from lfd_envs.mujoco.sawyer_push import SawyerPushObstacleEnv

pytestmark = pytest.mark.filterwarnings("ignore:.*(infinity|Box observation space).*")

ENVS = {"push": SawyerPushObstacleEnv, "lift": SawyerLiftObstacleEnv, "assembly": SawyerAssemblyObstacleEnv}
IDS = {"push": "SawyerPushObstacle-v0", "lift": "SawyerLiftObstacle-v0", "assembly": "SawyerAssemblyObstacle-v0"}


@pytest.fixture(scope="module")
def envs():
    made = {k: cls() for k, cls in ENVS.items()}
    yield made
    for env in made.values():
        env.close()


def rollout(env, policy, seed):
    obs, info = env.reset(seed=seed, options={"split": "eval", "variant": seed})
    total = 0.0
    for _ in range(env.horizon):
        obs, r, term, trunc, info = env.step(policy(obs))
        total += r
        if term or trunc:
            break
    return total, info


@pytest.mark.parametrize("task", list(ENVS))
def test_make_check_env_and_control_constants(task, envs):
    env = gym.make(f"lfd_envs:{IDS[task]}")
    base = env.unwrapped
    assert base.horizon == 250 and base.frame_skip == 75 and np.isclose(base.model.opt.timestep, 0.002)
    assert base.dq_step == 0.05 and env.action_space.shape == ((8,) if task == "lift" else (7,))
    kp = base.model.actuator_gainprm[base.arm_actuators, 0]
    assert np.allclose(kp, (500, 500, 200, 200, 50, 50, 50))
    check_env(base, skip_render_check=True)
    env.close()


def test_image_and_goal_conditioned_modes():
    env = SawyerPushObstacleEnv(obs_mode="state+image")
    obs, _ = env.reset(seed=0)
    assert obs["image"].shape == (84, 84, 3) and obs["image"].dtype == np.uint8 and obs["state"].shape == (47,)
    assert obs["image"].std() > 5  # not a blank frame
    env.close()
    check_env(SawyerLiftObstacleEnv(goal_conditioned=True), skip_render_check=True)


@pytest.mark.parametrize("task", list(ENVS))
def test_goal_conditioned_reward_matches_step_reward(task):
    env = ENVS[task](goal_conditioned=True)
    obs, _ = env.reset(seed=3)
    rng = np.random.default_rng(0)
    ags, dgs, infos, rewards = [], [], [], []
    for _ in range(4):
        obs, r, term, trunc, info = env.step(rng.uniform(-1, 1, env.action_space.shape))
        assert env.compute_reward(obs["achieved_goal"], obs["desired_goal"], info) == pytest.approx(r, abs=1e-5)
        ags.append(obs["achieved_goal"]), dgs.append(obs["desired_goal"]), infos.append(info), rewards.append(r)
    batched = env.compute_reward(np.array(ags), np.array(dgs), np.array(infos))
    assert batched.shape == (4,) and np.allclose(batched, rewards, atol=1e-5)
    # relabelling with the achieved goal as desired goal counts as success
    relabelled = env.compute_reward(np.array(ags), np.array(ags), np.array(infos))
    if task != "lift":  # Lift's success also needs a grasp
        assert np.all(relabelled >= 150.0)


def test_bad_input_raises_clear_errors(envs):
    env = envs["lift"]
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"\(8,\)"):
        env.step(np.zeros(7))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.full(8, np.nan))
    env.step(np.full(8, 5.0))  # out of range: clipped, env still usable
    with pytest.raises(TypeError, match="valid arguments"):
        SawyerPushObstacleEnv(frame_skip=10)
    with pytest.raises(ValueError):
        envs["push"].is_valid(np.zeros(6))


@pytest.mark.parametrize("task", list(ENVS))
def test_determinism_and_state_round_trip(task, envs):
    env = envs[task]
    actions = np.random.default_rng(1).uniform(-1, 1, (12, *env.action_space.shape))

    def run(start_state=None):
        obs, _ = env.reset(seed=7)
        if start_state is not None:
            env.set_state(start_state)
        out = [obs]
        for a in actions:
            out.append(env.step(a)[0])
        return np.array(out)

    first = run()
    assert np.array_equal(first, run())  # same seed, same actions -> bitwise identical
    env.reset(seed=7)
    for a in actions[:5]:
        env.step(a)
    state = env.get_state()
    tail = np.array([env.step(a)[0] for a in actions[5:]])
    env.reset(seed=99)
    env.set_state(state)
    assert np.array_equal(tail, np.array([env.step(a)[0] for a in actions[5:]]))


def _brute_force_valid(env, q):
    """Reference check: a fresh MjData at q, deep contacts minus the documented ignored pairs."""
    m = env.model
    d = mujoco.MjData(m)
    d.qpos[:] = env.data.qpos
    d.qpos[env._arm_qadr] = q
    mujoco.mj_forward(m, d)
    ignored = set()
    for a, b in env.ignored_contact_pairs:
        for ga in env._geoms_named(a):
            for gb in env._geoms_named(b):
                ignored |= {(ga, gb), (gb, ga)}
    moving = env._arm_body_mask[m.geom_bodyid]
    for c in d.contact[:d.ncon]:
        g1, g2 = c.geom
        if c.dist <= -0.002 and (g1, g2) not in ignored and (moving[g1] or moving[g2]):
            return False
    return True


@pytest.mark.parametrize("task", list(ENVS))
def test_is_valid_agrees_with_simulator_and_leaves_data_untouched(task, envs):
    env = envs[task]
    env.reset(seed=0)
    q0 = env.arm_qpos()
    assert env.is_valid(q0)  # start pose
    before = {k: getattr(env.data, k).copy() for k in ("qpos", "qvel", "ctrl", "qacc", "xpos")}
    ncon, time = env.data.ncon, env.data.time
    rng = np.random.default_rng(0)
    lo, hi = env.joint_limits.T
    verdicts = []
    for _ in range(40):
        q = np.clip(q0 + rng.normal(0, 0.8, 7), lo, hi)
        verdicts.append(env.is_valid(q))
        assert verdicts[-1] == _brute_force_valid(env, q)
    assert not all(verdicts) and any(verdicts)
    for k, v in before.items():
        assert np.array_equal(getattr(env.data, k), v), k
    assert env.data.ncon == ncon and env.data.time == time


def test_configuration_inside_obstacle_is_invalid(envs):
    env = envs["push"]
    env.reset(seed=0)
    from lfd_envs.mujoco.sawyer import SawyerIK

    # grip site in the middle of the tunnel's roof slab -> arm inside the obstacle
    q, err = SawyerIK(env).solve((0.98, 0.0, 1.235), (1.0, 0.0, 0.0), env.arm_qpos())
    assert err < 0.01
    pairs = env.colliding_pairs(q)
    assert not env.is_valid(q) and any("tunnel" in a or "tunnel" in b for a, b, _ in pairs)


def test_execute_path_reaches_end_configuration(envs):
    env = envs["push"]
    env.reset(seed=0)
    q0 = env.arm_qpos()
    q1 = q0 + np.array([0.3, -0.25, 0.2, 0.3, -0.3, 0.3, 0.4])
    path = densify_path(np.array([q0, q1]), env.dq_step)
    assert env.is_segment_valid(q0, q1)
    result = env.execute_path(path)
    assert result.steps == len(path) - 1 and len(result.rewards) == result.steps
    for _ in range(2):  # let the servos settle (set-point chained from the last waypoint)
        env.step(np.clip((q1 - env.arm_qpos()) / env.dq_step, -1, 1))
    assert np.max(np.abs(env.arm_qpos() - q1)) < 0.02


@pytest.mark.parametrize("task", list(ENVS))
def test_expert_beats_random_by_a_wide_margin(task, envs):
    env = envs[task]
    expert = make_expert(env)
    rng = np.random.default_rng(0)
    for seed in (0, 1):
        expert.reset()
        ret_e, info_e = rollout(env, lambda o: expert.predict(o)[0], seed)
        ret_r, info_r = rollout(env, lambda o: rng.uniform(-1, 1, env.action_space.shape), seed)
        assert info_e["is_success"] and not info_r["is_success"]
        assert ret_e > ret_r + 100.0


def test_lift_planning_carries_the_grasped_can(envs):
    from lfd_envs.mujoco.sawyer import SawyerIK
    from lfd_envs.mujoco.sawyer_lift import BIN_CENTER, BIN_HALF, BIN_WALL_TOP

    env = envs["lift"]
    expert = make_expert(env)
    obs, _ = env.reset(seed=0, options={"split": "eval", "variant": 0})
    expert.reset()
    before_grasp = env.get_state()
    while not (env.grasped and env.can_pos()[2] > 1.0):
        obs, _, term, trunc, _ = env.step(expert.predict(obs)[0])
        assert not (term or trunc)
    assert env.is_valid(env.arm_qpos())
    # gripper just inside the +x wall, fingers opening along y: only the carried can's rim
    # (2.5 cm radius, hanging 4 cm below the grip site) reaches over the top of the wall
    wall_face = BIN_CENTER[0] + BIN_HALF - 0.01
    target = (wall_face - 0.02, BIN_CENTER[1], BIN_WALL_TOP + 0.02)
    ik = SawyerIK(env)
    q, err = ik.solve(target, (0.0, 0.0, -1.0), env.arm_qpos(), roll_axis=(1.0, 0.0, 0.0))
    assert err < 5e-3
    pairs = env.colliding_pairs(q)
    assert pairs and all("can" in (a, b) for a, b, _ in pairs), pairs
    env.set_state(before_grasp)  # can on the bin floor: not carried, q is free
    assert env.is_valid(q)


def test_speed_benchmark_rows():
    from benchmarks.speed import sawyer_env_rows

    rows = sawyer_env_rows(steps=4, image_steps=2, valid_checks=20, repeats=1, env_ids=("SawyerPushObstacle-v0",))
    assert [r["obs"] for r in rows] == ["state", "image 84x84"]
    assert rows[0]["env_steps_per_s"] > 0 and rows[0]["is_valid_per_s"] > 0 and rows[1]["env_steps_per_s"] > 0
