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
