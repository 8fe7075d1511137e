"""MoPA: planner, wrapper, action rescaling, k-step replay targets, data reuse, exploration."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

from lfd_agents.mopa import (ActionMap, MoPAReplayBuffer, MoPASAC, MoPATD3, MoPAWrapper, OMPLPlanner,
                             invert_rescale, rescale_action, smdp_targets)


# ---------------------------------------------------------------------------------------- toy
class WallPointEnv(gym.Env):
    """2-DOF point "arm" in [-1, 1]² with a wall |x| < 0.1, y > -0.6 (gap at the bottom).

    Implements the planning interface of lfd_envs.mujoco.planning (path[0] = start).
    Reward: -|q - goal|; goal on the other side of the wall.
    """

    arm_joint_names = ["x", "y"]
    dq_step = 0.05

    def __init__(self, horizon: int = 200):
        self.joint_limits = np.array([[-1.0, 1.0], [-1.0, 1.0]])
        self.action_space = spaces.Box(-1, 1, (2,), np.float32)
        self.observation_space = spaces.Box(-2, 2, (4,), np.float32)
        self.goal = np.array([0.5, 0.5])
        self.horizon = horizon

    @staticmethod
    def is_valid(q) -> bool:
        q = np.asarray(q)
        return not (abs(q[0]) < 0.1 and q[1] > -0.6)

    def arm_qpos(self):
        return self.q.copy()

    def _obs(self):
        return np.concatenate([self.q, self.goal]).astype(np.float32)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.q = np.array([-0.5, 0.5]) + self.np_random.uniform(-0.02, 0.02, 2)
        self.t = 0
        return self._obs(), {}

    def step(self, action):
        new = np.clip(self.q + np.clip(action, -1, 1) * self.dq_step, -1, 1)
        if self.is_valid(new):
            self.q = new
        self.t += 1
        reward = -float(np.linalg.norm(self.q - self.goal))
        return self._obs(), reward, False, self.t >= self.horizon, {}

    def execute_path(self, path, gripper=None, discount=1.0):
        path = np.asarray(path)
        assert np.abs(path[0] - self.q).max() <= self.dq_step + 1e-9
        res = SimpleNamespace(obs=self._obs(), observations=[], rewards=[], terminated=False, truncated=False,
                              info={}, steps=0, discounted_return=0.0)
        for i in range(len(path) - 1):
            a = (path[i + 1] - path[i]) / self.dq_step
            assert np.abs(a).max() <= 1 + 1e-6, "waypoints farther apart than dq_step"
            obs, r, term, trunc, info = self.step(a)
            res.discounted_return += discount ** i * r
            res.rewards.append(r)
            res.observations.append(obs)
            res.obs, res.info, res.terminated, res.truncated = obs, info, term, trunc
            res.steps += 1
            if term or trunc:
                break
        return res


def _check_path_valid(is_valid, start, path, resolution):
    """Every waypoint and the points between them at ``resolution`` (per joint) are valid."""
    pts = np.vstack([start[None], path])
    for a, b in zip(pts[:-1], pts[1:]):
        n = max(1, int(np.ceil(np.abs(b - a).max() / resolution - 1e-9)))
        for t in np.linspace(0, 1, n + 1):
            assert is_valid(a + t * (b - a)), f"invalid configuration between {a} and {b}"


# ---------------------------------------------------------------------------------------- planner
@pytest.mark.parametrize("algorithm", ["rrt_connect", "rrt_star"])
def test_planner_goes_around_wall(algorithm):
    env = WallPointEnv()
    planner = OMPLPlanner(env.is_valid, env.joint_limits, dq_step=env.dq_step, range=0.2, algorithm=algorithm,
                          time_limit=0.5)
    start, goal = np.array([-0.5, 0.5]), np.array([0.5, 0.5])
    assert planner.interpolate(start, goal) is None  # straight line blocked
    res = planner.plan(start, goal)
    assert res.success and res.status == "planner" and res.used_planner
    np.testing.assert_allclose(res.path[-1], goal)
    assert np.abs(np.diff(np.vstack([start, res.path]), axis=0)).max() <= env.dq_step + 1e-9
    assert res.path[:, 1].min() < -0.6  # went through the gap
    _check_path_valid(env.is_valid, start, res.path, planner.check_resolution)
    planner.close()


def test_planner_straight_line_and_failures():
    env = WallPointEnv()
    planner = OMPLPlanner(env.is_valid, env.joint_limits, dq_step=env.dq_step, time_limit=0.2)
    res = planner.plan([-0.5, 0.5], [-0.3, 0.1])
    assert res.status == "interpolation" and not res.used_planner
    assert np.abs(np.diff(res.path, axis=0)).max() <= 0.8 * env.dq_step + 1e-9
    assert planner.plan([-0.5, 0.5], [0.0, 0.5]).status == "invalid_goal"
    assert planner.plan([0.0, 0.5], [0.5, 0.5]).status == "invalid_start"
    with pytest.raises(ValueError, match="shape"):
        planner.plan([0.0], [0.5, 0.5])
    with pytest.raises(ValueError, match="algorithm"):
        OMPLPlanner(env.is_valid, env.joint_limits, dq_step=0.05, algorithm="prm")


def test_check_budget_stops_a_search_that_cannot_succeed():
    """A goal cut off from the start (closed wall): the search stops after ``max_checks``
    validity checks, well inside the time limit, and a seeded planner fails the same way twice;
    a reachable goal is still found with the budget."""
    closed = lambda q: abs(q[0]) >= 0.1  # noqa: E731 - no gap: the right half is unreachable
    results = []
    for _ in range(2):
        planner = OMPLPlanner(closed, [[-1, 1], [-1, 1]], dq_step=0.05, range=0.2, time_limit=5.0, max_checks=400,
                              seed=3)
        res = planner.plan([-0.5, 0.5], [0.5, 0.5])
        assert res.status == "failed" and res.planning_time < 2.0
        assert 400 <= res.extra["checks"] < 400 + 50  # stops at the budget (one extension past it at most)
        results.append(res.extra["checks"])
        planner.close()
    assert results[0] == results[1]
    env = WallPointEnv()
    planner = OMPLPlanner(env.is_valid, env.joint_limits, dq_step=env.dq_step, range=0.2, max_checks=20_000, seed=0)
    res = planner.plan([-0.5, 0.5], [0.5, 0.5])
    assert res.status == "planner" and 0 < res.extra["checks"] < 20_000
    for bad in (0, -5, 1.5, True):
        with pytest.raises(ValueError, match="max_checks"):
            OMPLPlanner(env.is_valid, env.joint_limits, dq_step=0.05, max_checks=bad)
    planner.close()


def test_no_nanobind_warnings_at_exit():
    code = textwrap.dedent("""
        import numpy as np
        from lfd_agents.mopa import OMPLPlanner
        ok = lambda q: not (abs(q[0]) < 0.1 and q[1] > -0.6)
        planner = OMPLPlanner(ok, [[-1, 1], [-1, 1]], dq_step=0.05, range=0.2)
        result = planner.plan([-0.5, 0.5], [0.5, 0.5])
        assert result.status == "planner", result.status
        print("OK")
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                         env={**os.environ, "PYTHONWARNINGS": "ignore"})
    assert out.returncode == 0 and "OK" in out.stdout, out.stderr
    assert "nanobind" not in out.stderr and "leaked" not in out.stderr, out.stderr
    assert "Info:" not in out.stdout + out.stderr  # OMPL console log silenced


# ---------------------------------------------------------------------------------------- rescaling
def test_rescaling_boundary_points():
    dq_step, dq_mp, omega = 0.1, 1.0, 0.5
    u = np.array([0.0, omega, -omega, 1.0, -1.0, 0.75])
    expected = np.array([0.0, dq_step, -dq_step, dq_mp, -dq_mp, dq_step + (dq_mp - dq_step) * 0.25 / 0.5])
    np.testing.assert_allclose(rescale_action(u, dq_step, dq_mp, omega), expected, atol=1e-12)
    np.testing.assert_allclose(invert_rescale(expected, dq_step, dq_mp, omega), u, atol=1e-12)
    # continuous at ±ω and monotone
    eps = 1e-9
    lo, hi = rescale_action(np.array([omega - eps, omega + eps]), dq_step, dq_mp, omega)
    assert abs(lo - hi) < 1e-6
    grid = np.linspace(-1, 1, 201)
    assert np.all(np.diff(rescale_action(grid, dq_step, dq_mp, omega)) > 0)
    amap = ActionMap(0.05, 0.5, 0.7, rescale=False)
    np.testing.assert_allclose(amap.displacement(np.array([1.0, -0.2])), [0.5, -0.1])
    assert amap.is_direct(np.array([0.05, -0.02])) and not amap.is_direct(np.array([0.06, 0.0]))
    with pytest.raises(ValueError):
        ActionMap(0.05, 0.5, 1.0)


# ---------------------------------------------------------------------------------------- wrapper
def test_wrapper_direct_planned_and_info():
    env = MoPAWrapper(WallPointEnv(), dq_mp=1.0, omega=0.5, gamma=0.9, range=0.2)
    obs, _ = env.reset(seed=0)
    q0 = env.arm_qpos()
    obs, r, term, trunc, info = env.step(np.array([0.5, -0.25]))  # |u| ≤ ω: one direct step
    assert info["mopa_mode"] == "direct" and info["mopa_k"] == 1 and not info["mopa_planner_used"]
    np.testing.assert_allclose(env.arm_qpos() - q0, [0.05, -0.025], atol=1e-9)
    # large action across the wall: the target (x+1) is on the other side → planner
    env.reset(seed=0)
    q0 = env.arm_qpos()
    obs, r, term, trunc, info = env.step(np.array([1.0, 0.0]))
    assert info["mopa_mode"] == "planner" and info["mopa_planner_used"] and not info["mopa_planner_failed"]
    k = info["mopa_k"]
    assert k == len(info["mopa_path"]) > 10
    np.testing.assert_allclose(env.arm_qpos(), np.clip(q0 + [1.0, 0.0], -1, 1), atol=1e-9)
    traj = info["mopa_trajectory"]
    expected = sum(0.9 ** i * rr for i, rr in enumerate(traj["rewards"]))
    assert r == pytest.approx(expected)
    assert len(traj["observations"]) == k + 1 and len(traj["qpos"]) == k + 1
    _check_path_valid(WallPointEnv.is_valid, q0, info["mopa_path"], env.planner.check_resolution)


def test_invalid_target_handling():
    env = MoPAWrapper(WallPointEnv(), dq_mp=1.0, omega=0.5)
    env.reset(seed=1)
    q = env.arm_qpos()
    target = np.array([0.05, 0.5])  # inside the wall
    fixed = env.valid_target(q, target)
    assert fixed is not None and WallPointEnv.is_valid(fixed)
    assert np.linalg.norm(fixed - q) < np.linalg.norm(target - q)
    assert fixed[0] == pytest.approx(-0.1, abs=0.025)  # stopped just outside the wall
    env_off = MoPAWrapper(WallPointEnv(), dq_mp=1.0, omega=0.5, invalid_target_handling=False)
    env_off.reset(seed=1)
    assert env_off.valid_target(q, target) is None
    q_before = env_off.arm_qpos()
    _, _, _, _, info = env_off.step(np.array([0.78, 0.0]))  # Δq ≈ +0.55 → x ≈ 0.05, in the wall
    assert info["mopa_mode"] == "invalid_target" and info["mopa_planner_failed"] and info["mopa_k"] == 1
    np.testing.assert_allclose(env_off.arm_qpos(), q_before)
    env.reset(seed=1)
    _, _, _, _, info = env.step(np.array([0.78, 0.0]))
    assert info["mopa_mode"] == "interpolation" and WallPointEnv.is_valid(env.arm_qpos())


def test_ablation_switches():
    env = MoPAWrapper(WallPointEnv(), dq_mp=1.0, omega=0.5, direct_execution=False)
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([0.2, 0.0]))
    assert info["mopa_mode"] == "interpolation" and info["mopa_k"] == 1
    lin = MoPAWrapper(WallPointEnv(), dq_mp=1.0, omega=0.5, rescale=False)
    lin.reset(seed=0)
    q0 = lin.arm_qpos()
    _, _, _, _, info = lin.step(np.array([0.04, 0.0]))  # 0.04 rad ≤ Δq_step: direct
    assert info["mopa_mode"] == "direct"
    np.testing.assert_allclose(lin.arm_qpos() - q0, [0.04, 0.0], atol=1e-9)
    star = MoPAWrapper(WallPointEnv(), dq_mp=1.0, omega=0.5, algorithm="rrt_star", time_limit=0.2)
    assert star.planner.algorithm == "rrt_star"
    with pytest.raises(TypeError, match="planning interface"):
        MoPAWrapper(gym.make("Pendulum-v1"))


# ---------------------------------------------------------------------------------------- agent
def _buffer(gamma=0.9, reuse=0, scale=1.0):
    obs_space = spaces.Box(-2, 2, (4,), np.float32)
    return MoPAReplayBuffer(100, obs_space, spaces.Box(-1, 1, (2,), np.float32), device="cpu", gamma=gamma,
                            reward_scale=scale, reuse=reuse, seed=0)


def test_gamma_k_targets_against_hand_computed_batch():
    gamma, scale = 0.9, 0.5
    buf = _buffer(gamma, scale=scale)
    ks, rewards, dones = [1, 3, 7, 2], [1.0, -2.0, 0.5, 4.0], [0.0, 0.0, 0.0, 1.0]
    for i, (k, r, d) in enumerate(zip(ks, rewards, dones)):
        o = np.full((1, 4), i, np.float32)
        buf.add(o, o + 1, np.zeros((1, 2), np.float32), np.array([r]), np.array([d]), [{"mopa_k": k}])
    data = buf._get_samples(np.arange(4))
    next_v = np.array([10.0, 20.0, 30.0, 40.0])
    # SB3 SAC/TD3 target: rewards + (1 - dones) * discounts * next_values
    got = (data.rewards + (1 - data.dones) * data.discounts * next_v[:, None]).numpy()[:, 0]
    hand = np.array([0.5 * 1.0 + 0.9 * 10, 0.5 * -2.0 + 0.729 * 20, 0.5 * 0.5 + 0.9 ** 7 * 30, 0.5 * 4.0 + 0.0])
    np.testing.assert_allclose(got, hand, rtol=1e-5)
    np.testing.assert_allclose(smdp_targets(rewards, dones, ks, next_v, gamma, scale), hand, rtol=1e-6)


def test_reuse_transitions_rewards_and_actions():
    gamma = 0.9
    buf = _buffer(gamma, reuse=50)
    amap = ActionMap(0.05, 1.0, 0.5)
    qpos = np.array([[0.0, 0.0]] + [[0.05 * i, 0.0] for i in range(1, 7)])  # 6 steps along x
    rewards = np.arange(1.0, 7.0)
    traj = {"qpos": qpos, "observations": [np.full(4, i, np.float32) for i in range(7)], "rewards": rewards,
            "terminated": True, "extra_action": np.zeros(0), "action_map": amap}
    out = buf.reuse_transitions(traj)
    assert 0 < len(out) <= 6
    for obs, nobs, action, reward, done, k in out:
        s, g = int(obs[0]), int(nobs[0])
        assert k == g - s and k >= 2  # single steps are direct actions, never reused
        np.testing.assert_allclose(amap.displacement(action), qpos[g] - qpos[s], atol=1e-9)
        assert reward == pytest.approx(sum(gamma ** (i - s) * rewards[i] for i in range(s, g)))
        assert done == (g == 6)
    assert buf.reuse_transitions({**traj, "qpos": qpos[:4], "rewards": rewards[:3]}) == []  # k ≤ 3


def test_mopa_sac_and_td3_run_and_store_k_step_transitions(one_torch_thread):
    env = MoPAWrapper(WallPointEnv(horizon=60), dq_mp=1.0, omega=0.5, range=0.2, time_limit=0.2)
    model = MoPASAC("MlpPolicy", env, reward_scale=0.2, reuse=5, gamma=0.95, learning_starts=50, batch_size=32,
                    policy_kwargs={"net_arch": [32, 32]}, seed=0, device="cpu")
    assert env.gamma == 0.95  # synced with the agent
    model.learn(150)
    rb = model.replay_buffer
    n = rb.pos
    assert n > 150 and rb.reused_added > 0  # reused sub-segments were added
    assert rb.steps[:n].max() > 2
    model.predict(np.zeros(4, np.float32), deterministic=True)
    td3 = MoPATD3("MlpPolicy", env, reuse=0, learning_starts=20, batch_size=16, seed=0, device="cpu",
                  policy_kwargs={"net_arch": [16]})
    td3.learn(40)
    assert td3.replay_buffer.reused_added == 0


class _Recording(MoPASAC):
    """MoPA-SAC recording (transitions stored, updates done) after every ``train`` call."""

    def train(self, gradient_steps, batch_size=64):
        super().train(gradient_steps, batch_size)
        self.record.append((self.replay_buffer.stored, self._n_updates))


def test_update_per_stored_transition_counts_reuse_like_mopa_rl(one_torch_thread):
    """MoPA-RL's schedule: one gradient step per stored transition (reused sub-segments
    included) once the warm-up is over; SB3's default: one per decision."""
    for per_stored in (False, True):
        env = MoPAWrapper(WallPointEnv(horizon=60), dq_mp=1.0, omega=0.5, range=0.2, time_limit=0.2)
        model = _Recording("MlpPolicy", env, reuse=5, learning_starts=30, batch_size=16, seed=0, device="cpu",
                           policy_kwargs={"net_arch": [16, 16]}, update_per_stored=per_stored)
        model.record = []
        model.learn(80)
        stored, updates = np.array(model.record).T
        assert len(stored) == 80 - 30 and updates[0] == 1  # one call per decision after the warm-up
        if per_stored:  # every call updates once per transition stored since the previous call
            assert np.array_equal(np.diff(updates), np.diff(stored)) and np.diff(stored).max() > 1
        else:
            assert np.all(np.diff(updates) == 1)


def test_timeouts_stored_as_done_like_mopa_rl(one_torch_thread):
    """``timeouts_as_done``: a transition ending at the horizon has no bootstrap (MoPA-RL), also
    the reused sub-segments ending there; SB3's default bootstraps it."""
    for as_done in (False, True):
        env = MoPAWrapper(WallPointEnv(horizon=25), dq_mp=1.0, omega=0.5, range=0.2, time_limit=0.2)
        model = MoPASAC("MlpPolicy", env, reuse=5, learning_starts=1000, batch_size=16, seed=0, device="cpu",
                        policy_kwargs={"net_arch": [16]}, timeouts_as_done=as_done)
        model.learn(40)
        rb = model.replay_buffer
        n = rb.pos
        timeouts = rb.timeouts[:n, 0] if not as_done else rb.dones[:n, 0]
        assert timeouts.sum() >= 1  # at least one episode reached the horizon
        sampled = rb._get_samples(np.arange(n)).dones.numpy()[:, 0]
        assert sampled.sum() == (rb.dones[:n, 0].sum() if as_done else 0)  # WallPointEnv never terminates
    buf = _buffer(0.9, reuse=50)
    amap = ActionMap(0.05, 1.0, 0.5)
    qpos = np.array([[0.05 * i, 0.0] for i in range(7)])
    traj = {"qpos": qpos, "observations": [np.full(4, i, np.float32) for i in range(7)], "rewards": np.ones(6),
            "terminated": False, "truncated": True, "extra_action": np.zeros(0), "action_map": amap}
    assert not any(done for *_, done, _ in buf.reuse_transitions(traj))
    buf.handle_timeout_termination = False
    out = buf.reuse_transitions(traj)
    assert out and all(done == (int(nobs[0]) == 6) for _, nobs, _, _, done, _ in out)


def test_warmup_counts_stored_transitions_like_mopa_rl(one_torch_thread):
    """``warmup_stored``: uniformly random actions and no updates until that many transitions
    (reused sub-segments included) are stored; updates start right after."""
    env = MoPAWrapper(WallPointEnv(horizon=60), dq_mp=1.0, omega=0.5, range=0.2, time_limit=0.2)
    model = _Recording("MlpPolicy", env, reuse=5, learning_starts=0, batch_size=16, seed=0, device="cpu",
                       policy_kwargs={"net_arch": [16]}, warmup_stored=60, update_per_stored=True)
    model.record = []
    model.learn(60)
    stored, updates = np.array(model.record).T
    warm = stored < 60
    assert warm.any() and (~warm).any()
    assert np.all(updates[warm] == 0) and updates[~warm][0] == 1 and updates[-1] > 1
    for bad in (-1, 2.5, True):
        with pytest.raises(ValueError, match="warmup_stored"):
            MoPASAC("MlpPolicy", env, warmup_stored=bad, device="cpu")


# ---------------------------------------------------------------------------------------- exploration
def _coverage(env, n_steps: int, seed: int, ee_from_obs) -> int:
    """Distinct 2 cm end-effector cells visited (every low-level step) by uniform random actions."""
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    cells, steps = set(), 0
    while steps < n_steps:
        obs, _, term, trunc, info = env.step(rng.uniform(-1, 1, env.action_space.shape))
        traj = info.get("mopa_trajectory")
        visited = traj["observations"][1:] if traj is not None else [obs]
        for o in visited:
            cells.add(tuple(np.floor(ee_from_obs(o) / 0.02).astype(int)))
        steps += int(info.get("mopa_k", 1))
        if term or trunc:
            env.reset()
    return len(cells)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_planner_increases_exploration_coverage_toy(seed):
    """1,000 low-level steps of random actions: the planner reaches about 1.4x the cells of plain
    stepping (1.40-1.47x on seeds 0-4; at 300 steps the ratio still swings between 1.2x and 2x)."""
    n = 1000
    plain = _coverage(WallPointEnv(horizon=10_000), n, seed, lambda o: o[:2])
    mopa = _coverage(MoPAWrapper(WallPointEnv(horizon=10_000), dq_mp=1.0, omega=0.5, range=0.2), n, seed,
                     lambda o: o[:2])
    assert mopa > 1.3 * plain, (mopa, plain)


# ---------------------------------------------------------------------------------------- Push2D
@pytest.fixture(scope="module")
def push2d():
    import lfd_envs  # noqa: F401  (registers the ids)

    env = gym.make("Push2DObstacle-v0")
    env.reset(seed=0)
    yield env
    env.close()


def test_planner_on_push2d_scene(push2d):
    base = push2d.unwrapped
    push2d.reset(seed=0)
    planner = OMPLPlanner.from_env(push2d, range=0.2, time_limit=2.0)
    q0 = base.arm_qpos()
    goal = np.array([-1.313, 0.987, -0.374, -0.511])  # reachable, but not along a straight line
    assert base.is_valid(q0) and base.is_valid(goal)
    assert planner.interpolate(q0, goal) is None
    res = planner.plan(q0, goal)
    assert res.status == "planner", res
    np.testing.assert_allclose(res.path[-1], goal)
    _check_path_valid(base.is_valid, q0, res.path, planner.check_resolution)
    out = base.execute_path(np.vstack([q0, res.path]))  # the env accepts the path as is
    assert out.steps == len(res.path)
    planner.close()


def test_scene_snapshot_check_agrees_with_is_valid(push2d):
    """``validity_checker()`` answers as ``is_valid`` for the scene at the snapshot, and the
    planner checks a query's configurations with it."""
    base = push2d.unwrapped
    push2d.reset(seed=2)
    rng = np.random.default_rng(0)
    qs = rng.uniform(base.joint_limits[:, 0], base.joint_limits[:, 1], (300, 4))
    check = base.validity_checker()
    got = [check(q) for q in qs]
    assert got == [base.is_valid(q) for q in qs] and 0 < sum(got) < len(got)
    calls = []
    base.validity_checker = lambda: (calls.append(1), check)[1]  # instance attribute: seen by the planner
    planner = OMPLPlanner.from_env(push2d, range=0.2)
    planner.plan(base.arm_qpos(), np.array([-1.313, 0.987, -0.374, -0.511]))
    assert calls == [1]  # one snapshot per query
    del base.validity_checker
    planner.close()


def test_mopa_wrapper_on_push2d_info_and_validity(push2d):
    from lfd_agents.mopa import make_mopa_env

    env = make_mopa_env(push2d.unwrapped, time_limit=0.3)
    env.reset(seed=3)
    rng = np.random.default_rng(3)
    modes = set()
    for _ in range(12):
        q0 = env.arm_qpos()
        _, r, term, trunc, info = env.step(rng.uniform(-1, 1, 4))
        modes.add(info["mopa_mode"])
        assert info["mopa_k"] >= 1 and np.isfinite(r)
        if info["mopa_mode"] in ("interpolation", "planner"):
            path = info["mopa_path"]
            assert len(path) == info["mopa_k"]
            assert np.abs(np.diff(np.vstack([q0, path]), axis=0)).max() <= 0.1 + 1e-9
            assert all(env.unwrapped.is_valid(q) for q in path)
        if term or trunc:
            env.reset()
    assert modes & {"interpolation", "planner"}


def test_planner_increases_exploration_coverage_push2d(push2d):
    """Random actions through MoPA visit far more fingertip cells in the same low-level steps."""
    from lfd_agents.mopa import make_mopa_env

    n, tip = 400, (lambda o: o[16:18])
    plain = _coverage(push2d, n, 0, tip)
    mopa = _coverage(make_mopa_env(push2d.unwrapped, time_limit=0.2), n, 0, tip)
    assert mopa > 1.3 * plain, (mopa, plain)  # measured ≈ 1.7×


def test_benchmark_adapter_counts_low_level_steps_and_acts_on_plain_env(push2d, one_torch_thread):
    agent = MoPASAC.for_benchmark(gym.make("Push2DObstacle-v0"), seed=0, learning_starts=10_000,
                                  wrapper_kwargs={"time_limit": 0.2})
    from stable_baselines3.common.callbacks import BaseCallback

    class CountDecisions(BaseCallback):
        def _on_step(self) -> bool:
            self.n = getattr(self, "n", 0) + 1
            return True

    counter = CountDecisions()
    agent.learn(60, callback=counter)
    assert 60 <= agent.train_env.low_level_steps < 60 + 400  # stops after the action crossing the budget
    assert 1 <= counter.n <= agent.train_env.low_level_steps  # a user callback sees every decision
    env = gym.make("Push2DObstacle-v0")
    agent.bind(env)
    obs, _ = env.reset(seed=1)
    agent.reset()
    for _ in range(30):
        action, _ = agent.predict(obs)
        assert env.action_space.contains(action)
        obs, _, term, trunc, _ = env.step(action)
        if term or trunc:
            break
