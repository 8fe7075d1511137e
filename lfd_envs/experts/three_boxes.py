"""Scripted expert of ThreeBoxes-v0 (both action modes, any picker count).

Every move carries up to ``P`` boxes that are not yet at their goals straight to their goals
(picker on the middle of the top face, place = goal, resting on the table; boxes are assigned
to the pickers with the least total travel). With three or more
pickers the task is solved in one move (MAIL's teacher). With fewer, the boxes of a move are
chosen so that no goal is still occupied by a box that stays where it is (on the default
layout: 2 pickers move boxes 1 and 3, then box 2; 1 picker moves box 1, box 3, box 2 - the
longest carries first, so that the moves left for later are short), so
``ceil(3 / P)`` moves finish the task: 1, 2 and 3 moves for 3, 2 and 1 pickers, within the
pick-and-place horizon of 3. In delta mode the same moves are executed by the closed-loop
state machine of :class:`~lfd_envs.experts.picker_expert.PickerExpert` at full speed; the
75-step horizon covers them for every picker count.
"""

from __future__ import annotations

from itertools import combinations, permutations

import numpy as np

from lfd_envs.experts.picker_expert import Move, PickerExpert
from lfd_envs.tasks.three_boxes import BOX_HALF_EXTENTS

__all__ = ["ThreeBoxesExpert"]

#: a box closer than this (m) to its goal is left alone
DONE = 0.01
#: gap (m) kept between a goal footprint and a standing box
CLEARANCE = 0.01


class ThreeBoxesExpert(PickerExpert):
    """Expert of :class:`~lfd_envs.tasks.three_boxes.ThreeBoxesEnv` (see module docstring)."""

    def __init__(self, env, hold_speed: float = 1.0, **kwargs) -> None:
        super().__init__(env, hold_speed=hold_speed, **kwargs)

    def _state(self) -> tuple[np.ndarray, np.ndarray]:
        centers = self.task.box_centers(self.positions[None])[0]
        return centers, np.asarray(self.base.batch.ctx["goals"][0], np.float64)

    def choose(self, centers: np.ndarray, goals: np.ndarray) -> list[int]:
        """Boxes to move next: at most ``P`` of those off their goals, none of whose goals is
        blocked by a box that stays; among those the group with the longest total carry."""
        todo = [b for b in range(len(centers)) if np.linalg.norm(centers[b] - goals[b]) > DONE]
        k = min(self.num_pickers, len(todo))
        if k == 0:
            return []
        dist = np.linalg.norm(centers - goals, axis=1)
        groups = sorted(combinations(todo, k), key=lambda grp: -float(dist[list(grp)].sum()))
        for group in groups:  # longest carries first: what is left for later moves is short
            stay = [b for b in range(len(centers)) if b not in group]
            if not any(self._blocks(goals[g], g, centers[s], s) for g in group for s in stay):
                return list(group)
        return list(groups[0])

    @staticmethod
    def _blocks(goal: np.ndarray, box: int, other: np.ndarray, other_box: int) -> bool:
        reach = BOX_HALF_EXTENTS[box, :2] + BOX_HALF_EXTENTS[other_box, :2] + CLEARANCE
        return bool(np.all(np.abs(goal[:2] - other[:2]) < reach))

    def next_move(self) -> Move | None:
        centers, goals = self._state()
        group = self.choose(centers, goals)
        if not group:
            return None
        return self._make_move(group, centers, goals)

    def retarget(self, move: Move) -> Move:
        centers, goals = self._state()
        return self._make_move(move.info["boxes"], centers, goals, move.info["pickers"])

    def _assign(self, grasp: np.ndarray) -> tuple[int, ...]:
        """Pickers for grasp points ``(k, 3)``: the assignment with the least total travel."""
        here = self.pickers
        best = min(permutations(range(self.num_pickers), len(grasp)),
                   key=lambda ids: float(np.linalg.norm(here[list(ids)] - grasp, axis=1).sum()))
        return tuple(best)

    def _make_move(self, group: list[int], centers: np.ndarray, goals: np.ndarray,
                   pickers: tuple[int, ...] | None = None) -> Move:
        task = self.task
        grasp = np.stack([task.grasp_point(centers[b], b) for b in group])
        drop = np.stack([task.grasp_point(goals[b] + np.array([0.0, 0.0, 0.002]), b) for b in group])
        ids = self._assign(grasp) if pickers is None else pickers
        pick, place = self.pickers.copy(), self.pickers.copy()
        pick[list(ids)], place[list(ids)] = grasp, drop
        active = np.zeros(self.num_pickers, dtype=bool)
        active[list(ids)] = True
        return Move(pick, place, active, info={"boxes": list(group), "pickers": ids})
