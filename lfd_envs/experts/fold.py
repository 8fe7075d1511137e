"""Fold experts shared by the cloth-folding tasks: carry particles onto their mirror partners.

A fold task provides ``task.fold_pairs(k) -> (pick_indices, place_indices)``: ``k`` particles
on the border of the half that moves and the particles they must land on. With enough pickers
the whole fold is one move (every picker takes one pair); with fewer, the pairs are visited one
move at a time in the order given by :meth:`FoldExpert.plan`.
"""

from __future__ import annotations

import numpy as np

from lfd_envs.experts.picker_expert import Move, PickerExpert

__all__ = ["FoldExpert"]


class FoldExpert(PickerExpert):
    """Scripted fold: pick border particles, place them on their mirror partners."""

    #: pairs folded one at a time when there are fewer pickers than ``min_pickers_for_one_move``
    single_picker_pairs: int = 1
    #: place points are moved this far (m) along the pick->place direction; negative = short of
    #: the partner, which compensates the slide of the released edge (cloth layers slide freely)
    place_shift: float = 0.0
    #: height (m) above its partner at which a held particle is released
    clearance: float = 0.02

    def plan(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """``(pick_indices (P,), place_indices (P,))`` of each move."""
        p = self.num_pickers
        if p >= 2 or self.single_picker_pairs == 1:
            picks, places = self.task.fold_pairs(p if p >= 2 else 1)
            return [(picks, places)]
        picks, places = self.task.fold_pairs(self.single_picker_pairs)
        order = self.single_picker_order(len(picks))
        return [(picks[[i]], places[[i]]) for i in order]

    def single_picker_order(self, count: int) -> list[int]:
        """Order in which one picker visits the pairs (default: as given)."""
        return list(range(count))

    def next_move(self) -> Move | None:
        plan = self.plan()
        if self.moves_done >= len(plan):
            return None
        picks, places = plan[self.moves_done]
        return self._make_move(picks, places)

    def retarget(self, move: Move) -> Move:
        picks = move.info["picks"]
        return self._make_move(picks, move.info["places"], move.pick[:len(picks)], move.info["hang"],
                               move.info["shift"])

    def _make_move(self, picks: np.ndarray, places: np.ndarray, pick: np.ndarray | None = None,
                   hang: np.ndarray | None = None, shift: float | None = None) -> Move:
        """Carry particles ``picks`` onto ``places`` (picked at ``pick``, default the table under
        them; placed ``shift`` m along the carry, default :attr:`place_shift`)."""
        pos = self.positions
        if pick is None:
            pick = pos[picks].copy()
            pick[:, 2] = 0.0  # descend as low as the picker can go
        if hang is None:
            # the held particle will hang below the picker centre by its gap at the grasp; it is
            # lowered onto its partner with ``clearance`` (pressing it into the lower layer makes
            # it pop on release)
            hang = self.workspace.clip(pick)[:, 2] - pos[picks, 2]
        place = pos[places].copy()
        shift = self.place_shift if shift is None else shift
        if shift:
            d = place[:, :2] - pick[:, :2]
            place[:, :2] += shift * d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-9)
        place[:, 2] += hang + self.clearance
        p = self.num_pickers
        active = np.zeros(p, dtype=bool)
        active[:len(picks)] = True
        full_pick, full_place = self.pickers.copy(), self.pickers.copy()
        full_pick[:len(picks)], full_place[:len(picks)] = pick, place
        return Move(full_pick, full_place, active,
                    info={"picks": picks, "places": places, "hang": hang, "shift": shift})
