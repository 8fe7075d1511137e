"""Push2DObstacle-v0: a planar 4-link arm pushes a box to a goal among 7 obstacles (MoPA-RL "PusherObstacle").

Scene (MoPA-RL ``pusher_obstacle.xml``): the arm's base is at the origin; four links
of 0.1 m (capsules, radius 0.01) rotate about z; ``joint0`` is unlimited (bounds ±2π for
planning and set-points), joints 1-3 are limited to ±3 rad. A U-shaped gripper (three
capsules) sits 0.11 m beyond the last joint, opening along the last link; the ``fingertip``
site is at its cross bar. The 2 cm box moves on two slide joints (damping 1, Coulomb
friction ``frictionloss`` 2 N, standing in for sliding on a table, so it does not coast far);
seven fixed boxes are obstacles (half-height 0.05 m). Everything lies in the plane z ≈ 0.02.

Variants: box and goal xy are drawn in x ∈ [-0.35, -0.24], y ∈ [0.13, 0.20] with
‖box − goal‖ > 0.1 and goal_x ≤ box_x (so the box is pushed in -x); the arm starts at
q = 0 plus U(-0.02, 0.02) per joint (thesis B.1.1), drawn from the env's seeded RNG.

Control: joint-position deltas, Δq_step = 0.1 rad (thesis table B.1), position servos
kp = 1000, kv = 65 on joints with armature 1 and damping 1; one env step = 20 physics steps of
0.01 s (implicit-fast integrator). MoPA-RL used velocity actuators, a PID loop and 1 s per
step; servos reach the set-point within the step here, which makes joint paths exact.

Observation (20, float32): cos q (4), sin q (4), box xy (2), joint velocities (4),
box velocity (2), fingertip xy (2), goal xy (2).

Reward (thesis eq. B.1, planar distances): ``0.1·(1 − tanh 5 d_f)`` if ``d_f ≤ 0.1``
(d_f = ‖fingertip − box‖) + ``0.3·(1 − tanh 5 d_g)`` if ``d_g ≤ 0.1`` (d_g = ‖box − goal‖)
+ 150 on success. Success: ``d_g ≤ 0.05``; the episode then terminates. Horizon 400.
Performance p = −max(d_g − 0.05, 0), p_opt = 0, so p̂ = 1 exactly at success.

Planning: ``is_valid`` counts contacts penetrating ≥ 2 mm; no pairs are ignored (the arm
touching the box counts as a collision, so plan to poses that do not touch it).
Goal-conditioned variant (``goal_conditioned=True``): achieved goal = box xy, desired goal =
goal xy; the reward is B.1 **without the reach term** (``0.3·(1 − tanh 5 d_g)`` if
``d_g ≤ 0.1``, +150 on success), because a term that does not depend on the goal cannot be
recomputed by HER from goals alone (SB3's ``HerReplayBuffer`` passes empty infos by default).
``info["reach_reward"]`` still reports the reach term.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from gymnasium import spaces

from lfd_envs.mujoco.base import MujocoEnv
from lfd_envs.mujoco.planning import PlanningMixin

BOX_X_RANGE = (-0.35, -0.24)
BOX_Y_RANGE = (0.13, 0.20)
SUCCESS_DISTANCE = 0.05
ARM_JOINTS = ("joint0", "joint1", "joint2", "joint3")
#: (name, centre xy, half-size xy) of the obstacles (MoPA-RL pusher_obstacle.xml)
OBSTACLES = (
    ("obstacle1", (0.08, 0.13), (0.16, 0.06)),
    ("obstacle2", (0.17, -0.11), (0.02, 0.03)),
    ("obstacle3", (-0.16, -0.35), (0.08, 0.08)),
    ("obstacle4", (-0.33, -0.10), (0.06, 0.12)),
    ("obstacle5", (-0.30, 0.04), (0.09, 0.02)),
    ("obstacle6", (0.06, -0.22), (0.02, 0.01)),
    ("obstacle7", (-0.12, -0.12), (0.01, 0.01)),
)


def _scene_xml() -> str:
    obstacles = "\n".join(
        f'    <geom name="{n}" class="obstacle" pos="{c[0]} {c[1]} 0.01" size="{h[0]} {h[1]} 0.05"/>'
        for n, c, h in OBSTACLES)
    link = ('<geom name="link{i}" type="capsule" fromto="0 0 0 0.1 0 0" size="0.01" rgba="0.0 0.4 0.6 1"/>')
    return f"""
<mujoco model="push2d_obstacle">
  <compiler angle="radian"/>
  <option timestep="0.01" integrator="implicitfast"/>
  <visual><global offwidth="256" offheight="256"/><quality shadowsize="0"/></visual>
  <default>
    <joint type="hinge" axis="0 0 1" armature="1" damping="1" limited="true" range="-3.0 3.0"/>
    <geom contype="1" conaffinity="1" friction="1 0.005 0.0001" condim="3"/>
    <default class="obstacle"><geom type="box" contype="1" conaffinity="0" rgba="0.85 0.85 0.9 1"/></default>
  </default>
  <worldbody>
    <light pos="0 0 2" dir="0 0 -1" directional="true"/>
    <geom name="floor" type="plane" size="0.6 0.6 0.01" pos="0 0 -0.04" rgba="0.35 0.35 0.38 1" contype="0" conaffinity="0"/>
    <camera name="topdown" pos="0.03 -0.1 1.0" xyaxes="1 0 0 0 1 0" fovy="48"/>
{obstacles}
    <geom name="root" type="cylinder" pos="0 0 0.02" size="0.011 0.01" contype="0" conaffinity="0" rgba="0.1 0.1 0.1 1"/>
    <body name="body0" pos="0 0 0.02">
      <joint name="joint0" limited="false"/>
      {link.format(i=0)}
      <body name="body1" pos="0.1 0 0">
        <joint name="joint1"/>
        {link.format(i=1)}
        <body name="body2" pos="0.1 0 0">
          <joint name="joint2"/>
          {link.format(i=2)}
          <body name="body3" pos="0.1 0 0">
            <joint name="joint3"/>
            {link.format(i=3)}
            <body name="fingertip" pos="0.11 0 0">
              <site name="fingertip" size="0.005" rgba="1 0 0 1"/>
              <geom name="grip_bar" type="capsule" fromto="0 -0.03 0 0 0.03 0" size="0.01" rgba="0.2 0.2 0.2 1"/>
              <geom name="grip_left" type="capsule" fromto="0 0.03 0 0.03 0.03 0" size="0.01" rgba="0.2 0.2 0.2 1"/>
              <geom name="grip_right" type="capsule" fromto="0 -0.03 0 0.03 -0.03 0" size="0.01" rgba="0.2 0.2 0.2 1"/>
            </body>
          </body>
        </body>
      </body>
    </body>
    <body name="box" pos="0 0 0.02">
      <joint name="box_x" type="slide" axis="1 0 0" range="-0.4 0.4" damping="1" frictionloss="2" armature="0"/>
      <joint name="box_y" type="slide" axis="0 1 0" range="-0.4 0.4" damping="1" frictionloss="2" armature="0"/>
      <geom name="box" type="box" size="0.01 0.01 0.01" mass="1" rgba="0.9 0.4 0.1 1"/>
    </body>
    <body name="target" mocap="true" pos="-0.3 0.16 0.005">
      <geom name="target" type="cylinder" size="0.02 0.003" contype="0" conaffinity="0" rgba="0.2 0.8 0.2 0.6"/>
    </body>
  </worldbody>
  <actuator>
    <position name="a0" joint="joint0" kp="1000" kv="65"/>
    <position name="a1" joint="joint1" kp="1000" kv="65"/>
    <position name="a2" joint="joint2" kp="1000" kv="65"/>
    <position name="a3" joint="joint3" kp="1000" kv="65"/>
  </actuator>
</mujoco>
"""


class Push2DObstacleEnv(PlanningMixin, MujocoEnv):
    """2D Push among obstacles (module docstring has scene, control, reward and planning details).

    Args:
        obs_mode: ``"state"`` (20-dim), ``"image"`` (uint8 top-down view), ``"state+image"``.
        image_size: image side or ``(height, width)``; default 84.
        render_mode: ``"rgb_array"`` or None.
        horizon: low-level steps per episode (400).
        goal_conditioned: GoalEnv Dict observations for HER (``obs_mode="state"`` only).
        render_size: ``(height, width)`` (or an int) of ``render()`` frames (default 256×256).
    """

    task_name = "Push2DObstacle"
    camera: ClassVar[str] = "topdown"
    goal_dim: ClassVar[int] = 2
    ignored_contact_pairs: ClassVar[list[tuple[str, str]]] = []

    def __init__(self, obs_mode: str = "state", image_size: int | tuple[int, int] = 84,
                 render_mode: str | None = None, horizon: int = 400, goal_conditioned: bool = False,
                 render_size: int | tuple[int, int] | None = None) -> None:
        super().__init__(obs_mode=obs_mode, image_size=image_size, render_mode=render_mode, horizon=horizon,
                         render_size=render_size)
        self._init_mujoco(_scene_xml(), arm_joint_names=ARM_JOINTS, dq_step=0.1, frame_skip=20,
                          init_arm_qpos=np.zeros(4), init_noise="uniform", init_noise_scale=0.02,
                          goal_conditioned=goal_conditioned)
        m = self.model
        self._box_qadr = m.jnt_qposadr[[m.joint("box_x").id, m.joint("box_y").id]]
        self._box_dofadr = m.jnt_dofadr[[m.joint("box_x").id, m.joint("box_y").id]]
        self._fingertip = m.site("fingertip").id
        self._goal = np.zeros(2)
        self.state_space = spaces.Box(-np.inf, np.inf, (20,), np.float32)
        self._finish_init()

    # ------------------------------------------------------------------ variant
    def _setup_variant(self, rng: np.random.Generator) -> None:
        while True:
            box = rng.uniform((BOX_X_RANGE[0], BOX_Y_RANGE[0]), (BOX_X_RANGE[1], BOX_Y_RANGE[1]))
            goal = rng.uniform((BOX_X_RANGE[0], BOX_Y_RANGE[0]), (BOX_X_RANGE[1], BOX_Y_RANGE[1]))
            if np.linalg.norm(box - goal) > 0.1 and goal[0] <= box[0]:
                break
        self._reset_sim()
        self.data.qpos[self._box_qadr] = box
        self._set_goal(goal)
        self._forward()

    def _set_goal(self, goal: np.ndarray) -> None:
        self._goal = np.asarray(goal, np.float64).copy()
        self.data.mocap_pos[0, :2] = self._goal

    # ------------------------------------------------------------------ quantities
    def box_xy(self) -> np.ndarray:
        """Box centre (x, y)."""
        return self.data.qpos[self._box_qadr].copy()

    def fingertip_xy(self) -> np.ndarray:
        """Fingertip site (x, y)."""
        return self.data.site_xpos[self._fingertip, :2].copy()

    @property
    def goal(self) -> np.ndarray:
        """Goal (x, y) of the episode."""
        return self._goal.copy()

    def _goal_distance(self) -> float:
        return float(np.linalg.norm(self.box_xy() - self._goal))

    def _state_obs(self) -> np.ndarray:
        d = self.data
        q = d.qpos[self._arm_qadr]
        return np.concatenate([np.cos(q), np.sin(q), d.qpos[self._box_qadr], d.qvel[self._arm_dofadr],
                               d.qvel[self._box_dofadr], self.fingertip_xy(), self._goal]).astype(np.float32)

    def _performance(self) -> float:
        return -max(self._goal_distance() - SUCCESS_DISTANCE, 0.0)

    def _is_success(self) -> bool:
        return self._goal_distance() <= SUCCESS_DISTANCE

    # ------------------------------------------------------------------ reward
    def _reach_reward(self) -> float:
        d_f = float(np.linalg.norm(self.fingertip_xy() - self.box_xy()))
        return 0.1 * (1.0 - np.tanh(5.0 * d_f)) if d_f <= 0.1 else 0.0

    def _reward_info(self) -> dict[str, float]:
        return {"reach_reward": self._reach_reward()}

    def _goal_reward(self, achieved: np.ndarray, desired: np.ndarray, extras: dict[str, np.ndarray]) -> np.ndarray:
        """Goal terms of B.1: push shaping within 0.1 m and the success bonus."""
        d_g = np.linalg.norm(achieved - desired, axis=-1)
        push = np.where(d_g <= 0.1, 0.3 * (1.0 - np.tanh(5.0 * d_g)), 0.0)
        return push + 150.0 * (d_g <= SUCCESS_DISTANCE)

    def _goal_success(self, achieved: np.ndarray, desired: np.ndarray) -> np.ndarray:
        return np.linalg.norm(achieved - desired, axis=-1) <= SUCCESS_DISTANCE

    def _task_reward(self) -> float:
        return self._reach_reward() + float(self._goal_reward(self.box_xy()[None], self._goal[None], {})[0])

    def _achieved_goal(self) -> np.ndarray:
        return self.box_xy()

    def _desired_goal(self) -> np.ndarray:
        return self.goal

    # ------------------------------------------------------------------ state
    def _get_task_state(self) -> dict[str, np.ndarray]:
        return {"goal": self._goal.copy()}

    def _set_task_state(self, state: dict[str, np.ndarray]) -> None:
        if "goal" not in state or np.shape(state["goal"]) != (2,):
            raise ValueError("state needs 'sim/task/goal' of shape (2,); pass a dict from get_state()")
        self._set_goal(state["goal"])


__all__ = ["Push2DObstacleEnv"]
