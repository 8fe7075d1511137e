"""Where an engine frame spends its time, ``-v0`` against ``-v1``: ``python tools/frame_profile.py``.

Diagnostic (not installed). For each env id it steps a few random delta actions, then records
each phase of a frame (the distance constraints, the particle passes, prediction, velocity
update, neighbour builds) as a Warp graph with as many launches as one frame issues, replays it
and prints the median milliseconds of the calling thread's CPU time (Warp's CPU kernels run on
it, so other processes on shared cores do not count) next to the whole frame's. The phases are
timed from the same state, one after another, so their sum is close to but not exactly the
frame. Reads engine internals on purpose.
"""

from __future__ import annotations

import argparse
import time
import warnings
from typing import Any, Callable

import numpy as np


def _median_ms(graph: Any, repeats: int) -> float:
    import warp as wp

    times = []
    for _ in range(repeats):
        t0 = time.thread_time()
        wp.capture_launch(graph)
        times.append(time.thread_time() - t0)
    return 1e3 * float(np.median(times))


def _record(fn: Callable[[], None]) -> Any:
    import warp as wp

    wp.capture_begin(device="cpu")
    try:
        fn()
    finally:
        graph = wp.capture_end(device="cpu")
    return graph


def phases(sim: Any) -> dict[str, tuple[int, Callable[[], None]]]:
    """Phase name -> (launches per frame, the launches of one frame) of a CPU :class:`ParticleSim`."""
    import warp as wp

    from lfd_envs.sim import kernels as K

    p, W, N, P = sim._params, sim._W, sim._N, max(sim._P, 1)
    h, n = p.substep_dt, sim._W * sim._N
    subs, its = p.substeps, p.iterations
    sc_on = int(p.self_collision and sim._has_sc)
    passes = subs * (its + (p.collision_passes if sc_on else 0))
    builds = len(range(0, subs, p.self_collision_interval)) if sc_on else 0

    def predict() -> None:
        for _ in range(subs):
            wp.launch(K.predict, dim=1, device="cpu",
                      inputs=[sim.particle_q, sim._q_prev, sim.particle_v, sim._inv_mass, sim._attach, sim._attach_off,
                              sim._pick_start, sim._pick_end, sim._fric, sim._w_eff, N, P, 1.0, p.gravity, h,
                              1.0 - p.damping * h, p.max_speed, n, n])

    def update_velocity() -> None:
        for _ in range(subs):
            wp.launch(K.update_velocity, dim=1, device="cpu",
                      inputs=[sim.particle_q, sim._q_prev, sim.particle_v, sim._inv_mass, sim._attach, sim._fric,
                              1.0 / h, p.static_friction, p.dynamic_friction, p.max_speed, sim._picker_spheres,
                              sim._contact_pushes, n, n])

    return {
        "frame": (0, sim._frame_ops),
        "distance constraints": (subs * its * len(sim._color_sets),
                                 lambda: [sim._solve_distance_constraints() for _ in range(subs * its)]),
        "particle passes": (passes, lambda: [sim._particle_pass(sc_on) for _ in range(passes)]),
        "neighbour builds": (2 * builds, lambda: [sim._build_neighbors() for _ in range(builds)]),
        "predict": (subs, predict),
        "update velocity": (subs, update_velocity),
    }


def profile(env_id: str, repeats: int) -> dict[str, tuple[int, float]]:
    """Phase -> (launches per frame, median ms per frame) of ``env_id`` (ClothFold-like, delta, 2 pickers)."""
    import gymnasium as gym

    import lfd_envs  # noqa: F401  (registers the ids)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        env = gym.make(env_id, action_mode="delta", obs_mode="state", num_pickers=2)
    rng = np.random.default_rng(0)
    env.reset(seed=0, options={"variant": 0})
    for _ in range(3):
        env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
    sim = env.unwrapped.batch.sim
    state = sim.get_state()
    out = {}
    for name, (launches, fn) in phases(sim).items():
        sim.set_state(state)
        graph = _record(fn)
        sim.set_state(state)
        out[name] = (launches, _median_ms(graph, repeats))
    env.close()
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--envs", default="ClothFold-v0,ClothFold-v1", help="comma-separated env ids")
    parser.add_argument("--repeats", type=int, default=100, help="replays per phase (median)")
    args = parser.parse_args(argv)
    import warp as wp

    wp.config.quiet = True
    envs = args.envs.split(",")
    results = {e: profile(e, args.repeats) for e in envs}
    print("| phase | " + " | ".join(f"{e} launches | {e} ms/frame" for e in envs) + " |")
    print("|---|" + "---|---|" * len(envs))
    for name in results[envs[0]]:
        print(f"| {name} | " + " | ".join(f"{results[e][name][0] or '—'} | {results[e][name][1]:.3f}" for e in envs)
              + " |")


if __name__ == "__main__":
    main()
