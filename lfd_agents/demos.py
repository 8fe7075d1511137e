"""Demonstrations for the learning-from-demonstration agents: loading and replay-buffer filling.

Every agent that takes ``demonstrations=`` accepts the same things (see :func:`load_episodes`):

* a Minari dataset (``minari.MinariDataset``), a path to one (the dataset folder or its
  ``data`` folder, as written by ``lfd_envs.datasets.collect``) or a local Minari dataset id;
* a list of Minari ``EpisodeData``, of :class:`Episode`, or of dicts with the keys
  ``observations`` (T+1 entries), ``actions``, ``rewards``, ``terminations``, ``truncations``
  and optionally ``infos`` / ``states``.

Image observations of a dataset written by ``lfd_envs.datasets`` are rendered again from its
stored states (``lfd_envs.datasets.exact_observations``): Minari keeps them only as JPEG.

Per-step simulator states (for reference-state initialisation) are read from each episode's
``infos["state"]``: Minari episodes through ``lfd_envs.datasets.episode_states`` (which undoes
that module's key encoding), dict episodes by flattening nested dicts with ``"/"``. Each entry
is a dict for ``env.unwrapped.set_state`` (dtypes are matched to the env's at restore time).

:func:`fill_replay_buffer` writes the transitions into an SB3 ``ReplayBuffer`` /
``DictReplayBuffer`` (optionally repeating a small set to fill it), converting observations to
the buffer's layout (channel-first images, Dict subsets) and actions to SB3's [-1, 1] scaling.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any, Iterable, Sequence

import numpy as np
from gymnasium import spaces
from stable_baselines3.common.buffers import DictReplayBuffer, ReplayBuffer

Obs = Any  # np.ndarray or dict[str, np.ndarray]


@dataclass
class Episode:
    """One demonstration episode of T steps.

    Attributes:
        observations: T+1 observations (array with leading axis T+1, or dict of such arrays).
        actions: (T, act_dim) actions in env units.
        rewards, terminations, truncations: (T,) arrays.
        states: T+1 simulator states (``get_state`` dicts), or None when the demo has none.
    """

    observations: Obs
    actions: np.ndarray
    rewards: np.ndarray
    terminations: np.ndarray
    truncations: np.ndarray
    states: list[dict[str, np.ndarray]] | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        self.actions = np.asarray(self.actions, dtype=np.float32)
        if self.actions.ndim == 1:
            self.actions = self.actions[:, None]
        t = len(self.actions)
        self.rewards = np.asarray(self.rewards, dtype=np.float32).reshape(t)
        self.terminations = np.asarray(self.terminations, dtype=bool).reshape(t)
        self.truncations = np.asarray(self.truncations, dtype=bool).reshape(t)
        n_obs = _obs_len(self.observations)
        if n_obs != t + 1:
            raise ValueError(f"an episode of {t} actions needs {t + 1} observations, got {n_obs}")

    def __len__(self) -> int:
        return len(self.actions)

    def observation(self, t: int) -> Obs:
        """Observation ``t`` (0 = after reset)."""
        if isinstance(self.observations, dict):
            return {k: v[t] for k, v in self.observations.items()}
        return self.observations[t]


def _obs_len(obs: Obs) -> int:
    if isinstance(obs, dict):
        lengths = {len(v) for v in obs.values()}
        if len(lengths) != 1:
            raise ValueError(f"observation entries have different lengths {sorted(lengths)}")
        return lengths.pop()
    return len(obs)


def _as_obs(obs: Any) -> Obs:
    if isinstance(obs, dict):
        return {k: np.asarray(v) for k, v in obs.items()}
    return np.asarray(obs)


def flatten_dict(tree: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Flatten nested dicts, joining keys with ``"/"``."""
    out: dict[str, Any] = {}
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flatten_dict(value, name + "/"))
        else:
            out[name] = value
    return out


def states_from_infos(infos: dict[str, Any] | None, key: str = "state") -> list[dict[str, np.ndarray]] | None:
    """Split the per-step ``infos[key]`` (dict of arrays with a leading time axis) into state dicts."""
    if not infos or key not in infos or not isinstance(infos[key], dict):
        return None
    flat = {k: np.asarray(v) for k, v in flatten_dict(infos[key]).items()}
    if not flat:
        return None
    n = min(len(v) for v in flat.values())
    return [{k: v[t] for k, v in flat.items()} for t in range(n)]


def _minari_states(ep: Any) -> list[dict[str, np.ndarray]] | None:
    """States of a Minari episode written by ``lfd_envs.datasets`` (its own key encoding)."""
    infos = getattr(ep, "infos", None)
    if not infos or "state" not in infos:
        return None
    try:
        from lfd_envs.datasets import episode_states
    except ImportError:  # pragma: no cover - lfd_envs is a dependency
        return states_from_infos(infos)
    return episode_states(ep)


def _from_episode_data(ep: Any, images_env: Any = None) -> Episode:
    states = _minari_states(ep)
    obs = ep.observations
    if images_env is not None:
        from lfd_envs.datasets import exact_observations

        obs = exact_observations(ep, images_env, states)
    return Episode(observations=_as_obs(obs), actions=ep.actions, rewards=ep.rewards,
                   terminations=ep.terminations, truncations=ep.truncations, states=states)


def _images_env(dataset: Any) -> Any:
    """For a Minari dataset written by ``lfd_envs.datasets`` whose observations hold images: the
    env it was collected on, to render those images again exactly (Minari stores them as JPEG);
    else None."""
    from lfd_envs import datasets

    space = getattr(dataset, "observation_space", None)
    if space is None or not datasets.has_images(space):
        return None
    try:
        datasets.dataset_config(dataset)
    except (AttributeError, KeyError, TypeError, ValueError):  # not written by lfd_envs.datasets
        return None
    return datasets.make_env(dataset)


def _from_mapping(ep: dict[str, Any]) -> Episode:
    missing = [k for k in ("observations", "actions") if k not in ep]
    if missing:
        raise ValueError(f"demonstration dict is missing {missing}; needs observations (T+1) and actions (T)")
    t = len(ep["actions"])
    states = ep.get("states")
    if states is None:
        states = states_from_infos(ep.get("infos"))
    return Episode(observations=_as_obs(ep["observations"]), actions=ep["actions"],
                   rewards=ep.get("rewards", np.zeros(t)), terminations=ep.get("terminations", np.zeros(t, bool)),
                   truncations=ep.get("truncations", np.eye(1, t, t - 1, dtype=bool)[0]), states=states)


def _open_minari(source: str | os.PathLike) -> Any:
    import minari

    path = os.fspath(source)
    if os.path.isdir(path):
        data = os.path.join(path, "data")
        return minari.MinariDataset(data if os.path.isdir(data) else path)
    return minari.load_dataset(path)


def load_episodes(demonstrations: Any) -> list[Episode]:
    """Normalise any supported demonstration source (module docstring) to a list of :class:`Episode`."""
    if demonstrations is None:
        return []
    if isinstance(demonstrations, (str, os.PathLike)):
        demonstrations = _open_minari(demonstrations)
    images_env = None
    if hasattr(demonstrations, "iterate_episodes"):
        images_env = _images_env(demonstrations)
        demonstrations = demonstrations.iterate_episodes()
    try:
        episodes = _read_episodes(demonstrations, images_env)
    finally:
        if images_env is not None:
            images_env.close()
    if any(len(ep) == 0 for ep in episodes):
        raise ValueError("demonstration episodes must have at least one step")
    return episodes


def _read_episodes(demonstrations: Any, images_env: Any) -> list[Episode]:
    if isinstance(demonstrations, (Episode, dict)) or hasattr(demonstrations, "observations"):
        demonstrations = [demonstrations]
    episodes: list[Episode] = []
    for ep in demonstrations:
        if isinstance(ep, Episode):
            episodes.append(ep)
        elif isinstance(ep, dict):
            episodes.append(_from_mapping(ep))
        elif hasattr(ep, "observations") and hasattr(ep, "actions"):
            episodes.append(_from_episode_data(ep, images_env))
        else:
            raise TypeError(f"cannot read a demonstration episode from {type(ep).__name__}; pass a Minari "
                            "dataset, a path or id of one, or a list of EpisodeData / Episode / dicts")
    return episodes


# ---------------------------------------------------------------------------------- buffer filling
def _match_array(arr: np.ndarray, shape: tuple[int, ...], what: str) -> np.ndarray:
    """Make per-step arrays ``(N, *x)`` fit ``shape``: transpose HWC→CHW images when needed."""
    if arr.shape[1:] == tuple(shape):
        return arr
    if arr.ndim == 4 and arr.shape[1:] == (shape[1], shape[2], shape[0]):
        return np.ascontiguousarray(np.moveaxis(arr, -1, 1))
    raise ValueError(f"demonstration {what} have shape {arr.shape[1:]} per step but the agent expects {tuple(shape)}; "
                     "collect the demonstrations with the same obs_mode and image_size as the env")


def _select(obs: Obs, space: spaces.Space, what: str) -> Obs:
    """Pick the part of a demo observation (batch-first) that matches ``space``."""
    if isinstance(space, spaces.Dict):
        if not isinstance(obs, dict):
            raise ValueError(f"the agent expects Dict observations with keys {list(space.spaces)}, "
                             f"but the demonstration {what} are arrays")
        missing = [k for k in space.spaces if k not in obs]
        if missing:
            raise ValueError(f"demonstration {what} lack keys {missing} (they have {list(obs)})")
        return {k: _match_array(obs[k], space.spaces[k].shape, f"{what}[{k!r}]") for k in space.spaces}
    if isinstance(obs, dict):
        preferred = ["image", "state"] if len(space.shape) == 3 else ["state", "image"]
        for key in preferred + [k for k in obs if k not in preferred]:
            if key in obs:
                try:
                    return _match_array(obs[key], space.shape, f"{what}[{key!r}]")
                except ValueError:
                    continue
        raise ValueError(f"no entry of the demonstration {what} (keys {list(obs)}) fits the agent's "
                         f"observation shape {space.shape}")
    return _match_array(obs, space.shape, what)


def _concat(parts: list[Obs]) -> Obs:
    if isinstance(parts[0], dict):
        return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    return np.concatenate(parts)


def episodes_to_transitions(episodes: Sequence[Episode], observation_space: spaces.Space,
                            action_space: spaces.Box) -> dict[str, Any]:
    """Stack episodes into transition arrays fitted to the spaces (actions scaled to [-1, 1])."""
    if not episodes:
        raise ValueError("no demonstration episodes given")
    obs, next_obs = [], []
    for ep in episodes:
        o = _select(ep.observations, observation_space, "observations")
        if isinstance(o, dict):
            obs.append({k: v[:-1] for k, v in o.items()})
            next_obs.append({k: v[1:] for k, v in o.items()})
        else:
            obs.append(o[:-1])
            next_obs.append(o[1:])
    actions = np.concatenate([ep.actions for ep in episodes]).astype(np.float32)
    if actions.shape[1:] != action_space.shape:
        raise ValueError(f"demonstration actions have shape {actions.shape[1:]} but the env's action space is "
                         f"{action_space.shape}; collect demos with the same num_pickers and action_mode")
    low, high = action_space.low, action_space.high
    scaled = np.clip(2.0 * (actions - low) / (high - low) - 1.0, -1.0, 1.0).astype(np.float32)
    term = np.concatenate([ep.terminations for ep in episodes])
    trunc = np.concatenate([ep.truncations for ep in episodes])
    return {"observations": _concat(obs), "next_observations": _concat(next_obs), "actions": scaled,
            "rewards": np.concatenate([ep.rewards for ep in episodes]).astype(np.float32),
            "dones": (term | trunc).astype(np.float32), "timeouts": (trunc & ~term).astype(np.float32)}


def _write(target: np.ndarray, rows: np.ndarray, values: np.ndarray, n_envs: int) -> None:
    target[rows] = values.reshape((len(rows), n_envs) + target.shape[2:]).astype(target.dtype, copy=False)


def fill_replay_buffer(buffer: ReplayBuffer, demonstrations: Any, *, duplicate: bool | int = False) -> int:
    """Write demonstration transitions into an SB3 replay buffer (FIFO, from its current position).

    Args:
        buffer: a ``ReplayBuffer`` or ``DictReplayBuffer`` (``optimize_memory_usage=False``).
        demonstrations: anything :func:`load_episodes` accepts.
        duplicate: ``False`` writes each transition once; ``True`` repeats the set until the
            buffer is full; an int ``k`` writes it ``k`` times.

    Returns:
        Number of transitions written (including repeats).
    """
    if getattr(buffer, "optimize_memory_usage", False):
        raise ValueError("pre-filling needs a replay buffer with optimize_memory_usage=False")
    if not isinstance(buffer, (ReplayBuffer, DictReplayBuffer)):
        raise TypeError(f"cannot fill {type(buffer).__name__}; use a ReplayBuffer or DictReplayBuffer")
    episodes = load_episodes(demonstrations)
    if not episodes:
        return 0
    data = episodes_to_transitions(episodes, buffer.observation_space, buffer.action_space)
    n = len(data["actions"])
    n_envs, capacity = buffer.n_envs, buffer.buffer_size
    if duplicate is True:
        repeats = max(1, math.ceil(capacity * n_envs / n))
    else:
        repeats = int(duplicate) if duplicate else 1
        if repeats < 1:
            raise ValueError(f"duplicate must be a bool or an int >= 1, got {duplicate!r}")
    total = n * repeats
    n_rows = math.ceil(total / n_envs)
    idx = np.arange(n_rows * n_envs) % n  # repeats, and pads the last row with the first transitions
    n_rows_kept = min(n_rows, capacity)
    idx = idx[(n_rows - n_rows_kept) * n_envs:]
    rows = (buffer.pos + np.arange(n_rows_kept)) % capacity

    def take(x: Obs) -> Obs:
        return {k: v[idx] for k, v in x.items()} if isinstance(x, dict) else x[idx]

    for name in ("observations", "next_observations"):
        src, dst = take(data[name]), getattr(buffer, name)
        if isinstance(dst, dict):
            for k in dst:
                _write(dst[k], rows, src[k], n_envs)
        else:
            _write(dst, rows, src, n_envs)
    for name in ("actions", "rewards", "dones", "timeouts"):
        _write(getattr(buffer, name), rows, data[name][idx], n_envs)
    end = buffer.pos + n_rows_kept
    buffer.full = buffer.full or end >= capacity
    buffer.pos = end % capacity
    return min(total, n_rows_kept * n_envs)


def episodes_with_states(episodes: Iterable[Episode]) -> list[Episode]:
    """The episodes that carry per-step simulator states (usable for reference-state initialisation)."""
    return [ep for ep in episodes if ep.states]
