"""Scripted expert of the diagonal fold (pinned and unpinned, both action modes, any picker count).

One picker: carry the bottom-left corner onto the top-right corner (DMfD's expert, but closed
loop: the targets come from the simulator state instead of a fixed action list). More pickers
also carry points of the left and bottom edges onto their mirror partners.
"""

from __future__ import annotations

from lfd_envs.experts.fold import FoldExpert

__all__ = ["ClothFoldDiagonalExpert"]


class ClothFoldDiagonalExpert(FoldExpert):
    """Expert of :class:`~lfd_envs.tasks.cloth_fold_diagonal.ClothFoldDiagonalEnv`."""

    single_picker_pairs = 1
    clearance = 0.0
    track_place = True

    @property
    def place_shift(self) -> float:  # type: ignore[override]
        # the free cloth slides along with the fold: aim shorter than on the pinned cloth
        # (cloth-on-cloth friction holds the layers, so the aim is less short than before it existed)
        return -0.03 if self.task.pinned else -0.07
