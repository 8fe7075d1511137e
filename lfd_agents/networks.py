"""Network building blocks shared by the demonstration-based agents (DMfD, AWAC, BC).

* :class:`ImageEncoder` — the DMfD/DrQ image encoder (4 conv layers of 32 channels, LeakyReLU,
  then Linear → LayerNorm → tanh). Works for images from 16×16 up; SB3's ``NatureCNN`` needs
  at least 36×36, so pass ``policy_kwargs=dict(features_extractor_class=ImageEncoder)`` to run
  plain SB3 algorithms on our default 32×32 images.
* :class:`KeySubsetExtractor` — Dict-observation extractor over a chosen subset of keys (images
  through :class:`ImageEncoder`, vectors flattened). The asymmetric actor-critic uses it to give
  the actor only ``"image"`` while the critics see ``"state"`` and ``"image"``.
* :class:`GaussianActor` — the DMfD actor: ``μ = tanh(MLP(features))`` and a state-independent
  log-std ``lo + (hi - lo)·sigmoid(θ)``. The Gaussian is *not* squashed, so the log-likelihood
  of any stored action in [-1, 1] is finite; sampled actions are clipped to [-1, 1].
* :class:`ImagePolicyDefaults` / :class:`DictPolicyDefaults` — mixins giving a policy class the
  image / Dict encoder and LeakyReLU MLPs as defaults (the ``CnnPolicy``/``MultiInputPolicy``s).
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.preprocessing import is_image_space
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor, create_mlp
from stable_baselines3.common.type_aliases import Schedule
from torch import nn
from torch.distributions import Normal


def _channels_first(space: spaces.Box) -> tuple[int, int, int]:
    shape = space.shape
    if shape[0] in (1, 3, 4) and shape[-1] not in (1, 3, 4):
        return shape  # type: ignore[return-value]
    if shape[-1] in (1, 3, 4):
        return (shape[-1], shape[0], shape[1])
    return shape  # type: ignore[return-value]


class ImageEncoder(BaseFeaturesExtractor):
    """DMfD image encoder: Conv(k3,s2) + 3×Conv(k3,s1), 32 channels, LeakyReLU; Linear → LayerNorm → tanh.

    Expects channel-first images (SB3 transposes channel-last image observations itself) that
    SB3 has already scaled to [0, 1].

    Args:
        observation_space: image ``Box`` (C, H, W), H and W ≥ 16.
        features_dim: output size (50 in DMfD).
        channels: conv channels.
    """

    def __init__(self, observation_space: spaces.Box, features_dim: int = 50, channels: int = 32):
        super().__init__(observation_space, features_dim)
        c, h, w = _channels_first(observation_space)
        if min(h, w) < 16:
            raise ValueError(f"ImageEncoder needs images of at least 16x16 pixels, got {h}x{w}")
        self.convs = nn.Sequential(
            nn.Conv2d(c, channels, 3, stride=2), nn.LeakyReLU(),
            nn.Conv2d(channels, channels, 3, stride=1), nn.LeakyReLU(),
            nn.Conv2d(channels, channels, 3, stride=1), nn.LeakyReLU(),
            nn.Conv2d(channels, channels, 3, stride=1), nn.LeakyReLU(),
            nn.Flatten(),
        )
        with th.no_grad():
            n_flat = self.convs(th.zeros(1, c, h, w)).shape[1]
        self.head = nn.Sequential(nn.Linear(n_flat, features_dim), nn.LayerNorm(features_dim), nn.Tanh())
        for m in self.convs:
            if isinstance(m, nn.Conv2d):
                nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="leaky_relu")
                nn.init.zeros_(m.bias)

    def forward(self, observations: th.Tensor) -> th.Tensor:
        return self.head(self.convs(observations))


class KeySubsetExtractor(BaseFeaturesExtractor):
    """Features of a subset of the keys of a Dict observation, concatenated in key order.

    Args:
        observation_space: the Dict observation space.
        keys: keys to use (all keys when None).
        image_features_dim: output size of each image key's :class:`ImageEncoder`.
    """

    def __init__(self, observation_space: spaces.Dict, keys: Sequence[str] | None = None,
                 image_features_dim: int = 50):
        if not isinstance(observation_space, spaces.Dict):
            raise TypeError(f"KeySubsetExtractor needs a Dict observation space, got {observation_space}")
        keys = list(observation_space.spaces) if keys is None else list(keys)
        unknown = [k for k in keys if k not in observation_space.spaces]
        if unknown or not keys:
            raise ValueError(f"keys {unknown or keys} not valid; observation keys are {list(observation_space.spaces)}")
        extractors: dict[str, nn.Module] = {}
        total = 0
        for key in keys:
            sub = observation_space.spaces[key]
            if is_image_space(sub, check_channels=False, normalized_image=False) and len(sub.shape) == 3:
                extractors[key] = ImageEncoder(sub, image_features_dim)
                total += image_features_dim
            else:
                extractors[key] = nn.Flatten()
                total += int(np.prod(sub.shape))
        super().__init__(observation_space, features_dim=total)
        self.keys = keys
        self.extractors = nn.ModuleDict(extractors)

    def forward(self, observations: dict[str, th.Tensor]) -> th.Tensor:
        return th.cat([self.extractors[k](observations[k]) for k in self.keys], dim=1)


class GaussianActor(BasePolicy):
    """Unsquashed Gaussian policy with tanh mean and a state-independent std (DMfD/AWAC actor).

    Actions live in the normalised space [-1, 1]; ``predict`` rescales them to the env's bounds.

    Args:
        observation_space, action_space: spaces of the (wrapped) env.
        net_arch: hidden layer sizes of the MLP after the features extractor.
        features_extractor: module mapping observations to ``features_dim`` features.
        features_dim: size of those features.
        activation_fn: MLP activation.
        normalize_images: divide image observations by 255.
        log_std_bounds: (lo, hi) of the log-std; ``log_std = lo + (hi - lo)·sigmoid(θ)``, θ = 0 at start.
    """

    def __init__(self, observation_space: spaces.Space, action_space: spaces.Box, net_arch: list[int],
                 features_extractor: nn.Module, features_dim: int, activation_fn: type[nn.Module] = nn.ReLU,
                 normalize_images: bool = True, log_std_bounds: tuple[float, float] = (-6.0, 0.0)):
        super().__init__(observation_space, action_space, features_extractor=features_extractor,
                         normalize_images=normalize_images, squash_output=True)
        self.net_arch = list(net_arch)
        self.features_dim = features_dim
        self.activation_fn = activation_fn
        self.log_std_bounds = (float(log_std_bounds[0]), float(log_std_bounds[1]))
        action_dim = int(np.prod(action_space.shape))
        self.latent_pi = nn.Sequential(*create_mlp(features_dim, -1, self.net_arch, activation_fn))
        self.mu = nn.Linear(self.net_arch[-1] if self.net_arch else features_dim, action_dim)
        self.log_std_param = nn.Parameter(th.zeros(action_dim))

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(net_arch=self.net_arch, features_dim=self.features_dim, activation_fn=self.activation_fn,
                    features_extractor=self.features_extractor, log_std_bounds=self.log_std_bounds)
        return data

    def log_std(self) -> th.Tensor:
        lo, hi = self.log_std_bounds
        return lo + (hi - lo) * th.sigmoid(self.log_std_param)

    def distribution(self, obs: th.Tensor | dict[str, th.Tensor]) -> Normal:
        """Action distribution π(·|o) (factorised Normal; sum ``log_prob`` over the last axis)."""
        features = self.extract_features(obs, self.features_extractor)
        mean = th.tanh(self.mu(self.latent_pi(features)))
        return Normal(mean, self.log_std().exp().expand_as(mean))

    def forward(self, obs: th.Tensor | dict[str, th.Tensor], deterministic: bool = False) -> th.Tensor:
        dist = self.distribution(obs)
        action = dist.mean if deterministic else dist.sample()
        return action.clamp(-1.0, 1.0)

    def _predict(self, observation: th.Tensor | dict[str, th.Tensor], deterministic: bool = False) -> th.Tensor:
        return self(observation, deterministic)


def log_prob(dist: Normal, actions: th.Tensor) -> th.Tensor:
    """Log-likelihood of ``actions`` (batch, act_dim) under a factorised Normal, shape (batch,)."""
    return dist.log_prob(actions).sum(dim=-1)


class ImagePolicyDefaults:
    """Mixin for a policy class (listed first): image encoder (:class:`ImageEncoder`) and
    LeakyReLU MLPs by default, e.g. ``class BCCnnPolicy(ImagePolicyDefaults, BCPolicy)``."""

    def __init__(self, observation_space: spaces.Space, action_space: spaces.Box, lr_schedule: Schedule,
                 activation_fn: type[nn.Module] = nn.LeakyReLU,
                 features_extractor_class: type[BaseFeaturesExtractor] = ImageEncoder, **kwargs: Any):
        super().__init__(observation_space, action_space, lr_schedule, activation_fn=activation_fn,
                         features_extractor_class=features_extractor_class, **kwargs)


class DictPolicyDefaults:
    """Mixin for a policy class (listed first): Dict-observation encoder
    (:class:`KeySubsetExtractor`) and LeakyReLU MLPs by default."""

    def __init__(self, observation_space: spaces.Space, action_space: spaces.Box, lr_schedule: Schedule,
                 activation_fn: type[nn.Module] = nn.LeakyReLU,
                 features_extractor_class: type[BaseFeaturesExtractor] = KeySubsetExtractor, **kwargs: Any):
        super().__init__(observation_space, action_space, lr_schedule, activation_fn=activation_fn,
                         features_extractor_class=features_extractor_class, **kwargs)
