"""Dynamics backends for MAIL's trajectory optimisation: the true simulator or a learned model.

Both answer one question for CEM: *where do the object's particles end up* if the student
executes each of ``B`` pick-and-place action sequences from a given start state?
"""

from __future__ import annotations

from typing import Any, Protocol

import gymnasium as gym
import numpy as np

from lfd_agents.mail.dynamics import LearnedDynamics


class DynamicsBackend(Protocol):
    def final_particles(self, start_state: dict[str, np.ndarray], action_seqs: np.ndarray) -> np.ndarray:
        """(B, K, 3) particle positions after each sequence; K = :attr:`indices` size."""

    indices: np.ndarray


def particles_of(state: dict[str, np.ndarray]) -> np.ndarray:
    """Particle positions (N, 3) stored in an env state from ``get_state()``."""
    return np.asarray(state["sim/positions"], dtype=np.float64)


class SimulatorBackend:
    """Rolls sequences out in a batched particle vector env (``num_worlds`` worlds per launch).

    Args:
        env_id: student env id (a particle task).
        env_kwargs: student env kwargs (pick_place mode is forced).
        num_worlds: worlds stepped together; populations are processed in chunks of this size.
    """

    def __init__(self, env_id: str, env_kwargs: dict[str, Any], num_worlds: int = 64):
        kwargs = {**env_kwargs, "action_mode": "pick_place", "obs_mode": "particles"}
        self.venv = gym.make_vec(env_id, num_envs=int(num_worlds), vectorization_mode="vector_entry_point", **kwargs)
        self.venv.reset(seed=0)
        self.num_worlds = int(num_worlds)
        self.num_particles = int(getattr(self.venv.unwrapped, "num_particles",
                                         self.venv.single_observation_space.shape[0]))
        self.indices = np.arange(self.num_particles)
        self.transitions = 0

    def final_particles(self, start_state: dict[str, np.ndarray], action_seqs: np.ndarray) -> np.ndarray:
        seqs = np.asarray(action_seqs, dtype=np.float32)
        b, horizon, _ = seqs.shape
        out = np.empty((b, self.num_particles, 3))
        start = dict(start_state)
        start["episode/step"] = np.array(0)  # no time-limit reset inside a rollout
        for lo in range(0, b, self.num_worlds):
            chunk = seqs[lo:lo + self.num_worlds]
            n = len(chunk)
            for w in range(self.num_worlds):
                self.venv.unwrapped.set_state(w, start)
            obs = None
            for t in range(horizon):
                acts = np.zeros((self.num_worlds,) + self.venv.single_action_space.shape, np.float32)
                acts[:n] = chunk[:, t]
                obs, _, term, trunc, infos = self.venv.step(acts)
                done = np.logical_or(term, trunc)
                if done.any() and "final_obs" in infos:
                    obs = np.array(obs)
                    for i in np.flatnonzero(done):
                        obs[i] = infos["final_obs"][i]
            self.transitions += n * horizon
            out[lo:lo + n] = np.asarray(obs)[:n, : self.num_particles]
        return out

    def close(self) -> None:
        self.venv.close()


class LearnedBackend:
    """Rolls sequences out with a trained :class:`LearnedDynamics` (only the picker's 6 numbers)."""

    def __init__(self, model: LearnedDynamics):
        self.model = model
        self.indices = model.indices
        self.transitions = 0

    def final_particles(self, start_state: dict[str, np.ndarray], action_seqs: np.ndarray) -> np.ndarray:
        seqs = np.asarray(action_seqs, dtype=np.float32)
        self.transitions += seqs.shape[0] * seqs.shape[1]
        return self.model.rollout(particles_of(start_state), seqs)
