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

    single_picker_pairs = 3
    place_shift = -0.06
    clearance = 0.0

    def single_picker_order(self, count: int) -> list[int]:
        return [0, count - 1] + list(range(1, count - 1))
