"""Simulator throughput: ``python -m benchmarks.speed [--sections render,...] [--device cpu]``.

Protocol: warm-up discarded (kernel compilation, first BVH build), median of repeats,
versions and hardware printed. Each section is a ``*_rows()`` function returning a list of
dicts (one per table row); ``main`` prints every section as a table.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
import warnings
from typing import Any, Callable, Iterable


# ---------------------------------------------------------------------------- helpers
def _progress(message: str, since: float | None = None) -> None:
    """Progress line on stderr (the tables go to stdout), with the seconds since ``since``."""
    elapsed = "" if since is None else f" ({time.perf_counter() - since:.0f} s)"
    print(f"# {message}{elapsed}", file=sys.stderr, flush=True)


def _median_seconds(fn: Callable[[], Any], repeats: int, budget_s: float = 1.5) -> tuple[float, float]:
    """Median (wall, thread-CPU) seconds of ``fn`` after one discarded warm-up call.

    Runs fewer repeats when ``fn`` is slow. The CPU time of the calling thread is reported too
    because it is less sensitive to other processes sharing the cores (Warp CPU kernels run on
    the calling thread).
    """
    t0 = time.perf_counter()
    fn()
    first = time.perf_counter() - t0
    n = max(3, min(repeats, int(budget_s / max(first, 1e-6))))
    wall, cpu = [], []
    for _ in range(n):
        t0, c0 = time.perf_counter(), time.thread_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.thread_time() - c0)
    return statistics.median(wall), statistics.median(cpu)


def _step_resetting(env: Any, actions: Iterable[Any]) -> None:
    """Step ``env`` with each of ``actions``, resetting it whenever an episode ends."""
    for action in actions:
        *_, term, trunc, _ = env.step(action)
        if term or trunc:
            env.reset()


def _median_seconds_without_reset(run: Callable[[], Any], reset: Callable[[], Any], repeats: int,
                                  budget_s: float, reset_budget_s: float) -> tuple[float, float]:
    """:func:`_median_seconds` of ``run`` (which starts with ``reset()``) minus that of ``reset``."""
    sec, cpu = _median_seconds(run, repeats, budget_s=budget_s)
    rsec, rcpu = _median_seconds(reset, repeats, budget_s=reset_budget_s)
    return max(sec - rsec, 1e-9), max(cpu - rcpu, 1e-9)


def _cpu_model() -> str:
    """CPU model name from /proc/cpuinfo (Linux), else ``platform.processor()``."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def environment_info() -> dict[str, str]:
    """Versions and hardware, printed above the tables."""
    import numpy as np

    info = {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpu_count": str(os.cpu_count()),
        "cpu_model": _cpu_model(),
    }
    try:
        import warp as wp

        info["warp"] = wp.config.version
    except ImportError:  # pragma: no cover
        pass
    return info


# ---------------------------------------------------------------------------- renderer
def _render_benchmark_scene(num_worlds: int, frame: int, resolution: int = 40):
    """Layers of a typical particle-task frame: cloth, rope, 2 pickers, 3 boxes (+ ground).

    The cloth waves a little with ``frame`` so every render refits the BVH.
    """
    import numpy as np

    from lfd_envs.render import BoxLayer, CapsuleChainLayer, SphereLayer, TriangleMeshLayer, grid_triangles

    n = resolution
    xs = np.linspace(-0.25, 0.25, n)
    X, Y = np.meshgrid(xs, xs)
    cloth = np.empty((num_worlds, n * n, 3), np.float32)
    rope = np.empty((num_worlds, 41, 3), np.float32)
    s = np.linspace(0.0, 1.0, 41)
    for w in range(num_worlds):
        phase = 0.3 * frame + 0.5 * w
        Z = 0.006 + 0.08 * np.clip(X + 0.1, 0.0, None) * (1.2 + np.sin(6.0 * Y + phase))
        cloth[w] = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
        rope[w] = np.stack([-0.25 + 0.5 * s, -0.32 + 0.04 * np.sin(8 * s + phase), np.full_like(s, 0.01)], axis=1)
    pickers = np.tile(np.array([[-0.25, -0.25, 0.08], [0.25, 0.25, 0.12]], np.float32), (num_worlds, 1, 1))
    boxes = BoxLayer(
        np.array([[0.33, 0.0, 0.05], [0.33, 0.2, 0.08], [-0.34, 0.1, 0.02]], np.float32),
        half_extents=np.array([[0.05, 0.05, 0.05], [0.08, 0.08, 0.08], [0.02, 0.02, 0.02]]),
        colors=[(0.3, 0.6, 0.3), (0.6, 0.3, 0.6), (0.6, 0.6, 0.2)],
    )
    return [
        TriangleMeshLayer(cloth, grid_triangles(n, n)),
        CapsuleChainLayer(rope, radius=0.01),
        SphereLayer(pickers, radii=0.02),
        boxes,
    ]


def render_rows(
    device: str = "cpu",
    sizes: tuple[int, ...] = (32, 256),
    worlds: tuple[int, ...] = (1, 16),
    repeats: int = 30,
    shadows: bool = False,
) -> list[dict[str, Any]]:
    """Time :class:`lfd_envs.render.Renderer` on a 40x40 cloth + rope + 2 pickers + 3 boxes.

    One row per (image size, world count): median milliseconds per ``render`` call (all worlds,
    including host-side packing, BVH refit and the copy of the uint8 images to numpy), the
    calling thread's CPU milliseconds per call, and milliseconds per image.
    """
    from lfd_envs.render import Camera, Renderer

    camera = Camera(position=(0.0, -0.8, 0.9), look_at=(0.0, 0.0, 0.0), fov_y_deg=45.0)
    rows = []
    for size in sizes:
        for num_worlds in worlds:
            renderer = Renderer(size, size, camera, device=device, shadows=shadows)
            frames = [_render_benchmark_scene(num_worlds, f) for f in range(8)]
            state = {"k": 0}

            def step() -> None:
                state["k"] += 1
                renderer.render(frames[state["k"] % len(frames)], num_worlds)

            sec, cpu = _median_seconds(step, repeats)
            rows.append(
                {
                    "section": "render",
                    "device": str(renderer.device),
                    "image": f"{size}x{size}",
                    "worlds": num_worlds,
                    "shadows": shadows,
                    "ms_per_call": round(sec * 1e3, 3),
                    "cpu_ms_per_call": round(cpu * 1e3, 3),
                    "ms_per_image": round(sec * 1e3 / num_worlds, 3),
                    "images_per_s": round(num_worlds / sec, 1),
                }
            )
    return rows


# ---------------------------------------------------------------------------- MoPA
MOPA_BENCH_ENVS = ("Push2DObstacle-v0", "SawyerPushObstacle-v0", "SawyerLiftObstacle-v0", "SawyerAssemblyObstacle-v0")


def _mopa_planner_row(env_id: str, rrt_calls: int, budget_s: float, seed: int) -> dict[str, Any] | None:
    """Planner statistics of uniform random MoPA actions on one task (None if the task is missing).

    Acts until ``rrt_calls`` queries needed RRT-Connect or ``budget_s`` seconds passed.
    """
    import gymnasium as gym
    import numpy as np

    import lfd_envs  # noqa: F401
    from lfd_agents.mopa import make_mopa_env

    try:
        env = make_mopa_env(gym.make(env_id))
    except Exception as exc:  # a task not (yet) available must not stop the other rows
        print(f"# mopa: skipping {env_id}: {type(exc).__name__}: {exc}")
        return None
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    queries, rrt, solved, modes = [], [], [], {}
    t0 = time.perf_counter()
    actions = 0
    while len(rrt) < rrt_calls and time.perf_counter() - t0 < budget_s:
        actions += 1
        _, _, term, trunc, info = env.step(rng.uniform(-1, 1, env.action_space.shape))
        mode = info["mopa_mode"]
        modes[mode] = modes.get(mode, 0) + 1
        if mode not in ("direct", "invalid_target"):
            queries.append(info["mopa_planning_time"])
        if info["mopa_planner_used"]:
            rrt.append(info["mopa_planning_time"])
            if mode == "planner":
                solved.append(info["mopa_planning_time"])
        if term or trunc:
            env.reset()
    wall = time.perf_counter() - t0
    steps = env.low_level_steps
    env.close()
    ms = lambda xs, f: round(1e3 * float(f(xs)), 2) if xs else None  # noqa: E731
    return {
        "section": "mopa-planner", "env": env_id, "actions": actions,
        "queries": len(queries), "queries_per_s": round(len(queries) / max(sum(queries), 1e-9), 1),
        "query_median_ms": ms(queries, np.median), "query_mean_ms": ms(queries, np.mean),
        "rrt_calls": len(rrt), "rrt_median_ms": ms(rrt, np.median), "rrt_mean_ms": ms(rrt, np.mean),
        "rrt_solved_median_ms": ms(solved, np.median), "rrt_solved_mean_ms": ms(solved, np.mean),
        "rrt_failed": modes.get("failed", 0), "straight_line": modes.get("interpolation", 0),
        "direct": modes.get("direct", 0), "low_level_steps_per_s": round(steps / wall, 1),
    }


def mopa_training_rows(device: str = "cpu", env_id: str = "Push2DObstacle-v0", steps: int = 600,
                       seed: int = 0) -> list[dict[str, Any]]:
    """Training throughput of MoPA-SAC vs SAC: low-level env steps/s including gradient updates.

    ``steps`` low-level env steps each (MoPA counts every waypoint), learning starts after a
    third of them, batch 256, one torch thread. ``device`` is unused (CPU only).
    """
    import gymnasium as gym

    import lfd_envs  # noqa: F401
    from stable_baselines3 import SAC

    from lfd_agents.mopa import MoPASAC
    from lfd_agents.threads import torch_threads

    rows = []
    with torch_threads(1):
        for name in ("mopa_sac", "sac"):
            env = gym.make(env_id)
            common = dict(learning_starts=steps // 3, batch_size=256, device="cpu", verbose=0)
            t0 = time.perf_counter()
            if name == "sac":
                SAC("MlpPolicy", env, seed=seed, **common).learn(steps)
                done = steps
            else:
                agent = MoPASAC.for_benchmark(env, seed=seed, **common)
                agent.learn(steps)
                done = agent.train_env.low_level_steps
            wall = time.perf_counter() - t0
            rows.append({"section": "mopa-training", "env": env_id, "agent": name, "env_steps": done,
                         "wall_s": round(wall, 2), "env_steps_per_s": round(done / wall, 1)})
    return rows


def mopa_rows(device: str = "cpu", rrt_calls: int = 15, budget_s: float = 60.0, seed: int = 0) -> list[dict[str, Any]]:
    """MoPA planner speed per obstructed task (tasks not yet available are skipped).

    Rows: uniform random MoPA actions until ``rrt_calls`` queries needed RRT-Connect (or
    ``budget_s`` passed), with the task defaults of ``lfd_agents.mopa.MOPA_DEFAULTS`` (1 s limit). ``query_*``: every planning
    query (straight line first, then RRT-Connect); ``rrt_*``: queries where RRT-Connect ran
    (MoPA-RL reports ≈0.3 s per planner call; target ≤ 0.1 s median on the Sawyer tasks);
    ``rrt_solved_*``: those of them that found a path, so slow queries are told apart from
    failed ones (``rrt_failed``: no path within the time limit, mostly goals in pockets of the
    bins/tunnel that stay unsolved with 5 s too).
    ``device`` is unused (CPU only).
    """
    rows = (_mopa_planner_row(env_id, rrt_calls, budget_s, seed) for env_id in MOPA_BENCH_ENVS)
    return [r for r in rows if r is not None]


# ---------------------------------------------------------------------------- MuJoCo envs
MUJOCO_BENCH_ENVS = ("Push2DObstacle-v0", "SawyerPushObstacle-v0", "SawyerLiftObstacle-v0",
                     "SawyerAssemblyObstacle-v0")


def _mujoco_steps_per_s(env_id: str, obs_mode: str, steps: int, repeats: int, seed: int) -> tuple[float, float]:
    """Median (wall, CPU) env steps/s of uniform random actions (episodes reset when they end)."""
    import gymnasium as gym
    import numpy as np

    import lfd_envs  # noqa: F401  (registers the ids)

    env = gym.make(env_id, obs_mode=obs_mode).unwrapped
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)

    def run() -> None:
        _step_resetting(env, (rng.uniform(-1, 1, env.action_space.shape) for _ in range(steps)))

    sec, cpu = _median_seconds(run, repeats, budget_s=3.0)
    env.close()
    return steps / sec, steps / cpu


def _is_valid_per_s(env_id: str, checks: int, seed: int) -> tuple[float, float, float]:
    """``is_valid`` calls/s (wall, CPU) on uniform random arm configurations, and the fraction valid."""
    import gymnasium as gym
    import numpy as np

    import lfd_envs  # noqa: F401  (registers the ids)

    env = gym.make(env_id).unwrapped
    env.reset(seed=seed)
    lo, hi = env.joint_limits[:, 0], env.joint_limits[:, 1]
    qs = np.random.default_rng(seed).uniform(lo, hi, (checks, len(lo)))
    valid = [0]

    def run() -> None:
        valid[0] = sum(env.is_valid(q) for q in qs)

    sec, cpu = _median_seconds(run, 5, budget_s=3.0)
    env.close()
    return checks / sec, checks / cpu, valid[0] / checks


def mujoco_env_rows(device: str = "cpu", steps: int = 200, checks: int = 5000, seed: int = 0) -> list[dict[str, Any]]:
    """Throughput of the MuJoCo obstructed-manipulation envs (tasks not yet available are skipped).

    Per task: env steps/s with uniform random actions for ``obs_mode="state"`` and ``"image"``
    (84×84, headless MuJoCo renderer), median over repeats of ``steps`` steps after a warm-up,
    and ``is_valid`` collision checks/s on ``checks`` uniform random arm configurations
    (targets: ≥ 300 state steps/s for the Sawyer tasks, ≥ 20,000 checks/s). ``*_cpu_*``
    columns use the calling thread's CPU time (robust to other processes sharing the cores;
    image rendering on software GL also uses other threads, so only wall time is given).
    ``device`` is unused.
    """
    import os as _os

    rows = []
    for env_id in MUJOCO_BENCH_ENVS:
        try:
            state, state_cpu = _mujoco_steps_per_s(env_id, "state", steps, 5, seed)
            image, _ = _mujoco_steps_per_s(env_id, "image", steps // 2, 3, seed)
            checks_s, checks_cpu, frac = _is_valid_per_s(env_id, checks, seed)
        except Exception as exc:  # a task not (yet) available must not stop the other rows
            print(f"# mujoco: skipping {env_id}: {type(exc).__name__}: {exc}")
            continue
        rows.append({
            "section": "mujoco", "env": env_id, "state_steps_per_s": round(state, 1),
            "state_cpu_steps_per_s": round(state_cpu, 1), "image84_steps_per_s": round(image, 1),
            "is_valid_per_s": round(checks_s, 0), "is_valid_cpu_per_s": round(checks_cpu, 0),
            "random_q_valid_frac": round(frac, 3),
            "gl": _os.environ.get("MUJOCO_GL", ""),
        })
    return rows


# ---------------------------------------------------------------------------- particle engine
def _particle_engine_sim(resolution: int, num_worlds: int, device: str, **params: Any):
    """A 0.6 m cloth on the ground with one picker holding a corner (the benchmark scene).

    Returns ``(sim, step)`` where ``step()`` advances one frame with the picker circling above
    the cloth at SoftGym's maximum speed (0.01 m per frame and axis), so that the cloth keeps
    moving, folds and exercises self-collision.
    """
    import numpy as np

    from lfd_envs.sim import ParticleSim, SceneBuilder, SimParams

    builders = []
    for w in range(num_worlds):
        b = SceneBuilder()
        b.add_cloth(resolution, resolution, 0.6, 0.6, center=(0.0, 0.0, 0.01), yaw=0.1 * w)
        builders.append(b)
    sim = ParticleSim(builders, params=SimParams(**params), num_pickers=1, device=device)
    corner = builders[0].cloths[0].corners[0]
    start = sim.positions[:, corner][:, None, :].astype(np.float64)
    sim.set_picker_positions(start)
    state = {"k": 0, "pos": start.copy()}
    grasp = np.ones((num_worlds, 1), bool)

    def step() -> None:
        k = state["k"]
        state["k"] += 1
        d = np.array([0.01 * np.cos(0.05 * k), 0.01 * np.sin(0.05 * k), 0.005 if k < 40 else 0.0])
        state["pos"] = state["pos"] + d
        sim.step(state["pos"], grasp)

    for _ in range(30):  # lift the corner first: the measured frames see a moving, partly folded cloth
        step()
    return sim, step


def particle_engine_rows(
    device: str = "cpu",
    resolutions: tuple[int, ...] = (20, 40, 80, 120),
    worlds: tuple[int, ...] = (1, 4, 16, 64),
    iterations: int = 10,
    substeps: int = 4,
    repeats: int = 20,
) -> list[dict[str, Any]]:
    """Substeps per second of :class:`lfd_envs.sim.ParticleSim` (one frame = ``substeps``).

    Rows (``config`` column):

    * ``resolution``: one world, ``iterations`` solver iterations, self-collision on and off,
      cloth of ``n x n`` particles (targets: 40x40 >= 1000 substeps/s, 80x80 >= 250 substeps/s).
    * ``batched``: ``W`` worlds of 40x40 stepped by the same launches; ``cost_vs_1_world`` is
      the time per substep relative to one world (target for 16 worlds: <= 12).
    * ``task-default``: ``SimParams()`` defaults (what the particle tasks use) at 40x40:
      milliseconds per frame and env steps/s of the simulator alone (8 frames per env step).

    ``substeps_per_s`` uses the median wall time; ``cpu_substeps_per_s`` the median CPU time of
    the calling thread (robust to other processes sharing the cores).
    """
    rows: list[dict[str, Any]] = []

    def row(config: str, n: int, w: int, sc: bool, its: int, sub: int, sec: float, cpu: float, **extra):
        r = {
            "section": "particle-engine", "config": config, "device": device, "cloth": f"{n}x{n}",
            "worlds": w, "self_collision": sc, "iterations": its, "substeps": sub,
            "ms_per_frame": round(sec * 1e3, 3),
            "substeps_per_s": round(sub / sec, 1), "cpu_substeps_per_s": round(sub / cpu, 1),
        }
        r.update(extra)
        rows.append(r)
        _progress(f"particle_engine: {config} {n}x{n}, {w} world(s), self-collision {sc}")

    for n in resolutions:
        for sc in (True, False):
            _, step = _particle_engine_sim(n, 1, device, iterations=iterations, substeps=substeps,
                                           self_collision=sc)
            sec, cpu = _median_seconds(step, repeats)
            row("resolution", n, 1, sc, iterations, substeps, sec, cpu)
    base = None
    for w in worlds:
        _, step = _particle_engine_sim(40, w, device, iterations=iterations, substeps=substeps)
        sec, cpu = _median_seconds(step, repeats)
        base = cpu if base is None else base
        row("batched", 40, w, True, iterations, substeps, sec, cpu,
            cost_vs_1_world=round(cpu / base, 2), world_substeps_per_s=round(w * substeps / cpu, 1))
    from lfd_envs.sim import SimParams

    p = SimParams()
    _, step = _particle_engine_sim(40, 1, device)
    sec, cpu = _median_seconds(step, repeats * 5)
    row("task-default", 40, 1, p.self_collision, p.iterations, p.substeps, sec, cpu,
        sim_env_steps_per_s=round(1.0 / (8 * sec), 1))
    return rows


# ---------------------------------------------------------------------------- Sawyer obstructed tasks
SAWYER_ENV_IDS = ("SawyerPushObstacle-v0", "SawyerLiftObstacle-v0", "SawyerAssemblyObstacle-v0")


def sawyer_env_rows(device: str = "cpu", steps: int = 150, image_steps: int = 40, valid_checks: int = 2000,
                    repeats: int = 3, env_ids: tuple[str, ...] = SAWYER_ENV_IDS) -> list[dict[str, Any]]:
    """Env steps/s of the Sawyer tasks (75 physics substeps per step), state and 84×84 image
    observations, and ``is_valid`` collision checks/s.

    Random actions from a seeded generator, resets included when an episode ends; configurations
    for ``is_valid`` are the start pose + N(0, 0.5 rad) (typical planner queries, part of them in
    collision). ``device`` is unused (MuJoCo runs on the CPU).
    """
    import gymnasium as gym
    import numpy as np

    import lfd_envs  # noqa: F401  (registers the ids)

    rows = []
    for env_id in env_ids:
        for obs_mode, n in (("state", steps), ("image", image_steps)):
            env = gym.make(env_id, obs_mode=obs_mode, image_size=84)
            env.reset(seed=0)
            actions = np.random.default_rng(0).uniform(-1, 1, (n, *env.action_space.shape)).astype(np.float32)

            def run(env=env, actions=actions) -> None:
                _step_resetting(env, actions)

            sec, cpu = _median_seconds(run, repeats, budget_s=3.0)
            row = {"section": "sawyer", "env": env_id, "obs": f"{obs_mode}" + (" 84x84" if obs_mode == "image" else ""),
                   "env_steps_per_s": round(n / sec, 1), "cpu_env_steps_per_s": round(n / cpu, 1)}
            if obs_mode == "state":
                base = env.unwrapped
                q0 = base.arm_qpos()
                lo, hi = base.joint_limits.T
                qs = np.clip(q0 + np.random.default_rng(1).normal(0, 0.5, (valid_checks, q0.size)), lo, hi)

                def check(base=base, qs=qs) -> None:
                    for q in qs:
                        base.is_valid(q)

                vsec, vcpu = _median_seconds(check, repeats, budget_s=2.0)
                row["is_valid_per_s"] = round(valid_checks / vsec)
                row["cpu_is_valid_per_s"] = round(valid_checks / vcpu)
                row["valid_fraction"] = round(float(np.mean([base.is_valid(q) for q in qs[:200]])), 2)
            rows.append(row)
            env.close()
    return rows


# ---------------------------------------------------------------------------- DryCloth / ThreeBoxes
def drycloth_threeboxes_rows(device: str = "cpu", repeats: int = 3,
                             configs: tuple[tuple[str, str, int, str], ...] = (
                                 ("DryCloth-v0", "pick_place", 1, "state"),
                                 ("DryCloth-v0", "pick_place", 2, "state"),
                                 ("DryCloth-v0", "pick_place", 1, "image"),
                                 ("DryCloth-v0", "delta", 1, "state"),
                                 ("ThreeBoxes-v0", "pick_place", 1, "state"),
                                 ("ThreeBoxes-v0", "pick_place", 3, "image"),
                                 ("ThreeBoxes-v0", "delta", 1, "state"),
                             )) -> list[dict[str, Any]]:
    """Env steps/s of DryCloth-v0 and ThreeBoxes-v0 at their default resolution (target:
    DryCloth pick_place >= 5 env steps/s on the CPU; MAIL's FleX env ran 3.4 steps/s on a GPU).

    Seeded random actions (the random pick-and-place policy for pick_place, uniform random
    actions for delta), resets excluded; ``frames`` = engine frames per env step. Wall and
    calling-thread CPU rates are both reported (the CPU rate is robust to shared cores).
    """
    import gymnasium as gym
    import numpy as np

    import lfd_envs  # noqa: F401  (registers the ids)
    from lfd_envs.experts.random_pick_place import RandomPickPlacePolicy

    rows = []
    for env_id, mode, pickers, obs_mode in configs:
        env = gym.make(env_id, action_mode=mode, num_pickers=pickers, obs_mode=obs_mode, device=device)
        obs, _ = env.reset(seed=0)
        policy = RandomPickPlacePolicy(env, seed=0) if mode == "pick_place" else None
        rng = np.random.default_rng(0)
        n = 3 if mode == "pick_place" else 24
        actions = [rng.uniform(-1, 1, env.action_space.shape).astype(np.float32) for _ in range(n)]

        def run(env=env, policy=policy, actions=actions) -> None:
            env.reset(seed=0, options={"variant": 0})
            if policy is not None:
                policy.reset()
            for a in actions:
                env.step(a if policy is None else policy.predict(None)[0])

        def reset_only(env=env) -> None:
            env.reset(seed=0, options={"variant": 0})

        sec, cpu = _median_seconds_without_reset(run, reset_only, repeats, budget_s=4.0, reset_budget_s=0.5)
        base = env.unwrapped
        _progress(f"drycloth_threeboxes: {env_id} {mode} {pickers} picker(s) {obs_mode}")
        rows.append({"section": "drycloth_threeboxes", "env": env_id, "action_mode": mode, "pickers": pickers,
                     "obs": obs_mode, "resolution": base.task.resolution, "particles": base.num_particles,
                     "frames": base.picker_actions.frames_per_step, "device": device,
                     "env_steps_per_s": round(n / sec, 2), "cpu_env_steps_per_s": round(n / cpu, 2)})
        env.close()
    return rows


def particle_env_rows(device: str = "cpu", repeats: int = 3,
                      env_ids: tuple[str, ...] = ("StraightenRope-v0", "ClothFold-v0", "ClothFoldDiagonalPinned-v0",
                                                  "ClothFoldDiagonalUnpinned-v0"),
                      action_modes: tuple[str, ...] = ("delta", "pick_place"),
                      obs_modes: tuple[str, ...] = ("state", "image", "particles")) -> list[dict[str, Any]]:
    """Env steps/s of the rope and cloth-fold tasks: every task x action mode x obs mode, one env,
    default picker count and resolution, 32x32 images (targets: ClothFold delta/state >= 60,
    delta/image >= 50, pick_place >= 5 env steps/s on this CPU).

    Seeded uniform random actions, resets excluded; ``frames`` = engine frames per env step.
    Wall and calling-thread CPU rates are both reported (the CPU rate is robust to shared cores).
    """
    import gymnasium as gym
    import numpy as np

    import lfd_envs  # noqa: F401  (registers the ids)

    rows = []
    for env_id in env_ids:
        for mode in action_modes:
            for obs_mode in obs_modes:
                env = gym.make(env_id, action_mode=mode, obs_mode=obs_mode, device=device)
                rng = np.random.default_rng(0)
                n = 2 if mode == "pick_place" else 16
                actions = [rng.uniform(-1, 1, env.action_space.shape).astype(np.float32) for _ in range(n)]
                env.reset(seed=0, options={"variant": 0})

                def run(env=env, actions=actions) -> None:
                    env.reset(seed=0, options={"variant": 0})
                    for a in actions:
                        env.step(a)

                def reset_only(env=env) -> None:
                    env.reset(seed=0, options={"variant": 0})

                sec, cpu = _median_seconds_without_reset(run, reset_only, repeats, budget_s=3.0, reset_budget_s=0.3)
                base = env.unwrapped
                _progress(f"particle_envs: {env_id} {mode} {obs_mode}")
                rows.append({"section": "particle_envs", "env": env_id, "action_mode": mode, "obs": obs_mode,
                             "pickers": base.num_pickers, "resolution": base.task.resolution,
                             "particles": base.num_particles,
                             "frames": base.picker_actions.frames_per_step, "device": device,
                             "env_steps_per_s": round(n / sec, 2), "cpu_env_steps_per_s": round(n / cpu, 2)})
                env.close()
    return rows


def _random_pick_place_run(env: Any, variants: int, steps: int, seed: int) -> dict[str, float]:
    """MAIL's random pick-and-place (a random particle, a random place) on ``variants`` variants:
    thread-CPU seconds of the steps, frames per step, and how fast / far the particles end up."""
    import numpy as np

    from lfd_envs.experts.random_pick_place import RandomPickPlacePolicy

    base = env.unwrapped
    policy = RandomPickPlacePolicy(env, seed=seed)
    cpu, frames, fastest, farthest = 0.0, [], 0.0, 0.0
    for v in range(variants):
        env.reset(seed=seed + v, options={"variant": v})
        policy.reset()
        for _ in range(steps):
            action = policy.predict(None)[0]
            frames.append(int(base.picker_actions.plan_motion(action[None], base.batch.pickers).frames[0]))
            c0 = time.thread_time()
            env.step(action)
            cpu += time.thread_time() - c0
            fastest = max(fastest, float(np.linalg.norm(base.batch.sim.velocities[0], axis=-1).max()))
            farthest = max(farthest, float(np.abs(base.particle_positions[:, :2]).max()))
    return {"cpu_s": cpu, "frames": float(np.mean(frames)), "fastest": fastest, "farthest": farthest}


#: (env id, pickers) rows of :func:`pick_place_speed_rows`
PICK_PLACE_SPEED_CONFIGS = (("ClothFold-v0", 1), ("ClothFold-v0", 2), ("DryCloth-v0", 1), ("ThreeBoxes-v0", 1))


def pick_place_speed_rows(device: str = "cpu", variants: int = 4, steps: int = 3, seed: int = 0,
                          configs: tuple[tuple[str, int], ...] = PICK_PLACE_SPEED_CONFIGS,
                          speeds: tuple[float | None, ...] = (None, 1.0)) -> list[dict[str, Any]]:
    """Pick-and-place with the held-picker speed limit (``pick_place_speed``, m/s) against the
    task's default schedule, in the same run: mean engine frames per step, CPU env steps/s and
    the cost ratio, and the fastest particle at the end of a step / the farthest particle from the
    workspace centre (m) over MAIL-style random pick-and-place steps on train variants."""
    import gymnasium as gym

    import lfd_envs  # noqa: F401  (registers the ids)

    rows = []
    for env_id, pickers in configs:
        reference = None
        for speed in speeds:
            env = gym.make(env_id, action_mode="pick_place", num_pickers=pickers, obs_mode="state", device=device,
                           pick_place_speed=speed)
            r = _random_pick_place_run(env, variants, steps, seed)
            rate = variants * steps / max(r["cpu_s"], 1e-9)
            reference = rate if reference is None else reference
            _progress(f"pick_place_speed: {env_id} {pickers} picker(s), speed {speed}")
            rows.append({"section": "pick_place_speed", "env": env_id, "pickers": pickers,
                         "pick_place_speed": "default" if speed is None else speed, "frames": round(r["frames"], 1),
                         "cpu_env_steps_per_s": round(rate, 2), "cost_vs_default": round(reference / rate, 2),
                         "fastest_particle_m_s": round(r["fastest"], 2), "farthest_particle_m": round(r["farthest"], 3),
                         "device": device})
            env.close()
    return rows


#: (task, action mode, pickers) rows of :func:`version_rows`; the first two are the speed targets
VERSION_CONFIGS = (("ClothFold", "delta", 2), ("ClothFold", "pick_place", 2),
                   ("ClothFoldDiagonalUnpinned", "delta", 1), ("StraightenRope", "delta", 2))


def _timed_steps(env: Any, actions: list[Any]) -> float:
    """Thread-CPU seconds of ``env.step`` over ``actions`` from the same start (variant 0; the
    reset is not timed)."""
    env.reset(seed=0, options={"variant": 0})
    c0 = time.thread_time()
    for a in actions:
        env.step(a)
    return time.thread_time() - c0


def version_rows(device: str = "cpu", rounds: int = 3, configs: tuple[tuple[str, str, int], ...] = VERSION_CONFIGS,
                 seed: int = 0) -> list[dict[str, Any]]:
    """Env steps/s of the ``-v1`` ids (FleX-like physics) against their ``-v0`` twins, same run.

    Per row: the same seeded uniform random actions (16 delta steps or 2 pick-and-place steps,
    state observations) on both versions from the same start, timed in ``rounds`` interleaved
    rounds (``-v0`` then ``-v1``) after a discarded warm-up round, so both see the same load of
    shared cores; rates use the calling thread's CPU time, ``v1_vs_v0`` is the median of the
    per-round rate ratios; ``frames`` are engine frames per step (mean over the timed steps).
    """
    import gymnasium as gym
    import numpy as np

    import lfd_envs  # noqa: F401  (registers the ids)

    rows = []
    for task, mode, pickers in configs:
        t0 = time.perf_counter()
        with warnings.catch_warnings():  # Gymnasium's "-v0 is out of date" notice
            warnings.simplefilter("ignore", DeprecationWarning)
            envs = {v: gym.make(f"{task}-{v}", action_mode=mode, num_pickers=pickers, obs_mode="state",
                                device=device) for v in ("v0", "v1")}
        rng = np.random.default_rng(seed)
        n = 2 if mode == "pick_place" else 16
        actions = [rng.uniform(-1, 1, envs["v0"].action_space.shape).astype(np.float32) for _ in range(n)]
        frames = {v: _mean_frames(env, actions) for v, env in envs.items()}
        rates: dict[str, list[float]] = {"v0": [], "v1": []}
        for r in range(rounds + 1):
            for v, env in envs.items():
                sec = _timed_steps(env, actions)
                if r:  # round 0 warms up (kernel compilation, caches)
                    rates[v].append(n / max(sec, 1e-9))
            _progress(f"versions: {task} {mode} {pickers} picker(s), round {r}/{rounds}", t0)
        for env in envs.values():
            env.close()
        ratio = statistics.median(b / a for a, b in zip(rates["v0"], rates["v1"]))
        rows.append({"section": "versions", "env": task, "action_mode": mode, "pickers": pickers, "obs": "state",
                     "v0_frames": round(frames["v0"], 1), "v1_frames": round(frames["v1"], 1),
                     "v0_cpu_env_steps_per_s": round(statistics.median(rates["v0"]), 2),
                     "v1_cpu_env_steps_per_s": round(statistics.median(rates["v1"]), 2),
                     "v1_vs_v0": round(ratio, 3), "device": device})
    return rows


def _mean_frames(env: Any, actions: list[Any]) -> float:
    """Mean engine frames of the steps of ``actions`` from variant 0 (planned, not stepped: the
    frame count depends only on the action and the picker positions, which stepping moves)."""
    import numpy as np

    env.reset(seed=0, options={"variant": 0})
    base = env.unwrapped
    frames = []
    for a in actions:
        frames.append(int(base.picker_actions.plan_motion(np.asarray(a)[None], base.batch.pickers).frames[0]))
        env.step(a)
    return float(np.mean(frames))


# ---------------------------------------------------------------------------- NIST board
def _nist_steps_per_s(steps: int, seed: int, press: bool = False, **env_kwargs: Any) -> tuple[float, float]:
    """Median (wall, CPU) NistBoardInsert-v0 env steps/s: random actions, or pressing on the board."""
    import numpy as np

    from lfd_envs.mujoco.nist import NistBoardInsertEnv

    env = NistBoardInsertEnv(**env_kwargs)
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    down = np.array([0.0, 0.0, -1.0], np.float32)

    def run() -> None:
        _step_resetting(env, (down if press else rng.uniform(-1, 1, 3).astype(np.float32) for _ in range(steps)))

    if press:  # start on the board, beside the hole, so every physics step has contacts
        env.reset(seed=seed, options={"instruction": "insert medium peg in large hole"})
        hole = env.hole_top
        env.data.qpos[:3] = hole + [0.006, 0.0, 0.001]
        env.set_commanded_target(env.data.qpos[:3].copy())
    sec, cpu = _median_seconds(run, 3, budget_s=3.0)
    env.close()
    return steps / sec, steps / cpu


def nist_rows(device: str = "cpu", steps: int = 100, seed: int = 0) -> list[dict[str, Any]]:
    """Throughput of ``NistBoardInsert-v0`` (one env step = 20 physics steps of 2 ms).

    Rows: ``obs_mode="state"`` with random actions (mostly free motion) and pressed on the board
    (contacts every physics step), reported as env steps/s and physics steps/s; image
    observations with both cameras (workspace + wrist) at the default 128×160 and at the
    thesis' 512×640, headless MuJoCo rendering (``MUJOCO_GL``, no multisampling). Median of
    repeats after a warm-up; ``*_cpu`` columns use the calling thread's CPU time (rendering
    on software GL also uses other threads, so image rows are wall time only). ``device`` is unused.
    """
    from lfd_envs.mujoco.nist import FRAME_SKIP

    rows = []
    cases = [
        ("state, random actions", dict(obs_mode="state"), steps * 5, False),
        ("state, pressed on board", dict(obs_mode="state"), steps * 5, True),
        ("2 cameras 128x160", dict(obs_mode="image", image_size=(128, 160)), steps, False),
        ("2 cameras 512x640", dict(obs_mode="image", image_size=(512, 640)), max(10, steps // 4), False),
    ]
    for label, kwargs, n, press in cases:
        try:
            wall, cpu = _nist_steps_per_s(n, seed, press=press, **kwargs)
        except Exception as exc:  # e.g. no OpenGL: keep the other rows
            print(f"# nist: skipping {label}: {type(exc).__name__}: {exc}")
            continue
        row = {"section": "nist", "env": "NistBoardInsert-v0", "case": label, "env_steps_per_s": round(wall, 1),
               "physics_steps_per_s": round(wall * FRAME_SKIP, 0)}
        if kwargs["obs_mode"] == "state":
            row["env_cpu_steps_per_s"] = round(cpu, 1)
        row["gl"] = os.environ.get("MUJOCO_GL", "")
        rows.append(row)
    return rows


# ---------------------------------------------------------------------------- main
SECTIONS: dict[str, Callable[..., list[dict[str, Any]]]] = {
    "versions": version_rows,
    "particle_envs": particle_env_rows,
    "particle_engine": particle_engine_rows,
    "render": render_rows,
    "mujoco": mujoco_env_rows,
    "mopa": mopa_rows,
    "mopa_training": mopa_training_rows,
    "sawyer": sawyer_env_rows,
    "drycloth_threeboxes": drycloth_threeboxes_rows,
    "pick_place_speed": pick_place_speed_rows,
    "nist": nist_rows,
}


def print_table(rows: list[dict[str, Any]]) -> None:
    """Print rows (dicts) as an aligned markdown table."""
    if not rows:
        return
    keys: list[str] = []
    for r in rows:  # union of keys, first-seen order (sections may add columns to some rows)
        keys += [k for k in r if k not in keys]
    widths = {k: max(len(k), *(len(str(r.get(k, ""))) for r in rows)) for k in keys}
    print("| " + " | ".join(k.ljust(widths[k]) for k in keys) + " |")
    print("|" + "|".join("-" * (widths[k] + 2) for k in keys) + "|")
    for r in rows:
        print("| " + " | ".join(str(r.get(k, "")).ljust(widths[k]) for k in keys) + " |")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sections", default=",".join(SECTIONS), help=f"comma-separated subset of {list(SECTIONS)}")
    parser.add_argument("--device", default="cpu", help="warp device (cpu, cuda:0)")
    args = parser.parse_args(argv)
    names = args.sections.split(",")
    for name in names:  # all checked before anything runs
        if name not in SECTIONS:
            parser.error(f"unknown section {name!r}; choose from {list(SECTIONS)}")
    import warp as wp

    wp.config.quiet = True
    for key, value in environment_info().items():
        print(f"# {key}: {value}")
    for name in names:
        print(f"\n## {name}", flush=True)
        t0 = time.perf_counter()
        _progress(f"{name}: running")
        rows = SECTIONS[name](device=args.device)
        _progress(f"{name}: {len(rows)} rows", t0)
        print_table(rows)
        sys.stdout.flush()


if __name__ == "__main__":
    main()
