"""Shared machinery of the Sawyer obstructed-manipulation tasks (MoPA-RL scenes).

:class:`SawyerObstacleEnv` is the common base of ``SawyerPushObstacle-v0``,
``SawyerLiftObstacle-v0`` and ``SawyerAssemblyObstacle-v0``. The robot (robosuite's Sawyer arm,
Rethink gripper and mount; see :mod:`lfd_envs.mujoco.sawyer_models`) is controlled as in
MoPA-RL:

* action ``a ∈ [-1, 1]^7`` (+ a gripper dimension for Lift): joint-position displacement,
  set-point ``q + a · Δq_step`` with Δq_step = 0.05 rad, held by position servos with
  kp = (500, 500, 200, 200, 50, 50, 50) for 75 physics steps of 2 ms (0.15 s per env step);
* gravity compensation inside every physics step (MuJoCo's body ``gravcomp``);
* horizon 250 low-level steps; the episode terminates on success;
* the arm starts at the task's nominal pose plus N(0, 0.02) rad per joint (env RNG).

State observation (float32), common part (32): sin q (7), cos q (7), joint velocities (7),
finger positions (2), finger velocities (2), grip-site position (3), gripper quaternion
(4, w x y z); each task appends its object/goal features (see the task modules).

Images (``obs_mode`` "image"/"state+image" and ``render()``) come from the task camera
``task_cam`` (default 84×84). ``robot_visual="primitive"`` (default) draws the robot with its
collision primitives; ``"mesh"`` draws robosuite's visual meshes (≈280k triangles; about 30×
slower with software OpenGL).

Every env has the planning interface of :class:`~lfd_envs.mujoco.planning.PlanningMixin`
(``is_valid``, ``execute_path`` ...), image observations from the task camera (default 84×84)
and a goal-conditioned ``GoalEnv`` variant (``goal_conditioned=True``).

:class:`SawyerIK` solves inverse kinematics for a site (position + approach axis) with MuJoCo
Jacobians on a private ``MjData``; the experts and users can use it for Cartesian targets.
"""

from __future__ import annotations

from typing import Any, Callable, ClassVar, Sequence

import mujoco
import numpy as np
from gymnasium import spaces

from lfd_envs.core.errors import check_choice
from lfd_envs.mujoco import sawyer_models as sm
from lfd_envs.mujoco.base import MujocoEnv
from lfd_envs.mujoco.planning import PlanningMixin
from lfd_envs.mujoco.rendering import make_renderer

DQ_STEP = 0.05
FRAME_SKIP = 75
TIMESTEP = 0.002
HORIZON = 250
COMMON_OBS_DIM = 32
#: how the robot is drawn in images: its collision primitives (fast) or robosuite's meshes
ROBOT_VISUALS = ("primitive", "mesh")


class SawyerObstacleEnv(PlanningMixin, MujocoEnv):
    """Base of the Sawyer obstructed tasks (see the module docstring).

    Subclasses define ``task_name``, ``init_qpos`` (nominal start pose), ``task_obs_dim``,
    ``scene_builder`` (the task module's ``scene_xml``, as a ``staticmethod``),
    :meth:`_init_task` (task ids after the model is loaded), and the task hooks of
    :class:`~lfd_envs.mujoco.base.MujocoEnv` (``_setup_variant``, ``_task_obs``,
    ``_achieved_goal``/``_desired_goal``, ``_goal_reward`` ...).

    Args:
        obs_mode: ``"state"`` (``32 + task_obs_dim`` values), ``"image"`` (uint8 RGB from
            ``task_cam``), ``"state+image"``.
        image_size: image side or ``(height, width)``; default 84.
        render_mode: ``"rgb_array"`` or None.
        horizon: low-level steps per episode (250).
        goal_conditioned: GoalEnv Dict observations for HER (``obs_mode="state"`` only).
        render_size: ``(height, width)`` (or an int) of ``render()`` frames (default 256×256).
        robot_visual: ``"primitive"`` (robot drawn with its collision shapes, fast) or ``"mesh"``.
    """

    camera: ClassVar[str] = "task_cam"
    init_qpos: ClassVar[tuple[float, ...]] = (0.0,) * 7
    task_obs_dim: ClassVar[int] = 0
    #: whether the gripper is the 8th action dimension
    gripper_action: ClassVar[bool] = False
    #: finger opening held when the gripper is not part of the action (left-finger coordinate)
    finger_hold: ClassVar[float] = sm.FINGER_CLOSED
    goal_dim: ClassVar[int] = 3
    #: ``scene_xml(robot_meshes: bool) -> str`` of the task (set as a ``staticmethod``)
    scene_builder: ClassVar[Callable[..., str]]

    def __init__(self, obs_mode: str = "state", image_size: int | tuple[int, int] = 84,
                 render_mode: str | None = None, horizon: int = HORIZON, goal_conditioned: bool = False,
                 robot_visual: str = "primitive", render_size: int | tuple[int, int] | None = None) -> None:
        super().__init__(obs_mode=obs_mode, image_size=image_size, render_mode=render_mode, horizon=horizon,
                         render_size=render_size)
        self._init_sawyer(goal_conditioned=goal_conditioned, robot_visual=robot_visual)
        self._init_task()
        self._finish_init()

    def _init_task(self) -> None:
        """Task-specific setup once the model is loaded (ids of the task's bodies, sites ...)."""

    def _init_sawyer(self, *, goal_conditioned: bool, robot_visual: str = "primitive") -> None:
        """Model, control and spaces shared by the Sawyer tasks (after ``LfdEnv.__init__``)."""
        self.robot_visual = check_choice("robot_visual", robot_visual, ROBOT_VISUALS)
        self._scene_option = mujoco.MjvOption()
        if self.robot_visual == "primitive":  # collision primitives instead of ~280k mesh triangles
            self._scene_option.geomgroup[1] = 0
            self._scene_option.geomgroup[3] = 1
        self._init_mujoco(
            sm.load_model(self._scene_xml()), arm_joint_names=sm.ARM_JOINTS, dq_step=DQ_STEP,
            frame_skip=FRAME_SKIP, timestep=TIMESTEP, servo_kp=sm.ARM_KP, gravity_compensation="gravcomp",
            init_arm_qpos=self.init_qpos, init_noise="normal", init_noise_scale=0.02,
            n_extra_actions=1 if self.gripper_action else 0, goal_conditioned=goal_conditioned)
        m = self.model
        self._grip_site = int(sm.ids(m, mujoco.mjtObj.mjOBJ_SITE, [sm.GRIP_SITE])[0])
        self._eef_body = int(sm.ids(m, mujoco.mjtObj.mjOBJ_BODY, [sm.EEF_BODY])[0])
        fingers = sm.ids(m, mujoco.mjtObj.mjOBJ_JOINT, sm.FINGER_JOINTS)
        self._finger_qadr = m.jnt_qposadr[fingers].copy()
        self._finger_dofadr = m.jnt_dofadr[fingers].copy()
        self._finger_act = sm.ids(m, mujoco.mjtObj.mjOBJ_ACTUATOR, ("gripper_l_servo", "gripper_r_servo"))
        self._left_finger_geoms = sm.ids(m, mujoco.mjtObj.mjOBJ_GEOM, sm.LEFT_FINGER_GEOMS)
        self._right_finger_geoms = sm.ids(m, mujoco.mjtObj.mjOBJ_GEOM, sm.RIGHT_FINGER_GEOMS)
        self.state_space = spaces.Box(-np.inf, np.inf, (COMMON_OBS_DIM + self.task_obs_dim,), np.float32)
        self._obs_buf = np.zeros(COMMON_OBS_DIM + self.task_obs_dim, np.float64)

    def _scene_xml(self) -> str:
        return self.scene_builder(robot_meshes=self.robot_visual == "mesh")

    def _render(self, height: int, width: int) -> np.ndarray:
        key = (int(height), int(width))
        renderer = self._renderers.get(key)
        if renderer is None:
            renderer = self._renderers[key] = make_renderer(self.model, *key)
        renderer.update_scene(self.data, camera=self.camera, scene_option=self._scene_option)
        return renderer.render().copy()

    # ------------------------------------------------------------------ simulation helpers
    def _reset_robot(self) -> None:
        """Arm at the start pose + noise; fingers at ``finger_hold`` (open for Lift)."""
        self._reset_sim()
        self._set_fingers(self.finger_hold, qpos=True)

    def _set_fingers(self, left: float, qpos: bool = False) -> None:
        """Finger servo set-points (left-finger coordinate; the right finger mirrors it)."""
        left = float(np.clip(left, sm.FINGER_CLOSED, sm.FINGER_OPEN))
        self.data.ctrl[self._finger_act] = (left, -left)
        if qpos:
            self.data.qpos[self._finger_qadr] = (left, -left)

    def finger_opening(self) -> float:
        """Current left-finger coordinate (``FINGER_CLOSED`` … ``FINGER_OPEN``)."""
        return float(self.data.qpos[self._finger_qadr[0]])

    def eef_pos(self) -> np.ndarray:
        """Grip-site position (world, m)."""
        return self.data.site_xpos[self._grip_site].copy()

    def eef_xmat(self) -> np.ndarray:
        """Gripper orientation (3×3); column 2 is the approach axis."""
        return self.data.site_xmat[self._grip_site].reshape(3, 3).copy()

    def _touching(self, geoms_a: np.ndarray, geom_b: int | np.ndarray) -> bool:
        """True if any live contact joins a geom of ``geoms_a`` with one of ``geom_b``."""
        d = self.data
        if d.ncon == 0:
            return False
        g = d.contact.geom
        b = np.atleast_1d(geom_b)
        return bool(np.any((np.isin(g[:, 0], geoms_a) & np.isin(g[:, 1], b))
                           | (np.isin(g[:, 1], geoms_a) & np.isin(g[:, 0], b))))

    def _fingers_touch(self, geoms: np.ndarray) -> bool:
        """Both fingers touch one of ``geoms`` (MoPA-RL's grasp test)."""
        return self._touching(self._left_finger_geoms, geoms) and self._touching(self._right_finger_geoms, geoms)

    # ------------------------------------------------------------------ reward
    def _task_reward(self) -> float:
        """The goal reward (:meth:`_goal_reward`) of the current goals and reward info."""
        info = self._reward_info()
        extras = {k: np.array([info[k]]) for k in self.reward_info_keys}
        return float(self._goal_reward(self._achieved_goal()[None], self._desired_goal()[None], extras)[0])

    # ------------------------------------------------------------------ observation
    def _state_obs(self) -> np.ndarray:
        d, buf = self.data, self._obs_buf
        q = d.qpos[self._arm_qadr]
        buf[0:7] = np.sin(q)
        buf[7:14] = np.cos(q)
        buf[14:21] = d.qvel[self._arm_dofadr]
        buf[21:23] = d.qpos[self._finger_qadr]
        buf[23:25] = d.qvel[self._finger_dofadr]
        buf[25:28] = d.site_xpos[self._grip_site]
        buf[28:32] = d.xquat[self._eef_body]
        buf[32:] = self._task_obs()
        return buf.astype(np.float32)

    def _task_obs(self) -> np.ndarray:
        """Task features appended to the common observation (``task_obs_dim`` values)."""
        raise NotImplementedError


def lookat_camera(name: str, pos: Sequence[float], target: Sequence[float], fovy: float = 45.0) -> str:
    """MJCF ``<camera>`` at ``pos`` looking at ``target`` (world z up)."""
    pos, target = np.asarray(pos, float), np.asarray(target, float)
    forward = target - pos
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, (0.0, 0.0, 1.0))
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    xy = " ".join(f"{v:.5f}" for v in (*right, *up))
    return f'<camera name="{name}" pos="{pos[0]:g} {pos[1]:g} {pos[2]:g}" xyaxes="{xy}" fovy="{fovy:g}"/>'


class SawyerIK:
    """Damped-least-squares inverse kinematics of a site on a private ``MjData``.

    Solves for arm joints so that the site reaches ``pos`` and (optionally) its z axis points
    along ``axis``; other joints/objects stay as in the env's live simulation. Joint limits
    are enforced by clipping. The live simulation is never modified.

    Args:
        env: a :class:`SawyerObstacleEnv` (or wrapper of one).
        site: name of the site to place (default: the grip site).
    """

    def __init__(self, env: Any, site: str = sm.GRIP_SITE) -> None:
        self.env = env.unwrapped
        m = self.env.model
        self.model = m
        self.data = mujoco.MjData(m)
        self.site = int(sm.ids(m, mujoco.mjtObj.mjOBJ_SITE, [site])[0])
        self._qadr = self.env._arm_qadr
        self._dof = self.env._arm_dofadr
        self._lo, self._hi = self.env.joint_limits[:, 0], self.env.joint_limits[:, 1]
        self._jacp = np.zeros((3, m.nv))
        self._jacr = np.zeros((3, m.nv))

    def site_pose(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Site position and 3×3 orientation at arm configuration ``q``."""
        d = self.data
        d.qpos[:] = self.env.data.qpos
        d.qpos[self._qadr] = q
        mujoco.mj_kinematics(self.model, d)
        mujoco.mj_comPos(self.model, d)  # cdof/subtree_com for the Jacobians
        return d.site_xpos[self.site].copy(), d.site_xmat[self.site].reshape(3, 3).copy()

    def solve(self, pos: Sequence[float], axis: Sequence[float] | None, q_init: np.ndarray, *,
              iters: int = 200, tol: float = 1e-3, damping: float = 1e-2, rot_weight: float = 0.3,
              q_rest: np.ndarray | None = None, rest_weight: float = 0.0,
              roll_axis: Sequence[float] | None = None) -> tuple[np.ndarray, float]:
        """Return ``(q, error)``; ``error`` is the position error (m) plus the axis error (rad).

        ``roll_axis`` (optional) is a world direction the site's x axis should point along.
        ``q_rest`` with ``rest_weight`` > 0 pulls the solution towards a preferred pose in the
        Jacobian's null space.
        """
        m, d = self.model, self.data
        target = np.asarray(pos, float)
        z_goal = None if axis is None else np.asarray(axis, float) / np.linalg.norm(axis)
        x_goal = None if roll_axis is None else np.asarray(roll_axis, float) / np.linalg.norm(roll_axis)
        q = np.clip(np.asarray(q_init, float).copy(), self._lo, self._hi)
        err_total = np.inf
        for _ in range(iters):
            p, r = self.site_pose(q)
            rows = [target - p]
            mujoco.mj_jacSite(m, d, self._jacp, self._jacr, self.site)
            jac = [self._jacp[:, self._dof]]
            ang = 0.0
            if z_goal is not None:
                w = np.cross(r[:, 2], z_goal)
                ang = float(np.arccos(np.clip(r[:, 2] @ z_goal, -1, 1)))
                rows.append(rot_weight * w)
                jac.append(rot_weight * self._jacr[:, self._dof])
            if x_goal is not None:
                x_proj = x_goal - (x_goal @ r[:, 2]) * r[:, 2]
                w = np.cross(r[:, 0], x_proj / max(np.linalg.norm(x_proj), 1e-9))
                rows.append(rot_weight * 0.5 * w)
                jac.append(rot_weight * 0.5 * self._jacr[:, self._dof])
                ang += float(np.linalg.norm(w)) * 0.5
            e = np.concatenate(rows)
            j = np.vstack(jac)
            err_total = float(np.linalg.norm(target - p)) + ang
            if err_total < tol:
                break
            jjt = j @ j.T + damping ** 2 * np.eye(len(e))
            dq = j.T @ np.linalg.solve(jjt, e)
            if q_rest is not None and rest_weight > 0:
                null = np.eye(len(q)) - j.T @ np.linalg.solve(jjt, j)
                dq += rest_weight * null @ (np.asarray(q_rest) - q)
            step = np.max(np.abs(dq))
            if step > 0.2:
                dq *= 0.2 / step
            q = np.clip(q + dq, self._lo, self._hi)
        return q, err_total

    def delta(self, dpos: Sequence[float], axis: Sequence[float] | None, q: np.ndarray,
              rot_weight: float = 0.5, damping: float = 0.02) -> np.ndarray:
        """Joint displacement that moves the site by ``dpos`` (m) and turns it towards ``axis``."""
        m, d = self.model, self.data
        _, r = self.site_pose(q)
        mujoco.mj_jacSite(m, d, self._jacp, self._jacr, self.site)
        rows, jac = [np.asarray(dpos, float)], [self._jacp[:, self._dof]]
        if axis is not None:
            z_goal = np.asarray(axis, float) / np.linalg.norm(axis)
            rows.append(rot_weight * np.cross(r[:, 2], z_goal))
            jac.append(rot_weight * self._jacr[:, self._dof])
        e, j = np.concatenate(rows), np.vstack(jac)
        return j.T @ np.linalg.solve(j @ j.T + damping ** 2 * np.eye(len(e)), e)


__all__ = ["SawyerObstacleEnv", "SawyerIK", "lookat_camera", "DQ_STEP", "FRAME_SKIP", "HORIZON"]
