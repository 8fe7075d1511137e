"""Picker action modes shared by every particle task (SPEC §4.3), batched over worlds.

An action mode turns a batch of normalised actions ``(W, A)`` into the picker motion of one
env step: picker targets ``(T, W, P, 3)`` and grasp flags ``(T, W, P)`` for ``T`` engine frames
(each frame moves every picker linearly to its target, see :meth:`ParticleSim.step`).
The frame count of a step depends only on the world's own action (the same for every action
unless a pick-and-place speed limit is set) and a world holds still after its own frames
(:class:`PickerMotion`), so a world's future never depends on the other worlds of a batch (a
vector env equals single envs).

* :class:`DeltaActions` (SoftGym/DMfD) - per picker ``[dx, dy, dz, grasp]``: the picker moves
  ``0.01 * a`` m per frame for ``action_repeat`` = 8 frames (<= 0.08 m per axis and step) and
  grasps while ``grasp > 0``. Positions are clipped to the workspace (minus the picker radius).
* :class:`PickPlaceActions` (MAIL) - per picker ``[pick xyz, place xyz]`` normalised to the
  task's workspace box; one step runs approach -> descend -> grasp -> lift -> carry -> lower ->
  release -> retreat for all pickers at once, then lets the scene settle.
"""

from __future__ import annotations

import functools
import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from gymnasium import spaces

__all__ = ["Workspace", "ActionMode", "DeltaActions", "PickPlaceActions", "PickPlaceSchedule",
           "ACTION_MODES", "PickerMotion", "make_action_mode", "carry_point", "arc_length", "FAST_FREE_MOVES"]


def _read_only(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class Workspace:
    """Axis-aligned box (metres) in which picker centres move; ``low[2]`` is usually the table.

    Picker centres are kept ``margin`` (the picker radius) inside the box, so a picker resting
    on the table has its centre at ``z = low[2] + margin``.
    """

    low: tuple[float, float, float]
    high: tuple[float, float, float]
    margin: float = 0.0

    def __post_init__(self) -> None:
        lo, hi = np.asarray(self.low, float), np.asarray(self.high, float)
        if lo.shape != (3,) or hi.shape != (3,) or np.any(hi - lo <= 2 * self.margin):
            raise ValueError(f"workspace needs low < high (by more than 2*margin), got {self.low}, {self.high}")

    @functools.cached_property
    def lo(self) -> np.ndarray:
        """``low`` as a read-only float64 array (computed once)."""
        return _read_only(np.asarray(self.low, dtype=np.float64))

    @functools.cached_property
    def hi(self) -> np.ndarray:
        """``high`` as a read-only float64 array (computed once)."""
        return _read_only(np.asarray(self.high, dtype=np.float64))

    @functools.cached_property
    def _clip_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return _read_only(self.lo + self.margin), _read_only(self.hi - self.margin)

    def clip(self, pos: np.ndarray) -> np.ndarray:
        """Clip picker centres ``(..., 3)`` into ``[low + margin, high - margin]``."""
        return np.clip(pos, *self._clip_bounds)

    def to_world(self, a: np.ndarray) -> np.ndarray:
        """Map normalised coordinates in [-1, 1] ``(..., 3)`` to metres (not clipped)."""
        return self.lo + (np.asarray(a, dtype=np.float64) + 1.0) * 0.5 * (self.hi - self.lo)

    def to_action(self, pos: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`to_world`, clipped to [-1, 1]."""
        a = 2.0 * (np.asarray(pos, dtype=np.float64) - self.lo) / (self.hi - self.lo) - 1.0
        return np.clip(a, -1.0, 1.0)


class ActionMode(ABC):
    """How a normalised action drives the pickers during one env step."""

    name: ClassVar[str]
    #: numbers per picker in the action vector
    per_picker: ClassVar[int]

    def __init__(self, num_pickers: int, workspace: Workspace) -> None:
        self.num_pickers = int(num_pickers)
        self.workspace = workspace

    @property
    def action_space(self) -> spaces.Box:
        """float32 ``Box`` in [-1, 1] of ``per_picker * num_pickers`` numbers."""
        return spaces.Box(-1.0, 1.0, (self.per_picker * self.num_pickers,), np.float32)

    @property
    @abstractmethod
    def frames_per_step(self) -> int:
        """Engine frames ``T`` run by one env step (the same for every action)."""

    @abstractmethod
    def plan(self, actions: np.ndarray, pickers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Picker targets ``(T, W, P, 3)`` and grasp flags ``(T, W, P)`` for actions ``(W, A)``.

        ``pickers`` are the current picker centres ``(W, P, 3)``.
        """

    def plan_motion(self, actions: np.ndarray, pickers: np.ndarray) -> "PickerMotion":
        """:meth:`plan` with the number of frames each world runs (all ``T`` here)."""
        targets, grasp = self.plan(actions, pickers)
        return PickerMotion(targets, grasp, np.full(targets.shape[1], targets.shape[0], dtype=np.int64))


@dataclass(frozen=True)
class PickerMotion:
    """The picker motion of one env step for a batch of worlds.

    Attributes:
        targets: Picker centres ``(T, W, P, 3)`` at the end of each frame.
        grasp: Grasp flags ``(T, W, P)`` of each frame.
        frames: Frames each world runs ``(W,)``, at most ``T``; a world holds still after its own
            frames (see ``ParticleSim.step_frames``), so its future does not depend on the others.
    """

    targets: np.ndarray
    grasp: np.ndarray
    frames: np.ndarray


class DeltaActions(ActionMode):
    """Per picker ``[dx, dy, dz, grasp]`` in [-1, 1]: ``step_size * a`` metres per frame."""

    name = "delta"
    per_picker = 4

    def __init__(self, num_pickers: int, workspace: Workspace, action_repeat: int = 8,
                 step_size: float = 0.01) -> None:
        super().__init__(num_pickers, workspace)
        self.action_repeat = int(action_repeat)
        self.step_size = float(step_size)

    @property
    def frames_per_step(self) -> int:
        return self.action_repeat

    def plan(self, actions: np.ndarray, pickers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        a = np.asarray(actions, dtype=np.float64).reshape(len(actions), self.num_pickers, 4)
        delta = a[..., :3] * self.step_size
        grasp = np.broadcast_to(a[..., 3] > 0.0, (self.action_repeat,) + a.shape[:2])
        targets = np.empty((self.action_repeat,) + pickers.shape)
        pos = np.asarray(pickers, dtype=np.float64)
        for t in range(self.action_repeat):
            pos = self.workspace.clip(pos + delta)
            targets[t] = pos
        return targets, np.ascontiguousarray(grasp)


@dataclass(frozen=True)
class PickPlaceSchedule:
    """Timing and path of one pick-and-place step.

    Path of a picker: approach (above the pick point at ``hover``) -> descend -> grasp -> lift
    (vertically by ``lift``) -> carry along an arc to above the place point -> lower -> hold
    (``hold_frames``, lets a draped cloth come to rest) -> release -> retreat (``hover`` above
    the place point). The carry arc rises ``arc`` above the straight
    line between its ends, ``arc = clip(arc_ratio * d, 0, arc_max)`` for a horizontal distance
    ``d``: with ``arc_ratio = 0.5`` the held point moves on a half circle around the middle, the
    natural motion of a fold (the held edge keeps its distance to the fold line); with 0 it is a
    straight carry (rope dragging, box moving). See :func:`carry_point`.

    Each phase moves at ``speed`` (m/frame) but takes at least one and at most ``*_frames``
    frames (faster when the distance needs it). Phase lengths are per world; the step always
    lasts :attr:`total_frames` frames and worlds that finish early settle with released pickers.

    With ``max_speed`` set, a picker that holds something (lift, carry, lower) never moves
    faster than ``max_speed`` m/frame: those phases take as many frames as their distance needs
    (their ``*_frames`` bounds no longer apply), so a step's length depends on the action (never
    below :attr:`total_frames`), and each world runs its own number of frames
    (:class:`PickerMotion`). ``max_free_speed`` does the same for empty pickers (approach,
    descend, release, retreat); they need it only when the engine's ``picker_collision`` is on,
    since otherwise they touch nothing.

    Attributes:
        hover: Approach height (m) above the pick point, and retreat height after release.
        lift: Vertical lift (m) after the grasp and before the carry (and the final lowering).
        arc_ratio: Arc height per metre of horizontal carry distance.
        arc_max: Upper bound of the arc height (m).
        free_speed: Speed (m/frame) of empty pickers.
        carry_speed: Speed (m/frame) of pickers that hold something.
        max_speed: Speed limit (m/frame) of pickers that hold something, or None (no limit
            beyond the phase frame bounds).
        max_free_speed: Speed limit (m/frame) of empty pickers, or None.
    """

    hover: float = 0.05
    lift: float = 0.05
    arc_ratio: float = 0.0
    arc_max: float = 0.4
    free_speed: float = 0.04
    carry_speed: float = 0.015
    approach_frames: int = 16
    descend_frames: int = 8
    grasp_frames: int = 1
    lift_frames: int = 8
    carry_frames: int = 56
    lower_frames: int = 8
    hold_frames: int = 0
    release_frames: int = 1
    retreat_frames: int = 4
    settle_frames: int = 6
    max_speed: float | None = None
    max_free_speed: float | None = None

    def __post_init__(self) -> None:
        for name in ("max_speed", "max_free_speed"):
            value = getattr(self, name)
            if value is not None and not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number of metres per frame or None, got {value}")

    @property
    def limited(self) -> bool:
        """Whether a speed limit makes step lengths depend on the action."""
        return self.max_speed is not None or self.max_free_speed is not None

    @property
    def total_frames(self) -> int:
        """Frames of every step without a speed limit (with one: the fewest a step takes)."""
        return (self.approach_frames + self.descend_frames + self.grasp_frames + self.lift_frames
                + self.carry_frames + self.lower_frames + self.hold_frames + self.release_frames + self.retreat_frames
                + self.settle_frames)

    def most_frames(self, workspace: Workspace) -> int:
        """The longest a step can last in ``workspace`` (:attr:`total_frames` without a speed limit)."""
        span = float(np.linalg.norm(workspace.hi - workspace.lo - 2.0 * workspace.margin))
        total = self.total_frames
        if self.max_speed is not None:  # lift, carry (chord + rise, fastest at pi/2 its mean speed), lower
            total += self._frames_beyond(self.max_speed, [(self.lift, self.lift_frames),
                                                          (math.pi / 2 * (span + 2.0 * self.arc_max), self.carry_frames),
                                                          (self.lift, self.lower_frames)])
        if self.max_free_speed is not None:  # approach, descend (hover), retreat (hover)
            total += self._frames_beyond(self.max_free_speed, [(span, self.approach_frames),
                                                               (self.hover, self.descend_frames),
                                                               (self.hover, self.retreat_frames)])
        return total

    @staticmethod
    def _frames_beyond(speed: float, phases: list[tuple[float, int]]) -> int:
        """Frames that phases of the given (longest distance, frame bound) need beyond their bounds."""
        return sum(max(0, math.ceil(d / speed - 1e-9) - bound) for d, bound in phases)

    def arc_height(self, start: np.ndarray, end: np.ndarray) -> np.ndarray:
        """Arc height ``(...)`` of carries from ``start`` to ``end`` ``(..., 3)``."""
        d = np.linalg.norm(np.asarray(end)[..., :2] - np.asarray(start)[..., :2], axis=-1)
        return np.clip(self.arc_ratio * d, 0.0, self.arc_max)

    def waypoints(self, pick: np.ndarray, place: np.ndarray, top: float) -> dict[str, np.ndarray]:
        """Key points ``(..., 3)`` of the path: ``above_pick``, ``lifted``, ``above_place``,
        ``retreat`` (heights capped at ``top``)."""
        def raised(p: np.ndarray, dz: float) -> np.ndarray:
            out = np.array(p, dtype=np.float64, copy=True)
            out[..., 2] = np.minimum(out[..., 2] + dz, top)
            return out

        return {"above_pick": raised(pick, self.hover), "lifted": raised(pick, self.lift),
                "above_place": raised(place, self.lift), "retreat": raised(place, self.hover)}


#: :class:`PickPlaceSchedule` overrides that move *empty* pickers (approach, descend, retreat) in
#: one frame each, and lift/lower the held point (by ``lift`` <= 0.03 m) in the frames it needs.
#: Pickers do not collide with particles, so a fast empty picker changes nothing physically; the
#: frames saved are engine work where nothing happens (cloth-fold tasks: ~40 % fewer frames).
FAST_FREE_MOVES: dict[str, float | int] = {"free_speed": 2.0, "approach_frames": 1, "descend_frames": 1,
                                           "retreat_frames": 1, "lift_frames": 2, "lower_frames": 2}


def carry_point(start: np.ndarray, end: np.ndarray, height: np.ndarray, alpha: np.ndarray, top: float) -> np.ndarray:
    """Point at progress ``alpha`` in [0, 1] of the carry arc from ``start`` to ``end``.

    ``theta = pi * alpha``; the point moves ``(1 - cos theta) / 2`` of the way along the
    straight line and rises ``height * sin theta`` above it (a half ellipse; a half circle
    around the midpoint when ``height`` is half the horizontal distance). Shapes broadcast:
    ``start``/``end`` ``(..., 3)``, ``height`` ``(...)``, ``alpha`` ``(...)``.
    """
    theta = np.pi * np.asarray(alpha, dtype=np.float64)
    frac = (0.5 * (1.0 - np.cos(theta)))[..., None]
    point = start + frac * (end - start)
    point[..., 2] = np.minimum(point[..., 2] + np.asarray(height) * np.sin(theta), top)
    return point


def arc_length(start: np.ndarray, end: np.ndarray, height: np.ndarray) -> np.ndarray:
    """Length estimate ``(...)`` of a carry arc (chord plus twice the rise, an upper bound)."""
    return np.linalg.norm(end - start, axis=-1) + 2.0 * np.asarray(height)


class PickPlaceActions(ActionMode):
    """Per picker ``[pick x, y, z, place x, y, z]`` in [-1, 1], normalised to the workspace box.

    The action vector lists the picks of all pickers first, then their places (MAIL layout):
    ``[pick_1, ..., pick_P, place_1, ..., place_P]``, 3 numbers each.
    """

    name = "pick_place"
    per_picker = 6

    def __init__(self, num_pickers: int, workspace: Workspace,
                 schedule: PickPlaceSchedule | None = None) -> None:
        super().__init__(num_pickers, workspace)
        self.schedule = schedule or PickPlaceSchedule()

    @property
    def frames_per_step(self) -> int:
        """Frames of a step (with a speed-limited schedule: the most a step can take)."""
        return self.schedule.most_frames(self.workspace)

    def split(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pick and place points in metres, each ``(W, P, 3)``, clipped to the workspace."""
        a = np.asarray(actions, dtype=np.float64).reshape(len(actions), 2, self.num_pickers, 3)
        ws = self.workspace
        return ws.clip(ws.to_world(a[:, 0])), ws.clip(ws.to_world(a[:, 1]))

    def join(self, pick: np.ndarray, place: np.ndarray) -> np.ndarray:
        """Normalised action ``(..., 6P)`` of pick/place points ``(..., P, 3)`` in metres."""
        ws = self.workspace
        pick, place = np.asarray(pick, np.float64), np.asarray(place, np.float64)
        a = np.concatenate([ws.to_action(pick), ws.to_action(place)], axis=-2)
        return a.reshape(a.shape[:-2] + (-1,)).astype(np.float32)

    def phases(self, pick: np.ndarray, place: np.ndarray) -> list[tuple[np.ndarray, bool, int, float, np.ndarray | None]]:
        """Phase list ``(end point (W, P, 3), grasp, max frames, speed, arc height or None)``."""
        s = self.schedule
        top = self.workspace.hi[2] - self.workspace.margin
        wpt = s.waypoints(pick, place, top)
        arc = s.arc_height(wpt["lifted"], wpt["above_place"])
        return [
            (wpt["above_pick"], False, s.approach_frames, s.free_speed, None),
            (pick, False, s.descend_frames, s.free_speed, None),
            (pick, True, s.grasp_frames, s.carry_speed, None),
            (wpt["lifted"], True, s.lift_frames, s.carry_speed, None),
            (wpt["above_place"], True, s.carry_frames, s.carry_speed, arc),
            (place, True, s.lower_frames, s.carry_speed, None),
            (place, True, s.hold_frames, 0.0, None),
            (place, False, s.release_frames, s.free_speed, None),
            (wpt["retreat"], False, s.retreat_frames, s.free_speed, None),
        ]

    def plan(self, actions: np.ndarray, pickers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        motion = self.plan_motion(actions, pickers)
        return motion.targets, motion.grasp

    def _phase_frames(self, length: np.ndarray, grab: bool, max_frames: int, speed: float,
                      peak: float = 1.0) -> np.ndarray:
        """Frames ``(W,)`` of one phase whose pickers travel ``length`` ``(W, P)`` metres; ``peak``
        is the phase's largest speed over its mean speed (a carry eases in and out: pi/2)."""
        w = length.shape[0]
        if speed <= 0:  # fixed-length phase (hold)
            return np.full(w, max_frames, dtype=np.int64)
        limit = self.schedule.max_speed if grab else self.schedule.max_free_speed
        if limit is not None:  # limited phases: as long as the speed limit needs, at their fastest frame
            frames = np.maximum(np.ceil(length.max(axis=-1) / speed - 1e-9),
                                np.ceil(peak * length.max(axis=-1) / limit - 1e-9))
            return np.maximum(frames, 1).astype(np.int64)
        return np.clip(np.ceil(length.max(axis=-1) / speed - 1e-9), 1, max_frames).astype(np.int64)

    def _phase_frame_counts(self, phases: list, start: np.ndarray) -> list[np.ndarray]:
        """Frames ``(W,)`` of every phase of :meth:`phases` (0 for skipped phases)."""
        out = []
        for end, grab, max_frames, speed, arc in phases:
            if max_frames == 0:
                out.append(np.zeros(len(start), dtype=np.int64))
                continue
            length = np.linalg.norm(end - start, axis=-1) if arc is None else arc_length(start, end, arc)
            out.append(self._phase_frames(length, grab, max_frames, speed, 1.0 if arc is None else math.pi / 2))
            start = end
        return out

    def plan_motion(self, actions: np.ndarray, pickers: np.ndarray) -> PickerMotion:
        pick, place = self.split(actions)
        start = np.asarray(pickers, dtype=np.float64)
        w, p = start.shape[:2]
        phases = self.phases(pick, place)
        counts = self._phase_frame_counts(phases, start)
        if not self.schedule.limited:
            world_frames = np.full(w, self.schedule.total_frames, dtype=np.int64)
        else:
            # never shorter than the task schedule's step: the limit only adds frames where needed
            world_frames = np.maximum(np.sum(counts, axis=0) + self.schedule.settle_frames, self.schedule.total_frames)
        total = int(world_frames.max())
        top = self.workspace.hi[2] - self.workspace.margin
        targets = np.empty((total, w, p, 3))
        grasp = np.zeros((total, w, p), dtype=bool)
        t0 = np.zeros(w, dtype=np.int64)  # first frame of the current phase, per world
        frames = np.arange(total)[:, None]  # (T, 1)
        for (end, grab, max_frames, speed, arc), n in zip(phases, counts):
            if max_frames == 0:
                continue
            k = frames - t0[None, :] + 1  # (T, W) frame number inside this phase
            alpha = np.clip(k / n[None, :], 0.0, 1.0)[..., None]  # (T, W, 1)
            inside = (k >= 1) & (k <= n[None, :])
            if arc is None:
                seg = start[None] + alpha[..., None] * (end - start)[None]
            else:
                seg = carry_point(start[None], end[None], arc[None], np.broadcast_to(alpha, (total, w, p)), top)
            targets = np.where(inside[..., None, None], seg, targets)
            grasp[inside] = grab
            start, t0 = end, t0 + n
        tail = frames >= t0[None, :]  # settle: stay at the retreat point, released
        targets = np.where(tail[..., None, None], start[None], targets)
        grasp[tail] = False
        return PickerMotion(targets, grasp, world_frames)


ACTION_MODES = ("delta", "pick_place")


def make_action_mode(name: str, num_pickers: int, workspace: Workspace,
                     schedule: PickPlaceSchedule | None = None, action_repeat: int = 8) -> ActionMode:
    """Action mode ``name`` (one of :data:`ACTION_MODES`)."""
    if name == "delta":
        return DeltaActions(num_pickers, workspace, action_repeat=action_repeat)
    if name == "pick_place":
        return PickPlaceActions(num_pickers, workspace, schedule)
    raise ValueError(f"action_mode must be one of {ACTION_MODES}, got {name!r}")
