"""Escape check of the particle tasks: ``python -m tools.escapes [--steps 10000] [--envs ...]``.

Drives every particle task in delta mode with random actions (each world keeps its action for a
geometric number of steps, mean 5, so pickers also press into the table and drag for a while,
grasp flag included) and checks every simulated frame that nothing left the scene:

* no particle centre (free, grasped, or part of a rigid box) below the table top (``z < -tol``);
* no free particle inside a static box (the pin block, the drying plank) by more than ``tol``;
* every position finite and within 5 m of the origin.

``--steps`` counts env steps summed over the ``--worlds`` worlds stepped together (10,000 by
default, e.g. 1,000 steps of 10 worlds); the engine is stepped frame by frame as the env would
step it, and the worlds are reset to new variants every horizon. Prints one row per
task: frames checked, violations of each kind, the lowest particle height and the deepest
static-box penetration seen.
"""

from __future__ import annotations

import argparse
from typing import Any

import gymnasium as gym
import numpy as np

from lfd_envs import PARTICLE_ENV_IDS

#: tolerance (m) of the checks. Contact puts particle centres at their radius (5-12.5 mm) above the
#: table; an escape (a box pressed through the table, a particle under it) is centimetres.
TOLERANCE = 1e-3
#: every particle task once (ClothFoldDiagonal is the unpinned task under another id), ``-v0``
#: settings; ``--envs`` takes ``-v1`` ids as well
PARTICLE_TASKS = tuple(i for i in PARTICLE_ENV_IDS if i.endswith("-v0") and i != "ClothFoldDiagonal-v0")


def static_box_depth(positions: np.ndarray, boxes: dict[str, np.ndarray]) -> np.ndarray:
    """How deep (m) each particle is inside any static box, ``(W, N)`` (<= 0: outside).

    ``boxes`` is :attr:`ParticleSim.static_boxes` (``center``/``rotation``/``half_extents`` with a
    leading world axis; zero half extents mark unused slots)."""
    depth = np.full(positions.shape[:2], -np.inf)
    centers, rots, halves = boxes["center"], boxes["rotation"], boxes["half_extents"]
    for s in range(centers.shape[1]):
        local = np.einsum("wnk,wkj->wnj", positions - centers[:, None, s], rots[:, s])
        inside = (halves[:, None, s] - np.abs(local)).min(axis=-1)
        used = halves[:, s, 0] > 0
        depth = np.where(used[:, None], np.maximum(depth, inside), depth)
    return depth


def check_task(env_id: str, steps: int = 10_000, worlds: int = 10, seed: int = 0) -> dict[str, Any]:
    """Run the random-action escape check on one task; returns the row printed by :func:`main`."""
    envs = gym.make_vec(env_id, num_envs=worlds, vectorization_mode="vector_entry_point",
                        action_mode="delta", obs_mode="state")
    try:
        return _check(envs.unwrapped, steps, seed)
    finally:
        envs.close()


def _check(venv: Any, steps: int, seed: int) -> dict[str, Any]:
    batch, sim = venv.batch, venv.batch.sim
    rng = np.random.default_rng(seed)
    venv.reset(seed=seed)
    space = venv.single_action_space
    W = batch.num_worlds
    actions = rng.uniform(space.low, space.high, size=(W,) + space.shape).astype(np.float32)
    frames = below = inside = 0
    lowest, deepest, farthest = np.inf, -np.inf, 0.0
    free = sim.inverse_masses > 0
    horizon = int(venv.horizon)
    for t in range(max(1, steps // W)):
        if t and t % horizon == 0:
            venv.reset(seed=seed + t)
            free = sim.inverse_masses > 0  # the pinned particles differ between variants
        redraw = rng.random(W) < 0.2
        actions[redraw] = rng.uniform(space.low, space.high, size=(int(redraw.sum()),) + space.shape)
        targets, grasp = batch.action_mode.plan(actions, sim.picker_positions)
        for f in range(len(targets)):
            sim.step(targets[f], grasp[f])
            q = sim.positions
            frames += W
            z = q[..., 2]
            lowest = min(lowest, float(z.min()))
            below += int((z.min(axis=1) < -TOLERANCE).sum())
            if sim.num_static_boxes:
                depth = np.where(free & (sim.attached < 0), static_box_depth(q, sim.static_boxes), -np.inf)
                deepest = max(deepest, float(depth.max()))
                inside += int((depth.max(axis=1) > TOLERANCE).sum())
            farthest = max(farthest, float(np.abs(q).max()) if np.isfinite(q).all() else np.inf)
    return {"frames": frames, "below_table": below, "inside_static_box": inside, "lowest_z": lowest,
            "deepest_static_penetration": deepest if np.isfinite(deepest) else None,
            "farthest": farthest, "escaped": below + inside + int(not farthest < 5.0)}


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--envs", nargs="+", default=list(PARTICLE_TASKS))
    p.add_argument("--steps", type=int, default=10_000, help="env steps per task, summed over the worlds")
    p.add_argument("--worlds", type=int, default=10)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    print(f"| task | frames checked | below the table | inside a static box | lowest z (m) | "
          f"deepest static-box penetration (m) | farthest (m) |")
    print("|---|---|---|---|---|---|---|")
    for env_id in args.envs:
        r = check_task(env_id, args.steps, args.worlds, args.seed)
        deep = "—" if r["deepest_static_penetration"] is None else f"{r['deepest_static_penetration']:.4f}"
        print(f"| {env_id} | {r['frames']} | {r['below_table']} | {r['inside_static_box']} | "
              f"{r['lowest_z']:.4f} | {deep} | {r['farthest']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
