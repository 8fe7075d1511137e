"""Scripted expert of DryCloth-v0 (both action modes, any picker count).

Two or more pickers (MAIL's teacher): one move - the pickers take evenly spaced points of the
plank-side edge (grid column 0, the two corners first) and carry them 0.1 m past the plank,
0.55 m high, spread along the plank over the cloth's width (centred on the edge's middle);
released there, the cloth falls over the plank and hangs on both sides.

One picker: (1) the middle of the plank-side edge goes 0.12 m past the plank, 0.55 m high (the
cloth hangs over the plank, bunched along it); (2, 3) the two corners of the opposite edge,
which hang on the near side, are pulled apart along the plank (0.2 m either side of the middle,
0.04 m in front of the plank, 0.26 m high) to spread the cloth. With FleX-like physics
(colliding pickers, the stiff small-step cloth; the ``-v1`` ids) one picker makes move (1)
only, 0.2 m past the plank: the stiff cloth hangs spread by itself, and pulling its corners
drags it off the plank; in pick-and-place it then moves the crease back to the middle column
while it is more than 2 cm of cloth off (picked on top of the plank, lifted towards the shorter
side by the surplus): released 0.2 m past the plank, the cloth does not always slide back into
balance, and the longer side's hem then lies on the table. In delta mode the moves are
executed by the closed-loop state machine of
:class:`~lfd_envs.experts.picker_expert.PickerExpert` while the horizon lasts.
"""

from __future__ import annotations

import numpy as np

from lfd_envs.experts.picker_expert import Move, PickerExpert
from lfd_envs.tasks.dry_cloth import CLOTH_SIZE

__all__ = ["DryClothExpert"]

#: (distance past the plank, height) of the places of the teacher move
TEACHER_PLACE = (0.1, 0.55)
#: single picker: the edge middle goes here, then the opposite corners are spread here
SINGLE_OVER = (0.12, 0.55)
SINGLE_SPREAD = (-0.04, 0.26)
#: single picker with FleX-like physics: the edge middle goes here, and that is the only move
FLEX_LIKE_SINGLE_OVER = (0.2, 0.55)
#: particles lower than this are picked with the picker at its lowest height
GROUND = 0.03
#: single picker: the opposite corners are pulled this far (m) along the plank from the middle
SPREAD_HALF_WIDTH = 0.2
#: single picker with FleX-like physics: a crease farther than this (m of cloth) from the middle
#: column is moved back
CREASE_TOLERANCE = 0.02


class DryClothExpert(PickerExpert):
    """Expert of :class:`~lfd_envs.tasks.dry_cloth.DryClothEnv` (see module docstring)."""

    def reset(self) -> None:
        super().reset()
        self._frame: tuple[float, float] | None = None  # (edge middle along the plank, sign)

    def _ctx(self) -> dict[str, np.ndarray]:
        return {k: v[0] for k, v in self.base.batch.ctx.items()}

    def _along(self, point: np.ndarray) -> float:
        plank = self._ctx()["plank"]
        u = np.array([-np.sin(plank[3]), np.cos(plank[3])])
        return float(np.dot(np.asarray(point)[:2] - plank[:2], u))

    def _edge_frame(self) -> tuple[float, float]:
        """Position of the plank-side edge's middle along the plank and the direction in which
        its rows grow, both taken at the first move of the episode."""
        if self._frame is None:
            pos, task = self.positions, self.task
            n = task.resolution
            a0, a1 = self._along(pos[task.grid_index(0, 0)]), self._along(pos[task.grid_index(n - 1, 0)])
            self._frame = (0.5 * (a0 + a1), 1.0 if a1 >= a0 else -1.0)
        return self._frame

    def plan(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """``(particle indices (k,), place points (k, 3))`` of every move."""
        task, ctx = self.task, self._ctx()
        n, p, side = task.resolution, self.num_pickers, 0.5
        mid, sign = self._edge_frame()
        if p >= 2:
            frac = np.linspace(0.0, 1.0, p)
            rows = np.round(frac * (n - 1)).astype(int)
            places = np.stack([task.far_side_point(ctx, mid + sign * (f - 0.5) * side, *TEACHER_PLACE) for f in frac])
            return [(task.grid_index(rows, 0), places)]
        middle = task.grid_index(np.array([n // 2]), 0)
        if self._flex_like:
            return [(middle, task.far_side_point(ctx, mid, *FLEX_LIKE_SINGLE_OVER)[None])]
        over = task.far_side_point(ctx, mid, *SINGLE_OVER)[None]
        low = task.far_side_point(ctx, mid - sign * SPREAD_HALF_WIDTH, *SINGLE_SPREAD)[None]
        high = task.far_side_point(ctx, mid + sign * SPREAD_HALF_WIDTH, *SINGLE_SPREAD)[None]
        return [(middle, over),
                (task.grid_index(np.array([0]), n - 1), low),
                (task.grid_index(np.array([n - 1]), n - 1), high)]

    def _centre_crease(self) -> tuple[np.ndarray, np.ndarray] | None:
        """One picker, ``-v1``: ``(particle, place)`` of a move that puts the crease over the
        plank back on the middle column, or None when it is within ``CREASE_TOLERANCE``
        m of cloth of it. The crease (the highest particle of the middle row) is lifted
        ``|offset|`` of cloth towards the shorter side: released there, the longer side's
        surplus falls back over the plank."""
        task, n = self.task, self.task.resolution
        row = task.grid_index(np.full(n, n // 2), np.arange(n))
        crease = int(np.argmax(self.positions[row, 2]))
        offset = (crease - 0.5 * (n - 1)) * CLOTH_SIZE / (n - 1)  # m; > 0: the far side hangs too long
        if abs(offset) <= CREASE_TOLERANCE:
            return None
        plank = self._ctx()["plank"]
        towards_near = np.array([np.cos(plank[3]), np.sin(plank[3]), 0.0])
        length = abs(offset)
        place = self.positions[row[crease]] + np.sign(offset) * towards_near * (0.87 * length)
        place[2] += 0.5 * length
        return row[crease:crease + 1], place[None]

    def next_move(self) -> Move | None:
        if self._flex_like and self.num_pickers == 1 and self.mode == "pick_place" and self.moves_done:
            correction = self._centre_crease()  # as often as the crease is off and steps are left
            return None if correction is None else self._make_move(*correction, on_top=True)
        plan = self.plan()
        if self.moves_done >= len(plan):
            return None
        idx, places = plan[self.moves_done]
        return self._make_move(idx, places)

    def retarget(self, move: Move) -> Move:
        return self._make_move(move.info["picks"], move.info["places"], move.info.get("on_top", False))

    def _make_move(self, idx: np.ndarray, places: np.ndarray, on_top: bool = False) -> Move:
        pick = self.positions[idx].copy()
        pick[pick[:, 2] < GROUND, 2] = 0.0  # descend as low as the picker can go
        k = len(idx)
        full_pick, full_place = self.pickers.copy(), self.pickers.copy()
        full_pick[:k], full_place[:k] = pick, places
        active = np.zeros(self.num_pickers, dtype=bool)
        active[:k] = True
        move = Move(full_pick, full_place, active, info={"picks": idx, "places": places, "on_top": on_top})
        if on_top:  # picked from above the plank: rest on top of the particle, place as high above
            self._rest_on_top(move)
        return move
