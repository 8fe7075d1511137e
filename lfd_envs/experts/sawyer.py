"""Scripted experts for the Sawyer obstructed tasks: plan to a pre-contact pose, then act directly.

Every expert follows the same two phases, using only the env's planning interface
(``is_valid``, ``joint_limits``, ``arm_qpos``, ``dq_step``) and privileged object positions:

1. **Plan.** Inverse kinematics (:class:`~lfd_envs.mujoco.sawyer.SawyerIK`, MuJoCo Jacobians,
   several seeds) gives a valid pre-contact configuration; a joint path to it comes from OMPL
   RRT-Connect (:class:`lfd_envs.mujoco.ompl_planner.OMPLPlanner`, the planner MoPA uses too:
   straight line first when it is free) or, when OMPL is not installed, from
   :func:`lfd_envs.mujoco.planning.plan_path` (with a warning naming both), with a
   stricter validity check (:class:`ClearanceChecker`: 1.5 cm from obstacles, so the arm does
   not drag along walls it grazes). The path is followed waypoint by waypoint (steps of
   0.03 rad, actions compensating the servos' per-joint lag).
2. **Contact.** Small direct actions from differential IK on the grip site (or the leg tip):
   Push steers the cube to the goal; Lift descends, closes the gripper and lifts; Assembly
   lowers the leg into the hole with lateral correction.

If IK or planning fails the expert retries a few steps later from wherever the arm is.
"""

from __future__ import annotations

import copy
import warnings
from typing import Any, Sequence

import numpy as np

from lfd_envs.mujoco import sawyer_models as sm
from lfd_envs.mujoco.ompl_planner import OMPLPlanner, ompl_available
from lfd_envs.mujoco.planning import densify_path, plan_path
from lfd_envs.mujoco.sawyer import SawyerIK
from lfd_envs.experts.episodes import EpisodeTracker


class ClearanceChecker:
    """Stricter validity for the expert's plans: ``env.is_valid(q)`` and ≥ ``clearance`` metres
    between the arm and everything that does not move with it.

    ``is_valid`` accepts grazing contacts (penetration < 2 mm); a path scraping along a wall is
    valid but the real arm then drags on it. This checker runs collision detection on a
    private copy of the model whose geoms have ``margin = clearance`` (so contacts closer than
    that are reported) and a private ``MjData``; the env is never modified.

    Args:
        env: a Sawyer obstructed env.
        clearance: required distance (m) between arm geoms and other geoms.
        ignore: body names whose geoms need no clearance (e.g. the object to be grasped).
    """

    def __init__(self, env: Any, clearance: float = 0.01, ignore: Sequence[str] = ()) -> None:
        import mujoco

        self._mj = mujoco
        self.base = env.unwrapped
        self.model = copy.deepcopy(self.base.model)
        self.data = mujoco.MjData(self.model)
        m = self.model
        self.clearance = float(clearance)
        m.geom_margin[:] = np.maximum(m.geom_margin, self.clearance)
        root = int(m.jnt_bodyid[m.joint(self.base.arm_joint_names[0]).id])
        arm_bodies = np.zeros(m.nbody, bool)
        arm_bodies[sm.subtree_bodies(m, m.body(root).name)] = True
        self._arm_geom = arm_bodies[m.geom_bodyid]
        skip = np.zeros(m.ngeom, bool)
        if ignore:
            skip[sm.body_geoms(m, list(ignore), collidable_only=False)] = True
        self._skip = skip
        self._qadr = self.base._arm_qadr

    def clear(self, q: np.ndarray) -> bool:
        """True if every arm geom is at least ``clearance`` away from non-arm geoms."""
        mj, m, d = self._mj, self.model, self.data
        d.qpos[:] = self.base.data.qpos
        d.qpos[self._qadr] = q
        mj.mj_kinematics(m, d)
        mj.mj_collision(m, d)
        if d.ncon == 0:
            return True
        g = d.contact.geom
        arm = self._arm_geom[g]
        cross = arm[:, 0] != arm[:, 1]
        relevant = cross & ~self._skip[g[:, 0]] & ~self._skip[g[:, 1]]
        return not bool(np.any(d.contact.dist[relevant] < self.clearance))

    def __call__(self, q: np.ndarray) -> bool:
        return bool(self.base.is_valid(q)) and self.clear(q)


def make_planner(env: Any, time_limit: float = 2.0, seed: int = 0, is_valid: Any = None):
    """``plan(q_start, q_goal) -> path (k, d) incl. start, or None`` for ``env``.

    ``is_valid`` defaults to ``env.is_valid``.
    """
    base = env.unwrapped
    check = base.is_valid if is_valid is None else is_valid
    if not ompl_available():
        warnings.warn("OMPL is not installed: the Sawyer expert plans with lfd_envs.mujoco.planning.plan_path "
                      "(RRT-Connect in Python) instead of OMPLPlanner (OMPL RRT-Connect); its paths and "
                      "success rates differ from the documented ones", RuntimeWarning, stacklevel=2)
        rng = np.random.default_rng(seed)
        checked = _WithValidity(base, check)
        return lambda q0, q1: plan_path(checked, q1, q0, rng=rng)
    planner = OMPLPlanner(check, base.joint_limits, dq_step=base.dq_step, time_limit=time_limit,
                          range=0.3, seed=seed)

    def plan(q0: np.ndarray, q1: np.ndarray) -> np.ndarray | None:
        result = planner.plan(q0, q1)
        return np.vstack([q0[None], result.path]) if result.success else None

    plan.planner = planner  # type: ignore[attr-defined]
    return plan


class _WithValidity:
    """The env seen through another validity function (for :func:`~lfd_envs.mujoco.planning.plan_path`)."""

    def __init__(self, env: Any, is_valid: Any) -> None:
        self._env, self.is_valid = env, is_valid
        self._is_valid_unchecked = lambda q: bool(is_valid(q))  # what plan_path checks edges with

    def __getattr__(self, name: str) -> Any:
        return getattr(self._env, name)


class _SawyerExpert:
    """Shared plan-then-act logic (module docstring). Subclasses define the task parts."""

    #: IK site the pre-contact target refers to
    ik_site: str = sm.GRIP_SITE
    #: largest Cartesian move of the controlled site per step in the contact phase (m)
    max_move: float = 0.02
    #: clearance (m) planned paths keep from obstacles
    clearance: float = 0.015
    #: joint-space step (rad, largest joint) between followed waypoints
    follow_step: float = 0.03
    #: bodies that need no clearance (e.g. the object the gripper will touch)
    clearance_ignore: tuple[str, ...] = ()

    def __init__(self, env: Any, planner_time: float = 2.0, seed: int = 0) -> None:
        self.env = env
        self.base = env.unwrapped
        self.ik = SawyerIK(self.base, self.ik_site)
        m, b = self.base.model, self.base
        kp = m.actuator_gainprm[b._arm_act, 0]
        damping = m.dof_damping[b._arm_dofadr]
        self._servo_fraction = 1.0 - np.exp(-kp / np.maximum(damping, 1e-6) * b.dt)
        self.checker = ClearanceChecker(env, self.clearance, self.clearance_ignore)
        self._plan = make_planner(env, planner_time, seed, is_valid=self.checker)
        self.seed = int(seed)
        self._episodes = EpisodeTracker(env)
        self.reset()

    def reset(self) -> None:
        """Forget the current plan (done by itself when the env starts a new episode)."""
        self._episodes.mark()
        self._rng = np.random.default_rng(self.seed)  # IK seeds: the same in every episode
        self.phase = "plan"
        self.path: np.ndarray | None = None
        self.index = 0
        self.wait = 0
        self.stage = 0
        self.counter = 0

    # ------------------------------------------------------------------ helpers
    def _arm_action(self, dq: np.ndarray) -> np.ndarray:
        """Joint displacement -> normalised action (direction kept when clipping)."""
        a = np.asarray(dq, float) / self.base.dq_step
        peak = np.max(np.abs(a))
        return a / peak if peak > 1.0 else a

    def _action(self, arm: np.ndarray, gripper: float | None = None) -> np.ndarray:
        a = np.asarray(arm, np.float32)
        if self.base.n_extra_actions:
            a = np.concatenate([a, [np.float32(0.0 if gripper is None else gripper)]])
        return a.astype(np.float32)

    def _cartesian(self, dpos: np.ndarray, axis: Sequence[float] | None) -> np.ndarray:
        """Action moving the IK site by ``dpos`` (clipped to ``max_move``) towards ``axis``."""
        dpos = np.asarray(dpos, float)
        n = np.linalg.norm(dpos)
        if n > self.max_move:
            dpos = dpos * (self.max_move / n)
        q = self.base.arm_qpos()
        return self._arm_action(self.ik.delta(dpos, axis, q))

    def _ik_candidates(self, pos: np.ndarray, axis: np.ndarray, seeds: list[np.ndarray],
                       tol: float = 4e-3) -> list[np.ndarray]:
        """Valid IK solutions (checker-clear), closest to the current pose (L1) first."""
        q_now = self.base.arm_qpos()
        found = []
        for seed in seeds:
            q, err = self.ik.solve(pos, axis, seed, q_rest=seed, rest_weight=0.05)
            if err < tol and self.checker(q):
                found.append((float(np.sum(np.abs(q - q_now))), len(found), q))
        return [q for _, _, q in sorted(found, key=lambda t: t[:2])]

    def _solve_ik(self, pos: np.ndarray, axis: np.ndarray, seeds: list[np.ndarray],
                  tol: float = 4e-3) -> np.ndarray | None:
        """The best valid IK solution or None."""
        found = self._ik_candidates(pos, axis, seeds, tol)
        return found[0] if found else None

    def _motion_clear(self, q0: np.ndarray, q1: np.ndarray, checker: Any, n: int = 6) -> bool:
        """``checker`` holds at ``n`` points of the joint-space segment q0 → q1."""
        return all(checker(q0 + t * (q1 - q0)) for t in np.linspace(0.0, 1.0, n))

    def _seeds(self, extra: Sequence[Sequence[float]] = ()) -> list[np.ndarray]:
        q = self.base.arm_qpos()
        seeds = [q, *[np.asarray(s, float) for s in extra]]
        lo, hi = self.base.joint_limits[:, 0], self.base.joint_limits[:, 1]
        for _ in range(4):
            seeds.append(np.clip(q + self._rng.normal(0, 0.4, len(q)), lo, hi))
        return seeds

    def _follow(self) -> np.ndarray | None:
        """Next path-following arm action, or None when the path is done.

        A servo moves joint ``j`` by only a fraction ``f_j = 1 - exp(-kp_j / damping_j · dt)``
        of its set-point change within one step, and the fractions differ between joints, so
        commanding raw waypoint differences would bend the executed path away from the planned
        one. The expert divides by ``f_j`` and walks the path in steps of ``follow_step`` rad.
        """
        assert self.path is not None
        q = self.base.arm_qpos()
        if self.index < len(self.path) - 1:
            self.index += 1
            return self._arm_action((self.path[self.index] - q) / self._servo_fraction)
        err = self.path[-1] - q
        if np.max(np.abs(err)) > 0.01 and self.counter < 8:
            self.counter += 1
            return self._arm_action(err / self._servo_fraction)
        return None

    def _plan_to(self, q_goal: np.ndarray | None) -> bool:
        if q_goal is None:
            return False
        path = self._plan(self.base.arm_qpos(), q_goal)
        if path is None:
            return False
        path = densify_path(path, self.follow_step)
        self.path, self.index, self.counter = path, 0, 0
        return True

    # ------------------------------------------------------------------ policy
    def predict(self, observation: Any, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, None]:
        """SB3-style policy call; the expert reads the privileged simulator state."""
        if self._episodes.new_episode():
            self.reset()
        zero = np.zeros(self.base.n_arm)
        if self.phase == "plan":
            if self.wait > 0:
                self.wait -= 1
                return self._action(zero, self._gripper_during_plan()), None
            if self._plan_to(self._pre_contact()):
                self.phase = "follow"
            else:
                self.wait = 3
                return self._action(zero, self._gripper_during_plan()), None
        if self.phase == "follow":
            arm = self._follow()
            if arm is not None:
                return self._action(arm, self._gripper_during_plan()), None
            self.phase, self.stage, self.counter = "contact", 0, 0
        return self._contact(), None

    # ------------------------------------------------------------------ task parts
    def _pre_contact(self) -> np.ndarray | None:
        raise NotImplementedError

    def _contact(self) -> np.ndarray:
        raise NotImplementedError

    def _gripper_during_plan(self) -> float | None:
        return None


class SawyerPushExpert(_SawyerExpert):
    """Expert for ``SawyerPushObstacle-v0``: reach into the tunnel behind the cube, push it to the goal."""

    clearance_ignore = ("cube",)
    #: grip site this far behind the cube centre before pushing (fingertips ≈ 3 cm beyond the site)
    pre_contact = 0.11
    contact = 0.065
    max_move = 0.02
    #: approach axis below horizontal (deg) and grip-site height above the cube centre (m)
    tilt_deg = 45.0
    height = 0.015

    def __init__(self, env: Any, **kwargs: Any) -> None:
        super().__init__(env, **kwargs)
        self._push_checker = ClearanceChecker(env, 0.01, ("cube",)).clear

    def _push_dir(self) -> np.ndarray:
        d = self.base.goal[:2] - self.base.cube_pos()[:2]
        n = np.linalg.norm(d)
        return np.array([1.0, 0.0]) if n < 1e-6 else d / n

    def _pre_contact(self) -> np.ndarray | None:
        """Grip site behind the cube on the cube→goal line, gripper pointing along it (tilted
        down); only IK solutions from which the whole push stays clear of the tunnel are used."""
        cube, u = self.base.cube_pos(), self._push_dir()
        pos = np.array([*(cube[:2] - self.pre_contact * u), cube[2] + self.height])
        tilt = np.radians(self.tilt_deg)  # pointing down at 45° keeps the wrist off the table
        axis = np.array([u[0] * np.cos(tilt), u[1] * np.cos(tilt), -np.sin(tilt)])
        self.axis = axis
        seeds = self._seeds([(0.0, 0.6, 0.0, 0.5, 0.0, 0.4, 0.0), (0.0, 0.3, 0.0, 1.2, 0.0, -0.1, 0.0),
                             (0.0, -0.3, 0.0, 1.9, 0.0, -0.1, 1.57), (0.3, -0.3, -0.3, 1.5, 0.3, -0.5, 0.0)])
        # the whole push must have room too: the pose with the cube delivered must be clear
        end = np.array([*(self.base.goal[:2] - self.contact * u), pos[2]])
        for q in self._ik_candidates(pos, axis, seeds):
            q_end, err = self.ik.solve(end, axis, q)
            if err < 4e-3 and self._motion_clear(q, q_end, self._push_checker):
                return q
        return None

    def _contact(self) -> np.ndarray:
        cube, goal = self.base.cube_pos(), self.base.goal
        u = self._push_dir()
        eef = self.base.eef_pos()
        behind = cube[:2] - self.contact * u
        rel = eef[:2] - behind
        along = float(rel @ u)
        lateral = rel - along * u
        if np.linalg.norm(lateral) > 0.015:
            # re-align behind the cube (back off a little first if we are level with it)
            target = behind - 0.02 * u if along > -0.01 else behind
        else:
            remaining = float(np.linalg.norm(goal[:2] - cube[:2]))
            target = behind + min(0.03, remaining + 0.01) * u
        dpos = np.array([*(target - eef[:2]), cube[2] + self.height - eef[2]])
        return self._action(self._cartesian(dpos, self.axis))


class SawyerLiftExpert(_SawyerExpert):
    """Expert for ``SawyerLiftObstacle-v0``: plan above the can, descend, grasp, lift out of the bin."""

    #: grip site above the can centre at the pre-grasp pose
    pre_grasp_height = 0.15
    grasp_height = 0.005
    lift_to = 1.32
    max_move = 0.025
    down = np.array([0.0, 0.0, -1.0])

    def _gripper_during_plan(self) -> float | None:
        return -1.0

    def _pre_contact(self) -> np.ndarray | None:
        can = self.base.can_pos()
        pos = can + np.array([0.0, 0.0, self.pre_grasp_height])
        seeds = self._seeds([(0.0, -0.3, 0.0, 1.6, 0.0, 0.3, 0.0), (-0.5, -0.2, 0.0, 1.6, 0.0, 0.2, 0.0),
                             (-0.4, 0.2, 0.0, 1.0, 0.0, 0.4, 0.0)])
        return self._solve_ik(pos, self.down, seeds)

    def _contact(self) -> np.ndarray:
        can, eef = self.base.can_pos(), self.base.eef_pos()
        self.counter += 1
        if self.stage == 0:  # descend around the can
            target = can + np.array([0.0, 0.0, self.grasp_height])
            if np.linalg.norm(target - eef) < 0.01 or self.counter > 25:
                self.stage, self.counter = 1, 0
            return self._action(self._cartesian(target - eef, self.down), -1.0)
        if self.stage == 1:  # close
            if self.counter >= 3:
                self.stage, self.counter = 2, 0
            return self._action(np.zeros(self.base.n_arm), 1.0)
        if not self.base.grasped and self.counter > 4:  # lost it: open and start again
            self.stage, self.counter = 0, 0
            return self._action(np.zeros(self.base.n_arm), -1.0)
        target = np.array([can[0], can[1], self.lift_to]) if self.base.grasped else eef + [0, 0, 0.02]
        target[:2] = eef[:2]
        return self._action(self._cartesian(target - eef, self.down), 1.0)


class SawyerAssemblyExpert(_SawyerExpert):
    """Expert for ``SawyerAssemblyObstacle-v0``: plan the leg above the hole (clear of the other
    legs), then lower it in with lateral correction."""

    ik_site = "leg_head"
    #: leg tip above the hole bottom at the pre-insertion pose
    pre_insert_height = 0.14
    max_move = 0.02
    down = np.array([0.0, 0.0, -1.0])

    def _pre_contact(self) -> np.ndarray | None:
        pos = self.base.hole_bottom() + np.array([0.0, 0.0, self.pre_insert_height])
        seeds = self._seeds([(0.0, 0.0, 0.0, 1.2, 0.0, 0.4, 0.0), (-0.5, 0.0, 0.0, 1.2, 0.0, 0.4, 0.0),
                             (-0.4, -0.3, 0.0, 1.8, 0.0, 0.1, 0.0)])
        return self._solve_ik(pos, self.down, seeds)

    def _contact(self) -> np.ndarray:
        tip, hole = self.ik_tip(), self.base.hole_bottom()
        lateral = hole[:2] - tip[:2]
        # descend only while the tip is centred over the hole; keep correcting laterally
        dz = -0.02 if np.linalg.norm(lateral) < 0.006 else 0.0
        dpos = np.array([lateral[0], lateral[1], dz])
        if tip[2] - hole[2] > 0.09:  # well above the socket: descend and centre together
            dpos[2] = -0.02
        return self._action(self._cartesian(dpos, self.down))

    def ik_tip(self) -> np.ndarray:
        """Tip of the held leg (the site the expert steers)."""
        return self.base.leg_head()


__all__ = ["SawyerPushExpert", "SawyerLiftExpert", "SawyerAssemblyExpert", "ClearanceChecker", "make_planner"]
