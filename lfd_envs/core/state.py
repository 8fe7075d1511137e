"""Checks of a ``get_state()`` dict before ``set_state`` changes anything.

Every env restores states in two phases: first the whole state is checked against the
env's own layout (the keys, shapes and dtypes its ``get_state`` produces), the episode
counters and the task identity, and the task's value ranges; only then is anything written.
So a rejected state raises ``TypeError``/``ValueError`` naming the offending key and leaves
the env exactly as it was. The single envs (:class:`~lfd_envs.core.base_env.LfdEnv`) and the
batched particle env share these helpers.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np

from lfd_envs.core.variants import VariantSplit, stable_hash

#: keys of the episode counters every state has
EPISODE_KEYS = ("episode/split", "episode/variant", "episode/step", "episode/p0",
                "episode/prev_performance", "episode/task_id")


class EpisodeState(NamedTuple):
    """The episode part of a checked state."""

    split: str
    variant: int
    step: int
    p0: float
    prev_performance: float


def task_id(identity: Mapping[str, Any]) -> int:
    """Stable non-negative int64 id of a task identity (task name and the construction
    arguments that change the task, e.g. picker count or NIST fit)."""
    text = "|".join(f"{k}={identity[k]!r}" for k in sorted(identity))
    return stable_hash(text) & 0x7FFF_FFFF_FFFF_FFFF


def episode_arrays(split: str, variant: int, step: int, p0: float, prev: float,
                   identity: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """The ``episode/*`` entries of a state (the counterpart of :func:`check_episode`)."""
    return {
        "episode/split": np.array(0 if split == "train" else 1, dtype=np.int64),
        "episode/variant": np.array(variant, dtype=np.int64),
        "episode/step": np.array(step, dtype=np.int64),
        "episode/p0": np.array(p0, dtype=np.float64),
        "episode/prev_performance": np.array(prev, dtype=np.float64),
        "episode/task_id": np.array(task_id(identity), dtype=np.int64),
    }


def check_state_dict(state: Any) -> Mapping[str, Any]:
    """``state`` itself if it is a mapping, else ``TypeError``."""
    if not isinstance(state, Mapping):
        raise TypeError(f"state must be a dict from get_state(), got {type(state).__name__}")
    return state


def check_state_layout(state: Any, reference: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Check ``state`` against ``reference`` (the env's own ``get_state`` layout).

    The key sets must be equal; every value must have the reference's shape and a compatible
    real dtype (floats: any real number, finite; ints: integral values; bools: 0/1).
    Returns copies converted to the reference dtypes. ``TypeError`` for a non-mapping or a
    non-numeric value, ``ValueError`` otherwise; both name the key.
    """
    state = check_state_dict(state)
    missing = sorted(set(reference) - set(state))
    unknown = sorted(set(state) - set(reference))
    if missing or unknown:
        raise ValueError(f"state keys do not match this env: missing keys {missing}, unknown keys {unknown}; "
                         "pass a dict from this env's get_state()")
    return {key: _check_value(key, state[key], np.asarray(ref)) for key, ref in reference.items()}


def _check_value(key: str, value: Any, ref: np.ndarray) -> np.ndarray:
    arr = np.asarray(value)
    if arr.dtype.kind not in "biuf":
        raise TypeError(f"state[{key!r}] must be a real numeric array, got dtype {arr.dtype}")
    if arr.shape != ref.shape:
        raise ValueError(f"state[{key!r}] must have shape {ref.shape}, got shape {arr.shape}")
    if arr.dtype.kind == "f" and not np.all(np.isfinite(arr)):
        raise ValueError(f"state[{key!r}] must be finite (no NaN/inf)")
    kind = ref.dtype.kind
    if kind in "biu" and arr.dtype.kind == "f" and np.any(arr != np.round(arr)):
        raise ValueError(f"state[{key!r}] must hold integers, got {arr}")
    if kind == "b" and np.any((arr != 0) & (arr != 1)):
        raise ValueError(f"state[{key!r}] must hold booleans (0 or 1), got {arr}")
    return arr.astype(ref.dtype, copy=True)


def check_episode(state: Mapping[str, np.ndarray], variants: VariantSplit, horizon: int,
                  identity: Mapping[str, Any]) -> EpisodeState:
    """Check the ``episode/*`` entries (already through :func:`check_state_layout`)."""
    expected = task_id(identity)
    if int(state["episode/task_id"]) != expected:
        described = ", ".join(f"{k}={v!r}" for k, v in sorted(identity.items()))
        raise ValueError(f"state['episode/task_id'] is from another task; this env is {described}")
    code = int(state["episode/split"])
    if code not in (0, 1):
        raise ValueError(f"state['episode/split'] must be 0 (train) or 1 (eval), got {code}")
    split = "train" if code == 0 else "eval"
    k = int(state["episode/variant"])
    n = variants.size(split)
    if not 0 <= k < n:
        raise ValueError(f"state['episode/variant'] must be in [0, {n}) for split {split!r}, got {k}")
    step = int(state["episode/step"])
    if not 0 <= step <= horizon:
        raise ValueError(f"state['episode/step'] must be in [0, {horizon}] (the horizon), got {step}")
    return EpisodeState(split, k, step, float(state["episode/p0"]), float(state["episode/prev_performance"]))


def check_range(key: str, arr: np.ndarray, low: float | None = None, high: float | None = None, *,
                strict_low: bool = False) -> None:
    """``ValueError`` naming ``key`` unless every entry lies in ``[low, high]`` (``(low, high]``
    with ``strict_low``); ``None`` leaves that side open."""
    arr = np.asarray(arr)
    if arr.size == 0:
        return
    bad_low = low is not None and (np.any(arr <= low) if strict_low else np.any(arr < low))
    bad_high = high is not None and np.any(arr > high)
    if bad_low or bad_high:
        lo = "-inf" if low is None else f"{low}"
        hi = "inf" if high is None else f"{high}"
        bracket = "(" if strict_low else "["
        raise ValueError(f"state[{key!r}] must lie in {bracket}{lo}, {hi}], got values from "
                         f"{float(np.min(arr))} to {float(np.max(arr))}")


__all__ = ["EPISODE_KEYS", "EpisodeState", "task_id", "episode_arrays", "check_state_dict", "check_state_layout",
           "check_episode", "check_range"]
