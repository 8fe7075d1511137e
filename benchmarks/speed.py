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
import time
from typing import Any, Callable


# ---------------------------------------------------------------------------- helpers
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


def environment_info() -> dict[str, str]:
    """Versions and hardware, printed above the tables."""
    import numpy as np

    info = {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "platform": platform.platform(),
        "processor": platform.processor() or platform.machine(),
        "cpu_count": str(os.cpu_count()),
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


# ---------------------------------------------------------------------------- main
SECTIONS: dict[str, Callable[..., list[dict[str, Any]]]] = {
    "render": render_rows,
}


def print_table(rows: list[dict[str, Any]]) -> None:
    """Print rows (dicts with the same keys) as an aligned text table."""
    if not rows:
        return
    keys = list(rows[0])
    widths = {k: max(len(k), *(len(str(r.get(k, ""))) for r in rows)) for k in keys}
    print("  ".join(k.ljust(widths[k]) for k in keys))
    for r in rows:
        print("  ".join(str(r.get(k, "")).ljust(widths[k]) for k in keys))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sections", default=",".join(SECTIONS), help=f"comma-separated subset of {list(SECTIONS)}")
    parser.add_argument("--device", default="cpu", help="warp device (cpu, cuda:0)")
    args = parser.parse_args(argv)
    import warp as wp

    wp.config.quiet = True
    for key, value in environment_info().items():
        print(f"# {key}: {value}")
    for name in args.sections.split(","):
        if name not in SECTIONS:
            parser.error(f"unknown section {name!r}; choose from {list(SECTIONS)}")
        print(f"\n## {name}")
        print_table(SECTIONS[name](device=args.device))


if __name__ == "__main__":
    main()
