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
    padded = F.pad(images if images.is_floating_point() else images.float(), (pad, pad, pad, pad), mode="replicate")
    dy = th.randint(0, 2 * pad + 1, (b,), device=images.device, generator=generator)
    dx = th.randint(0, 2 * pad + 1, (b,), device=images.device, generator=generator)
    wp = w + 2 * pad
    window = (th.arange(h, device=images.device)[:, None] * wp + th.arange(w, device=images.device)[None, :]).view(1, -1)
    index = (dy * wp + dx)[:, None] + window  # (B, H·W): flat positions of each image's window in the padded image
    out = padded.view(b, c, -1).gather(2, index[:, None, :].expand(b, c, h * w)).view(b, c, h, w)
    return out.to(dtype)


def image_keys(space: spaces.Space) -> list[str | None]:
    """Image entries of an observation space: ``[None]`` for an image Box, Dict keys for a Dict."""
    if isinstance(space, spaces.Dict):
        return [k for k, s in space.spaces.items()
                if len(s.shape or ()) == 3 and is_image_space(s, check_channels=False)]
    if isinstance(space, spaces.Box) and len(space.shape) == 3 and is_image_space(space, check_channels=False):
        return [None]
    return []


def augment_observations(obs: Any, keys: list[str | None], pad: int,
                         generator: th.Generator | None = None) -> Any:
    """Apply :func:`random_shift` to the image entries ``keys`` of a batch of observations
    (shifts drawn from ``generator``, or torch's global generator when None)."""
    if not keys or pad <= 0:
        return obs
    if isinstance(obs, dict):
        out = dict(obs)
        for k in keys:
            out[k] = random_shift(obs[k], pad, generator)
        return out
    return random_shift(obs, pad, generator)
