"""Image augmentation for image-based actors: replicate-pad and random crop back (DrQ/DMfD).

``random_shift`` pads each image by ``pad`` pixels (edge replication) and crops a random
window of the original size, i.e. a random shift of up to ±``pad`` pixels per image.
"""

from __future__ import annotations

from typing import Any

import torch as th
import torch.nn.functional as F
from gymnasium import spaces
from stable_baselines3.common.preprocessing import is_image_space


def random_shift(images: th.Tensor, pad: int = 2, generator: th.Generator | None = None) -> th.Tensor:
    """Randomly shift a batch of channel-first images (B, C, H, W) by up to ``pad`` pixels.

    The output has the input's shape and dtype; each image gets its own shift.
    """
    if images.ndim != 4:
        raise ValueError(f"random_shift expects images of shape (B, C, H, W), got {tuple(images.shape)}")
    if pad <= 0:
        return images
    b, c, h, w = images.shape
    dtype = images.dtype
    padded = F.pad(images.float(), (pad, pad, pad, pad), mode="replicate")
    dy = th.randint(0, 2 * pad + 1, (b,), device=images.device, generator=generator)
    dx = th.randint(0, 2 * pad + 1, (b,), device=images.device, generator=generator)
    rows = (dy[:, None] + th.arange(h, device=images.device)[None, :])  # (B, H)
    cols = (dx[:, None] + th.arange(w, device=images.device)[None, :])  # (B, W)
    batch = th.arange(b, device=images.device)[:, None, None]
    out = padded.permute(0, 2, 3, 1)[batch, rows[:, :, None], cols[:, None, :]]  # (B, H, W, C)
    return out.permute(0, 3, 1, 2).contiguous().to(dtype)


def image_keys(space: spaces.Space) -> list[str | None]:
    """Image entries of an observation space: ``[None]`` for an image Box, Dict keys for a Dict."""
    if isinstance(space, spaces.Dict):
        return [k for k, s in space.spaces.items()
                if len(s.shape or ()) == 3 and is_image_space(s, check_channels=False)]
    if isinstance(space, spaces.Box) and len(space.shape) == 3 and is_image_space(space, check_channels=False):
        return [None]
    return []


def augment_observations(obs: Any, keys: list[str | None], pad: int) -> Any:
    """Apply :func:`random_shift` to the image entries ``keys`` of a batch of observations."""
    if not keys or pad <= 0:
        return obs
    if isinstance(obs, dict):
        out = dict(obs)
        for k in keys:
            out[k] = random_shift(obs[k], pad)
        return out
    return random_shift(obs, pad)
