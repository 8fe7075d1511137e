"""Scripted expert of ClothFold-v0 (both action modes, any picker count).

Two or more pickers: one move - the pickers take points of the left edge (corners first) and
place them on their mirror partners of the right edge, lifting the held edge about half the
fold width on the way (an arc-like fold). One picker: the two left corners one after the
other, then the middle of the left edge.

With FleX-like physics (colliding pickers, the stiff small-step cloth; the ``-v1`` ids):

* pick-and-place picks where the picker rests on top of the cloth
  (:attr:`~lfd_envs.experts.picker_expert.PickerExpert.pick_place_on_top`). Sent down to the
  table, a colliding picker squeezes the cloth under it; traced on eval variant 1 with 40
  substeps, the half that should stay then slid 8.6 cm while the corners were lifted 5 cm.
* one picker folds in one move: the middle of the left edge onto the middle of the right edge,
  6 cm short (3 cm in delta mode). A move that carries one corner onto its partner cannot keep
  an inextensible cloth's other left corner in place (the only straight crease that maps a
  corner onto its mirror partner is the centre line, which takes the whole edge along), so on
  stiff cloth it drags the cloth; the corners follow the middle instead.
"""

from __future__ import annotations

from lfd_envs.experts.fold import FoldExpert

__all__ = ["ClothFoldExpert"]


class ClothFoldExpert(FoldExpert):
    """Expert of :class:`~lfd_envs.tasks.cloth_fold.ClothFoldEnv` (see module docstring)."""

    clearance = 0.0
    single_picker_pairs = 3
    pick_place_on_top = True  # only with colliding pickers (see PickerExpert)

    # Shifts tuned on eval variants (benchmarks.experts).
    @property
    def place_shift(self) -> float:  # type: ignore[override]
        if self._flex_like and self.num_pickers == 1:
            return -0.03 if self.mode == "delta" else -0.06
        return -0.06

    def single_picker_order(self, count: int) -> list[int]:
        if self._flex_like:
            return [count // 2]  # the middle of the left edge only
        return [0, count - 1] + list(range(1, count - 1))
