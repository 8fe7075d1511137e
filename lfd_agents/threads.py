"""Temporarily set torch's intra-op thread count (small networks on shared CPUs run fastest
with one thread; more threads oversubscribe the cores)."""

from __future__ import annotations

import contextlib
from typing import Iterator

import torch


@contextlib.contextmanager
def torch_threads(n: int | None) -> Iterator[None]:
    """Run the block with ``n`` intra-op torch threads, restoring the previous count afterwards.

    ``None`` or ``n <= 0`` leaves torch's setting unchanged.
    """
    if n is None or n <= 0:
        yield
        return
    previous = torch.get_num_threads()
    torch.set_num_threads(int(n))
    try:
        yield
    finally:
        torch.set_num_threads(previous)


__all__ = ["torch_threads"]
