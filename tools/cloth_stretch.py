"""Cloth stretch against solver settings: ``python -m tools.cloth_stretch [--resolutions 40 80]``.

A 0.6 m cloth of ``n x n`` particles hangs from two corners for ``--frames`` frames (self-collision
on, no pickers); per solver setting the table gives the worst and the mean relative stretch of the
stretch constraints at the end and the CPU time per simulated second, also as a ratio to the
default setting measured in the same run (these machines are noisy; the ratio is what to compare).

Settings: the engine default (2 substeps x 5 iterations, with tethers), the default without
tethers, and "small steps" (many substeps of one iteration, no tethers, no extra collision pass,
self-collision lists rebuilt every 10 substeps) with 20 and 40 substeps, and the ``-v1`` tasks'
settings, which scale their substeps with the resolution (``substeps_reference_resolution=40``: 20 up to 40
particles per side, ``ceil(20 x (n / 40) ** 1.5)`` above, 57 at 80).
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

from lfd_envs.registration import FLEX_LIKE_SIM_OPTIONS
from lfd_envs.sim import ParticleSim, SceneBuilder, SimParams

SMALL_STEPS = dict(iterations=1, tethers=False, collision_passes=0, self_collision_interval=10)
SETTINGS: dict[str, SimParams] = {
    "default (2 x 5, tethers)": SimParams(),
    "default without tethers": SimParams(tethers=False),
    "small steps 20 x 1": SimParams(substeps=20, **SMALL_STEPS),
    "small steps 40 x 1": SimParams(substeps=40, **SMALL_STEPS),
    "-v1 settings (substeps by resolution)": SimParams(**FLEX_LIKE_SIM_OPTIONS),
}


def hang(n: int, params: SimParams, frames: int = 250, size: float = 0.6) -> dict[str, float]:
    """Hang the cloth and measure its stretch and the CPU time per simulated second."""
    b = SceneBuilder()
    c = b.add_cloth(n, n, size, size, center=(0, 0, 0.8))
    b.pin([c.index(0, 0), c.index(0, n - 1)])
    sim = ParticleSim(b, params=params, num_pickers=0)
    sim.step(np.zeros((1, 0, 3)))  # kernel compilation and graph capture outside the timing
    t0 = time.thread_time()
    for _ in range(frames - 1):
        sim.step(np.zeros((1, 0, 3)))
    cpu = time.thread_time() - t0
    ex = b._export()
    stretch = ex["con_type"] == 0
    i, j = ex["con_i"][stretch], ex["con_j"][stretch]
    rest = np.linalg.norm(ex["positions"][i] - ex["positions"][j], axis=1)
    q = sim.positions[0]
    strain = np.linalg.norm(q[i] - q[j], axis=1) / rest - 1.0
    return {"worst": float(strain.max()), "mean": float(strain.mean()),
            "cpu_s_per_sim_s": cpu / ((frames - 1) * params.frame_dt), "substeps": sim.substeps}


def rows(resolutions: tuple[int, ...] = (40, 80), frames: int = 250) -> list[dict[str, Any]]:
    out = []
    for n in resolutions:
        base = None
        for name, params in SETTINGS.items():
            r = hang(n, params, frames)
            base = base or r["cpu_s_per_sim_s"]
            out.append({"cloth": f"{n}x{n}", "setting": name, **r, "time_vs_default": r["cpu_s_per_sim_s"] / base})
    return out


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--resolutions", type=int, nargs="+", default=[40, 80])
    p.add_argument("--frames", type=int, default=250)
    args = p.parse_args(argv)
    print("| cloth | solver | substeps | worst edge stretch | mean stretch | CPU s per simulated s | vs default |")
    print("|---|---|---|---|---|---|---|")
    for r in rows(tuple(args.resolutions), args.frames):
        print(f"| {r['cloth']} | {r['setting']} | {r['substeps']} | {100 * r['worst']:.1f} % | {100 * r['mean']:.2f} % | "
              f"{r['cpu_s_per_sim_s']:.2f} | {r['time_vs_default']:.2f}x |", flush=True)


if __name__ == "__main__":
    main()
