"""SawyerPushObstacle-v0: push a cube through a tunnel to a goal (MoPA-RL ``SawyerPushObstacle``).

Scene (MoPA-RL ``sawyer_push_obstacle.xml`` in world coordinates, robot base at (0, 0, 0.95)):
a table (top at z = 0.82, centre (1.05, 0)) carries a four-walled tunnel, open at both ends
along x: interior x ∈ [0.78, 1.18], y ∈ [−0.17, 0.17], z ∈ [0.83, 1.22]. A 6 cm cube
(density 300, friction 0.95) starts inside at (0.92, 0, 0.86); the goal lies at
(1.04, 0) + N(0, 0.02) per axis (clipped to ±0.04; drawn per variant), also inside, so the arm
must reach in through an opening. The arm starts stretched above the tunnel (MoPA-RL's start
pose + N(0, 0.02) rad). Control and common observation: :mod:`lfd_envs.mujoco.sawyer`;
the Rethink gripper's fingers are held closed and are not part of the action (7-dim).

Observation (47 = 32 common + 15): goal position (3), cube position (3), cube quaternion
(4, w x y z), grip site − cube (3), cube − goal (xy, 2).

Reward (thesis eq. B.2): ``0.1·(1 − tanh 5 d_ec)`` if ``d_ec ≤ 0.1`` (d_ec = ‖grip site − cube‖)
+ ``0.3·(1 − tanh 5 d_cg)`` if ``d_cg ≤ 0.1`` (d_cg = xy distance cube–goal) + 150 on success.
Success: ``d_cg < 0.05``; the episode then terminates. Horizon 250.
Performance p = −max(d_cg − 0.05, 0), p_opt = 0 (p̂ = 1 at success).

Planning: contacts of the cube with the table/tunnel never invalidate a configuration
(MoPA-RL's ignored pairs; they do not depend on the arm anyway); the arm touching the cube does.
Goal-conditioned variant: achieved goal = cube position, desired goal = goal position (3 each);
``compute_reward`` reproduces the step reward with ``info["reach_reward"]``.
"""

from __future__ import annotations

import functools
from typing import ClassVar

import numpy as np

from lfd_envs.mujoco import sawyer_models as sm
from lfd_envs.mujoco.sawyer import SawyerObstacleEnv, lookat_camera

SUCCESS_DISTANCE = 0.05
CUBE_HALF = 0.03
CUBE_START = (0.92, 0.0, 0.86)
GOAL_NOMINAL = (1.04, 0.0, 0.86)
GOAL_NOISE, GOAL_NOISE_CLIP = 0.02, 0.04
#: tunnel: centre x, inner half-width (y), floor top z, ceiling bottom z, half-length (x)
TUNNEL = {"x": 0.98, "half_width": 0.17, "floor": 0.83, "ceiling": 1.22, "half_length": 0.20}
INIT_QPOS = (0.000457, -0.114, 0.0321, -0.00712, 0.0303, -0.0302, -0.00994)


@functools.lru_cache(maxsize=None)
def scene_xml(robot_meshes: bool = False) -> str:
    """MJCF of the push scene."""
    t = TUNNEL
    hl, hw, wall = t["half_length"], t["half_width"], 0.01
    zc = (t["floor"] + t["ceiling"]) / 2
    hz = (t["ceiling"] - t["floor"]) / 2
    tunnel = "".join([
        sm.box("tunnel_left", (0, hw + wall, zc), (hl, wall, hz + wall)),
        sm.box("tunnel_right", (0, -hw - wall, zc), (hl, wall, hz + wall)),
        sm.box("tunnel_roof", (0, 0, t["ceiling"] + wall), (hl, hw + 2 * wall, wall)),
        sm.box("tunnel_floor", (0, 0, t["floor"] - 0.005), (hl, hw + 2 * wall, 0.005)),
    ])
    scene = (
        sm.work_table((1.05, 0.0, 0.80), (0.4, 0.4, 0.02))
        + f'<body name="tunnel" pos="{t["x"]} 0 0">{tunnel}</body>'
        + f'<body name="cube" pos="{sm.fmt(CUBE_START)}"><freejoint name="cube_joint"/>'
        f'<geom name="cube" type="box" size="{CUBE_HALF} {CUBE_HALF} {CUBE_HALF}" density="300" '
        'friction="0.95 0.3 0.1" condim="4" rgba="0.85 0.2 0.2 1"/></body>'
        + f'<body name="goal" mocap="true" pos="{sm.fmt(GOAL_NOMINAL)}">'
        '<geom name="goal" type="sphere" size="0.025" contype="0" conaffinity="0" rgba="0.2 0.85 0.2 0.5"/></body>'
    )
    camera = lookat_camera("task_cam", (0.15, 0.75, 1.55), (0.95, 0.0, 0.92), fovy=50)
    return sm.compose_scene_xml("sawyer_push_obstacle", scene, camera, robot_meshes=robot_meshes)


class SawyerPushObstacleEnv(SawyerObstacleEnv):
    """Sawyer pushes a cube inside a tunnel to a goal (module docstring has all details).

    Constructor arguments: see :class:`~lfd_envs.mujoco.sawyer.SawyerObstacleEnv` (state
    observation: 47 values).
    """

    task_name = "SawyerPushObstacle"
    scene_builder = staticmethod(scene_xml)
    reward_info_keys: ClassVar[tuple[str, ...]] = ("reach_reward",)
    ignored_contact_pairs: ClassVar[list[tuple[str, str]]] = [("cube", "table"), ("cube", "tunnel")]
    init_qpos = INIT_QPOS
    task_obs_dim = 15

    def _init_task(self) -> None:
        m = self.model
        self._cube_body = m.body("cube").id
        self._cube_qadr = int(m.jnt_qposadr[m.joint("cube_joint").id])
        self._goal = np.array(GOAL_NOMINAL)

    # ------------------------------------------------------------------ variant
    def _setup_variant(self, rng: np.random.Generator) -> None:
        offset = np.clip(rng.normal(0.0, GOAL_NOISE, 2), -GOAL_NOISE_CLIP, GOAL_NOISE_CLIP)
        self._reset_robot()
        self._set_goal(np.array([GOAL_NOMINAL[0] + offset[0], GOAL_NOMINAL[1] + offset[1], GOAL_NOMINAL[2]]))
        self._forward()

    def _set_goal(self, goal: np.ndarray) -> None:
        self._goal = np.asarray(goal, np.float64).copy()
        self.data.mocap_pos[0] = self._goal

    # ------------------------------------------------------------------ quantities
    def cube_pos(self) -> np.ndarray:
        """Cube centre (world)."""
        return self.data.qpos[self._cube_qadr:self._cube_qadr + 3].copy()

    @property
    def goal(self) -> np.ndarray:
        """Goal position of the episode."""
        return self._goal.copy()

    def _goal_distance(self) -> float:
        return float(np.linalg.norm(self.cube_pos()[:2] - self._goal[:2]))

    def _task_obs(self) -> np.ndarray:
        cube = self.cube_pos()
        quat = self.data.qpos[self._cube_qadr + 3:self._cube_qadr + 7]
        return np.concatenate([self._goal, cube, quat, self.eef_pos() - cube, (cube - self._goal)[:2]])

    def _performance(self) -> float:
        return -max(self._goal_distance() - SUCCESS_DISTANCE, 0.0)

    def _is_success(self) -> bool:
        return self._goal_distance() < SUCCESS_DISTANCE

    # ------------------------------------------------------------------ reward
    def _reach_reward(self) -> float:
        d = float(np.linalg.norm(self.eef_pos() - self.cube_pos()))
        return 0.1 * (1.0 - np.tanh(5.0 * d)) if d <= 0.1 else 0.0

    def _reward_info(self) -> dict[str, float]:
        return {"reach_reward": self._reach_reward()}

    def _goal_reward(self, achieved: np.ndarray, desired: np.ndarray, extras: dict[str, np.ndarray]) -> np.ndarray:
        d = np.linalg.norm(achieved[:, :2] - desired[:, :2], axis=-1)
        push = np.where(d <= 0.1, 0.3 * (1.0 - np.tanh(5.0 * d)), 0.0)
        return extras["reach_reward"] + push + 150.0 * (d < SUCCESS_DISTANCE)

    def _goal_success(self, achieved: np.ndarray, desired: np.ndarray) -> np.ndarray:
        return np.linalg.norm(achieved[:, :2] - desired[:, :2], axis=-1) < SUCCESS_DISTANCE

    def _achieved_goal(self) -> np.ndarray:
        return self.cube_pos()

    def _desired_goal(self) -> np.ndarray:
        return self.goal

    # ------------------------------------------------------------------ state
    def _get_task_state(self) -> dict[str, np.ndarray]:
        return {"goal": self._goal.copy()}

    def _set_task_state(self, state: dict[str, np.ndarray]) -> None:
        if "goal" not in state or np.shape(state["goal"]) != (3,):
            raise ValueError("state needs 'sim/task/goal' of shape (3,); pass a dict from get_state()")
        self._set_goal(state["goal"])


__all__ = ["SawyerPushObstacleEnv", "scene_xml"]
