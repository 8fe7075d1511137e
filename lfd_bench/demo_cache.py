"""Expert demonstrations for the harness, collected once per (env, kwargs, episodes, seed) and cached.

The cache lives under the results folder (``<out>/_demos/<key>``). A dataset is collected into a
temporary sibling folder and renamed into place only when Minari has finished writing it, so a
killed run never leaves a half-written cache entry behind. Every cache hit is read back and
checked (episode count, non-empty episodes); a broken entry is removed and collected again with
a warning that names it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import shutil
import uuid
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym

#: Sub-folder of the results folder holding the demonstration cache.
CACHE_DIRNAME = "_demos"


@dataclass(frozen=True)
class Demonstrations:
    """A validated cached demonstration dataset."""

    path: Path  #: the Minari dataset folder (pass ``str(path)`` to the agents)
    episodes: int  #: episodes in the dataset
    transitions: int  #: environment transitions in the dataset
    mean_final_performance: float  #: mean final p̂ of the demonstration episodes


def cache_key(env_id: str, env_kwargs: dict[str, Any], episodes: int, seed: int, policy: str = "expert",
              policy_kwargs: dict[str, Any] | None = None) -> str:
    """Folder name of the cache entry of these collection settings (the expert's keys predate the
    ``policy`` arguments and stay as they were)."""
    parts: list[Any] = [env_id, env_kwargs, int(episodes), int(seed)]
    if policy != "expert" or policy_kwargs:
        parts += [policy, dict(policy_kwargs or {})]
    blob = json.dumps(parts, sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def _dataset_dir(root: Path) -> Path | None:
    found = sorted(p.parent for p in root.rglob("data") if p.is_dir()) if root.is_dir() else []
    return found[0] if found else None


def validate(path: Path, episodes: int) -> Demonstrations:
    """Read the dataset at ``path`` back; raises ``ValueError`` naming ``path`` if it is unusable."""
    from lfd_agents.demos import load_episodes
    from lfd_envs import datasets

    try:
        recorded = list(datasets.load(path).iterate_episodes())  # read once: episodes and their p̂
        eps = load_episodes(recorded)
    except Exception as exc:  # h5py/Minari raise OSError, KeyError, ValueError... on a broken file
        raise ValueError(f"cannot read demonstrations at {path}: {type(exc).__name__}: {exc}") from exc
    if len(eps) != int(episodes):
        raise ValueError(f"demonstrations at {path} hold {len(eps)} episodes, expected {episodes}")
    return Demonstrations(path=Path(path), episodes=len(eps), transitions=int(sum(len(ep) for ep in eps)),
                          mean_final_performance=_mean_final_performance(recorded))


def _mean_final_performance(recorded: list[Any]) -> float:
    """Mean final p̂ recorded in the episodes' infos (NaN when they have none)."""
    from lfd_envs import datasets

    try:
        finals = datasets.final_performances(recorded)
    except (KeyError, IndexError, TypeError):
        return float("nan")
    return float(sum(finals) / len(finals)) if finals else float("nan")


def _remove_abandoned(cache_dir: Path, key: str) -> None:
    """Delete temporary collection folders of ``key`` left by killed processes of this machine."""
    for tmp in cache_dir.glob(f".{key}.tmp-*"):
        try:
            pid = int(tmp.name.split(".tmp-", 1)[1].split("-", 1)[0])
            os.kill(pid, 0)  # raises if no such process
        except ProcessLookupError:
            shutil.rmtree(tmp, ignore_errors=True)
        except (ValueError, PermissionError):
            pass  # not ours to judge


def demonstrations_for(env: gym.Env, episodes: int, cache_dir: str | os.PathLike, seed: int = 0,
                       policy: str = "expert", policy_kwargs: dict[str, Any] | None = None) -> Demonstrations:
    """Demonstrations for ``env``'s id and kwargs from ``cache_dir`` (collected on a miss).

    Args:
        env: an env made with ``gymnasium.make`` (its spec defines what is collected).
        episodes: number of demonstration episodes.
        cache_dir: cache root, normally ``<results folder>/_demos``.
        seed: collection seed (episode ``i`` resets with ``seed + 500_000 + i``).
        policy: the demonstrator, a name of :data:`lfd_envs.datasets.POLICIES` (default: the
            scripted expert; ``"noisy_expert"`` gives demonstrations of lower quality).
        policy_kwargs: arguments of the demonstrator, e.g. ``{"epsilon": 0.2}``.
    """
    from lfd_envs import datasets

    spec = env.spec
    if spec is None:
        raise ValueError("demonstration agents need an env made with gymnasium.make (env.spec is None)")
    if int(episodes) < 1:
        raise ValueError(f"demo_episodes must be >= 1, got {episodes}")
    if policy not in datasets.POLICIES:
        raise ValueError(f"unknown demonstration policy {policy!r}; valid: {sorted(datasets.POLICIES)}")
    kwargs = {k: v for k, v in (spec.kwargs or {}).items() if k != "render_mode"}
    cache_dir = Path(cache_dir)
    root = cache_dir / cache_key(spec.id, kwargs, episodes, seed, policy, policy_kwargs)
    if root.exists():
        found = _dataset_dir(root)
        try:
            if found is None:
                raise ValueError(f"no Minari dataset under {root}")
            return validate(found, episodes)
        except ValueError as exc:
            warnings.warn(f"demonstration cache {root} is broken ({exc}); collecting it again", stacklevel=2)
            shutil.rmtree(root, ignore_errors=True)
    cache_dir.mkdir(parents=True, exist_ok=True)
    _remove_abandoned(cache_dir, root.name)
    tmp = cache_dir / f".{root.name}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}"
    try:
        written = datasets.collect(spec.id, int(episodes), tmp, env_kwargs=kwargs, seed=seed + 500_000,
                                   policy=policy, policy_kwargs=policy_kwargs, progress=False)
        rel = Path(written).resolve().relative_to(tmp.resolve())
        checked = validate(tmp / rel, episodes)
        try:
            tmp.rename(root)
            if (root / rel / "data").is_dir():  # ours, now in place: already checked
                return dataclasses.replace(checked, path=root / rel)
        except OSError:  # another worker finished the same entry first: use theirs
            if _dataset_dir(root) is None:
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    found = _dataset_dir(root)
    if found is None:
        raise RuntimeError(f"demonstration cache {root} has no dataset after collection")
    return validate(found, episodes)
