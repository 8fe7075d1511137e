"""Scripted experts for the Sawyer obstructed tasks: plan to a pre-contact pose, then act directly.

Every expert follows the same two phases, using only the env's planning interface
(``is_valid``, ``joint_limits``, ``arm_qpos``, ``dq_step``) and privileged object positions:

1. **Plan.** Inverse kinematics (:class:`~lfd_envs.mujoco.sawyer.SawyerIK`, MuJoCo Jacobians,
   several seeds) gives a valid pre-contact configuration; a joint path to it comes from OMPL
   RRT-Connect (``lfd_agents.mopa.planner.OMPLPlanner``: straight line first when it is free)
   or, when OMPL is unavailable, from :func:`lfd_envs.mujoco.planning.plan_path`. The path is
   followed waypoint by waypoint with actions ``(waypoint − q) / Δq_step``.
2. **Contact.** Small direct actions from differential IK on the grip site (or the leg tip):
   Push steers the cube to the goal; Lift descends, closes the gripper and lifts; Assembly
   lowers the leg into the hole with lateral correction.

If IK or planning fails the expert retries a few steps later from wherever the arm is.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from lfd_envs.mujoco import sawyer_models as sm
from lfd_envs.mujoco.sawyer import SawyerIK


def make_planner(env: Any, time_limit: float = 2.0, seed: int = 0):
    """``plan(q_start, q_goal) -> path (k, d) incl. start, or None`` for ``env``."""
    base = env.unwrapped
    try:
        from lfd_agents.mopa.planner import OMPLPlanner
    except ImportError:  # OMPL (or lfd_agents) missing: the env package's own RRT-Connect
        from lfd_envs.mujoco.planning import plan_path

        rng = np.random.default_rng(seed)
        return lambda q0, q1: plan_path(base, q1, q0, rng=rng)
    planner = OMPLPlanner(base.is_valid, base.joint_limits, dq_step=base.dq_step, time_limit=time_limit,
                          range=0.3, seed=seed)

    def plan(q0: np.ndarray, q1: np.ndarray) -> np.ndarray | None:
        result = planner.plan(q0, q1)
        return np.vstack([q0[None], result.path]) if result.success else None

    plan.planner = planner  # type: ignore[attr-defined]
    return plan


class _SawyerExpert:
    """Shared plan-then-act logic (module docstring). Subclasses define the task parts."""

    #: IK site the pre-contact target refers to
    ik_site: str = sm.GRIP_SITE
    #: largest Cartesian move of the controlled site per step in the contact phase (m)
    max_move: float = 0.02

    def __init__(self, env: Any, planner_time: float = 2.0, seed: int = 0) -> None:
        self.env = env
        self.base = env.unwrapped
        self.ik = SawyerIK(self.base, self.ik_site)
        self._plan = make_planner(env, planner_time, seed)
        self._rng = np.random.default_rng(seed)
        self.reset()

    def reset(self) -> None:
        """Forget the current plan (call after every ``env.reset``)."""
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

    def _solve_ik(self, pos: np.ndarray, axis: np.ndarray, seeds: list[np.ndarray],
                  tol: float = 4e-3) -> np.ndarray | None:
        """A valid IK solution (closest to the current pose) or None."""
        q_now = self.base.arm_qpos()
        best, best_d = None, np.inf
        for seed in seeds:
            q, err = self.ik.solve(pos, axis, seed, q_rest=seed, rest_weight=0.05)
            if err < tol and self.base.is_valid(q):
                d = float(np.max(np.abs(q - q_now)))
                if d < best_d:
                    best, best_d = q, d
        return best

    def _seeds(self, extra: Sequence[Sequence[float]] = ()) -> list[np.ndarray]:
        q = self.base.arm_qpos()
        seeds = [q, *[np.asarray(s, float) for s in extra]]
        lo, hi = self.base.joint_limits[:, 0], self.base.joint_limits[:, 1]
        for _ in range(4):
            seeds.append(np.clip(q + self._rng.normal(0, 0.4, len(q)), lo, hi))
        return seeds

    def _follow(self) -> np.ndarray | None:
        """Next path-following arm action, or None when the path is done."""
        assert self.path is not None
        q = self.base.arm_qpos()
        if self.index < len(self.path) - 1:
            self.index += 1
            return self._arm_action(self.path[self.index] - q)
        err = self.path[-1] - q
        if np.max(np.abs(err)) > 0.01 and self.counter < 6:
            self.counter += 1
            return self._arm_action(err)
        return None

    def _plan_to(self, q_goal: np.ndarray | None) -> bool:
        if q_goal is None:
            return False
        path = self._plan(self.base.arm_qpos(), q_goal)
        if path is None:
            return False
        self.path, self.index, self.counter = path, 0, 0
        return True

    # ------------------------------------------------------------------ policy
    def predict(self, observation: Any, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, None]:
        """SB3-style policy call; the expert reads the privileged simulator state."""
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

    #: grip site this far behind the cube centre before pushing (fingertips ≈ 3 cm beyond the site)
    pre_contact = 0.11
    contact = 0.065
    max_move = 0.02

    def _push_dir(self) -> np.ndarray:
        d = self.base.goal[:2] - self.base.cube_pos()[:2]
        n = np.linalg.norm(d)
        return np.array([1.0, 0.0]) if n < 1e-6 else d / n

    def _pre_contact(self) -> np.ndarray | None:
        cube, u = self.base.cube_pos(), self._push_dir()
        pos = np.array([*(cube[:2] - self.pre_contact * u), cube[2] + 0.005])
        axis = np.array([u[0], u[1], 0.0])
        self.axis = axis
        seeds = self._seeds([(0.0, 0.6, 0.0, 0.5, 0.0, 0.4, 0.0), (0.0, 0.3, 0.0, 1.2, 0.0, -0.1, 0.0),
                             (0.0, -0.3, 0.0, 1.9, 0.0, -0.1, 1.57)])
        return self._solve_ik(pos, axis, seeds)

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
        dpos = np.array([*(target - eef[:2]), cube[2] + 0.005 - eef[2]])
        return self._action(self._cartesian(dpos, self.axis))


__all__ = ["SawyerPushExpert", "make_planner"]
