"""Scripted expert for Push2DObstacle-v0: plan to a pre-contact pose, then push with small actions.

Uses only the env's planning interface (``is_valid``, ``colliding_pairs``, ``joint_limits``,
``arm_qpos``, ``dq_step``) plus the box/goal/fingertip positions:

1. **Choose a pushing pose.** The box must travel along ``u = (goal - box)/|goal - box|``.
   For gripper headings ``h`` within ±70° of ``u`` (the box is carried in the U-shaped gripper
   even when the heading and the push direction differ) and many elbow configurations
   (analytic IK of the planar arm), keep candidates whose pre-contact pose (fingertip 5.5 cm
   behind the box along ``h``) is valid and whose approach and push (fingertip moved along
   ``h`` to the box, then along ``u`` until the box would be at the goal) only touch the box.
   Prefer small heading deviations, then poses reachable in a straight line from the
   staging pose (below), then short joint distances.
2. **Plan** a collision-free joint path to the pre-contact pose and follow it waypoint by
   waypoint: a fixed route (planned once with :func:`~lfd_envs.mujoco.planning.plan_path`)
   swings the arm clockwise to a staging pose pointing up the free corridor, then
   ``plan_path`` (usually a straight line) reaches the episode's pre-contact pose.
3. **Approach and push** with damped-least-squares differential IK on the fingertip
   position and heading, at most 1.5 cm per step, re-aiming at the goal every step.

If no candidate or no path is found the expert retries a few steps later, from wherever the arm is.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from lfd_envs.mujoco.planning import plan_path
from lfd_envs.experts.episodes import EpisodeTracker

LINKS = np.array([0.1, 0.1, 0.1, 0.11])  # last: joint3 -> fingertip site
CONTACT = 0.02  # box centre ahead of the fingertip when it touches the cross bar
PRE_CONTACT = 0.055  # fingertip this far behind the box before the approach
MAX_MOVE = 0.015  # fingertip displacement per step (m)
#: heading deviations from the push direction tried, in order (degrees)
DEVIATIONS = (0, 10, -10, 20, -20, 30, -30, 40, -40, 50, -50, 60, -60, 70, -70)
#: via configurations from the start pose (arm along +x) to the staging pose (arm reaching up the
#: free corridor between obstacles 1 and 5, gripper pointing at the box region): the arm swings
#: clockwise, since obstacle 1 blocks the counter-clockwise way
VIA = (np.zeros(4), np.array([-np.pi / 2, 0.0, 0.0, 0.0]), np.array([-np.pi, -np.pi / 2, 0.0, 0.0]),
       np.array([-3.665, -0.716, -0.68, 2.289]))
_ROUTE_CACHE: dict[str, np.ndarray] = {}


def staging_route(env: Any) -> np.ndarray:
    """Collision-free joint path through :data:`VIA` (planned once per process, seeded)."""
    if "route" not in _ROUTE_CACHE:
        pieces = [VIA[0][None]]
        for a, b in zip(VIA[:-1], VIA[1:]):
            piece = plan_path(env, b, q_start=a, rng=np.random.default_rng(0), max_iters=20000)
            if piece is None:
                raise RuntimeError("Push2DExpert: no path to the staging pose; the scene geometry changed?")
            pieces.append(piece[1:])
        _ROUTE_CACHE["route"] = np.vstack(pieces)
    return _ROUTE_CACHE["route"]


def forward_kinematics(q: np.ndarray) -> tuple[np.ndarray, float]:
    """Fingertip (x, y) and heading of the planar arm."""
    angles = np.cumsum(q)
    return np.array([np.sum(LINKS * np.cos(angles)), np.sum(LINKS * np.sin(angles))]), float(angles[-1])


def jacobian(q: np.ndarray) -> np.ndarray:
    """3×4 Jacobian of (x, y, heading) w.r.t. q."""
    angles = np.cumsum(q)
    cx, sy = LINKS * np.cos(angles), LINKS * np.sin(angles)
    jac = np.ones((3, 4))
    jac[0] = -np.cumsum(sy[::-1])[::-1]
    jac[1] = np.cumsum(cx[::-1])[::-1]
    return jac


def _wrap(a: np.ndarray | float) -> np.ndarray | float:
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def inverse_kinematics(tip: np.ndarray, heading: float, q0_ref: float, n_base: int = 48) -> list[np.ndarray]:
    """All arm configurations (over a grid of base angles, both elbows) putting the fingertip
    at ``tip`` with ``heading``; joint0 is expressed within ±π of ``q0_ref``."""
    wrist = tip - LINKS[3] * np.array([np.cos(heading), np.sin(heading)])
    out = []
    for q0 in np.linspace(-np.pi, np.pi, n_base, endpoint=False):
        elbow = LINKS[0] * np.array([np.cos(q0), np.sin(q0)])
        dx, dy = wrist - elbow
        c2 = (dx * dx + dy * dy - LINKS[1] ** 2 - LINKS[2] ** 2) / (2 * LINKS[1] * LINKS[2])
        if abs(c2) > 1:
            continue
        for q2 in (np.arccos(c2), -np.arccos(c2)):
            a12 = np.arctan2(dy, dx) - np.arctan2(LINKS[2] * np.sin(q2), LINKS[1] + LINKS[2] * np.cos(q2))
            q1 = _wrap(a12 - q0)
            q3 = _wrap(heading - a12 - q2)
            if max(abs(q1), abs(q2), abs(q3)) <= 2.95:
                base = q0_ref + _wrap(q0 - q0_ref)
                out.append(np.array([base, q1, q2, q3]))
    return out


def dls_step(q: np.ndarray, d_tip: np.ndarray, d_heading: float, damping: float = 0.02) -> np.ndarray:
    """Joint change realising a fingertip displacement and heading change (damped least squares)."""
    jac = jacobian(q)
    err = np.array([d_tip[0], d_tip[1], 0.1 * d_heading])
    jac_w = jac * np.array([[1.0], [1.0], [0.1]])
    return jac_w.T @ np.linalg.solve(jac_w @ jac_w.T + damping ** 2 * np.eye(3), err)


class Push2DExpert:
    """Expert for :class:`~lfd_envs.mujoco.push2d.Push2DObstacleEnv` (module docstring).

    Args:
        env: the env (wrappers allowed; the expert reads ``env.unwrapped``).
        seed: seed of the path planner's generator (re-seeded with it at every ``reset``).
    """

    def __init__(self, env: Any, seed: int = 0) -> None:
        self.env = env.unwrapped
        self.seed = int(seed)
        self._episodes = EpisodeTracker(env)
        self.reset()

    def reset(self) -> None:
        """Forget the current plan (done by itself when the env starts a new episode)."""
        self._episodes.mark()
        self._rng = np.random.default_rng(self.seed)
        self._path: np.ndarray | None = None
        self._waypoint = 0
        self._heading: float | None = None
        self._phase = "plan"
        self._retry_in = 0

    # ------------------------------------------------------------------ choosing the pose
    def _touches_only_box(self, q: np.ndarray) -> bool:
        return all("box" in (a, b) for a, b, _ in self.env.colliding_pairs(q))

    def _push_is_free(self, q: np.ndarray, heading: float, u: np.ndarray, box: np.ndarray, goal: np.ndarray) -> bool:
        """Simulate the approach and push kinematically; True if only the box is ever touched."""
        tip, _ = forward_kinematics(q)
        end = goal - CONTACT * np.array([np.cos(heading), np.sin(heading)])
        contact = box - CONTACT * np.array([np.cos(heading), np.sin(heading)])
        for target in (contact, end):
            for _ in range(40):
                delta = target - tip
                if np.linalg.norm(delta) < 0.003:
                    break
                delta *= min(1.0, 0.01 / np.linalg.norm(delta))
                q = q + dls_step(q, delta, float(_wrap(heading - forward_kinematics(q)[1])))
                tip, _ = forward_kinematics(q)
                if not self._touches_only_box(q):
                    return False
            if np.linalg.norm(target - tip) > 0.01:
                return False
        return True

    def _pre_contact_pose(self) -> tuple[np.ndarray, float] | None:
        env = self.env
        box, goal, q_now = env.box_xy(), env.goal, VIA[-1]
        u = goal - box
        u /= max(np.linalg.norm(u), 1e-9)
        base = float(np.arctan2(u[1], u[0]))
        for deviation in np.deg2rad(DEVIATIONS):
            heading = base + deviation
            h = np.array([np.cos(heading), np.sin(heading)])
            candidates = inverse_kinematics(box - PRE_CONTACT * h, heading, q_now[0])
            candidates.sort(key=lambda c: float(np.abs(c - q_now).sum()))
            good = [q for q in candidates if env.is_valid(q) and self._push_is_free(q, heading, u, box, goal)]
            if good:  # prefer a pose reachable in a straight line from the staging pose
                straight = [q for q in good if env.is_segment_valid(q_now, q)]
                return (straight or good)[0], heading
        return None

    # ------------------------------------------------------------------ acting
    def _plan(self) -> bool:
        choice = self._pre_contact_pose()
        if choice is None:
            return False
        q_pre, self._heading = choice
        tail = plan_path(self.env, q_pre, q_start=VIA[-1], rng=self._rng, max_iters=3000)
        if tail is None:
            return False
        path = np.vstack([staging_route(self.env), tail[1:]])
        self._path, self._waypoint, self._phase = path, 1, "follow"
        return True

    def _follow(self, q: np.ndarray) -> np.ndarray:
        assert self._path is not None
        while self._waypoint < len(self._path) - 1 and np.abs(self._path[self._waypoint] - q).max() < 0.3 * self.env.dq_step:
            self._waypoint += 1
        target = self._path[self._waypoint]
        if self._waypoint == len(self._path) - 1 and np.abs(target - q).max() < 0.02:
            self._phase = "approach"
        return (target - q) / self.env.dq_step

    def _push(self, q: np.ndarray) -> np.ndarray:
        env = self.env
        box, goal = env.box_xy(), env.goal
        h = np.array([np.cos(self._heading), np.sin(self._heading)])
        u = goal - box
        u /= max(np.linalg.norm(u), 1e-9)
        tip, heading = forward_kinematics(q)
        target = box - CONTACT * h  # box against the cross bar, inside the U
        if self._phase == "approach" and np.linalg.norm(target - tip) < 0.006:
            self._phase = "push"
        if self._phase == "push":
            target = target + 0.03 * u  # carry the box towards the goal
        delta = target - tip
        norm = np.linalg.norm(delta)
        if norm > MAX_MOVE:
            delta *= MAX_MOVE / norm
        return dls_step(q, delta, float(_wrap(self._heading - heading))) / env.dq_step

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, None]:
        """Action for the env's current state (``observation`` is not needed; privileged state is read)."""
        if self._episodes.new_episode():
            self.reset()
        q = self.env.arm_qpos()
        action = np.zeros(4)
        if self._phase == "plan":
            if self._retry_in > 0:
                self._retry_in -= 1
            elif not self._plan():
                self._retry_in = 5
        if self._phase == "follow":
            action = self._follow(q)
        if self._phase in ("approach", "push"):
            action = self._push(q)
        return np.clip(action, -1.0, 1.0).astype(np.float32), None


__all__ = ["Push2DExpert", "forward_kinematics", "inverse_kinematics"]
