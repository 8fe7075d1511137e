"""lfd_agents: Stable-Baselines3-compatible agents for learning from demonstrations.

Imports are lazy (``lfd_agents.DMfD`` imports torch/SB3 on first access), so
``import lfd_agents`` stays cheap. Each name maps to ``"module:attribute"`` in ``_LAZY``;
add new agents there.
"""

from __future__ import annotations

import importlib
from typing import Any

_LAZY: dict[str, str] = {
    # DMfD and learning-from-demonstration baselines (issue 8)
    "DMfD": "lfd_agents.dmfd:DMfD",
    "SACLfD": "lfd_agents.baselines:SACLfD",
    "BC": "lfd_agents.baselines:BC",
    "AWAC": "lfd_agents.baselines:AWAC",
    # SAC from pixels: DrQ and CURL (shared encoder, augmented batches)
    "DrQ": "lfd_agents.drq:DrQ",
    "CURL": "lfd_agents.curl:CURL",
    "ReferenceStateInit": "lfd_agents.rsi:ReferenceStateInit",
    "ImageEncoder": "lfd_agents.networks:ImageEncoder",
    "load_episodes": "lfd_agents.demos:load_episodes",
    "fill_replay_buffer": "lfd_agents.demos:fill_replay_buffer",
}

__all__ = sorted(_LAZY)


def __getattr__(name: str) -> Any:
    target = _LAZY.get(name)
    if target is None:
        raise AttributeError(f"module 'lfd_agents' has no attribute {name!r}")
    module, attr = target.split(":")
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
