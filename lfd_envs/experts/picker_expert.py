"""Shared machinery of the scripted particle-task experts: plans of pick-and-place moves.

A task expert only says *what* to move: :meth:`PickerExpert.next_move` returns the next
:class:`Move` (pick and place points of every picker, computed from the privileged simulator
state), and optionally :meth:`PickerExpert.retarget` updates a move while it is executed.
This class executes moves in both action modes:

* ``pick_place``: one move per env step, encoded as the normalised pick/place action.
* ``delta``: a closed-loop state machine over env steps - approach (above the pick point) ->
  descend -> grasp -> lift -> carry -> lower -> release -> retreat - with the same carry height
  as the pick-and-place action mode (the task's :class:`PickPlaceSchedule`), so both modes
  follow the same path.

Works for any picker count: pickers that a move does not use stay where they are (delta) or
pick and place in empty air at the top of the workspace (pick_place).

With the ``flex_like`` physics (``env.unwrapped.physics``; the ``-v1`` ids, colliding pickers)
a delta-mode picker descends only until it rests on top of the particles under its pick point,
and a descent or lowering also ends when the picker is stopped by what it pushes on (a box
top). Experts with
:attr:`PickerExpert.pick_place_on_top` (the rope's and ClothFold's) also pick at that resting
height in pick_place mode and place that much higher.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lfd_envs.tasks.picker_actions import arc_length, carry_point
from lfd_envs.experts.episodes import EpisodeTracker

__all__ = ["Move", "PickerExpert"]

PHASES = ("approach", "descend", "grasp", "lift", "carry", "lower", "hold", "release", "retreat")
ONE_SHOT = {"grasp", "release"}
HOLDING = {"grasp", "lift", "carry", "lower", "hold"}
#: phases that move a picker down onto something: they also end when the picker is blocked
#: (a colliding picker resting on a box or on the cloth never reaches a target inside it)
CONTACT = {"descend", "lower"}
#: a picker is blocked when its last step covered less than this fraction of the commanded one
BLOCKED_FRACTION = 0.2


@dataclass
class Move:
    """One pick-and-place of all pickers (world coordinates, metres).

    Attributes:
        pick: Pick points ``(P, 3)``.
        place: Place points ``(P, 3)``.
        active: Which pickers take part ``(P,)`` (default all).
    """

    pick: np.ndarray
    place: np.ndarray
    active: np.ndarray | None = None
    info: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.pick = np.asarray(self.pick, dtype=np.float64).reshape(-1, 3)
        self.place = np.asarray(self.place, dtype=np.float64).reshape(-1, 3)
        if self.active is None:
            self.active = np.ones(len(self.pick), dtype=bool)
        self.active = np.asarray(self.active, dtype=bool)


class PickerExpert:
    """Base class of the particle-task experts (see module docstring).

    Args:
        env: A particle env (wrappers allowed).
        hold_speed: Fraction of the maximum delta speed used while holding (delta mode).
        free_speed: Fraction of the maximum delta speed used while not holding (delta mode).
        tolerance: Distance (m) at which a delta-mode waypoint counts as reached.
        max_phase_steps: Steps after which a delta-mode phase is abandoned (never stalls).
        direct_approach: delta mode: approach the pick point on a straight line from wherever
            the picker is, instead of first moving above it at the hover height and then
            descending vertically in a separate phase. The descent is then spread over the
            approach steps, an action field without the jump from "move sideways" to "drop"
            above the pick point, which regression-based learners smear over neighbouring
            states. With picker collisions on, the low end of that line may brush the cloth.
        grasp_in_descent: delta mode: turn the grasp flag on in the last step of the descent
            (with ``direct_approach``: of the approach), the step that reaches the pick point,
            and skip the motionless grasp step (a picker grasps whenever its flag is on and it
            holds nothing). Default off: the picker arrives with the flag off and grasps in a
            step of its own. The grasp then happens a little above the pick point, so the lift
            never lowers the picker, and the arrival ends once the picker holds. Such
            demonstrations are harder to imitate, not easier: a policy that turns the flag on a
            little early holds nothing (or a particle beside the pick point) and still lifts
            (``repro-cpu-v1``'s grasp-on-arrival cell: BC 0.04 against 0.86).
        press: delta mode, ``flex_like`` physics: the descent (with ``direct_approach``: the
            approach) goes down to the pick point at the table, which the workspace clips to the
            picker's radius above it, instead of stopping where the picker rests on top of the
            particles; the grasp happens at that lowest height. On the cloth tasks the particle
            under the picker is then well inside the grasp radius (it is within it up to about
            1.7 cm above the clip height, only 0.5 cm above the resting height), so a descent
            imitated a little short still ends within reach, and one imitated too long is
            clipped. Holding its particle one particle diameter closer than a resting picker, it
            lowers it that much less (pressed down to the clip height over the layer below, it
            squeezes that layer and the released particle pops). Not for the rope: a picker
            pressed down squeezes the thin rope out of its reach. Without colliding pickers
            every descent already ends at the clip height. A number instead of ``True`` presses
            that many metres below the resting height (never below the clip height), and the
            place is raised by as much (at most a particle diameter): a partial press keeps a
            margin for a learner's short descent without squeezing the layer under the picker.
            Experts whose :attr:`presses` is off (the rope's) accept ``press`` and ignore it, so
            one demonstrator setting serves every task.
    """

    #: delta mode: keep re-aiming the place point at the live target during the lift and the
    #: carry's arc (else the move is fixed once the picker leaves the approach phase). Not after
    #: the arc: a carried particle touching the cloth there can drag its target along, and the
    #: picker would chase it across the table.
    track_place: bool = False
    #: pick_place mode with the ``flex_like`` physics (colliding pickers): pick where the picker
    #: rests on top of the particles and place that much higher (see :meth:`_rest_on_top`). Off
    #: by default (on for the rope and ClothFold): the other cloth experts' plans are tuned to
    #: picks at the cloth's height.
    pick_place_on_top: bool = False
    #: whether ``press`` applies: on the cloth the layer under a pressing picker stays in reach,
    #: held in place by its neighbours; the rope's single strand rolls out from under it.
    presses: bool = True

    def __init__(self, env: Any, hold_speed: float = 0.6, tolerance: float = 1e-3, max_phase_steps: int = 80,
                 direct_approach: bool = False, free_speed: float = 1.0, grasp_in_descent: bool = False,
                 press: bool | float = False) -> None:
        for name, speed in (("hold_speed", hold_speed), ("free_speed", free_speed)):
            if not 0.0 < float(speed) <= 1.0:
                raise ValueError(f"{name} must be in (0, 1] (a fraction of the maximum delta speed), got {speed!r}")
        base = env.unwrapped
        if not hasattr(base, "batch") or not hasattr(base, "task"):
            raise TypeError(f"{type(self).__name__} needs a particle-task env, got {type(base).__name__}")
        self.env = env
        self.base = base
        self.task = base.task
        self.mode = base.action_mode
        self.num_pickers = base.num_pickers
        self.workspace = base.batch.workspace
        self.schedule = self.task.pick_place_schedule()
        self.actions = base.batch.action_mode
        self.hold_speed = float(hold_speed)
        self.free_speed = float(free_speed)
        self.tolerance = float(tolerance)
        self.max_phase_steps = int(max_phase_steps)
        self.direct_approach = bool(direct_approach)
        self.grasp_in_descent = bool(grasp_in_descent)
        if isinstance(press, bool) or press is None:
            self.press_depth = float("inf") if press else 0.0
        elif isinstance(press, (int, float, np.floating, np.integer)) and float(press) >= 0.0:
            self.press_depth = float(press)
        else:
            raise ValueError(f"press must be a bool or a depth >= 0 in metres, got {press!r}")
        if not type(self).presses:
            self.press_depth = 0.0
        self.press = self.press_depth > 0.0
        self._episodes = EpisodeTracker(env)
        self.reset()

    # ------------------------------------------------------------------ to implement
    def next_move(self) -> Move | None:
        """The next move from the current state, or None when the plan is done."""
        raise NotImplementedError

    def retarget(self, move: Move) -> Move:
        """Update a move under way (delta mode) from the current state; default: unchanged."""
        return move

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget the current plan (done by itself when the env starts a new episode)."""
        self._episodes.mark()
        self.moves_done = 0
        self._move: Move | None = None
        self._phase = 0
        self._phase_steps = 0
        self._issued = False
        self._carry_alpha = 0.0
        self._sent: np.ndarray | None = None  # (picker positions, commanded targets) of the last step

    @property
    def positions(self) -> np.ndarray:
        """Particle positions ``(N, 3)`` of the env (privileged)."""
        return np.asarray(self.base.particle_positions, dtype=np.float64)

    @property
    def pickers(self) -> np.ndarray:
        """Picker centres ``(P, 3)``."""
        return np.asarray(self.base.picker_positions, dtype=np.float64)

    @property
    def _flex_like(self) -> bool:
        """Whether the env runs the ``flex_like`` physics (the ``-v1`` ids, colliding pickers):
        the plans follow the env's physics preset, not engine options given on top of it."""
        return self.base.physics == "flex_like"

    def _resting_on_top(self, points: np.ndarray) -> np.ndarray:
        """``points`` raised to the lowest picker-centre height that touches no free particle.

        A colliding picker (``picker_collision``) sent lower than that squeezes the particles
        under it against the table and shoots them sideways, out of its grasp radius; resting
        on top it is within the grasp radius of the particle it touches (the grasp radius of
        every task exceeds picker radius + particle radius).
        """
        params = self.base.batch.sim.params
        reach = params.picker_radius + params.particle_radius
        pos = self.positions[self.base.batch.sim.attached[0] < 0]
        out = np.asarray(points, np.float64).copy()
        for k, point in enumerate(out):
            dxy2 = np.sum((pos[:, :2] - point[:2]) ** 2, axis=1)
            under = dxy2 < reach ** 2
            if under.any():
                out[k, 2] = max(point[2], float(np.max(pos[under, 2] + np.sqrt(reach ** 2 - dxy2[under]))))
        return out

    @property
    def steps_left(self) -> int:
        return int(self.base.horizon - self.base.elapsed_steps)

    # ------------------------------------------------------------------ SB3 policy API
    def predict(self, observation: Any, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, None]:
        """Action for the env's current state (the observation itself is not needed)."""
        if self._episodes.new_episode():
            self.reset()
        if self.mode == "pick_place":
            action = self._pick_place_action()
        else:
            action = self._delta_action()
        return action.astype(np.float32), None

    # ------------------------------------------------------------------ pick_place mode
    def _pick_place_action(self) -> np.ndarray:
        move = self.next_move()
        if move is not None:
            self.moves_done += 1
            if self._flex_like and self.pick_place_on_top:
                self._rest_on_top(move)
        pick, place = self._idle_points()
        if move is not None:
            pick[move.active] = move.pick[move.active]
            place[move.active] = move.place[move.active]
        return self.actions.join(pick, place)

    def _rest_on_top(self, move: Move) -> None:
        """Pick-and-place with colliding pickers: pick where the picker rests on top of the
        particles under the pick point (sent lower, it squeezes them out of its reach before the
        grasp), and place that much higher too (lowered onto the table, it presses the released
        particle aside)."""
        rest = self._resting_on_top(move.pick)
        move.place[:, 2] += rest[:, 2] - move.pick[:, 2]
        move.pick = rest

    def _idle_points(self) -> tuple[np.ndarray, np.ndarray]:
        """Pick/place points that touch nothing: above each picker, at the workspace top."""
        top = self.workspace.hi[2] - self.workspace.margin
        idle = self.pickers.copy()
        idle[:, 2] = top
        return idle.copy(), idle.copy()

    # ------------------------------------------------------------------ delta mode
    def _target(self, name: str, move: Move, cur: np.ndarray) -> np.ndarray:
        """Delta-mode waypoint of phase ``name`` (same path as the pick_place action mode)."""
        ws, s = self.workspace, self.schedule
        top = ws.hi[2] - ws.margin
        pick, place = ws.clip(move.pick), ws.clip(move.place)
        if self._flex_like and name in ("approach", "descend") and not self._presses(name):  # before the grasp
            pick = ws.clip(self._resting_on_top(pick))
        elif self._flex_like and self._presses(name) and np.isfinite(self.press_depth):  # a partial press
            pick = self._resting_on_top(pick)
            pick[:, 2] -= self.press_depth
            pick = ws.clip(pick)
        if self._flex_like and self.press and name == "lower":
            place = place.copy()
            place[:, 2] += min(self.press_depth, 2.0 * self.base.batch.sim.params.particle_radius)
        wpt = s.waypoints(pick, place, top)
        approach = pick if self.direct_approach else wpt["above_pick"]
        target = {"approach": approach, "descend": pick, "lift": wpt["lifted"],
                  "lower": place, "retreat": wpt["retreat"], "carry_end": wpt["above_place"]}.get(name, cur)
        if name == "carry":
            arc = s.arc_height(wpt["lifted"], wpt["above_place"])
            length = arc_length(wpt["lifted"], wpt["above_place"], arc)[move.active].max()
            step = self.hold_speed * self.actions.step_size * self.actions.action_repeat
            self._carry_alpha = min(1.0, self._carry_alpha + step / max(length, 1e-9))
            target = carry_point(wpt["lifted"], wpt["above_place"], arc, np.full(len(arc), self._carry_alpha), top)
        if name == "lift" and self.grasp_in_descent:  # grasped higher up: the lift never goes down
            target = target.copy()
            target[:, 2] = np.maximum(target[:, 2], cur[:, 2])
        out = cur.copy()
        out[move.active] = ws.clip(target)[move.active]
        return out

    def _hold_steps(self) -> int:
        frames = self.schedule.hold_frames
        return -(-frames // self.actions.action_repeat) if frames > 0 else 0

    def _delta_action(self) -> np.ndarray:
        p = self.num_pickers
        cur = self.pickers
        action = np.zeros((p, 4))
        action[:, 3] = -1.0
        for _ in range(len(PHASES) + 2):  # advance through finished phases
            if self._move is None:
                self._move = self.next_move()
                self._phase, self._phase_steps, self._issued = 0, 0, False
                if self._move is None:
                    return action.ravel()
            name = PHASES[self._phase]
            if name == "approach" or (self.track_place and name in ("lift", "carry") and self._carry_alpha < 1.0):
                self._move = self.retarget(self._move)
            move = self._move
            if name != "carry":
                self._carry_alpha = 0.0
                target = self._target(name, move, cur)
                gap = np.abs(target - cur).max()
            else:  # the arc advances with every step; done once its end is reached
                gap = np.abs(self._target("carry_end", move, cur) - cur).max() if self._carry_alpha >= 1.0 else 1.0
                if gap >= self.tolerance:
                    target = self._target(name, move, cur)
            if name == "hold":  # keep still, holding, for the schedule's hold time (in env steps)
                done = self._phase_steps >= self._hold_steps()
            elif name == "grasp" and self.grasp_in_descent:  # the flag went on in the descent
                done = True
            else:
                done = (self._issued if name in ONE_SHOT else gap < self.tolerance) or self._phase_steps >= self.max_phase_steps
                if not done and self._grasps_on_arrival(name) and self._phase_steps > 0:
                    done = bool(np.all(self.base.held_particles[move.active] > 0))  # grasped on the way: arrived
                if not done and name in CONTACT and self._phase_steps > 0:  # reached or stopped by contact
                    reached = np.abs(target - cur).max(axis=1) < self.tolerance
                    done = bool(np.all((reached | self._blocked(cur))[move.active]))
            if not done:
                break
            self._phase += 1
            self._phase_steps, self._issued = 0, False
            if self._phase == len(PHASES):
                self.moves_done += 1
                self._move = None
        else:  # pragma: no cover - defensive
            return action.ravel()
        reach = self.actions.step_size * self.actions.action_repeat
        speed = self.hold_speed if name in HOLDING else self.free_speed
        delta = (target - cur) / reach
        scale = max(1.0, np.abs(delta).max() / speed)
        action[:, :3] = delta / scale
        action[move.active, 3] = 1.0 if name in HOLDING else -1.0
        if self._grasps_on_arrival(name):  # flag on in the step that arrives at the pick point
            arrives = np.abs(target - cur).max(axis=1) <= speed * reach + self.tolerance
            action[move.active & arrives, 3] = 1.0
        self._phase_steps += 1
        self._issued = True
        self._sent = np.stack([cur, cur + action[:, :3] * reach])
        return action.ravel()

    def _presses(self, name: str) -> bool:
        """Phase ``name`` is the one that reaches the pick point and ``press`` is on."""
        return self.press and (name == "descend" or (name == "approach" and self.direct_approach))

    def _grasps_on_arrival(self, name: str) -> bool:
        """Phase ``name`` is the one that reaches the pick point and ``grasp_in_descent`` is on."""
        return self.grasp_in_descent and (name == "descend" or (name == "approach" and self.direct_approach))

    def _blocked(self, cur: np.ndarray) -> np.ndarray:
        """Per picker: it covered less than :data:`BLOCKED_FRACTION` of the displacement
        commanded in the last step (something it pushes on stops it)."""
        if self._sent is None:
            return np.zeros(len(cur), dtype=bool)
        start, commanded = self._sent
        wanted = np.linalg.norm(commanded - start, axis=1)
        moved = np.linalg.norm(cur - start, axis=1)
        return (wanted > self.tolerance) & (moved < BLOCKED_FRACTION * wanted)
