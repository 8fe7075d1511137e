"""MoPA action space: a Gymnasium wrapper adding motion-planned large actions.

:class:`MoPAWrapper` turns any env with the planning interface (``arm_joint_names``,
``joint_limits``, ``arm_qpos()``, ``is_valid(q)``, ``dq_step``, ``execute_path(...)``; see
``lfd_envs.mujoco.planning``) into the MoPA-RL action space. A policy action ``u ∈ [-1, 1]^A``
(arm joints first, then e.g. a gripper dimension) is mapped per arm joint by
:class:`ActionMap` to a joint displacement Δq:

* ``|u| ≤ ω``  → ``Δq = u·Δq_step/ω`` (reachable in one low-level step: executed directly),
* ``|u| > ω``  → ``Δq = sign(u)·(Δq_step + (Δq_MP − Δq_step)(|u| − ω)/(1 − ω))``.

If any joint needs more than Δq_step, the target ``q + Δq`` (clipped to the limits) is pulled
back toward the current pose while it is in collision (0.02 rad per try, ≤ 100 tries), then
reached by a straight line if free, else by an OMPL path (:class:`OMPLPlanner`); each
waypoint is one low-level env step. The returned reward is the discounted sum
``Σ γ^i r_i`` over the executed steps; ``info`` describes what happened:

``mopa_mode``          "direct", "interpolation", "planner", "failed" or "invalid_target"
``mopa_k``             number of low-level steps executed (≥ 1)
``mopa_path``          ``(k, d)`` arm waypoints commanded (empty for failures/direct)
``mopa_planner_used``  the sampling-based planner ran
``mopa_planner_failed`` no path (failure: the arm holds still for one step)
``mopa_planning_time`` seconds spent planning
``mopa_trajectory``    per-step data used by MoPA-SAC's data reuse (planned actions only)

Ablations: ``rescale=False`` (Δq = u·Δq_MP), ``direct_execution=False`` (every action is
planned), ``invalid_target_handling=False`` (colliding targets fail), ``algorithm="rrt_star"``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from lfd_agents.mopa.planner import OMPLPlanner

__all__ = ["ActionMap", "MoPAPlan", "MoPAWrapper", "rescale_action", "invert_rescale", "PLANNING_INTERFACE", "MOPA_MODES"]

#: how a policy action is executed (``info["mopa_mode"]``)
MOPA_MODES = ("direct", "interpolation", "planner", "failed", "invalid_target")
#: attributes an env must expose to be wrapped
PLANNING_INTERFACE = ("arm_joint_names", "joint_limits", "arm_qpos", "is_valid", "dq_step", "execute_path")


def rescale_action(u: np.ndarray, dq_step: float, dq_mp: float, omega: float) -> np.ndarray:
    """Piecewise MoPA rescaling of normalised actions ``u ∈ [-1, 1]`` to joint displacements."""
    u = np.asarray(u, dtype=np.float64)
    a = np.abs(u)
    small = u * (dq_step / omega)
    large = np.sign(u) * (dq_step + (dq_mp - dq_step) * (a - omega) / (1.0 - omega))
    return np.where(a <= omega, small, large)


def invert_rescale(dq: np.ndarray, dq_step: float, dq_mp: float, omega: float) -> np.ndarray:
    """Inverse of :func:`rescale_action` (displacements beyond Δq_MP map outside [-1, 1])."""
    dq = np.asarray(dq, dtype=np.float64)
    a = np.abs(dq)
    small = dq * (omega / dq_step)
    large = np.sign(dq) * (omega + (a - dq_step) * (1.0 - omega) / (dq_mp - dq_step))
    return np.where(a <= dq_step, small, large)


@dataclass(frozen=True)
class ActionMap:
    """Normalised arm action ↔ joint displacement (one per wrapper; travels in ``info``).

    With ``rescale=False`` (ablation) the map is linear, ``Δq = u·Δq_MP``.
    """

    dq_step: float
    dq_mp: float
    omega: float
    rescale: bool = True

    def __post_init__(self) -> None:
        if not (0 < self.omega < 1):
            raise ValueError(f"omega must be in (0, 1), got {self.omega}")
        if not (0 < self.dq_step < self.dq_mp):
            raise ValueError(f"need 0 < dq_step < dq_mp, got dq_step={self.dq_step}, dq_mp={self.dq_mp}")

    def displacement(self, u: np.ndarray) -> np.ndarray:
        """Joint displacement for normalised arm action ``u``."""
        if self.rescale:
            return rescale_action(u, self.dq_step, self.dq_mp, self.omega)
        return np.asarray(u, dtype=np.float64) * self.dq_mp

    def action(self, dq: np.ndarray) -> np.ndarray:
        """Normalised arm action producing displacement ``dq`` (inverse of :meth:`displacement`)."""
        if self.rescale:
            return invert_rescale(dq, self.dq_step, self.dq_mp, self.omega)
        return np.asarray(dq, dtype=np.float64) / self.dq_mp

    def is_direct(self, dq: np.ndarray) -> bool:
        """True when one low-level step can execute ``dq`` (no joint beyond Δq_step)."""
        return bool(np.max(np.abs(dq)) <= self.dq_step * (1 + 1e-9))


@dataclass
class MoPAPlan:
    """How one MoPA action will be carried out (see :meth:`MoPAWrapper.resolve`).

    ``mode``: "direct", "interpolation", "planner", "failed" or "invalid_target"; ``path``:
    ``(k, d)`` waypoints after ``start`` (None for direct actions and failures).
    """

    mode: str
    dq: np.ndarray
    extra: np.ndarray
    start: np.ndarray
    path: np.ndarray | None = None
    planning_time: float = 0.0
    used_planner: bool = False


@dataclass
class _Execution:
    """Normalised outcome of executing some low-level steps."""

    obs: Any
    rewards: list[float]
    terminated: bool
    truncated: bool
    info: dict
    observations: list[Any]
    qpos: list[np.ndarray]


class MoPAWrapper(gym.Wrapper):
    """Motion-planner-augmented action space for an env with the planning interface.

    Args:
        env: env (or wrapped env) whose ``unwrapped`` exposes :data:`PLANNING_INTERFACE`.
        dq_step: largest per-joint displacement of one low-level step (default: the env's).
        dq_mp: largest per-joint displacement of one planned action (Δq_MP).
        omega: fraction of the action range mapped to direct execution (ω).
        gamma: discount used for the reward of multi-step actions (MoPA-SAC syncs it).
        rescale: piecewise rescaling (False: linear ``u·Δq_MP``, ablation).
        direct_execution: execute small actions directly (False: plan every action, ablation).
        invalid_target_handling: pull colliding targets back (False: they fail, ablation).
        invalid_target_step: pull-back distance per try [rad] (0.02).
        invalid_target_tries: maximum pull-back tries (100).
        algorithm: ``"rrt_connect"`` or ``"rrt_star"`` (ablation).
        time_limit: OMPL time per query [s]. range: OMPL extension length.
        max_checks: validity checks one OMPL search may run (None: ``time_limit`` only).
        planner: a ready :class:`OMPLPlanner` (overrides algorithm/time_limit/range/planner_kwargs).
        planner_kwargs: extra :class:`OMPLPlanner` arguments.
    """

    def __init__(
        self,
        env: gym.Env,
        dq_step: float | None = None,
        dq_mp: float = 0.5,
        omega: float = 0.7,
        *,
        gamma: float = 0.99,
        rescale: bool = True,
        direct_execution: bool = True,
        invalid_target_handling: bool = True,
        invalid_target_step: float = 0.02,
        invalid_target_tries: int = 100,
        algorithm: str = "rrt_connect",
        time_limit: float = 1.0,
        range: float | None = None,  # noqa: A002 - OMPL's name
        max_checks: int | None = None,
        planner: OMPLPlanner | None = None,
        planner_kwargs: dict | None = None,
    ) -> None:
        super().__init__(env)
        base = env.unwrapped
        missing = [a for a in PLANNING_INTERFACE if not hasattr(base, a)]
        if missing:
            raise TypeError(f"{type(base).__name__} does not expose the planning interface; missing {missing}")
        self.base = base
        self.env_dq_step = float(base.dq_step)
        dq_step = self.env_dq_step if dq_step is None else float(dq_step)
        if dq_step > self.env_dq_step * (1 + 1e-9):
            raise ValueError(f"dq_step={dq_step} exceeds the env's per-step limit {self.env_dq_step}")
        self.action_map = ActionMap(dq_step, float(dq_mp), float(omega), bool(rescale))
        self.n_arm = len(base.arm_joint_names)
        if not isinstance(env.action_space, spaces.Box) or env.action_space.shape[0] < self.n_arm:
            raise ValueError(f"env action space must be a Box with ≥ {self.n_arm} dims, got {env.action_space}")
        self.action_space = spaces.Box(-1.0, 1.0, env.action_space.shape, np.float32)
        self.gamma = float(gamma)
        self.direct_execution = bool(direct_execution)
        self.invalid_target_handling = bool(invalid_target_handling)
        self.invalid_target_step = float(invalid_target_step)
        self.invalid_target_tries = int(invalid_target_tries)
        if planner is None:
            kw = dict(planner_kwargs or {})
            kw.setdefault("algorithm", algorithm)
            kw.setdefault("time_limit", time_limit)
            if range is not None:
                kw.setdefault("range", range)
            if max_checks is not None:
                kw.setdefault("max_checks", max_checks)
            kw.setdefault("dq_step", dq_step)
            planner = OMPLPlanner(base.is_valid, np.asarray(base.joint_limits), **kw)
        self.planner = planner
        self._obs: Any = None
        #: low-level env steps executed since construction (MoPA budgets count these)
        self.low_level_steps = 0
        self.stats = dict.fromkeys(MOPA_MODES, 0)

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self._obs = obs
        return obs, info

    def step(self, action):
        if self._obs is None:
            raise RuntimeError("call reset() before step()")
        u = self._check_action(action)
        plan = self.resolve(u)
        if plan.mode == "direct":
            ex = self._direct(plan.dq, plan.extra)
        elif plan.path is None:
            ex = self._hold(plan.extra)
        else:
            ex = self._execute(plan.path, plan.extra, plan.start)
        path = None if plan.path is None else plan.path[: len(ex.rewards)]
        return self._finish(u, ex, plan.mode, path, plan.planning_time, plan.used_planner)

    def _check_action(self, action) -> np.ndarray:
        u = np.asarray(action, dtype=np.float64).reshape(-1)
        if u.shape != self.action_space.shape or not np.all(np.isfinite(u)):
            raise ValueError(f"action must be a finite array of shape {self.action_space.shape}, got {action!r}")
        return np.clip(u, -1.0, 1.0)

    def resolve(self, action) -> MoPAPlan:
        """Decide how to carry out MoPA ``action`` from the current state, without moving.

        Returns a :class:`MoPAPlan`: a direct step, a planned path (waypoints ≤ Δq_step apart,
        start excluded), or a failure (``path`` None: the arm holds still for one step).
        Used by :meth:`step` and by agents acting on an unwrapped env (one waypoint a step).
        """
        u = self._check_action(action)
        dq = self.action_map.displacement(u[: self.n_arm])
        extra = u[self.n_arm:]
        q0 = self.planner.clip(self.arm_qpos())
        if self.direct_execution and self.action_map.is_direct(dq):
            return MoPAPlan("direct", dq, extra, q0)
        target = self.valid_target(q0, self.planner.clip(q0 + dq))
        if target is None:
            return MoPAPlan("invalid_target", dq, extra, q0)
        result = self.planner.plan(q0, target)
        if not result.success:
            return MoPAPlan("failed", dq, extra, q0, None, result.planning_time, result.used_planner)
        return MoPAPlan(result.status, dq, extra, q0, result.path, result.planning_time, result.used_planner)

    def low_level_actions(self, plan: MoPAPlan) -> list[np.ndarray]:
        """Env actions carrying out ``plan`` with plain ``env.step`` calls (one per waypoint)."""
        if plan.mode == "direct":
            return [np.concatenate([plan.dq / self.env_dq_step, plan.extra]).astype(np.float32)]
        if plan.path is None:
            return [np.zeros(self.env.action_space.shape, np.float32)]
        steps = np.diff(np.vstack([plan.start[None], plan.path]), axis=0) / self.env_dq_step
        out = []
        for i, arm in enumerate(np.clip(steps, -1.0, 1.0)):
            extra = plan.extra if i == len(steps) - 1 else np.zeros_like(plan.extra)
            out.append(np.concatenate([arm, extra]).astype(np.float32))
        return out

    # ------------------------------------------------------------------ execution
    def _direct(self, dq: np.ndarray, extra: np.ndarray) -> _Execution:
        q0 = self.arm_qpos()
        env_action = np.concatenate([dq / self.env_dq_step, extra]).astype(np.float32)
        obs, r, term, trunc, info = self.env.step(env_action)
        return _Execution(obs, [float(r)], bool(term), bool(trunc), info, [self._obs, obs], [q0, self.arm_qpos()])

    def valid_target(self, q: np.ndarray, target: np.ndarray) -> np.ndarray | None:
        """Pull ``target`` toward ``q`` until valid (None when it stays in collision)."""
        if self.planner.check(target):
            return target
        if not self.invalid_target_handling:
            return None
        target = np.array(target, dtype=np.float64)
        for _ in range(self.invalid_target_tries):
            gap = q - target
            dist = float(np.linalg.norm(gap))
            if dist <= self.invalid_target_step:
                target = np.array(q, dtype=np.float64)
            else:
                target += self.invalid_target_step * gap / dist
            if self.planner.check(target):
                return target
            if dist <= self.invalid_target_step:
                break
        return None

    def _hold(self, extra: np.ndarray) -> _Execution:
        """Failure: the arm holds still for one low-level step (no gripper change)."""
        q0 = self.arm_qpos()
        action = np.zeros(self.env.action_space.shape, np.float32)
        obs, r, term, trunc, info = self.env.step(action)
        return _Execution(obs, [float(r)], bool(term), bool(trunc), info, [self._obs, obs], [q0, self.arm_qpos()])

    def _execute(self, path: np.ndarray, extra: np.ndarray, q0: np.ndarray) -> _Execution:
        """Execute waypoints one low-level step each (``env.execute_path``), extra dims on the last."""
        res = self.base.execute_path(np.vstack([q0[None], path]), gripper=extra if extra.size else None,
                                     discount=self.gamma)
        k = int(res.steps)
        qpos = [q0] + [np.asarray(q) for q in path[:k]]
        return _Execution(res.obs, list(res.rewards), bool(res.terminated), bool(res.truncated), dict(res.info),
                          [self._obs] + list(res.observations), qpos)

    # ------------------------------------------------------------------ bookkeeping
    def _finish(self, u: np.ndarray, ex: _Execution, mode: str, path, timing: float, used: bool):
        k = len(ex.rewards)
        discounts = self.gamma ** np.arange(k)
        reward = float(np.dot(discounts, ex.rewards))
        self.stats[mode] += 1
        info = dict(ex.info)
        info.update(
            mopa_mode=mode,
            mopa_k=k,
            mopa_path=np.zeros((0, self.n_arm)) if path is None else np.asarray(path),
            mopa_planner_used=bool(used),
            mopa_planner_failed=mode in ("failed", "invalid_target"),
            mopa_planning_time=float(timing),
        )
        if mode in ("interpolation", "planner") and k > 1:
            info["mopa_trajectory"] = {
                "qpos": np.asarray(ex.qpos), "observations": ex.observations, "rewards": np.asarray(ex.rewards),
                "terminated": ex.terminated, "truncated": ex.truncated, "extra_action": u[self.n_arm:].copy(),
                "action_map": self.action_map,
            }
        self._obs = ex.obs
        self.low_level_steps += k
        return ex.obs, reward, ex.terminated, ex.truncated, info

    # ------------------------------------------------------------------ helpers
    def arm_qpos(self) -> np.ndarray:
        """Current arm configuration (from the env)."""
        return np.asarray(self.base.arm_qpos(), dtype=np.float64).copy()

    def set_gamma(self, gamma: float) -> None:
        """Discount for multi-step rewards (called by MoPA-SAC so both agree)."""
        if not (0 < gamma <= 1):
            raise ValueError(f"gamma must be in (0, 1], got {gamma}")
        self.gamma = float(gamma)

    def close(self) -> None:
        self.planner.close()
        super().close()

