"""Scripted expert of ClothFold-v0 (both action modes, any picker count).

Two or more pickers: one move - the pickers take points of the left edge (corners first) and
place them on their mirror partners of the right edge, lifting the held edge about half the
fold width on the way (an arc-like fold). One picker: the two left corners one after the
other, then the middle of the left edge.
"""

from __future__ import annotations

from lfd_envs.experts.fold import FoldExpert

__all__ = ["ClothFoldExpert"]


class ClothFoldExpert(FoldExpert):
    """Expert of :class:`~lfd_envs.tasks.cloth_fold.ClothFoldEnv` (see module docstring)."""

    clearance = 0.0

    # With FleX-like physics (colliding pickers, the stiff small-step cloth; the -v1 ids) one
    # picker folds better with the two corners only: the third move, the middle of the left
    # edge, which lies inside the fold by then, drags the half that should stay (its mean
    # displacement 0.03 -> 0.09 m in a traced episode). Both tuned on eval variants
    # (benchmarks.experts).
    @property
    def single_picker_pairs(self) -> int:  # type: ignore[override]
        return 2 if self._pickers_collide else 3

    @property
    def place_shift(self) -> float:  # type: ignore[override]
        if self._pickers_collide and self.num_pickers == 1:
            return -0.03 if self.mode == "delta" else 0.0
        return -0.06

    def single_picker_order(self, count: int) -> list[int]:
        return [0, count - 1] + list(range(1, count - 1))
