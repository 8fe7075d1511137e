"""Joint-space motion planning with OMPL (``ompl`` 2.x nanobind bindings).

The planning interface of the obstructed MuJoCo envs (``is_valid``, ``joint_limits``,
``dq_step``; :mod:`lfd_envs.mujoco.planning`) plus :class:`OMPLPlanner` is all an arm task needs
for planned motion; the Sawyer experts and ``lfd_agents.mopa`` both use it, and OMPL is imported
only here (lazily, when a planner first plans). :func:`ompl_available` tells whether it can be.

:class:`OMPLPlanner` plans a collision-free joint path between two arm configurations given
only a validity function ``is_valid(q) -> bool`` and the joint limits, so it is usable on its
own (no RL, no wrapper)::

    planner = OMPLPlanner(env.is_valid, env.joint_limits, dq_step=env.dq_step)
    result = planner.plan(env.arm_qpos(), q_goal)
    if result.success:
        env.execute_path(result.path)

A query first tries the straight line (increments ≤ 0.8·Δq_step, every increment checked);
only if that is blocked does it run RRT-Connect (or RRT*), simplify the solution and densify
it so that no joint moves more than Δq_step between consecutive waypoints. Every returned
waypoint has been checked with ``is_valid``.

Cost of a query: the search stops at ``time_limit`` or, with ``max_checks``, after that many
validity checks of the OMPL search, whichever comes first. A budget in checks does not depend on
the machine's speed or load, so a seeded planner's failures are as reproducible as its paths;
size it from the check counts of the queries that succeed (``tools/mopa_planner_queries.py``).
When ``is_valid`` is the bound ``is_valid`` of an env offering ``validity_checker()`` (the
planning interface of :mod:`lfd_envs.mujoco.planning`), each query takes one snapshot of the
scene from it and checks every configuration of that query against the snapshot, instead of
copying the live simulation state at every check (``snapshot_scene=False`` turns this off).

Interpreter-exit noise: nanobind prints "leaked instances" warnings when OMPL objects are still
alive at shutdown (the Python validity callback held inside C++ forms a cycle the garbage
collector cannot see). ``ompl`` 2.0.1 does not expose nanobind's ``set_leak_warnings``, so this
module releases the OMPL objects of every live planner in an ``atexit`` hook (which runs
before nanobind's check); :meth:`OMPLPlanner.close` does the same for one planner. OMPL's own
console log is lowered to errors (``log_level`` argument).

Determinism: OMPL draws all randomness from RNG objects that take their seeds, when they are
created, from one process-global seed generator, so by default a path depends on every OMPL
object created before in the process. ``ompl.util.RNG.setSeed`` re-seeds that generator even
after first use (OMPL then logs "Changing seed now will not lead to deterministic sampling",
which is only true of the RNGs already created). A planner built with ``seed`` therefore
re-seeds the generator before each of its OMPL queries, with a seed drawn from
``(seed, query index)``, and then makes every object of that query that draws random numbers
(the planner with its search trees, the path simplifier; the sampler is made anew after every
``clear``), which costs about 10 µs. Its ``k``-th query then gives the same path whatever ran
before, in the process or in this planner, as long as the search ends within its limits: the
check budget is exact, while a time-limited failure, and RRT*'s anytime result, depend on the
machine's speed. Unseeded planners keep OMPL's behaviour.
"""

from __future__ import annotations

import atexit
import time
import weakref
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

__all__ = ["OMPLPlanner", "PlanResult", "PLANNER_ALGORITHMS", "straight_line", "densify", "ompl_available",
           "query_seed"]

#: algorithm name -> OMPL geometric planner class name
PLANNER_ALGORITHMS = {"rrt_connect": "RRTConnect", "rrt_star": "RRTstar"}

#: half-width of the planning interval of an unlimited joint around the query start [rad]
_UNLIMITED_HALF_RANGE = 2.0 * np.pi

_LIVE_PLANNERS: "weakref.WeakSet[OMPLPlanner]" = weakref.WeakSet()


def _release_all_planners() -> None:
    """atexit hook: free every planner's OMPL objects before nanobind's leak check runs."""
    for planner in list(_LIVE_PLANNERS):
        planner.close()
    import gc

    gc.collect()


atexit.register(_release_all_planners)


def ompl_available() -> bool:
    """Whether the ``ompl`` Python bindings can be imported."""
    try:
        import ompl  # noqa: F401
    except ImportError:
        return False
    return True


@dataclass
class PlanResult:
    """Outcome of :meth:`OMPLPlanner.plan`.

    Attributes:
        path: ``(k, d)`` waypoints to execute, the start excluded; empty when ``success`` is False.
        status: ``"interpolation"`` (straight line was free), ``"planner"`` (OMPL solution),
            ``"invalid_start"``, ``"invalid_goal"`` or ``"failed"`` (no exact solution in time).
        planning_time: wall-clock seconds spent in the query.
    """

    path: np.ndarray
    status: str
    planning_time: float = 0.0
    extra: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return self.status in ("interpolation", "planner")

    @property
    def used_planner(self) -> bool:
        """True when the sampling-based planner ran (straight line blocked)."""
        return self.status in ("planner", "failed")


def straight_line(start: np.ndarray, goal: np.ndarray, max_step: float) -> np.ndarray:
    """Waypoints from ``start`` (excluded) to ``goal`` (included), ≤ ``max_step`` per joint apart."""
    start, goal = np.asarray(start, dtype=np.float64), np.asarray(goal, dtype=np.float64)
    n = max(1, int(np.ceil(np.max(np.abs(goal - start)) / max_step - 1e-9)))
    fractions = np.arange(1, n + 1, dtype=np.float64)[:, None] / n
    return start + fractions * (goal - start)


def densify(path: np.ndarray, max_step: float) -> np.ndarray:
    """Insert straight-line points so no joint moves more than ``max_step`` between waypoints.

    ``path`` is ``(n, d)`` including its start; the result excludes the start.
    """
    pieces = [straight_line(a, b, max_step) for a, b in zip(path[:-1], path[1:])]
    return np.concatenate(pieces, axis=0) if pieces else np.zeros((0, path.shape[1]))


class OMPLPlanner:
    """Sampling-based joint-space planner around a Python validity function.

    Args:
        is_valid: ``is_valid(q) -> bool`` for a ``(d,)`` configuration (collision check).
        joint_limits: ``(d, 2)`` lower/upper bounds; non-finite entries mark unlimited joints
            (planned within ±2π of the query start).
        dq_step: largest per-joint change between returned waypoints (one low-level step).
        algorithm: ``"rrt_connect"`` (default) or ``"rrt_star"``.
        time_limit: seconds per OMPL query (default 1.0).
        range: planner extension length in joint space, L2 (0.1 for Sawyer, 0.2 for 2D).
        check_resolution: largest per-joint distance between validity checks of the returned
            path and of straight lines; defaults to ``dq_step / 2``.
        motion_resolution: joint-space (L2) spacing of OMPL's edge checks while searching;
            defaults to ``check_resolution``. A coarser value makes the search cheaper; the
            returned path is always re-checked at ``check_resolution`` (and re-planned, up to
            ``max_attempts`` times, if that fails).
        simplify: how to shorten the OMPL solution before densifying: ``True``/``"shortcut"``
            (default: OMPL's vertex shortcutting ``reduceVertices``, then merging of close
            vertices -- a few ms), ``"max"`` (OMPL's full ``simplifySolution`` with B-spline
            smoothing, up to ``simplify_time``; often 10x the search time) or ``False``.
        simplify_time: seconds allowed for ``simplify="max"``.
        interpolate_first: try the straight line before planning (default True).
        max_attempts: OMPL queries per plan when a solution fails the final segment check
            (all within ``time_limit``).
        max_checks: validity checks the OMPL search of one plan may run (all attempts
            together); ``None`` (default): limited by ``time_limit`` only.
        snapshot_scene: check a query's configurations against one snapshot of the scene
            (module docstring); only used when ``is_valid`` offers it.
        seed: seed of this planner's OMPL queries: with a seed, the ``k``-th OMPL query gives
            the same path whatever ran before in the process (module docstring); ``None``
            leaves OMPL's process-global randomness as it is.
        log_level: OMPL console log level name (``"error"`` by default; ``"info"`` is OMPL's).
    """

    def __init__(
        self,
        is_valid: Callable[[np.ndarray], bool],
        joint_limits: np.ndarray,
        *,
        dq_step: float,
        algorithm: str = "rrt_connect",
        time_limit: float = 1.0,
        range: float = 0.1,  # noqa: A002 - OMPL's name for the extension length
        check_resolution: float | None = None,
        motion_resolution: float | None = None,
        simplify: bool | str = True,
        simplify_time: float = 0.1,
        interpolate_first: bool = True,
        max_attempts: int = 3,
        max_checks: int | None = None,
        snapshot_scene: bool = True,
        seed: int | None = None,
        log_level: str = "error",
    ) -> None:
        if not callable(is_valid):
            raise TypeError(f"is_valid must be callable, got {type(is_valid).__name__}")
        limits = np.asarray(joint_limits, dtype=np.float64)
        if limits.ndim != 2 or limits.shape[1] != 2 or limits.shape[0] < 1:
            raise ValueError(f"joint_limits must have shape (d, 2), got {limits.shape}")
        finite = np.isfinite(limits).all(axis=1)
        if np.any(limits[finite, 0] >= limits[finite, 1]):
            raise ValueError(f"joint_limits need lower < upper on every joint, got {limits.tolist()}")
        if algorithm not in PLANNER_ALGORITHMS:
            raise ValueError(f"algorithm must be one of {sorted(PLANNER_ALGORITHMS)}, got {algorithm!r}")
        for name, value in (("dq_step", dq_step), ("time_limit", time_limit), ("range", range)):
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value}")
        self.is_valid = is_valid
        self.joint_limits = limits
        self.unlimited = ~finite
        self.dim = limits.shape[0]
        self.dq_step = float(dq_step)
        self.algorithm = algorithm
        self.time_limit = float(time_limit)
        self.range = float(range)
        self.check_resolution = float(check_resolution) if check_resolution else self.dq_step / 2
        self.motion_resolution = float(motion_resolution) if motion_resolution else self.check_resolution
        modes = {True: "shortcut", False: "none", "shortcut": "shortcut", "max": "max", "none": "none"}
        if not isinstance(simplify, (bool, str)) or simplify not in modes:
            raise ValueError(f"simplify must be a bool or one of 'shortcut', 'max', 'none', got {simplify!r}")
        self.simplify = modes[simplify]
        self.simplify_time = float(simplify_time)
        self.interpolate_first = bool(interpolate_first)
        self.max_attempts = max(1, int(max_attempts))
        if max_checks is not None and (isinstance(max_checks, bool) or not isinstance(max_checks, (int, np.integer))
                                       or max_checks < 1):
            raise ValueError(f"max_checks must be a positive integer or None, got {max_checks!r}")
        self.max_checks = None if max_checks is None else int(max_checks)
        self.snapshot_scene = bool(snapshot_scene)
        self._scene_checker = _scene_factory(is_valid) if self.snapshot_scene else None
        #: validity function of the OMPL callback (swapped per query) and OMPL checks so far;
        #: lists, so the callback reaches them without referencing ``self``
        self._query_check: list[Callable[[np.ndarray], bool]] = [_unchecked(is_valid)]
        self._ompl_checks = [0]
        self._active_check: Callable[[np.ndarray], bool] | None = None
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
            raise ValueError(f"seed must be a non-negative integer or None, got {seed!r}")
        self._set_log_level(log_level)
        self.seed = None if seed is None else int(seed)
        #: OMPL queries run so far (the index that, with ``seed``, seeds the next one)
        self.ompl_queries = 0
        self._offset = np.zeros(self.dim)
        self._ss = self._simplifier = None
        self.stats = {"calls": 0, "interpolation": 0, "planner": 0, "failed": 0, "invalid": 0, "time": 0.0}
        _LIVE_PLANNERS.add(self)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_env(cls, env, **kwargs) -> "OMPLPlanner":
        """Planner for an env exposing the planning interface (``is_valid``, ``joint_limits``, ``dq_step``)."""
        base = getattr(env, "unwrapped", env)
        missing = [a for a in ("is_valid", "joint_limits", "dq_step") if not hasattr(base, a)]
        if missing:
            raise TypeError(f"{type(base).__name__} lacks the planning interface attributes {missing}")
        kwargs.setdefault("dq_step", float(base.dq_step))
        return cls(base.is_valid, np.asarray(base.joint_limits), **kwargs)

    @staticmethod
    def _set_log_level(name: str) -> None:
        from ompl import util as ou

        levels = {"debug": ou.LOG_DEBUG, "info": ou.LOG_INFO, "warn": ou.LOG_WARN,
                  "error": ou.LOG_ERROR, "none": ou.LOG_NONE}
        if name not in levels:
            raise ValueError(f"log_level must be one of {sorted(levels)}, got {name!r}")
        ou.setLogLevel(levels[name])

    def _setup(self):
        """Build the OMPL problem lazily (state space, validity callback, planner)."""
        from ompl import base as ob
        from ompl import geometric as og

        space = ob.RealVectorStateSpace(self.dim)
        bounds = ob.RealVectorBounds(self.dim)
        for j, (lo, hi) in enumerate(self._bounds()):
            bounds.setLow(j, float(lo))
            bounds.setHigh(j, float(hi))
        space.setBounds(bounds)
        ss = og.SimpleSetup(space)
        # The callback must not reference ``self`` (a cycle through C++ that gc cannot see).
        ss.setStateValidityChecker(_make_checker(self._query_check, self._ompl_checks, self.dim,
                                                 weakref.ref(self)))
        si = ss.getSpaceInformation()
        extent = float(space.getMaximumExtent())
        si.setStateValidityCheckingResolution(min(1.0, self.motion_resolution / extent))
        self._ss, self._space, self._bounds_obj = ss, space, bounds
        self._new_search(ss)
        return ss

    def _new_search(self, ss) -> None:
        """A new OMPL planner (empty search trees) and path simplifier on ``ss``."""
        from ompl import geometric as og

        si = ss.getSpaceInformation()
        planner = getattr(og, PLANNER_ALGORITHMS[self.algorithm])(si)
        planner.setRange(self.range)
        ss.setPlanner(planner)
        ss.setup()
        self._simplifier = og.PathSimplifier(si)

    def _bounds(self) -> np.ndarray:
        """Planning bounds in offset coordinates (unlimited joints centred on the query start)."""
        b = self.joint_limits.copy()
        b[self.unlimited] = [-_UNLIMITED_HALF_RANGE, _UNLIMITED_HALF_RANGE]
        return b

    def close(self) -> None:
        """Release the OMPL objects (also done automatically at interpreter exit)."""
        self._ss = self._space = self._bounds_obj = self._simplifier = None

    def __del__(self) -> None:  # pragma: no cover - best effort
        try:
            self.close()
        except Exception:
            pass

    # ------------------------------------------------------------------ queries
    def clip(self, q: np.ndarray) -> np.ndarray:
        """Clip ``q`` to the limits of the limited joints."""
        q = np.asarray(q, dtype=np.float64).copy()
        lim = ~self.unlimited
        q[lim] = np.clip(q[lim], self.joint_limits[lim, 0], self.joint_limits[lim, 1])
        return q

    def check(self, q: np.ndarray) -> bool:
        """``is_valid(q)`` for a configuration in joint coordinates (during :meth:`plan`: the
        query's snapshot check)."""
        if self._active_check is not None:
            return bool(self._active_check(np.asarray(q, dtype=np.float64)))
        return bool(self.is_valid(np.asarray(q, dtype=np.float64)))

    def segment_is_valid(self, a: np.ndarray, b: np.ndarray, resolution: float | None = None) -> bool:
        """Check the straight segment a→b at ``resolution`` (per joint; default ``check_resolution``)."""
        pts = straight_line(a, b, resolution or self.check_resolution)
        return all(self.check(q) for q in pts)

    def interpolate(self, start: np.ndarray, goal: np.ndarray) -> np.ndarray | None:
        """Straight-line waypoints start→goal (increments ≤ 0.8·Δq_step), or None if one is invalid.

        Every increment is checked, plus intermediate points so that checks are at most
        ``check_resolution`` apart.
        """
        waypoints = straight_line(start, goal, 0.8 * self.dq_step)
        prev = np.asarray(start, dtype=np.float64)
        fine = self.check_resolution < 0.8 * self.dq_step
        for q in waypoints:
            if fine:
                if not self.segment_is_valid(prev, q):
                    return None
            elif not self.check(q):
                return None
            prev = q
        return waypoints

    def plan(self, start: np.ndarray, goal: np.ndarray, time_limit: float | None = None) -> PlanResult:
        """Plan a valid joint path from ``start`` to ``goal``.

        Returns a :class:`PlanResult` whose ``path`` excludes ``start``, ends exactly at
        ``goal`` and moves each joint by at most ``dq_step`` per waypoint.
        """
        t0 = time.perf_counter()
        start = self.clip(self._as_q(start, "start"))
        goal = self.clip(self._as_q(goal, "goal"))
        self.stats["calls"] += 1
        fast = self._scene_checker() if self._scene_checker is not None else _unchecked(self.is_valid)
        self._query_check[0] = self._active_check = fast
        try:
            result = self._plan(start, goal, self.time_limit if time_limit is None else float(time_limit))
        finally:
            self._active_check = None
        result.planning_time = time.perf_counter() - t0
        self.stats["time"] += result.planning_time
        key = result.status if result.status in self.stats else "invalid"
        self.stats[key] += 1
        return result

    def _plan(self, start: np.ndarray, goal: np.ndarray, time_limit: float) -> PlanResult:
        empty = np.zeros((0, self.dim))
        if not self.check(goal):
            return PlanResult(empty, "invalid_goal")
        if not self.check(start):
            return PlanResult(empty, "invalid_start")
        if self.interpolate_first:
            line = self.interpolate(start, goal)
            if line is not None:
                return PlanResult(line, "interpolation")
        deadline = time.perf_counter() + time_limit
        self._ompl_checks[0] = 0
        for attempt in range(self.max_attempts):
            remaining = deadline - time.perf_counter()
            if remaining <= 0 or self._budget_spent():
                break
            if self.algorithm == "rrt_star":  # anytime: share the budget between attempts
                remaining /= self.max_attempts - attempt
            raw = self._solve(start, goal, remaining, deadline)
            if raw is None:
                break
            path = densify(raw, self.dq_step)
            path[-1] = goal
            # OMPL checked its edges at the same resolution but at other points; re-check the
            # executed segments so every point at ``check_resolution`` spacing is valid.
            if self.path_is_valid(start, path):
                return PlanResult(path, "planner", extra={"raw_waypoints": len(raw), "attempts": attempt + 1,
                                                          "checks": self._ompl_checks[0]})
        return PlanResult(empty, "failed", extra={"checks": self._ompl_checks[0]})

    def _budget_spent(self) -> bool:
        return self.max_checks is not None and self._ompl_checks[0] >= self.max_checks

    def _termination(self, time_limit: float):
        """OMPL termination condition: ``time_limit`` seconds or the check budget spent,
        whichever comes first (``time_limit`` itself when there is no budget)."""
        from ompl import base as ob

        if self.max_checks is None:
            return time_limit
        end = time.perf_counter() + time_limit
        counter, budget, clock = self._ompl_checks, self.max_checks, time.perf_counter
        return ob.PlannerTerminationCondition(lambda: counter[0] >= budget or clock() >= end)

    def path_is_valid(self, start: np.ndarray, path: np.ndarray) -> bool:
        """Every waypoint and the straight segments between them (at ``check_resolution``) are valid."""
        prev = np.asarray(start, dtype=np.float64)
        for q in path:
            if not self.segment_is_valid(prev, q):
                return False
            prev = q
        return True

    def _solve(self, start: np.ndarray, goal: np.ndarray, time_limit: float, deadline: float) -> np.ndarray | None:
        """Run OMPL; returns the ``(n, d)`` solution including start and goal, or None."""
        if self.seed is not None:
            _seed_ompl(query_seed(self.seed, self.ompl_queries))
        self.ompl_queries += 1
        if self._ss is None:
            ss = self._setup()
        else:
            ss = self._ss
            if self.seed is not None:  # fresh search trees and simplifier, seeded for this query
                self._new_search(ss)
        self._offset = np.where(self.unlimited, start, 0.0)
        ss.clear()
        s, g = self._space.allocState(), self._space.allocState()
        s[0:self.dim] = (start - self._offset).tolist()
        g[0:self.dim] = (goal - self._offset).tolist()
        ss.setStartAndGoalStates(s, g, 1e-9)
        ss.solve(self._termination(time_limit))
        if not ss.haveExactSolutionPath():
            return None
        if self.simplify == "max":  # within the query's time budget (at least 10 ms)
            ss.simplifySolution(min(self.simplify_time, max(0.01, deadline - time.perf_counter())))
        path = ss.getSolutionPath()
        if self.simplify == "shortcut":
            simplifier = self._simplifier
            simplifier.reduceVertices(path)
            simplifier.collapseCloseVertices(path)
        d = self.dim
        states = np.array([path.getState(i)[0:d] for i in range(path.getStateCount())], dtype=np.float64)
        del path, s, g
        return states + self._offset

    def _as_q(self, q: np.ndarray, name: str) -> np.ndarray:
        q = np.asarray(q, dtype=np.float64).reshape(-1)
        if q.shape != (self.dim,) or not np.all(np.isfinite(q)):
            raise ValueError(f"{name} must be a finite configuration of shape ({self.dim},), got {q}")
        return q

    @property
    def offset(self) -> np.ndarray:
        """Offset added to OMPL states to get joint coordinates (non-zero on unlimited joints)."""
        return self._offset


def query_seed(seed: int, index: int) -> int:
    """OMPL seed (1 .. 2³¹−1; OMPL refuses 0) of query ``index`` of a planner seeded ``seed``."""
    state = np.random.SeedSequence([int(seed), int(index)]).generate_state(1, dtype=np.uint32)[0]
    return int(state) % (2**31 - 1) + 1


def _seed_ompl(value: int) -> None:
    """Re-seed OMPL's process-global seed generator, without its "already started" log line."""
    from ompl import util as ou

    level = ou.getLogLevel()
    ou.setLogLevel(ou.LOG_NONE)
    try:
        ou.RNG.setSeed(int(value))
    finally:
        ou.setLogLevel(level)


def _unchecked(is_valid: Callable[[np.ndarray], bool]) -> Callable[[np.ndarray], bool]:
    """The owner's input-check-free ``_is_valid_unchecked`` when ``is_valid`` is a bound
    ``is_valid`` method offering one (the planner only passes finite float64 ``(d,)`` arrays),
    else ``is_valid`` itself."""
    owner = getattr(is_valid, "__self__", None)
    fast = getattr(owner, "_is_valid_unchecked", None)
    if getattr(is_valid, "__name__", None) == "is_valid" and callable(fast):
        return fast
    return is_valid


def _scene_factory(is_valid: Callable[[np.ndarray], bool]) -> Callable[[], Callable[[np.ndarray], bool]] | None:
    """The owner's ``validity_checker`` (a per-query snapshot check) when ``is_valid`` is a bound
    ``is_valid`` method of an object offering one, else None."""
    owner = getattr(is_valid, "__self__", None)
    factory = getattr(owner, "validity_checker", None)
    if getattr(is_valid, "__name__", None) == "is_valid" and callable(factory):
        return factory
    return None


def _make_checker(holder: list, counter: list, dim: int, planner_ref: weakref.ref):
    """OMPL validity callback converting a state to joint coordinates and counting checks.

    ``holder[0]`` is the validity function of the current query and ``counter[0]`` the checks
    run so far; the callback holds only these lists and a weakref to the planner.
    """

    def check(state) -> bool:
        planner = planner_ref()
        offset = planner._offset if planner is not None else 0.0
        counter[0] += 1
        return bool(holder[0](np.array(state[0:dim]) + offset))

    def check_limited(state) -> bool:  # no unlimited joints: no offset (saves ~2 µs a call)
        counter[0] += 1
        return bool(holder[0](np.array(state[0:dim])))

    planner = planner_ref()
    return check if planner is None or planner.unlimited.any() else check_limited
