"""Probabilistic reference-state initialisation (RSI) with an imitation reward (DMfD).

:class:`ReferenceStateInit` wraps an lfd env. On each training reset, with probability ``p``
it restores a random demonstration state — episode ``j`` uniformly, step ``t ~ U{0..T-1}`` —
through ``env.unwrapped.set_state`` (the episode step counter is restored too, so only
``horizon - t`` steps remain) and, for the rest of that demonstration, adds the imitation reward

    ir_k = 1 / (1 + exp(‖s_ref(t+k) − s_k‖))  ∈ (0, 0.5]

to the task reward after the agent's k-th step, where ``s`` is the env's reduced state
(corners + pickers for cloth) and ``s_ref(t+k)`` the demonstration's reduced state after the
same number of steps. (The original code compared with the demo state *before* that step, an
off-by-one we do not copy.) Episodes that are not reset this way get no imitation reward.
Resets with ``options={"split": "eval"}`` are never changed.

``info`` gets ``"rsi"`` (bool) and ``"rsi_step"`` (t or -1) on reset and
``"imitation_reward"`` on every step.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from lfd_agents.demos import episodes_with_states, load_episodes


def _reduced_state(env: gym.Env, obs: Any) -> np.ndarray:
    base = env.unwrapped
    if hasattr(base, "state_observation"):
        return np.asarray(base.state_observation(), dtype=np.float64).ravel()
    if isinstance(obs, dict) and "state" in obs:
        return np.asarray(obs["state"], dtype=np.float64).ravel()
    return np.asarray(obs, dtype=np.float64).ravel()


class ReferenceStateInit(gym.Wrapper):
    """Reset to demonstration states with probability ``probability`` and add an imitation reward.

    Args:
        env: an env whose ``unwrapped`` has ``set_state``, ``current_observation`` and
            ``current_info`` (every :class:`lfd_envs.core.LfdEnv`). Wrap the base env directly.
        demonstrations: anything :func:`lfd_agents.demos.load_episodes` accepts; episodes need
            per-step states in ``infos["state"]``.
        probability: chance of a reference-state reset (0 disables; DMfD: 0.2 state, 0.3 image).
        imitation_reward_scale: factor on the imitation reward (0 keeps RSI without it).
        seed: seed of the wrapper's own generator (reseeded by ``reset(seed=...)``).
    """

    def __init__(self, env: gym.Env, demonstrations: Any, probability: float = 0.2,
                 imitation_reward_scale: float = 1.0, seed: int | None = None):
        super().__init__(env)
        if not 0.0 <= float(probability) <= 1.0:
            raise ValueError(f"probability must be in [0, 1], got {probability}")
        base = env.unwrapped
        missing = [m for m in ("set_state", "current_observation", "current_info") if not hasattr(base, m)]
        if missing:
            raise TypeError(f"{type(base).__name__} lacks {missing}; reference-state initialisation needs an lfd env")
        self.episodes = episodes_with_states(load_episodes(demonstrations))
        if not self.episodes:
            raise ValueError("no demonstration episode carries simulator states (infos['state']); "
                             "collect demonstrations with lfd_envs.datasets.collect or disable RSI")
        self.probability = float(probability)
        self.imitation_reward_scale = float(imitation_reward_scale)
        self._rng = np.random.default_rng(seed)
        self._refs: dict[int, np.ndarray] = {}
        self._template: dict[str, tuple[np.dtype, tuple[int, ...]]] | None = None
        self._active: tuple[int, int] | None = None

    # ------------------------------------------------------------------ reference tracks
    def _reference(self, j: int) -> np.ndarray:
        """Reduced states (T+1, d) along demonstration ``j`` (from its observations or its states)."""
        if j in self._refs:
            return self._refs[j]
        ep = self.episodes[j]
        base = self.env.unwrapped
        current = _reduced_state(self.env, base.current_observation())
        obs = ep.observations
        vec = obs.get("state") if isinstance(obs, dict) else (obs if np.ndim(obs) == 2 else None)
        if vec is not None and np.shape(vec)[1:] == current.shape:
            ref = np.asarray(vec, dtype=np.float64)
        else:  # image-only demonstrations: read the reduced state off each restored state
            rows = []
            for state in ep.states:  # type: ignore[union-attr]
                base.set_state(self._typed(state))
                rows.append(_reduced_state(self.env, base.current_observation()))
            ref = np.stack(rows)
        self._refs[j] = ref
        return ref

    def _typed(self, state: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Cast a stored state to the dtypes/shapes of the env's own ``get_state`` (datasets may
        store bools as ints)."""
        if self._template is None:
            self._template = {k: (np.asarray(v).dtype, np.shape(v)) for k, v in self.env.unwrapped.get_state().items()}
        out = {}
        for key, value in state.items():
            spec = self._template.get(key)
            arr = np.asarray(value)
            fits = spec is not None and arr.size == int(np.prod(spec[1]))
            out[key] = arr.astype(spec[0], copy=False).reshape(spec[1]) if fits else arr
        return out

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if seed is not None:
            self._rng = np.random.default_rng([int(seed), 0x5253])
        obs, info = self.env.reset(seed=seed, options=options)
        self._active = None
        split = (options or {}).get("split", "train")
        if split == "train" and self.probability > 0 and self._rng.random() < self.probability:
            j = int(self._rng.integers(len(self.episodes)))
            ep = self.episodes[j]
            t = int(self._rng.integers(min(len(ep), len(ep.states) - 1)))  # type: ignore[arg-type]
            obs, info = self.restore(j, t)
        info["rsi"] = self._active is not None
        info["rsi_step"] = self._active[1] if self._active is not None else -1
        return obs, info

    def restore(self, episode: int, step: int) -> tuple[Any, dict[str, Any]]:
        """Put the env into state ``step`` of demonstration ``episode``; returns (obs, info)."""
        self._reference(episode)  # may move the env; the restore below fixes that
        base = self.env.unwrapped
        base.set_state(self._typed(self.episodes[episode].states[step]))  # type: ignore[index]
        self._active = (episode, step)
        return base.current_observation(), dict(base.current_info())

    def step(self, action: Any):
        obs, reward, terminated, truncated, info = self.env.step(action)
        ir = 0.0
        if self._active is not None:
            j, t = self._active
            t += 1
            ref = self._reference(j)
            if t < len(ref):
                dist = float(np.linalg.norm(ref[t] - _reduced_state(self.env, obs)))
                ir = float(1.0 / (1.0 + np.exp(dist)))
                self._active = (j, t)
            else:
                self._active = None
        info["imitation_reward"] = ir
        return obs, float(reward) + self.imitation_reward_scale * ir, terminated, truncated, info
