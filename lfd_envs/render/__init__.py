"""Headless ray-casting renderer (pure Warp, no OpenGL; same code on CPU and CUDA).

Public API::

    from lfd_envs.render import (Camera, Renderer, TriangleMeshLayer, SphereLayer,
                                 CapsuleChainLayer, BoxLayer, grid_triangles, save_png)

Example (one world, a 40x40 cloth and two pickers, numpy inputs)::

    import numpy as np
    from lfd_envs.render import Camera, Renderer, SphereLayer, TriangleMeshLayer, grid_triangles, save_png

    n = 40
    xs = np.linspace(-0.2, 0.2, n)
    X, Y = np.meshgrid(xs, xs)                       # particle (r, c) = index r * n + c
    cloth = np.stack([X.ravel(), Y.ravel(), np.full(n * n, 0.005)], axis=1)[None]  # (W=1, 1600, 3)
    pickers = np.array([[[-0.2, -0.2, 0.05], [0.2, 0.2, 0.05]]])                  # (W=1, 2, 3)
    renderer = Renderer(32, 32, Camera(position=(0.0, -0.8, 0.9), look_at=(0.0, 0.0, 0.0)))
    images = renderer.render([TriangleMeshLayer(cloth, grid_triangles(n, n)),
                              SphereLayer(pickers, radii=0.02)])                   # (1, 32, 32, 3) uint8
    save_png("out/cloth.png", images[0], scale=8)

Batches: give positions as ``(W, N, 3)`` numpy arrays or flat ``wp.array(dtype=wp.vec3)`` of
``W * N`` entries (pass ``num_worlds=W``); one kernel launch renders every world.
See :class:`Renderer` for the options and :mod:`lfd_envs.render.scene` for the layer formats.
"""

from lfd_envs import _warp  # noqa: F401  (quiet Warp before first use)
from .camera import Camera
from .image_io import save_png, tile_images
from .renderer import DEFAULT_CAMERA, Renderer
from .scene import (
    CLOTH_BACK_COLOR,
    CLOTH_FRONT_COLOR,
    PICKER_COLOR,
    ROPE_COLOR,
    BoxLayer,
    CapsuleChainLayer,
    Layer,
    SphereLayer,
    TriangleMeshLayer,
    grid_triangles,
)

#: Alias: a rope is drawn as a chain of capsules.
RopeLayer = CapsuleChainLayer

__all__ = [
    "Camera",
    "Renderer",
    "DEFAULT_CAMERA",
    "TriangleMeshLayer",
    "SphereLayer",
    "CapsuleChainLayer",
    "RopeLayer",
    "BoxLayer",
    "Layer",
    "grid_triangles",
    "save_png",
    "tile_images",
    "PICKER_COLOR",
    "CLOTH_FRONT_COLOR",
    "CLOTH_BACK_COLOR",
    "ROPE_COLOR",
]
