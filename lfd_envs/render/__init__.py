"""Headless ray-casting renderer (pure Warp, no OpenGL; same code on CPU and CUDA).

Public API::

    from lfd_envs.render import (Camera, Renderer, TriangleMeshLayer, SphereLayer,
                                 CapsuleChainLayer, BoxLayer, grid_triangles, save_png)

See :class:`Renderer` for the options and :mod:`lfd_envs.render.scene` for the layer formats.
"""

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
