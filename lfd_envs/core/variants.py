"""Task variants and the train/eval split.

SoftGym cached 1000 variants per task on disk and split them 80/20. Ours are generated on
demand: variant ``k`` of a split is drawn from a generator seeded with the task name and a
*global* variant id, and the two splits use disjoint global id ranges, so train and eval
variants can never coincide and no cache file is needed.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np

SPLITS = ("train", "eval")


def stable_hash(name: str) -> int:
    """A hash of ``name`` that is the same in every process (unlike ``hash``)."""
    return int.from_bytes(hashlib.sha256(name.encode()).digest()[:8], "little")


@dataclass(frozen=True)
class VariantSplit:
    """Maps ``(split, k)`` to a reproducible random generator for a task.

    Attributes:
        task_name: name used to seed variant generation (variants differ between tasks).
        num_train: number of training variants (global ids ``0 .. num_train-1``).
        num_eval: number of evaluation variants (global ids ``num_train ..``).
    """

    task_name: str
    num_train: int = 800
    num_eval: int = 200

    def size(self, split: str) -> int:
        """Number of variants in ``split``."""
        self._check_split(split)
        return self.num_train if split == "train" else self.num_eval

    def global_id(self, split: str, k: int) -> int:
        """Global variant id of variant ``k`` of ``split`` (disjoint ranges per split)."""
        n = self.size(split)
        if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer)) or not 0 <= int(k) < n:
            raise ValueError(f"variant must be an int in [0, {n}) for split {split!r}, got {k!r}")
        return int(k) if split == "train" else self.num_train + int(k)

    def rng(self, split: str, k: int) -> np.random.Generator:
        """Generator that produces the parameters of variant ``k`` of ``split``."""
        return np.random.default_rng([stable_hash(self.task_name), self.global_id(split, k)])

    @staticmethod
    def _check_split(split: str) -> None:
        if split not in SPLITS:
            raise ValueError(f"split must be one of {SPLITS}, got {split!r}")
