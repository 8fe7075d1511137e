"""How an expert notices that its env started a new episode.

Every :class:`~lfd_envs.core.LfdEnv` counts the episodes it starts (``episode_count``: one more
after every ``reset`` and every ``set_state``). An expert keeps an :class:`EpisodeTracker` and
forgets its plan when the count moved, so an evaluation loop that never calls
``expert.reset()`` still gets a fresh plan per episode; calling ``reset()`` stays allowed (it
marks the current episode as seen, so the plan is not dropped twice).
"""

from __future__ import annotations

from typing import Any


class EpisodeTracker:
    """Watches ``env.unwrapped.episode_count`` (wrappers allowed)."""

    def __init__(self, env: Any) -> None:
        self._base = env.unwrapped
        self._seen: int | None = None

    def _count(self) -> int | None:
        return getattr(self._base, "episode_count", None)

    def mark(self) -> None:
        """The expert has just been reset for the env's current episode."""
        self._seen = self._count()

    def new_episode(self) -> bool:
        """True once per episode the expert has not seen yet (then marks it as seen)."""
        count = self._count()
        if count is None or count == self._seen:
            return False
        self._seen = count
        return True


__all__ = ["EpisodeTracker"]
