"""Input checking shared by every env: clear messages, nothing left half-changed."""

from __future__ import annotations

import functools
import inspect
from typing import Any, Callable, Iterable

import numpy as np


def check_choice(name: str, value: Any, choices: Iterable[Any]) -> Any:
    """Return ``value`` if it is one of ``choices``, else raise ``ValueError`` listing them."""
    choices = tuple(choices)
    if value not in choices:
        raise ValueError(f"{name} must be one of {choices}, got {value!r}")
    return value


def check_int_range(name: str, value: Any, low: int, high: int | None = None) -> int:
    """Return ``value`` as int if ``low <= value <= high`` (no upper bound when ``high`` is None),
    else raise ``ValueError`` (bools are rejected)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low or (
            high is not None and value > high):
        bound = f">= {low}" if high is None else f"in [{low}, {high}]"
        raise ValueError(f"{name} must be an int {bound}, got {value!r}")
    return int(value)


def check_bool(name: str, value: Any) -> bool:
    """Return ``value`` as bool if it is a bool (``numpy.bool_`` too), else raise ``ValueError``."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be a bool (True or False), got {value!r}")
    return bool(value)


def check_float(name: str, value: Any, low: float | None = None, high: float | None = None) -> float:
    """Return ``value`` as float if it is a finite real number in ``[low, high]`` (``None`` = open),
    else raise ``ValueError`` (bools and strings are rejected)."""
    real = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    if not real or not np.isfinite(value) or (low is not None and value < low) or (high is not None and value > high):
        bound = "" if low is None and high is None else f" in [{low}, {high}]"
        raise ValueError(f"{name} must be a finite number{bound}, got {value!r}")
    return float(value)


def check_str(name: str, value: Any) -> str:
    """Return ``value`` if it is a str, else raise ``ValueError``."""
    if not isinstance(value, str):
        raise ValueError(f"{name} must be a str, got {value!r}")
    return value


def check_image_size(value: Any, name: str = "image_size") -> tuple[int, int]:
    """Normalise an image size (an int or ``(height, width)`` ints) to ``(height, width)``."""
    def is_int(v: Any) -> bool:
        return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))

    if is_int(value):
        value = (int(value), int(value))
    if isinstance(value, (str, bytes)) or not isinstance(value, (tuple, list, np.ndarray)) or len(value) != 2 \
            or not all(is_int(v) for v in value):
        raise ValueError(f"{name} must be an int or (height, width) ints, got {value!r}")
    h, w = (int(v) for v in value)
    if not (1 <= h <= 2048 and 1 <= w <= 2048):
        raise ValueError(f"{name} must be within 1..2048 pixels per side, got {value!r}")
    return h, w


def as_real_array(name: str, value: Any, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a float64 array if it is real numeric data (no strings, complex or objects),
    else ``ValueError`` naming ``name`` and the expected ``shape``."""
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.dtype.kind not in "biuf":
        raise ValueError(f"{name} must be a real numeric array of shape {shape}, got {value!r}")
    return arr.astype(np.float64)


def check_array(name: str, value: Any, shape: tuple[int, ...], dtype: Any = np.float32) -> np.ndarray:
    """Convert ``value`` to an array of ``shape`` with finite entries, or raise ``ValueError``."""
    try:
        arr = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array of shape {shape}, got {value!r}") from None
    if arr.shape != tuple(shape):
        raise ValueError(f"{name} must have shape {tuple(shape)}, got shape {arr.shape}")
    if np.issubdtype(arr.dtype, np.floating) and not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN/inf), got {arr}")
    return arr


def _keyword_arguments(init: Callable) -> list[str] | None:
    """Sorted keyword names ``init`` accepts (None when it takes ``**kwargs``)."""
    params = inspect.signature(init).parameters
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
        return None
    return sorted(n for n, p in params.items()
                  if n != "self" and p.kind in (inspect.Parameter.KEYWORD_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD))


@functools.lru_cache(maxsize=None)
def _init_keyword_arguments(cls: type) -> list[str] | None:
    return _keyword_arguments(cls.__init__)


def check_init_kwargs(cls: type, kwargs: dict[str, Any]) -> None:
    """``TypeError`` listing the valid arguments when ``kwargs`` has names ``cls.__init__`` does not take.

    Python's own message only names the bad argument; users of ``gymnasium.make`` need
    to see what *is* accepted.
    """
    valid = _init_keyword_arguments(cls)
    unknown = [] if valid is None else sorted(set(kwargs) - set(valid))
    if unknown:
        raise TypeError(f"{cls.__name__} got unknown argument(s) {unknown}; valid arguments are {valid}")


class StrictInitKwargs:
    """Base class whose constructor rejects unknown keyword arguments with a ``TypeError`` listing
    the valid ones (:func:`check_init_kwargs` against the subclass's ``__init__``, before it runs).

    Subclasses that override ``__new__`` pass the constructor arguments on to ``super().__new__``.
    """

    def __new__(cls, *args: Any, **kwargs: Any):
        check_init_kwargs(cls, kwargs)
        return super().__new__(cls)


def strict_kwargs(init: Callable) -> Callable:
    """Decorate an ``__init__`` so unknown keyword arguments raise a ``TypeError`` listing the valid ones
    (for classes that do not derive from :class:`StrictInitKwargs`)."""
    valid = _keyword_arguments(init)

    @functools.wraps(init)
    def wrapper(self, *args, **kwargs):
        unknown = [] if valid is None else sorted(set(kwargs) - set(valid))
        if unknown:
            raise TypeError(f"{type(self).__name__} got unknown argument(s) {unknown}; valid arguments are {valid}")
        return init(self, *args, **kwargs)

    return wrapper
