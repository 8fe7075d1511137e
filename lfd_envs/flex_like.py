"""Constructors of the ``-v1`` particle ids: the ``-v0`` env classes with FleX-like settings.

For every ``-v0`` particle task this module has a constructor named like its env class (and one
like its vector env class), e.g. ``lfd_envs.flex_like:ClothFoldEnv``, which builds that class
with :data:`lfd_envs.FLEX_LIKE_SIM_OPTIONS` updated by any ``sim_options`` given and
:data:`lfd_envs.FLEX_LIKE_PICK_PLACE_SPEED` unless ``pick_place_speed`` is given. Gymnasium's
string entry points name them, so ``-v1`` specs serialise like the others.
"""

from __future__ import annotations

import importlib
from typing import Any, Callable

from lfd_envs.registration import FLEX_LIKE_PICK_PLACE_SPEED, FLEX_LIKE_SIM_OPTIONS, V0_PARTICLE_SPECS

__all__ = ["make_flex_like"]


def make_flex_like(entry_point: str, **kwargs: Any) -> Any:
    """Build the env class at ``entry_point`` (``"module:Class"``) with the ``-v1`` settings."""
    module, _, name = entry_point.partition(":")
    cls = getattr(importlib.import_module(module), name)
    given = kwargs.get("sim_options")
    if given is not None and not isinstance(given, dict):
        raise ValueError(f"sim_options must be a dict of SimParams fields, got {type(given).__name__}")
    kwargs["sim_options"] = {**FLEX_LIKE_SIM_OPTIONS, **(given or {})}
    kwargs.setdefault("pick_place_speed", FLEX_LIKE_PICK_PLACE_SPEED)
    return cls(**kwargs)


def _constructor(entry_point: str) -> Callable[..., Any]:
    def make(**kwargs: Any) -> Any:
        return make_flex_like(entry_point, **kwargs)

    make.__name__ = make.__qualname__ = entry_point.rpartition(":")[2]
    make.__doc__ = f"``{entry_point}`` with the ``-v1`` (FleX-like) settings."
    return make


for _entry, _vec_entry, _, _ in V0_PARTICLE_SPECS.values():
    for _ep in (_entry, _vec_entry):
        globals()[_ep.rpartition(":")[2]] = _constructor(_ep)
        __all__.append(_ep.rpartition(":")[2])
