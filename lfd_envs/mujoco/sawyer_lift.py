"""SawyerLiftObstacle-v0: grasp a can inside a deep bin and lift it out (MoPA-RL ``SawyerLiftObstacle``).

Scene (MoPA-RL ``sawyer_lift_obstacle.xml``, world coordinates, robot base at (0, 0, 0.95)):
a table (top z = 0.81) carries a bin centred at (0.5, −0.25): floor top at z = 0.82, walls
0.38 m high (tops at z = 1.20), interior 0.38 × 0.38 m. A can (cylinder r = 2.5 cm,
h = 8 cm, density 100, friction 0.95) stands at (0.55, −0.25) on the bin floor. The arm starts
above the far side of the bin (MoPA-RL's start pose + N(0, 0.02) rad), gripper open.

Action (8): 7 joint-position deltas (see :mod:`lfd_envs.mujoco.sawyer`) + gripper. The gripper
set-point integrates the 8th dimension: ``s ← clip(s − a₈ · span)`` over the finger range
(span = 3.2 cm), so ``+1`` closes fully, ``−1`` opens fully and ``0`` keeps the last command
(a closed grip keeps squeezing). Start: open.

Observation (45 = 32 common + 13): can position (3), can quaternion (4, w x y z),
grip site − can (3), target position (3) = (bin centre x, y, 1.25).

Reward (thesis eq. B.3): ``max(r_reach, r_grasp, r_lift) + 150·success`` with
``r_reach = 0.1·(1 − tanh(10·‖grip site − can‖))``, ``r_grasp = 0.35·grasped``,
``r_lift = 0.35·grasped + 0.15·(1 − tanh(15·max(1.25 − z_can, 0)))``; *grasped* = both fingers
touch the can (MoPA-RL's test). Success: grasped and ``z_can ≥ 1.20`` (the can's centre above
the bin walls; MoPA-RL used ``|z − 1.25| < 0.05``); the episode then terminates. Horizon 250.
Performance p = −max(1.20 − z_can, 0), p_opt = 0.

Planning: ignored pairs are can–table, can–bin floor and can–fingers. While the can is
grasped, :meth:`is_valid` carries it rigidly with the gripper (``planning_attached_bodies``),
so the can itself must clear the bin walls.
Goal-conditioned variant: achieved goal = can position, desired goal = target position;
``compute_reward`` uses ``info["reach_reward"]`` and ``info["grasped"]``; ``compute_terminated``
(no contact information) uses the height only.
"""

from __future__ import annotations

import functools
from typing import ClassVar

import mujoco
import numpy as np

from lfd_envs.mujoco import sawyer_models as sm
from lfd_envs.mujoco.sawyer import SawyerObstacleEnv, lookat_camera

BIN_CENTER = (0.5, -0.25)
BIN_FLOOR_Z = 0.82
BIN_WALL_TOP = 1.20
BIN_HALF = 0.2  # wall centre lines at ±0.2; walls 1 cm thick on each side
CAN_RADIUS, CAN_HALF_HEIGHT = 0.025, 0.04
CAN_START = (0.55, -0.25, BIN_FLOOR_Z + CAN_HALF_HEIGHT)
TARGET_Z = 1.25
SUCCESS_Z = 1.20
INIT_QPOS = (-0.0305, -0.7325, 0.03043, 1.16124, 1.87488, 0.0, 0.0)
FINGER_SPAN = sm.FINGER_OPEN - sm.FINGER_CLOSED


@functools.lru_cache(maxsize=None)
def scene_xml(robot_meshes: bool = False) -> str:
    """MJCF of the lift scene."""
    h = (BIN_WALL_TOP - BIN_FLOOR_Z) / 2
    zc = BIN_FLOOR_Z + h
    b = BIN_HALF
    walls = "".join([
        sm.box("bin_wall_py", (0, b, zc), (b + 0.01, 0.01, h)),
        sm.box("bin_wall_ny", (0, -b, zc), (b + 0.01, 0.01, h)),
        sm.box("bin_wall_px", (b, 0, zc), (0.01, b - 0.01, h)),
        sm.box("bin_wall_nx", (-b, 0, zc), (0.01, b - 0.01, h)),
        sm.box("bin_floor", (0, 0, BIN_FLOOR_Z - 0.005), (b, b, 0.005)),
    ])
    scene = (
        sm.work_table((0.66, 0.0, 0.40), (0.4, 0.73, 0.41))
        + f'<body name="bin" pos="{BIN_CENTER[0]} {BIN_CENTER[1]} 0">{walls}</body>'
        + f'<body name="can" pos="{sm.fmt(CAN_START)}"><freejoint name="can_joint"/>'
        f'<geom name="can" type="cylinder" size="{CAN_RADIUS} {CAN_HALF_HEIGHT}" density="100" '
        'friction="0.95 0.3 0.1" condim="4" solimp="0.95 0.99 0.001" rgba="0.8 0.15 0.15 1"/></body>'
        + f'<site name="target" pos="{BIN_CENTER[0]} {BIN_CENTER[1]} {TARGET_Z}" size="0.015" '
        'rgba="0.2 0.85 0.2 0.4"/>'
    )
    camera = lookat_camera("task_cam", (1.55, 0.45, 1.75), (0.55, -0.25, 0.95), fovy=45)
    return sm.compose_scene_xml("sawyer_lift_obstacle", scene, camera, robot_meshes=robot_meshes, impratio=10.0)


class SawyerLiftObstacleEnv(SawyerObstacleEnv):
    """Sawyer grasps a can in a deep bin and lifts it out (module docstring has all details).

    Constructor arguments: see :class:`~lfd_envs.mujoco.sawyer.SawyerObstacleEnv` (state
    observation: 45 values).
    """

    task_name = "SawyerLiftObstacle"
    scene_builder = staticmethod(scene_xml)
    reward_info_keys: ClassVar[tuple[str, ...]] = ("reach_reward", "grasped")
    ignored_contact_pairs: ClassVar[list[tuple[str, str]]] = [
        ("can", "table"), ("can", "bin_floor"),
        *[("can", g) for g in (*sm.LEFT_FINGER_GEOMS, *sm.RIGHT_FINGER_GEOMS)]]
    init_qpos = INIT_QPOS
    task_obs_dim = 13
    gripper_action = True
    finger_hold = sm.FINGER_OPEN

    def _init_task(self) -> None:
        m = self.model
        self._can_qadr = int(m.jnt_qposadr[m.joint("can_joint").id])
        self._can_geom = np.array([m.geom("can").id])
        self._target = np.array([BIN_CENTER[0], BIN_CENTER[1], TARGET_Z])
        self._grasped = False

    # ------------------------------------------------------------------ variant and control
    def _setup_variant(self, rng: np.random.Generator) -> None:
        self._reset_robot()
        self._forward()
        self._refresh()

    def _apply_extra_action(self, extra: np.ndarray) -> None:
        current = float(self.data.ctrl[self._finger_act[0]])
        self._set_fingers(current - float(extra[0]) * FINGER_SPAN)

    def _after_simulate(self) -> None:
        self._refresh()

    def _set_sim_state(self, state: dict[str, np.ndarray]) -> None:
        super()._set_sim_state(state)
        self._refresh()

    def _refresh(self) -> None:
        self._grasped = self._fingers_touch(self._can_geom)

    def planning_attached_bodies(self) -> list[tuple[str, str]]:
        """The can moves with the gripper in :meth:`is_valid` while it is grasped."""
        return [("can", sm.EEF_BODY)]

    def _carry_attached(self, pd: mujoco.MjData, poses: list) -> None:
        if self._grasped:  # otherwise the can stays where it is in the live simulation
            super()._carry_attached(pd, poses)

    # ------------------------------------------------------------------ quantities
    def can_pos(self) -> np.ndarray:
        """Can centre (world)."""
        return self.data.qpos[self._can_qadr:self._can_qadr + 3].copy()

    @property
    def grasped(self) -> bool:
        """Both fingers touch the can."""
        return self._grasped

    @property
    def target(self) -> np.ndarray:
        """Target position (bin centre at the lift height)."""
        return self._target.copy()

    def _task_obs(self) -> np.ndarray:
        can = self.can_pos()
        quat = self.data.qpos[self._can_qadr + 3:self._can_qadr + 7]
        return np.concatenate([can, quat, self.eef_pos() - can, self._target])

    def _performance(self) -> float:
        return -max(SUCCESS_Z - float(self.data.qpos[self._can_qadr + 2]), 0.0)

    def _is_success(self) -> bool:
        return bool(self._grasped and self.data.qpos[self._can_qadr + 2] >= SUCCESS_Z)

    # ------------------------------------------------------------------ reward
    def _reach_reward(self) -> float:
        return float(0.1 * (1.0 - np.tanh(10.0 * np.linalg.norm(self.eef_pos() - self.can_pos()))))

    def _reward_info(self) -> dict[str, float]:
        return {"reach_reward": self._reach_reward(), "grasped": float(self._grasped)}

    def _goal_reward(self, achieved: np.ndarray, desired: np.ndarray, extras: dict[str, np.ndarray]) -> np.ndarray:
        grasped = extras["grasped"] > 0.5
        lift = 0.35 * grasped + 0.15 * (1.0 - np.tanh(15.0 * np.maximum(desired[:, 2] - achieved[:, 2], 0.0)))
        staged = np.maximum(extras["reach_reward"], np.maximum(0.35 * grasped, np.where(grasped, lift, 0.0)))
        success = grasped & (achieved[:, 2] >= desired[:, 2] - (TARGET_Z - SUCCESS_Z))
        return staged + 150.0 * success

    def _goal_success(self, achieved: np.ndarray, desired: np.ndarray) -> np.ndarray:
        return achieved[:, 2] >= desired[:, 2] - (TARGET_Z - SUCCESS_Z)

    def _achieved_goal(self) -> np.ndarray:
        return self.can_pos()

    def _desired_goal(self) -> np.ndarray:
        return self.target


__all__ = ["SawyerLiftObstacleEnv", "scene_xml"]
