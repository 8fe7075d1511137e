"""Cloth stretch where the engine is pushed hardest, ``-v0`` against ``-v1`` settings:
``python -m tools.cloth_bounds``.

Each scenario runs twice: with the engine settings of a ``-v0`` task and with those of its
``-v1`` id (:data:`lfd_envs.FLEX_LIKE_SIM_OPTIONS`: no tethers, 20 substeps of one iteration,
colliding pickers, 1 cm thickness). Strain is measured on the stretch constraints (grid edges)
against their rest length.

* ``grasp and lift``: a 0.6 m cloth of 40 x 40 particles lies on the table; one picker grasps a
  corner and lifts it 0.4 m at 1 cm per frame, then holds it for 0.6 s. Worst strain of the two
  edges at the grasped particle, and of any edge.
* ``drape``: DryCloth's two-picker delta-mode expert, eval variants 0..2, whole 75-step episodes
  (the expert is done well before the end, the draped cloth settles in the remaining steps):
  edges stretched more than 20 % at the end (mean per episode) and the worst edge.
* ``pin block``: ClothFoldDiagonalPinned right after reset (eval variants 0..2; the block holds a
  corner region of the cloth): edges stretched more than 10 % and the worst edge.
* ``release``: one picker carries a corner of a 0.4 m cloth of 20 x 20 particles onto the opposite
  corner at 1 cm per frame, holds it until the cloth has settled (0.6 s) and lets go: the largest
  particle displacement in the release frame and in the last frame before it (mm).

A colliding picker grasps from on top of the particle (as the scripted experts do), the others
at the particle.
"""

from __future__ import annotations

import argparse
from typing import Any, Callable

import numpy as np

VERSIONS = ("v0", "v1")


def _options(version: str) -> dict[str, Any] | None:
    from lfd_envs import FLEX_LIKE_SIM_OPTIONS

    return dict(FLEX_LIKE_SIM_OPTIONS) if version == "v1" else None


def edge_strain(builder: Any, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(strain, i, j)`` of every stretch constraint of ``builder`` at ``positions`` (N, 3)."""
    from lfd_envs.sim import STRETCH

    ex = builder._export()
    keep = ex["con_type"] == STRETCH
    i, j = ex["con_i"][keep], ex["con_j"][keep]
    rest = np.linalg.norm(ex["positions"][i] - ex["positions"][j], axis=1)
    return np.linalg.norm(positions[i] - positions[j], axis=1) / rest - 1.0, i, j


def _cloth_params(version: str) -> Any:
    from lfd_envs.tasks.cloth_fold import ClothFoldTask
    from lfd_envs.tasks.particle_batch import with_sim_options

    return with_sim_options(ClothFoldTask().sim_params(), _options(version))


def _grasp_point(sim: Any, particle: int) -> np.ndarray:
    """Where a picker grasps ``particle``: at its centre, or resting on top of it when pickers
    collide (a colliding picker centred on the cloth pushes the neighbours out of its sphere)."""
    p = sim.params
    q = sim.positions[0][particle].astype(np.float64)
    return q + [0.0, 0.0, p.picker_radius + p.particle_radius] if p.picker_collision else q


def grasp_and_lift(version: str) -> dict[str, float]:
    from lfd_envs.sim import ParticleSim, SceneBuilder

    b = SceneBuilder()
    c = b.add_cloth(40, 40, 0.6, 0.6, center=(0, 0, 0.00625))
    sim = ParticleSim(b, params=_cloth_params(version), num_pickers=1)
    corner = _grasp_point(sim, c.corners[0])
    sim.set_picker_positions(corner[None, None])
    path = [corner + [0.0, 0.0, 0.01 * k] for k in range(1, 41)] + [corner + [0.0, 0.0, 0.4]] * 60
    sim.step_frames(np.array(path)[:, None, None], np.ones((len(path), 1, 1), bool))
    strain, i, j = edge_strain(b, sim.positions[0])
    at_grasp = (i == c.corners[0]) | (j == c.corners[0])
    return {"particles held": float((sim.attached[0] >= 0).sum()), "at grasp": float(strain[at_grasp].max()),
            "worst": float(strain.max())}


def _env_strain(env_id: str, version: str, variants: int, run: Callable[[Any], None], limit: float) -> dict[str, float]:
    import gymnasium as gym

    import lfd_envs  # noqa: F401

    env = gym.make(env_id.replace("-v0", f"-{version}"), obs_mode="state", action_mode="delta")
    over, worst = [], 0.0
    for k in range(variants):
        env.reset(seed=k, options={"split": "eval", "variant": k})
        run(env)
        base = env.unwrapped
        strain, _, _ = edge_strain(base.batch.sim.builders[0], base.particle_positions)
        over.append(float((strain > limit).sum()))
        worst = max(worst, float(strain.max()))
    env.close()
    return {f"edges over {100 * limit:.0f} %": float(np.mean(over)), "worst": worst}


def drape(version: str, variants: int = 3) -> dict[str, float]:
    from lfd_envs.core.rollout import finish_episode
    from lfd_envs.experts import make_expert

    def run(env: Any) -> None:
        expert = make_expert(env)
        finish_episode(env, expert, env.unwrapped.current_observation())

    return _env_strain("DryCloth-v0", version, variants, run, 0.20)


def pin_block(version: str, variants: int = 3) -> dict[str, float]:
    return _env_strain("ClothFoldDiagonalPinned-v0", version, variants, lambda env: None, 0.10)


def carry_corner_over(params: Any, hold_frames: int = 60) -> tuple[Any, np.ndarray]:
    """A 0.4 m cloth of 20 x 20 particles on the table; one picker grasps a corner, lifts it
    0.1 m, carries it at 1 cm per frame above the opposite corner, lowers it there and holds it
    for ``hold_frames`` frames (0.6 s by default: the folded cloth has settled; after 10 frames
    the stiff ``-v1`` cloth still slides 9-13 mm per frame while held). Returns the engine (still
    holding) and the picker's final position."""
    from lfd_envs.sim import ParticleSim, SceneBuilder

    b = SceneBuilder()
    c = b.add_cloth(20, 20, 0.4, 0.4, center=(0, 0, 0.00625))
    sim = ParticleSim(b, params=params, num_pickers=1)
    start = _grasp_point(sim, c.corners[0])
    goal = start + sim.positions[0][c.corners[2]] - sim.positions[0][c.corners[0]]
    sim.set_picker_positions(start[None, None])
    up = np.array([0.0, 0.0, 0.1])
    carry = int(np.ceil(np.linalg.norm(goal - start) / 0.01))
    path = [start + up * k / 10 for k in range(1, 11)]
    path += [start + (goal - start) * k / carry + up for k in range(1, carry + 1)]
    path += [goal + up * (1 - k / 10) for k in range(1, 11)] + [goal] * int(hold_frames)
    sim.step_frames(np.array(path)[:, None, None], np.ones((len(path), 1, 1), bool))
    return sim, goal


def release(version: str) -> dict[str, float]:
    sim, goal = carry_corner_over(_cloth_params(version))
    held = float((sim.attached[0] >= 0).sum())
    moved = []
    for grasp in (True, False):  # one more frame held, then the release frame
        before = sim.positions[0].astype(np.float64)
        sim.step(goal[None, None], np.full((1, 1), grasp))
        moved.append(1e3 * float(np.linalg.norm(sim.positions[0] - before, axis=1).max()))
    return {"particles held": held, "largest move in the release frame (mm)": moved[1],
            "in the frame before (mm)": moved[0]}


SCENARIOS: dict[str, Callable[[str], dict[str, float]]] = {
    "grasp and lift": grasp_and_lift, "drape": drape, "pin block": pin_block, "release": release}


def rows(scenarios: tuple[str, ...] = tuple(SCENARIOS)) -> list[dict[str, Any]]:
    return [{"scenario": s, "settings": v, **SCENARIOS[s](v)} for s in scenarios for v in VERSIONS]


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenarios", nargs="+", default=list(SCENARIOS), choices=list(SCENARIOS))
    args = p.parse_args(argv)
    print("| scenario | settings | measured |")
    print("|---|---|---|")
    for r in rows(tuple(args.scenarios)):
        values = ", ".join(f"{k} {100 * v:.1f} %" if k in ("at grasp", "worst") else f"{k} {v:.3g}"
                           for k, v in r.items() if k not in ("scenario", "settings"))
        print(f"| {r['scenario']} | `-{r['settings']}` | {values} |", flush=True)


if __name__ == "__main__":
    main()
