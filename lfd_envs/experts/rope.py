"""Scripted expert of StraightenRope-v0 (both action modes, any picker count).

Two or more pickers (DMfD-like): picker ``k`` takes the rope particle at fraction
``k / (P - 1)`` of its length (the two ends first) and places it at the same fraction of a
straight segment of length ``L`` through the middle of the current end points, along the
current end-to-end direction (kept inside the workspace). The move repeats while the end
distance is more than 2% off.

One picker: drag one end away from the other to a point ``L`` beyond it (the rope trails
behind and straightens), then do the same from the other end, alternating.
"""

from __future__ import annotations

import numpy as np

from lfd_envs.experts.picker_expert import Move, PickerExpert

__all__ = ["StraightenRopeExpert"]

#: fraction of the rope length the ends are placed apart
SPAN = 0.99
#: stop when |d - L| / L is below this
DONE_ERROR = 0.02


class StraightenRopeExpert(PickerExpert):
    """Expert of :class:`~lfd_envs.tasks.rope.StraightenRopeEnv` (see module docstring)."""

    #: with colliding pickers a pick at the table squeezes the thin rope's end out of reach
    #: before the grasp, and a place at the table presses the released end aside
    pick_place_on_top = True
    #: ``press`` is ignored: a picker pressed into the rope squeezes it out of reach, and learners
    #: imitate pressing rope demonstrations worse than resting ones.
    presses = False

    def _rope(self) -> tuple[np.ndarray, float]:
        pos = self.positions
        return pos, float(self.base.batch.ctx["length"][0])

    def next_move(self) -> Move | None:
        pos, length = self._rope()
        d = np.linalg.norm(pos[-1] - pos[0])
        if abs(d - length) / length < DONE_ERROR and self.moves_done > 0:
            return None
        if self.num_pickers >= 2:
            return self._straight_move(pos, length)
        return self._drag_move(pos, length)

    def _direction(self, pos: np.ndarray) -> np.ndarray:
        u = pos[-1, :2] - pos[0, :2]
        norm = np.linalg.norm(u)
        return u / norm if norm > 1e-6 else np.array([1.0, 0.0])

    def _straight_move(self, pos: np.ndarray, length: float) -> Move:
        p, n = self.num_pickers, len(pos)
        u = self._direction(pos)
        half = 0.5 * SPAN * length
        reach = self.workspace.hi[:2] - self.workspace.margin - half * np.abs(u) - 0.01
        center = np.clip(0.5 * (pos[0, :2] + pos[-1, :2]), -reach, reach)
        frac = np.linspace(0.0, 1.0, p)
        idx = np.round(frac * (n - 1)).astype(int)
        pick = pos[idx].copy()
        place = np.zeros((p, 3))
        place[:, :2] = center + (frac[:, None] - 0.5) * 2.0 * half * u
        pick[:, 2] = place[:, 2] = 0.0
        return Move(pick, place)

    def _drag_move(self, pos: np.ndarray, length: float) -> Move:
        # alternate ends; drag the chosen end to a point L beyond the other end
        end, other = (0, -1) if self.moves_done % 2 == 0 else (-1, 0)
        u = pos[end, :2] - pos[other, :2]
        norm = np.linalg.norm(u)
        u = u / norm if norm > 1e-6 else np.array([1.0, 0.0])
        lo = self.workspace.lo[:2] + self.workspace.margin + 0.01
        hi = self.workspace.hi[:2] - self.workspace.margin - 0.01
        target = pos[other, :2] + 1.05 * length * u
        if np.any(target < lo) or np.any(target > hi):
            # not enough room: slide the other end back so the straight rope fits
            target = np.clip(target, lo, hi)
        pick = pos[[end]].copy()
        place = np.zeros((1, 3))
        place[0, :2] = target
        pick[:, 2] = 0.0
        return Move(pick, place)
