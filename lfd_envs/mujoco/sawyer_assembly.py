"""SawyerAssemblyObstacle-v0: insert a table leg held in the gripper into an upside-down table
(MoPA-RL ``SawyerAssemblyObstacle``).

Scene (after MoPA-RL ``sawyer_assembly_obstacle.xml``, world coordinates, robot base at
(0, 0, 0.95)): a work table (top z = 0.82) carries a toy table lying **upside down** and free to
move (free joint): a 0.52 × 0.52 × 0.02 m top with three legs already mounted (cylinders
r = 2.5 cm, 0.33 m long, pointing up, on a 0.35 m square) and, at the fourth corner, a socket
made of four boxes around a square hole (half-width 3 cm, 7 cm deep). It is yawed by −37° and
centred at (0.66, −0.15), so the hole lies near (0.69, −0.40) among the legs. MoPA-RL built
the toy table from IKEA meshes; here it is made of primitives with the same layout and sizes.

The fourth leg (0.33 m: upper part r = 2.6 cm, lower/inserted part r = 2.2 cm) is fixed in the
gripper (a child body of the gripper, no joint), pointing along the approach axis; its tip
``leg_head`` is 0.30 m beyond the grip site. The arm starts at MoPA-RL's start pose
+ N(0, 0.02) rad; knocking the toy table with the arm or the leg moves it (and its hole).
Action: 7 joint-position deltas (fingers held on the leg, not actuated by the policy).

Observation (45 = 32 common + 13): hole-bottom position (3), leg tip (3), leg tail (3),
leg quaternion (4, w x y z).

Reward (thesis eq. B.4): ``0.4·(1 − tanh(15 d))`` if ``d ≤ 0.3`` + 150 on success, with
``d = ‖leg tip − hole bottom‖``. Success: ``d ≤ 0.05`` (the tip is at least 2 cm inside the
socket, within its walls); the episode then terminates. Horizon 250.
Performance p = −max(d − 0.05, 0), p_opt = 0.

Planning: the leg is part of the robot, so leg–toy-table contacts invalidate a configuration;
toy-table–work-table contacts are ignored (they do not depend on the arm).
Goal-conditioned variant: achieved goal = leg tip, desired goal = hole bottom (3 each).
"""

from __future__ import annotations

import functools
from typing import ClassVar

import numpy as np

from lfd_envs.mujoco import sawyer_models as sm
from lfd_envs.mujoco.sawyer import SawyerObstacleEnv, lookat_camera

SUCCESS_DISTANCE = 0.05
REWARD_RADIUS = 0.3
FURNITURE_POS = (0.66, -0.15, 0.82)
FURNITURE_YAW_DEG = -37.0
LEG_OFFSET = 0.175  # legs at (±L, ±L) in the toy table's frame; the hole at (L, −L)
PLATE_HALF, PLATE_THICK = 0.26, 0.02
HOLE_HALF, SOCKET_WALL, SOCKET_DEPTH = 0.03, 0.012, 0.07
LEG_LENGTH, LEG_TIP_BEYOND_GRIP = 0.33, 0.30
INIT_QPOS = (0.427, 0.13, 0.0557, 0.114, -0.0622, 0.0276, 0.00356)


def _furniture_xml() -> str:
    L, a, t, h = LEG_OFFSET, HOLE_HALF, SOCKET_WALL, SOCKET_DEPTH / 2
    top = PLATE_THICK
    legs = "".join(
        f'<geom name="furniture_leg{i}" class="furniture" type="cylinder" size="0.025 {LEG_LENGTH / 2}" '
        f'pos="{x} {y} {top + LEG_LENGTH / 2}"/>'
        for i, (x, y) in enumerate([(L, L), (-L, L), (-L, -L)]))
    hx, hy, z = L, -L, top + h
    socket = "".join([
        sm.box("socket_px", (hx + a + t / 2, hy, z), (t / 2, a + t, h), cls="furniture"),
        sm.box("socket_nx", (hx - a - t / 2, hy, z), (t / 2, a + t, h), cls="furniture"),
        sm.box("socket_py", (hx, hy + a + t / 2, z), (a, t / 2, h), cls="furniture"),
        sm.box("socket_ny", (hx, hy - a - t / 2, z), (a, t / 2, h), cls="furniture"),
    ])
    yaw = np.radians(FURNITURE_YAW_DEG)
    return (
        f'<body name="furniture" pos="{sm.fmt(FURNITURE_POS)}" quat="{np.cos(yaw / 2):.6f} 0 0 {np.sin(yaw / 2):.6f}">'
        '<freejoint name="furniture_joint"/>'
        + sm.box("furniture_top", (0, 0, top / 2), (PLATE_HALF, PLATE_HALF, top / 2), cls="furniture")
        + legs + socket
        + f'<site name="hole" pos="{hx} {hy} {top + SOCKET_DEPTH}" size="0.006" rgba="0.2 0.85 0.2 0.8"/>'
        f'<site name="hole_bottom" pos="{hx} {hy} {top}" size="0.006" rgba="0.2 0.2 0.85 0.8"/>'
        '</body>')


def _held_leg_xml() -> str:
    """The leg, as MJCF appended to the gripper's ``eef`` body (z = approach axis)."""
    tail = LEG_TIP_BEYOND_GRIP - LEG_LENGTH
    half = LEG_LENGTH / 4
    return (
        '<body name="leg">'
        f'<geom name="leg_upper" type="cylinder" size="0.026 {half}" pos="0 0 {tail + half}" density="300" '
        'rgba="0.85 0.72 0.5 1"/>'
        f'<geom name="leg_lower" type="cylinder" size="0.022 {half}" pos="0 0 {tail + 3 * half}" density="300" '
        'rgba="0.85 0.72 0.5 1"/>'
        f'<site name="leg_head" pos="0 0 {LEG_TIP_BEYOND_GRIP}" size="0.006" rgba="1 0 0 1"/>'
        f'<site name="leg_tail" pos="0 0 {tail}" size="0.006" rgba="1 0 0 1"/>'
        '</body>')


@functools.lru_cache(maxsize=None)
def scene_xml(robot_meshes: bool = False) -> str:
    """MJCF of the assembly scene."""
    scene = sm.work_table((0.66, 0.0, 0.41), (0.4, 0.6, 0.41)) + _furniture_xml()
    finger_bodies = ("gripper0_right_l_finger", "gripper0_right_r_finger",
                     "gripper0_right_l_finger_tip", "gripper0_right_r_finger_tip")
    camera = lookat_camera("task_cam", (1.75, 0.8, 1.85), (0.6, -0.05, 1.0), fovy=50)
    furniture = ('<default class="furniture"><geom rgba="0.93 0.86 0.7 1" density="300" '
                 'friction="1 0.005 0.0001"/></default>')
    return sm.compose_scene_xml("sawyer_assembly_obstacle", scene, camera, robot_meshes=robot_meshes,
                                attach_to_eef=_held_leg_xml(), excludes=[("leg", f) for f in finger_bodies],
                                defaults=furniture)


class SawyerAssemblyObstacleEnv(SawyerObstacleEnv):
    """Sawyer inserts a held table leg into an upside-down toy table (module docstring has all details).

    Constructor arguments: see :class:`~lfd_envs.mujoco.sawyer.SawyerObstacleEnv` (state
    observation: 45 values).
    """

    task_name = "SawyerAssemblyObstacle"
    scene_builder = staticmethod(scene_xml)
    ignored_contact_pairs: ClassVar[list[tuple[str, str]]] = [("furniture", "table")]
    init_qpos = INIT_QPOS
    task_obs_dim = 13
    finger_hold = 0.007  # finger pads on the leg (contacts between them are excluded)

    def _init_task(self) -> None:
        m = self.model
        self._head = m.site("leg_head").id
        self._tail = m.site("leg_tail").id
        self._hole_bottom = m.site("hole_bottom").id
        self._leg_body = m.body("leg").id

    def _setup_variant(self, rng: np.random.Generator) -> None:
        self._reset_robot()
        self._forward()

    # ------------------------------------------------------------------ quantities
    def leg_head(self) -> np.ndarray:
        """Tip of the held leg (world)."""
        return self.data.site_xpos[self._head].copy()

    def hole_bottom(self) -> np.ndarray:
        """Bottom centre of the hole (world; moves with the toy table)."""
        return self.data.site_xpos[self._hole_bottom].copy()

    def _distance(self) -> float:
        return float(np.linalg.norm(self.leg_head() - self.hole_bottom()))

    def _task_obs(self) -> np.ndarray:
        d = self.data
        return np.concatenate([self.hole_bottom(), self.leg_head(), d.site_xpos[self._tail],
                               d.xquat[self._leg_body]])

    def _performance(self) -> float:
        return -max(self._distance() - SUCCESS_DISTANCE, 0.0)

    def _is_success(self) -> bool:
        return self._distance() <= SUCCESS_DISTANCE

    # ------------------------------------------------------------------ reward
    def _goal_reward(self, achieved: np.ndarray, desired: np.ndarray, extras: dict[str, np.ndarray]) -> np.ndarray:
        dist = np.linalg.norm(achieved - desired, axis=-1)
        shaped = np.where(dist <= REWARD_RADIUS, 0.4 * (1.0 - np.tanh(15.0 * dist)), 0.0)
        return shaped + 150.0 * (dist <= SUCCESS_DISTANCE)

    def _goal_success(self, achieved: np.ndarray, desired: np.ndarray) -> np.ndarray:
        return np.linalg.norm(achieved - desired, axis=-1) <= SUCCESS_DISTANCE

    def _achieved_goal(self) -> np.ndarray:
        return self.leg_head()

    def _desired_goal(self) -> np.ndarray:
        return self.hole_bottom()


__all__ = ["SawyerAssemblyObstacleEnv", "scene_xml"]
