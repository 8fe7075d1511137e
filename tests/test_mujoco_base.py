"""MuJoCo env base and planning interface, on a tiny 2-link arm in a vertical plane (with gravity)."""

import mujoco
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env

from lfd_envs.mujoco.base import MujocoEnv
from lfd_envs.mujoco.planning import PlanningMixin, densify_path, interpolate, plan_path

pytestmark = pytest.mark.filterwarnings("ignore:.*(infinity|Box observation space).*")

TOY_XML = """
<mujoco>
  <compiler angle="radian"/>
  <option timestep="0.002" integrator="implicitfast"/>
  <default><joint type="hinge" axis="0 1 0" damping="5" armature="0.05" limited="true" range="-2.5 2.5"/></default>
  <worldbody>
    <camera name="side" pos="0 -1.5 0.3" xyaxes="1 0 0 0 0 1"/>
    <light pos="0 -1 2" dir="0 1 -1"/>
    <geom name="wall" type="box" pos="0.35 0 0.2" size="0.02 0.1 0.3"/>
    <geom name="shelf" type="box" pos="-0.35 0 0" size="0.02 0.1 0.1"/>
    <body name="link1" pos="0 0 0">
      <joint name="j1"/>
      <geom name="g1" type="capsule" fromto="0 0 0 0 0 0.2" size="0.02" mass="1"/>
      <body name="link2" pos="0 0 0.2">
        <joint name="j2"/>
        <geom name="g2" type="capsule" fromto="0 0 0 0 0 0.2" size="0.02" mass="1"/>
      </body>
    </body>
    <body name="load" pos="0 0 0.6">
      <freejoint/>
      <geom name="load" type="box" size="0.03 0.03 0.03" mass="0.1"/>
    </body>
  </worldbody>
  <actuator>
    <position joint="j1" kp="1" ctrlrange="-3 3"/>
    <position joint="j2" kp="1" ctrlrange="-3 3"/>
  </actuator>
</mujoco>
"""


class ToyArmEnv(PlanningMixin, MujocoEnv):
    """Two links pointing up; a tall wall to the right (x = 0.35), a low shelf to the left
    (contacts of link 2 with it are ignored) and a free load 0.6 m up (attachable to link 2)."""

    task_name = "ToyArm"
    camera = "side"
    ignored_contact_pairs = [("shelf", "link2")]

    def __init__(self, obs_mode="state", image_size=84, horizon=30, gravity_compensation="gravcomp",
                 attach_load=False):
        self._init_contract(obs_mode=obs_mode, image_size=image_size, render_mode=None, horizon=horizon)
        self._init_mujoco(TOY_XML, arm_joint_names=["j1", "j2"], dq_step=0.05, frame_skip=50,
                          servo_kp=[1000.0, 500.0], servo_kv=[20.0, 6.0],
                          gravity_compensation=gravity_compensation, init_arm_qpos=[0.0, 0.0])
        self.attach_load = attach_load
        self.state_space = spaces.Box(-np.inf, np.inf, (4,), np.float32)
        self._finish_init()

    def planning_attached_bodies(self):
        return [("load", "link2")] if self.attach_load else []

    def _setup_variant(self, rng):
        self._reset_sim()
        self._forward()

    def _state_obs(self):
        return np.concatenate([self.arm_qpos(), self.arm_qvel()]).astype(np.float32)

    def _task_reward(self):
        return float(-abs(self.arm_qpos()[0] - 0.5))

    def _performance(self):
        return self._task_reward()


class StrictToyArmEnv(ToyArmEnv):
    ignored_contact_pairs = []


def test_check_env_and_image_obs():
    check_env(ToyArmEnv(), skip_render_check=True)
    env = ToyArmEnv(obs_mode="image")
    obs, _ = env.reset(seed=0)
    assert obs.shape == (84, 84, 3) and obs.dtype == np.uint8 and obs.std() > 0
    obs, *_ = env.step(np.zeros(2))
    assert obs.shape == (84, 84, 3)
    env.close()


def test_joint_delta_servo_control_and_limits():
    env = ToyArmEnv()
    env.reset(seed=0)
    q0 = env.arm_qpos()
    env.step(np.array([1.0, -0.5]))
    assert np.allclose(env.data.ctrl[:2], q0 + [0.05, -0.025])  # set-point = measured q + a * dq_step
    assert np.allclose(env.arm_qpos() - q0, [0.05, -0.025], atol=0.008)
    env.step(np.array([7.0, 0.0]))  # clipped to a = 1
    assert np.allclose(env.arm_qpos()[0] - q0[0], 0.10, atol=0.015)
    for _ in range(60):
        env.step(np.array([-1.0, 0.0]))
    assert env.data.ctrl[0] >= env.joint_limits[0, 0] - 1e-9  # set-points clipped to the limits


@pytest.mark.parametrize("mode", ["gravcomp", "bias"])
def test_gravity_compensation_holds_a_tilted_arm(mode):
    drift = {}
    for m in ("none", mode):
        env = ToyArmEnv(gravity_compensation=m)
        env.reset(seed=0)
        env.unwrapped.data.qpos[:2] = [-0.8, -0.3]
        env.unwrapped.data.ctrl[:2] = [-0.8, -0.3]
        for _ in range(10):
            env.step(np.zeros(2))
        drift[m] = np.abs(env.arm_qpos() - [-0.8, -0.3]).max()
    assert drift[mode] < 0.01 < drift["none"]


def test_start_pose_noise_is_seeded():
    env = ToyArmEnv()
    a = env.reset(seed=3)[0]
    b = env.reset(seed=3)[0]
    c = env.reset(seed=4)[0]
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert 0 < np.abs(a[:2]).max() < 0.1


def test_is_valid_filters_and_leaves_live_data_untouched():
    env = ToyArmEnv()
    env.reset(seed=0)
    for _ in range(3):
        env.step(np.array([0.3, -0.2]))
    before = {k: np.copy(getattr(env.data, k)) for k in ("qpos", "qvel", "act", "ctrl", "qacc", "xpos", "contact")
              if k != "contact"}
    t, ncon = env.data.time, env.data.ncon
    assert env.is_valid(env.arm_qpos())
    assert not env.is_valid([1.0, 0.0])  # link 2's end into the wall
    assert "wall" in env.colliding_pairs([1.0, 0.0])[0][:2]
    assert env.is_valid([-1.2, -0.37])  # link2 through the shelf: an ignored pair
    strict = StrictToyArmEnv()
    strict.reset(seed=0)
    assert not strict.is_valid([-1.2, -0.37]) and strict.is_valid([0.0, 0.0])
    for k, v in before.items():
        assert np.array_equal(getattr(env.data, k), v), k
    assert env.data.time == t and env.data.ncon == ncon
    with pytest.raises(ValueError, match=r"shape \(2,\)"):
        env.is_valid([0.0, 0.0, 0.0])


def test_attached_body_moves_with_the_arm_in_is_valid():
    free, carried = ToyArmEnv(), ToyArmEnv(attach_load=True)
    for env in (free, carried):
        env.reset(seed=0)
    q = np.array([0.65, 0.0])  # the links are clear of the wall, the load 0.6 m out is not
    assert free.is_valid(q) and not carried.is_valid(q)
    assert any("load" in (a, b) for a, b, _ in carried.colliding_pairs(q))
    assert carried.is_valid(np.zeros(2))
    assert not carried.is_valid([1.2, 0.0]) and not free.is_valid([1.2, 0.0])


def test_execute_path_reaches_end_and_reports():
    env = ToyArmEnv(horizon=200)
    env.reset(seed=0)
    goal = np.array([0.6, -0.4])
    path = plan_path(env, goal)
    assert path is not None and np.abs(np.diff(path, axis=0)).max() <= env.dq_step + 1e-9
    res = env.execute_path(path, discount=0.9)
    assert res.steps == len(path) - 1 == len(res.rewards) == len(res.observations)
    assert np.isclose(res.discounted_return, sum(0.9 ** i * r for i, r in enumerate(res.rewards)))
    assert np.allclose(env.data.ctrl[:2], goal, atol=1e-6)  # set-points chained along the path
    assert np.abs(env.arm_qpos() - goal).max() < 0.01


def test_execute_path_stops_at_horizon():
    env = ToyArmEnv(horizon=5)
    env.reset(seed=0)
    res = env.execute_path(interpolate(env.arm_qpos(), [0.8, 0.0], env.dq_step))
    assert res.steps == 5 and res.truncated and not res.terminated


def test_bad_paths_raise_and_env_keeps_working():
    env = ToyArmEnv()
    env.reset(seed=0)
    q = env.arm_qpos()
    state = env.get_state()
    with pytest.raises(ValueError, match="dq_step"):
        env.execute_path([q, q + 0.2])
    with pytest.raises(ValueError, match="farther than dq_step"):
        env.execute_path([q + 0.5, q + 0.5])
    with pytest.raises(ValueError, match="joint limits"):
        env.execute_path([q, [5.0, 0.0]])
    with pytest.raises(ValueError, match="shape"):
        env.execute_path(np.zeros((3, 5)))
    with pytest.raises(ValueError, match="finite"):
        env.execute_path([q, [np.nan, 0.0]])
    with pytest.raises(ValueError, match=r"shape \(2,\)"):
        env.step(np.zeros(3))
    after = env.get_state()
    assert all(np.array_equal(state[k], after[k]) for k in state)
    env.step(np.zeros(2))
    assert env.execute_path(densify_path([q, q + 0.2], env.dq_step)).steps == 4


def test_interpolate_and_densify():
    seg = interpolate([0.0, 0.0], [0.25, -0.1], 0.05)
    assert len(seg) == 6 and np.allclose(seg[-1], [0.25, -0.1])
    path = densify_path(np.array([[0.0, 0.0], [0.1, 0.0], [0.1, 0.33]]), 0.05)
    assert np.abs(np.diff(path, axis=0)).max() <= 0.05 + 1e-12 and np.allclose(path[-1], [0.1, 0.33])


def test_get_set_state_round_trip_is_bitwise():
    env = ToyArmEnv(gravity_compensation="bias")
    env.reset(seed=1)
    rng = np.random.default_rng(0)
    for _ in range(4):
        env.step(rng.uniform(-1, 1, 2))
    state = env.get_state()
    actions = rng.uniform(-1, 1, (5, 2))
    first = [env.step(a)[0] for a in actions]
    env.reset(seed=7)
    env.set_state(state)
    second = [env.step(a)[0] for a in actions]
    assert all(np.array_equal(a, b) for a, b in zip(first, second))
    with pytest.raises(ValueError, match="shape"):
        env.set_state({**state, "sim/qpos": np.zeros(3)})


def test_constructor_errors():
    with pytest.raises(TypeError, match="valid arguments"):
        ToyArmEnv(frame_skips=3)
    with pytest.raises(ValueError, match="gravity_compensation"):
        ToyArmEnv(gravity_compensation="magic")
    model = mujoco.MjModel.from_xml_string(TOY_XML)
    assert model.nu == 2
