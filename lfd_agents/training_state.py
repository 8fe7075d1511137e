"""Everything a learner needs to continue training where it stopped, as plain picklable data.

A benchmark cell that runs for hours must survive being killed. The harness does that by
saving a learner's *training state* at fixed step counts and, whether or not the process was
killed, continuing from a freshly built learner into which that state is loaded — so a resumed
run and an uninterrupted one take exactly the same path. The state of a learner is:

* the parameters and optimiser states SB3 saves (``get_parameters``), and the extra tensors it
  names (SAC's ``log_ent_coef``);
* the filled part of the replay buffer (arrays cut to the rows written, plus its counters and
  generators) — buffers of demonstrations are rebuilt by the constructor from the same files;
* the plain attributes: counters (``num_timesteps``, ``_n_updates``, ``_episode_num``), flags
  (DMfD's ``_offline_done``), episode statistics, numpy and torch generators (augmentation shifts).

What is not in it — the envs, the last observation, torch's and numpy's global generators — is
set again by :func:`reseed` with a seed derived from the run's seed and the stop index.

Learners that wrap another (``SelectBest``, ``MoPAAgent``) provide ``get_training_state()``,
``set_training_state(state)`` and ``reseed(seed)`` themselves; any Stable-Baselines3 algorithm
works through :func:`get_training_state` as it is.

Example::

    state = get_training_state(model)          # model: DMfD, SAC, BC, ...
    fresh = DMfD("MlpPolicy", env, demonstrations=demos, seed=0)
    set_training_state(fresh, state)
    reseed(fresh, 1)
    fresh.learn(10_000, reset_num_timesteps=False)
"""

from __future__ import annotations

import copy
from collections import deque
from typing import Any

import numpy as np
import torch as th
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.buffers import BaseBuffer

__all__ = ["supports_training_state", "get_training_state", "set_training_state", "reseed"]

#: attributes that describe the current episode of the (rebuilt) env, not the learner
_EPISODE_ATTRS = frozenset({"_last_obs", "_last_original_obs", "_last_episode_starts", "start_time",
                            "_num_timesteps_at_start", "_total_timesteps"})


def supports_training_state(agent: Any) -> bool:
    """Whether :func:`get_training_state` can capture ``agent`` (an SB3 algorithm, or an object
    with ``get_training_state``/``set_training_state``/``reseed`` methods)."""
    if all(callable(getattr(agent, name, None)) for name in ("get_training_state", "set_training_state", "reseed")):
        return True
    return isinstance(agent, BaseAlgorithm)


def get_training_state(agent: Any) -> dict[str, Any]:
    """The training state of ``agent`` (module docstring); ``TypeError`` if it has none."""
    if callable(getattr(agent, "get_training_state", None)):
        return agent.get_training_state()
    if not isinstance(agent, BaseAlgorithm):
        raise TypeError(f"{type(agent).__name__} is neither an SB3 algorithm nor has get_training_state()")
    _, tensor_names = agent._get_torch_save_params()
    buffer = getattr(agent, "replay_buffer", None)
    return {
        "class": type(agent).__name__,
        "parameters": agent.get_parameters(),
        "tensors": {name: _attr(agent, name).detach().clone() for name in tensor_names},
        "replay_buffer": _buffer_state(buffer) if isinstance(buffer, BaseBuffer) else None,
        "attributes": _plain_attributes(agent, skip=_EPISODE_ATTRS),
    }


def set_training_state(agent: Any, state: dict[str, Any]) -> None:
    """Load ``state`` (from :func:`get_training_state` of a learner built the same way) into ``agent``."""
    if callable(getattr(agent, "set_training_state", None)):
        agent.set_training_state(state)
        return
    if not isinstance(agent, BaseAlgorithm):
        raise TypeError(f"{type(agent).__name__} is neither an SB3 algorithm nor has set_training_state()")
    if state.get("class") != type(agent).__name__:
        raise ValueError(f"training state of a {state.get('class')!r} cannot be loaded into a {type(agent).__name__}")
    agent.set_parameters(state["parameters"], exact_match=True, device=agent.device)
    with th.no_grad():
        for name, value in state["tensors"].items():
            _attr(agent, name).copy_(value)
    if state["replay_buffer"] is not None:
        _load_buffer(agent.replay_buffer, state["replay_buffer"])
    _load_plain_attributes(agent, state["attributes"])


def reseed(agent: Any, seed: int) -> None:
    """Seed ``agent``'s generators, its env's next reset and torch/numpy/random with ``seed``."""
    if callable(getattr(agent, "reseed", None)):
        agent.reseed(int(seed))
    elif isinstance(agent, BaseAlgorithm):
        agent.set_random_seed(int(seed))
    else:
        raise TypeError(f"cannot reseed a {type(agent).__name__}")


# ----------------------------------------------------------------------------------- helpers
def _attr(obj: Any, dotted: str) -> Any:
    for part in dotted.split("."):
        obj = getattr(obj, part)
    return obj


def _is_plain(value: Any) -> bool:
    """Data that pickles without references to live objects: scalars, strings, and containers of them."""
    if value is None or isinstance(value, (bool, int, float, str, np.bool_, np.integer, np.floating)):
        return True
    if isinstance(value, (list, tuple, deque)):
        return all(_is_plain(v) for v in value)
    if isinstance(value, dict):
        return all(isinstance(k, str) and _is_plain(v) for k, v in value.items())
    return False


def _plain_attributes(obj: Any, skip: frozenset[str] = frozenset()) -> dict[str, Any]:
    """Copies of ``obj``'s plain attributes; numpy generators as their bit-generator states."""
    out: dict[str, Any] = {}
    for name, value in vars(obj).items():
        if name in skip:
            continue
        if isinstance(value, np.random.Generator):
            out[name] = ("np.random.Generator", copy.deepcopy(value.bit_generator.state))
        elif isinstance(value, th.Generator):
            out[name] = ("torch.Generator", value.get_state().clone())
        elif _is_plain(value):
            out[name] = copy.deepcopy(value)
    return out


def _load_plain_attributes(obj: Any, saved: dict[str, Any]) -> None:
    for name, value in saved.items():
        if isinstance(value, tuple) and len(value) == 2 and value[0] == "np.random.Generator":
            getattr(obj, name).bit_generator.state = copy.deepcopy(value[1])
        elif isinstance(value, tuple) and len(value) == 2 and value[0] == "torch.Generator":
            getattr(obj, name).set_state(value[1])
        else:
            setattr(obj, name, copy.deepcopy(value))


def _rows(buffer: BaseBuffer, value: Any) -> bool:
    return isinstance(value, np.ndarray) and value.ndim >= 1 and value.shape[0] == buffer.buffer_size


def _buffer_state(buffer: BaseBuffer) -> dict[str, Any]:
    """The rows of ``buffer`` written so far (all once it wrapped) and its plain attributes."""
    n = buffer.buffer_size if buffer.full else buffer.pos
    arrays: dict[str, Any] = {}
    for name, value in vars(buffer).items():
        if _rows(buffer, value):
            arrays[name] = value[:n].copy()
        elif isinstance(value, dict) and value and all(_rows(buffer, v) for v in value.values()):
            arrays[name] = {key: v[:n].copy() for key, v in value.items()}
    return {"size": buffer.buffer_size, "rows": n, "arrays": arrays, "attributes": _plain_attributes(buffer)}


def _load_buffer(buffer: BaseBuffer, state: dict[str, Any]) -> None:
    if state["size"] != buffer.buffer_size:
        raise ValueError(f"saved replay buffer holds {state['size']} transitions, this one {buffer.buffer_size}")
    n = state["rows"]
    for name, saved in state["arrays"].items():
        target = getattr(buffer, name)
        if isinstance(saved, dict):
            for key, rows in saved.items():
                target[key][:n] = rows
        else:
            target[:n] = saved
    _load_plain_attributes(buffer, state["attributes"])
