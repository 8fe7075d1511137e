"""Saving rendered images."""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from lfd_envs.core.errors import check_int_range

__all__ = ["save_png", "tile_images"]


def tile_images(images: Any, columns: int | None = None, pad: int = 1, pad_value: int = 255) -> np.ndarray:
    """Arrange a batch ``(W, H, Wpx, 3)`` uint8 into one grid image (row-major), for figures."""
    imgs = np.asarray(images)
    if imgs.ndim != 4 or imgs.shape[-1] != 3 or imgs.shape[0] < 1:
        raise ValueError(f"images must have shape (N, H, W, 3) with N >= 1, got {imgs.shape}")
    n, h, w, _ = imgs.shape
    cols = int(columns) if columns else int(np.ceil(np.sqrt(n)))
    if cols < 1:
        raise ValueError(f"columns must be >= 1, got {columns!r}")
    rows = int(np.ceil(n / cols))
    grid = np.full((rows * (h + pad) + pad, cols * (w + pad) + pad, 3), pad_value, dtype=np.uint8)
    for k in range(n):
        r, c = divmod(k, cols)
        y, x = pad + r * (h + pad), pad + c * (w + pad)
        grid[y : y + h, x : x + w] = imgs[k]
    return grid


def save_png(path: str | os.PathLike, image: Any, scale: int = 1) -> str:
    """Write an RGB ``uint8`` image ``(H, W, 3)`` (or a batch ``(N, H, W, 3)``, tiled) as PNG.

    Args:
        path: Output file; parent folders are created.
        image: The image; float images in [0, 1] are converted to uint8.
        scale: Integer nearest-neighbour upscaling (handy for 32x32 observations).

    Returns:
        The path written, as a string.
    """
    from PIL import Image

    img = np.asarray(image)
    if img.ndim == 4:
        img = tile_images(img)
    if img.ndim != 3 or img.shape[-1] != 3:
        raise ValueError(f"image must have shape (H, W, 3) or (N, H, W, 3), got {img.shape}")
    if img.dtype != np.uint8:
        if not np.isfinite(img).all():
            raise ValueError("image contains NaN or inf")
        img = np.clip(np.round(img.astype(np.float64) * 255.0), 0, 255).astype(np.uint8)
    scale = check_int_range("scale", scale, 1)
    if scale > 1:
        img = np.repeat(np.repeat(img, scale, axis=0), scale, axis=1)
    path = os.fspath(path)
    parent = os.path.dirname(path)
    if parent:
        os.makedirs(parent, exist_ok=True)
    Image.fromarray(np.ascontiguousarray(img), mode="RGB").save(path)
    return path
