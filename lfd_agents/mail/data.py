"""Random-action transitions for MAIL's dynamics model, collected in batched worlds.

MAIL trains its forward model on random pick-and-place transitions of the student (reference
§3.1 step 2: each step stored as its own length-1 sequence). Here ``num_worlds`` worlds of the
task's vector env step together (one engine call per frame for all of them), and the random
moves are the task's own (``task.sample_pick_place``, as the ``"random_pick_place"`` dataset
policy; tasks without it pick a random particle and place it on the table anywhere).

CEM later proposes actions that *miss* the object, so a fraction of the moves is perturbed:
with probability ``explore`` the pick point gets Gaussian noise of ``noise`` (normalised units)
on every axis, and with probability ``uniform`` the whole action is uniform in ``[-1, 1]``.
Without such samples the model never learns that a missed pick moves nothing and CEM exploits it.

Transitions are saved as ``.npz``: ``x``, ``x_next`` (M, N, 3) float32 particle positions
(pickers excluded), ``actions`` (M, 6·P) float32, ``variants`` (M,) int64.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

__all__ = ["collect_transitions", "save_transitions", "load_transitions", "chamfer"]


def _random_action(venv: Any, world: int, rng: np.random.Generator, explore: float, noise: float,
                   uniform: float) -> np.ndarray:
    from lfd_envs.experts.random_pick_place import default_sample_pick_place

    task = venv.task
    modes = venv.picker_actions
    dim = int(np.prod(venv.single_action_space.shape))
    u = rng.random()
    if u < uniform:
        return rng.uniform(-1.0, 1.0, dim).astype(np.float32)
    positions = np.asarray(venv.particle_positions[world], np.float64)
    sampler = getattr(task, "sample_pick_place", None)
    if sampler is None:
        pick, place = default_sample_pick_place(task, positions, venv.workspace, rng)
    else:
        pick, place = sampler(positions, venv.world_context(world), rng)
    pick = np.asarray(pick, np.float64).copy()
    pick[:, 2] = np.where(pick[:, 2] < 0.03, 0.0, pick[:, 2])  # on the table: as low as possible
    action = modes.join(pick, place).astype(np.float64)
    if u < uniform + explore:
        p = pick.shape[0]
        action[: 3 * p] += rng.normal(0.0, noise, 3 * p)
    return np.clip(action, -1.0, 1.0).astype(np.float32)


def collect_transitions(env_id: str, env_kwargs: dict[str, Any], num: int, *, num_worlds: int = 16,
                        seed: int = 0, split: str = "train", explore: float = 0.25, noise: float = 0.1,
                        uniform: float = 0.1) -> dict[str, np.ndarray]:
    """``num`` random pick-and-place transitions of ``env_id`` (pick_place, particles forced).

    Worlds start in variants drawn by ``seed`` (world ``i`` seeded ``seed + i``) and are reset
    to a new variant when their episode ends (horizon of the pick_place mode).
    """
    if num < 1 or num_worlds < 1:
        raise ValueError(f"num and num_worlds must be >= 1, got {num}, {num_worlds}")
    kwargs = {**env_kwargs, "action_mode": "pick_place", "obs_mode": "particles"}
    w = int(min(num_worlds, num))
    venv = gym.make_vec(env_id, num_envs=w, vectorization_mode="vector_entry_point", **kwargs)
    base = venv.unwrapped
    rng = np.random.default_rng(seed)
    venv.reset(seed=seed, options={"split": split})
    n = base.num_particles
    xs, acts, nxt, variants = [], [], [], []
    while sum(len(a) for a in acts) < num:
        x = np.array(base.particle_positions, np.float32)
        var = base.variant_indices
        a = np.stack([_random_action(base, i, rng, explore, noise, uniform) for i in range(w)])
        obs, _, term, trunc, infos = venv.step(a)
        obs = np.array(obs)
        for i in np.flatnonzero(np.logical_or(term, trunc)):
            obs[i] = infos["final_obs"][i]
        xs.append(x)
        acts.append(a)
        nxt.append(obs[:, :n].astype(np.float32))
        variants.append(var)
    venv.close()
    cat = lambda items: np.concatenate(items)[:num]  # noqa: E731
    return {"x": cat(xs), "actions": cat(acts), "x_next": cat(nxt), "variants": cat(variants)}


def save_transitions(data: dict[str, np.ndarray], path: str | Path) -> Path:
    """Save :func:`collect_transitions` output (atomic: a partial file never looks complete)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".partial.npz")
    np.savez_compressed(tmp, **data)
    tmp.replace(path)
    return path


def load_transitions(path: str | Path) -> dict[str, np.ndarray]:
    """Load a file written by :func:`save_transitions`."""
    with np.load(str(path)) as f:
        return {k: f[k] for k in f.files}


def chamfer(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Symmetric chamfer distance (mean nearest-neighbour distance both ways, halved) of point
    clouds ``(..., K, 3)`` and ``(..., L, 3)`` → ``(...)`` in metres."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    d = np.linalg.norm(a[..., :, None, :] - b[..., None, :, :], axis=-1)
    return 0.5 * (d.min(axis=-1).mean(axis=-1) + d.min(axis=-2).mean(axis=-1))
