"""Planning interface of the obstructed MuJoCo envs, used by MoPA and the experts.

:class:`PlanningMixin` is mixed into a :class:`~lfd_envs.mujoco.base.MujocoEnv` subclass
(``class Env(PlanningMixin, MujocoEnv)``) and gives it:

* ``arm_joint_names`` (list[str]), ``joint_limits`` ``(d, 2)``, ``continuous_joints`` ``(d,)``
  bool (unlimited hinges; their bounds are ±2π), ``dq_step`` (rad per unit action) and
  ``arm_qpos()`` -- all defined by the base env;
* :meth:`~PlanningMixin.is_valid` -- collision check of an arm configuration on a **private**
  ``MjData``: every qpos/mocap entry other than the arm joints is copied from the live
  simulation, the arm joints are set to ``q``, then ``mj_kinematics`` + ``mj_collision``
  run. ``q`` is invalid if a contact penetrates by ``planning_penetration`` (2 mm) or more,
  unless its geom pair is in ``ignored_contact_pairs`` or neither geom moves with the arm
  (such contacts do not depend on ``q``). Joint limits are not part of validity; planners
  sample inside ``joint_limits``. The live ``MjData`` is never touched;
  :meth:`~PlanningMixin.validity_checker` gives the same check against a snapshot of the
  live state taken once (for the many checks of one planning query);
* ``ignored_contact_pairs`` -- list of ``(name_a, name_b)``; each name is a geom or a body
  (a body stands for all of its geoms); contacts between the two sets are ignored;
* ``planning_attached_bodies()`` -- optional hook returning ``(body, parent_body)`` pairs:
  each body (with a free joint, e.g. a grasped can) is carried rigidly with ``parent_body``
  during :meth:`is_valid`, keeping its current relative pose in the live simulation;
* :meth:`~PlanningMixin.execute_path` -- run a joint-space path, one low-level env step per
  waypoint, and return a :class:`PathResult`.

Module helpers :func:`interpolate` and :func:`densify_path` cut straight segments into
steps no larger than ``dq_step`` per joint; :func:`plan_path` finds a collision-free joint
path with ``is_valid`` (straight line first, else a seeded RRT-Connect with shortcutting),
deterministic for a given generator (no OMPL, no time limits in the result).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, ClassVar

import mujoco
import numpy as np

_TOL = 1e-6


@dataclass
class PathResult:
    """Outcome of :meth:`PlanningMixin.execute_path`.

    Attributes:
        obs: observation after the last executed step (the current one if none ran).
        observations: observation after every executed step (``steps`` entries).
        rewards: reward of every executed step.
        discounted_return: ``sum_i discount**i * rewards[i]``.
        terminated, truncated: flags of the last executed step (False if none ran).
        info: ``info`` of the last executed step (current info if none ran).
        infos: ``info`` of every executed step.
        steps: number of env steps executed (<= ``len(path) - 1``).
    """

    obs: Any
    observations: list[Any] = field(default_factory=list)
    rewards: list[float] = field(default_factory=list)
    discounted_return: float = 0.0
    terminated: bool = False
    truncated: bool = False
    info: dict[str, Any] = field(default_factory=dict)
    infos: list[dict[str, Any]] = field(default_factory=list)
    steps: int = 0


def interpolate(q_start: np.ndarray, q_goal: np.ndarray, max_step: float) -> np.ndarray:
    """Straight joint-space segment ``(n+1, d)`` from ``q_start`` to ``q_goal`` (both included),
    with equal increments of at most ``max_step`` per joint."""
    q_start = np.asarray(q_start, np.float64)
    q_goal = np.asarray(q_goal, np.float64)
    n = max(1, int(np.ceil(np.max(np.abs(q_goal - q_start)) / max_step - 1e-9)))
    t = np.linspace(0.0, 1.0, n + 1)[:, None]
    return q_start + t * (q_goal - q_start)


def densify_path(path: np.ndarray, max_step: float) -> np.ndarray:
    """Insert waypoints so that consecutive rows differ by at most ``max_step`` per joint."""
    path = np.asarray(path, np.float64)
    if len(path) < 2:
        return path.copy()
    pieces = [interpolate(a, b, max_step)[1:] for a, b in zip(path[:-1], path[1:])]
    return np.vstack([path[:1], *pieces])


def _segment_free(env: "PlanningMixin", a: np.ndarray, b: np.ndarray, resolution: float) -> bool:
    """Every interpolated configuration after ``a`` up to ``b`` is valid (``a`` itself is not checked)."""
    check = env._is_valid_unchecked
    return all(check(q) for q in interpolate(a, b, resolution)[1:])


class _Tree:
    """Nodes (growing array) and parent indices of one RRT tree."""

    def __init__(self, root: np.ndarray, capacity: int) -> None:
        self.nodes = np.empty((capacity + 1, len(root)))
        self.nodes[0] = root
        self.parents = np.full(capacity + 1, -1)
        self.size = 1

    def nearest(self, q: np.ndarray) -> tuple[int, float]:
        d = np.linalg.norm(self.nodes[: self.size] - q, axis=1)
        i = int(np.argmin(d))
        return i, float(d[i])

    def add(self, q: np.ndarray, parent: int) -> int:
        if self.size == len(self.nodes):
            self.nodes = np.vstack([self.nodes, np.empty_like(self.nodes)])
            self.parents = np.concatenate([self.parents, np.full(len(self.parents), -1)])
        self.nodes[self.size], self.parents[self.size] = q, parent
        self.size += 1
        return self.size - 1

    def branch(self, i: int) -> list[np.ndarray]:
        """Nodes from ``i`` back to the root."""
        out = []
        while i >= 0:
            out.append(self.nodes[i].copy())
            i = int(self.parents[i])
        return out


def _rrt_connect(env: "PlanningMixin", q_start: np.ndarray, q_goal: np.ndarray, rng: np.random.Generator,
                 max_iters: int, step: float, resolution: float) -> list[np.ndarray] | None:
    """Bidirectional RRT (RRT-Connect, L2 metric) in the box ``env.joint_limits``."""
    lo, hi = env.joint_limits[:, 0], env.joint_limits[:, 1]
    trees = [_Tree(q_start, 1024), _Tree(q_goal, 1024)]

    def extend(tree: _Tree, target: np.ndarray) -> tuple[int, bool]:
        """Grow ``tree`` towards ``target`` by at most ``step``; (new index or -1, reached)."""
        i, dist = tree.nearest(target)
        reached = dist <= step
        near = tree.nodes[i]
        new = target if reached else near + (target - near) * (step / dist)
        if not _segment_free(env, near, new, resolution):
            return -1, False
        return tree.add(new, i), reached

    for it in range(max_iters):
        grow, other = trees[it % 2], trees[(it + 1) % 2]
        i, _ = extend(grow, rng.uniform(lo, hi))
        if i < 0:
            continue
        target = grow.nodes[i].copy()
        while True:  # connect: grow the other tree towards the new node until blocked or joined
            j, reached = extend(other, target)
            if j < 0:
                break
            if reached:
                a, b = grow.branch(i), other.branch(j)
                return a[::-1] + b[1:] if it % 2 == 0 else b[::-1] + a[1:]
    return None


def _shortcut(env: "PlanningMixin", path: list[np.ndarray], rng: np.random.Generator, iters: int,
              resolution: float) -> list[np.ndarray]:
    """Random shortcutting: replace sub-paths by straight segments when those are valid."""
    path = list(path)
    for _ in range(iters):
        if len(path) < 3:
            break
        i, j = sorted(rng.choice(len(path), 2, replace=False))
        if j - i >= 2 and _segment_free(env, path[i], path[j], resolution):
            path = path[: i + 1] + path[j:]
    return path


def plan_path(env: "PlanningMixin", q_goal: Any, q_start: Any = None, *, rng: np.random.Generator | None = None,
              max_iters: int = 5000, step: float = 0.3, resolution: float | None = None,
              shortcut_iters: int = 60) -> np.ndarray | None:
    """Collision-free joint path from ``q_start`` (default ``env.arm_qpos()``) to ``q_goal``.

    Tries the straight line first, then RRT-Connect (``step`` = tree extension length, L2 rad)
    followed by shortcutting. Edges are checked with :meth:`PlanningMixin.is_valid` every
    ``resolution`` rad per joint (default ``dq_step / 8``); ``q_start`` itself is not checked
    (the arm may rest against something). Returns a ``(k, d)`` path densified to ``dq_step``
    per joint with ``path[0] = q_start`` (ready for :meth:`PlanningMixin.execute_path`), or
    None if ``q_goal`` is invalid or nothing was found within ``max_iters``. Deterministic for a
    given ``rng`` (default ``np.random.default_rng(0)``).
    """
    q_start = env.arm_qpos() if q_start is None else env._check_q(q_start)  # type: ignore[attr-defined]
    q_goal = env._check_q(q_goal)
    res = env.dq_step / 8 if resolution is None else float(resolution)
    if not env.is_valid(q_goal):
        return None
    if _segment_free(env, q_start, q_goal, res):
        return interpolate(q_start, q_goal, env.dq_step)
    rng = np.random.default_rng(0) if rng is None else rng
    path = _rrt_connect(env, q_start, q_goal, rng, max_iters, float(step), res)
    if path is None:
        return None
    return densify_path(np.asarray(_shortcut(env, path, rng, shortcut_iters, res)), env.dq_step)


class PlanningMixin:
    """Planning interface (module docstring). Mix in before ``MujocoEnv``."""

    #: (name_a, name_b) geom-or-body name pairs whose contacts never invalidate a configuration
    ignored_contact_pairs: ClassVar[list[tuple[str, str]]] = []
    #: penetration depth (m) from which a contact makes a configuration invalid
    planning_penetration: ClassVar[float] = 0.002

    # attributes provided by MujocoEnv
    model: mujoco.MjModel
    data: mujoco.MjData
    dq_step: float
    n_arm: int
    n_extra_actions: int
    joint_limits: np.ndarray
    _arm_qadr: np.ndarray
    _arm_body_mask: np.ndarray
    _path_reference: np.ndarray | None

    def planning_attached_bodies(self) -> list[tuple[str, str]]:
        """``(body, parent_body)`` pairs moved rigidly with the arm in :meth:`is_valid`. Default: none."""
        return []

    # ------------------------------------------------------------------ collision checking
    def _planning_setup(self) -> None:
        """Build the private ``MjData`` and contact filters (lazily, on first use)."""
        m = self.model
        self._plan_data = mujoco.MjData(m)
        ignored = np.zeros((m.ngeom, m.ngeom), bool)
        for a, b in self.ignored_contact_pairs:
            ga, gb = self._geoms_named(a), self._geoms_named(b)
            ignored[np.ix_(ga, gb)] = True
            ignored[np.ix_(gb, ga)] = True
        attached = [(self._body_id(b), self._body_id(p)) for b, p in self.planning_attached_bodies()]
        moving_body = self._arm_body_mask.copy()
        for body, _ in attached:
            moving_body |= self._subtree_mask(body)  # type: ignore[attr-defined]
        moving_geom = moving_body[m.geom_bodyid]
        ignored |= ~(moving_geom[:, None] | moving_geom[None, :])  # pairs that do not depend on q
        self._ignored_geoms = ignored
        self._attached = []
        for body, parent in attached:
            jnt = m.body_jntadr[body]
            if m.body_jntnum[body] != 1 or int(m.jnt_type[jnt]) != int(mujoco.mjtJoint.mjJNT_FREE):
                raise ValueError(f"attached body {m.body(body).name!r} needs exactly one free joint")
            self._attached.append((body, parent, int(m.jnt_qposadr[jnt])))
        self._plan_ready_for = id(m)

    def _body_id(self, name: str) -> int:
        bid = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name)
        if bid < 0:
            raise ValueError(f"body {name!r} not in the model")
        return bid

    def _geoms_named(self, name: str) -> np.ndarray:
        m = self.model
        geoms = set()
        gid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)
        if gid >= 0:
            geoms.add(gid)
        bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
        if bid >= 0:
            geoms.update(np.flatnonzero(m.geom_bodyid == bid).tolist())
        if not geoms and gid < 0 and bid < 0:
            raise ValueError(f"ignored_contact_pairs: {name!r} is neither a geom nor a body of the model")
        return np.array(sorted(geoms), dtype=int)

    def _snapshot_scene(self) -> list[tuple[int, int, np.ndarray, np.ndarray]]:
        """Copy the live state into the private ``MjData``; returns the attached bodies'
        ``(qpos address, parent, p_rel, q_rel)`` relative poses in the live simulation."""
        if getattr(self, "_plan_ready_for", None) != id(self.model):
            self._planning_setup()
        m, live, pd = self.model, self.data, self._plan_data
        pd.qpos[:] = live.qpos
        if m.nmocap:
            pd.mocap_pos[:] = live.mocap_pos
            pd.mocap_quat[:] = live.mocap_quat
        poses = []
        for body, parent, qadr in self._attached:
            # p_rel = R_p^T (p_b - p_p), q_rel = q_p^-1 q_b
            inv = np.empty(4)
            mujoco.mju_negQuat(inv, live.xquat[parent])
            q_rel = np.empty(4)
            mujoco.mju_mulQuat(q_rel, inv, live.xquat[body])
            p_rel = live.xmat[parent].reshape(3, 3).T @ (live.xpos[body] - live.xpos[parent])
            poses.append((qadr, parent, p_rel, q_rel))
        return poses

    def _load_plan_data(self, q: np.ndarray) -> mujoco.MjData:
        return self._scene_poser(self._snapshot_scene())(q)

    def _scene_poser(self, poses: list) -> Callable[[np.ndarray], mujoco.MjData]:
        """``pose(q)``: arm at ``q`` in the snapshot scene, attached bodies carried, contacts found."""
        m, pd, arm = self.model, self._plan_data, self._arm_qadr
        qpos, kinematics, collision, carry = pd.qpos, mujoco.mj_kinematics, mujoco.mj_collision, self._carry_attached

        def pose(q: np.ndarray) -> mujoco.MjData:
            qpos[arm] = q
            kinematics(m, pd)
            if poses:
                carry(pd, poses)
            collision(m, pd)
            return pd

        return pose

    def _carry_attached(self, pd: mujoco.MjData, poses: list) -> None:
        """Re-pose attached bodies so their pose relative to the parent equals the snapshot's."""
        for qadr, parent, p_rel, q_rel in poses:
            pos = pd.xpos[parent] + pd.xmat[parent].reshape(3, 3) @ p_rel
            quat = np.empty(4)
            mujoco.mju_mulQuat(quat, pd.xquat[parent], q_rel)
            pd.qpos[qadr:qadr + 3] = pos
            pd.qpos[qadr + 3:qadr + 7] = quat
        mujoco.mj_kinematics(self.model, pd)

    def _check_q(self, q: Any) -> np.ndarray:
        arr = np.asarray(q, np.float64)
        if arr.shape != (self.n_arm,) or not np.isfinite(arr).all():
            raise ValueError(f"q must be a finite array of shape ({self.n_arm},), got {arr!r}")
        return arr

    def is_valid(self, q: Any) -> bool:
        """True if arm configuration ``q`` ``(d,)`` is collision-free (module docstring)."""
        return self._is_valid_unchecked(self._check_q(q))

    def _is_valid_unchecked(self, q: np.ndarray) -> bool:
        """:meth:`is_valid` for a known-good float64 array (planner inner loops)."""
        return self._contacts_allowed(self._load_plan_data(q))

    def _contacts_allowed(self, pd: mujoco.MjData) -> bool:
        """No contact of ``pd`` penetrates ``planning_penetration`` or more outside the ignored pairs."""
        if pd.ncon == 0:
            return True
        contact = pd.contact
        deep = contact.dist <= -self.planning_penetration
        if not deep.any():
            return True
        g = contact.geom[deep]
        return bool(self._ignored_geoms[g[:, 0], g[:, 1]].all())

    def validity_checker(self) -> Callable[[np.ndarray], bool]:
        """:meth:`is_valid` against a snapshot of the current live state, for many checks in a row.

        Everything but the arm (objects, mocap bodies, attached bodies' relative poses) is copied
        from the live simulation once, now; the returned ``check(q)`` then only poses the arm and
        finds contacts. It takes known-good ``(d,)`` float64 arrays (no input checks) and gives
        the answer :meth:`is_valid` gives while the live state stays as it was at the snapshot.
        Any later :meth:`is_valid` call or snapshot replaces the scene of earlier checkers.
        """
        pose, allowed = self._scene_poser(self._snapshot_scene()), self._contacts_allowed

        def check(q: np.ndarray) -> bool:
            return allowed(pose(q))

        return check

    def colliding_pairs(self, q: Any) -> list[tuple[str, str, float]]:
        """``(geom_a, geom_b, penetration)`` of every contact that makes ``q`` invalid (for debugging)."""
        pd = self._load_plan_data(self._check_q(q))
        out = []
        for i in range(pd.ncon):
            c = pd.contact[i]
            if c.dist <= -self.planning_penetration and not self._ignored_geoms[c.geom[0], c.geom[1]]:
                out.append((self.model.geom(c.geom[0]).name, self.model.geom(c.geom[1]).name, float(-c.dist)))
        return out

    def is_segment_valid(self, q_start: Any, q_goal: Any, max_step: float | None = None) -> bool:
        """True if every configuration of the straight segment (steps ≤ ``max_step``,
        default ``dq_step / 2``) is valid, both ends included."""
        step = self.dq_step / 2 if max_step is None else float(max_step)
        qs = interpolate(self._check_q(q_start), self._check_q(q_goal), step)
        return all(self.is_valid(q) for q in qs)

    # ------------------------------------------------------------------ path execution
    def _check_path(self, path: Any) -> np.ndarray:
        arr = np.asarray(path, np.float64)
        d = self.n_arm
        if arr.ndim != 2 or arr.shape[1] != d or len(arr) < 1:
            raise ValueError(f"path must have shape (k, {d}) with k >= 1, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError("path must be finite (no NaN/inf)")
        lo, hi = self.joint_limits[:, 0] - _TOL, self.joint_limits[:, 1] + _TOL
        if np.any(arr < lo) or np.any(arr > hi):
            raise ValueError(f"path leaves the joint limits {self.joint_limits.tolist()}")
        steps = np.abs(np.diff(np.vstack([self.arm_qpos()[None], arr]), axis=0))  # type: ignore[attr-defined]
        bad = np.flatnonzero(steps.max(axis=1) > self.dq_step * (1 + _TOL) + _TOL)
        if len(bad):
            i = int(bad[0])
            what = "path[0] is farther than dq_step from arm_qpos()" if i == 0 else f"path[{i}] - path[{i - 1}]"
            raise ValueError(f"{what}: per-joint change {steps[i].max():.4f} rad exceeds dq_step={self.dq_step}; "
                             "use densify_path(path, env.dq_step)")
        return arr

    def _check_gripper(self, gripper: Any) -> np.ndarray:
        n = self.n_extra_actions
        if gripper is None:
            return np.zeros(n)
        arr = np.asarray(gripper, np.float64).reshape(-1)
        if arr.shape != (n,) or not np.all(np.isfinite(arr)):
            raise ValueError(f"gripper must be None or a finite array of {n} extra action value(s), got {gripper!r}")
        return arr

    def execute_path(self, path: Any, gripper: Any = None, discount: float = 1.0) -> PathResult:
        """Follow a joint-space path, one low-level env step per waypoint.

        Args:
            path: ``(k, d)`` waypoints; ``path[0]`` is the start configuration (normally
                ``arm_qpos()``, at most ``dq_step`` per joint away from it) and is not
                executed; ``k - 1`` steps follow. Step ``i`` uses the action
                ``(path[i+1] - path[i]) / dq_step`` with the servo set-point chained from
                ``path[i]`` (so the set-point is exactly ``path[i+1]``). Consecutive
                waypoints must differ by at most ``dq_step`` per joint (see
                :func:`densify_path`) and stay within ``joint_limits``.
            gripper: values of the extra action dims (e.g. the Lift gripper) applied on the
                **last** waypoint only; intermediate waypoints use 0. None = 0 throughout.
            discount: γ of ``discounted_return``.

        Stops early when a step terminates (success) or truncates (horizon). Raises
        ``ValueError`` before moving anything if the path or gripper is malformed.
        """
        arr = self._check_path(path)
        grip = self._check_gripper(gripper)
        result = PathResult(obs=None)
        try:
            for i in range(len(arr) - 1):
                self._path_reference = arr[i]
                action = np.clip((arr[i + 1] - arr[i]) / self.dq_step, -1.0, 1.0)
                extra = grip if i == len(arr) - 2 else np.zeros_like(grip)
                step = self.step  # type: ignore[attr-defined]
                obs, reward, terminated, truncated, info = step(np.concatenate([action, extra]))
                result.discounted_return += float(discount) ** i * reward
                result.rewards.append(float(reward))
                result.observations.append(obs)
                result.infos.append(info)
                result.obs, result.info = obs, info
                result.terminated, result.truncated = bool(terminated), bool(truncated)
                result.steps += 1
                if terminated or truncated:
                    break
        finally:
            self._path_reference = None
        if result.steps == 0:
            result.obs = self.current_observation()  # type: ignore[attr-defined]
            result.info = self.current_info()  # type: ignore[attr-defined]
        return result


__all__ = ["PlanningMixin", "PathResult", "interpolate", "densify_path", "plan_path"]
