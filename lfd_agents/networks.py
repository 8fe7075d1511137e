"""Network building blocks shared by the demonstration-based agents (DMfD, AWAC, BC).

* :class:`ImageEncoder` — the image encoder (by default 3 conv layers of 16 channels, strides
  2-2-1; ``THESIS_ENCODER`` gives DMfD's 4 layers of 32 channels, strides 2-1-1-1), LeakyReLU,
  then Linear → LayerNorm → tanh. Works for images from 16×16 up; SB3's ``NatureCNN`` needs
  at least 36×36, so pass ``policy_kwargs=dict(features_extractor_class=ImageEncoder)`` to run
  plain SB3 algorithms on our default 32×32 images.
* :class:`DetachedExtractor`, :func:`own_parameters` — an actor reading the critic's encoder
  without gradient (one encoder for actor and critic, trained by the critic's loss).
* :class:`KeySubsetExtractor` — Dict-observation extractor over a chosen subset of keys (images
  through :class:`ImageEncoder`, vectors flattened). The asymmetric actor-critic uses it to give
  the actor only ``"image"`` while the critics see ``"state"`` and ``"image"``.
* :class:`GaussianActor` — the DMfD actor: ``μ = tanh(MLP(features))`` and a state-independent
  log-std ``lo + (hi - lo)·sigmoid(θ)``. The Gaussian is *not* squashed, so the log-likelihood
  of any stored action in [-1, 1] is finite; sampled actions are clipped to [-1, 1].
* :class:`EnsembleCritic` — drop-in for SB3's ``ContinuousCritic``: the ``n_critics`` Q MLPs
  held as stacked weights ``[n_critics, in, out]`` and run as one batched matmul per layer
  (``torch.baddbmm``) instead of one small MLP after another; same initial weights for a seed.
* :func:`normal_log_prob`, :func:`polyak_update_`, :func:`fast_optimizer_kwargs`,
  :func:`q_values`, :func:`frozen` — the pieces of an update step without per-call overhead
  (no distribution objects, one fused call for the target-network update, fused Adam, no
  critic weight gradients in the actor's backward pass).
* :class:`ImagePolicyDefaults` / :class:`DictPolicyDefaults` — mixins giving a policy class the
  image / Dict encoder and LeakyReLU MLPs as defaults (the ``CnnPolicy``/``MultiInputPolicy``s).
"""

from __future__ import annotations

import contextlib
import math
from typing import Any, Iterator, Sequence

import numpy as np
import torch as th
from gymnasium import spaces
from stable_baselines3.common.policies import BaseModel, BasePolicy
from stable_baselines3.common.preprocessing import get_action_dim, is_image_space
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


#: the encoder of the thesis (DMfD, after DrQ): 4 conv layers of 32 channels, strides 2, 1, 1, 1
THESIS_ENCODER: dict[str, Any] = {"channels": 32, "strides": (2, 1, 1, 1)}


class ImageEncoder(BaseFeaturesExtractor):
    """Image encoder: 3×3 convolutions with LeakyReLU, then Linear → LayerNorm → tanh.

    The default is a lean encoder: 3 conv layers of 16 channels with strides 2, 2, 1 (a 32×32
    image ends as 16×5×5 after the convolutions). ``**THESIS_ENCODER`` (``channels=32,
    strides=(2, 1, 1, 1)``) gives the thesis's DMfD/DrQ encoder (32×9×9 from 32×32), with an
    order of magnitude more multiply-adds; ``python -m benchmarks.train_speed --image`` measures what each costs.

    Expects channel-first images (SB3 transposes channel-last image observations itself) that
    SB3 has already scaled to [0, 1].

    Args:
        observation_space: image ``Box`` (C, H, W), H and W ≥ 16.
        features_dim: output size (50 in DMfD).
        channels: channels of every conv layer.
        strides: one stride per conv layer.
        bf16: run the convolutions under ``torch.autocast("cpu", torch.bfloat16)`` (faster on
            CPUs with bfloat16 instructions, much slower on others; off by default).
    """

    def __init__(self, observation_space: spaces.Box, features_dim: int = 50, channels: int = 16,
                 strides: Sequence[int] = (2, 2, 1), bf16: bool = False):
        super().__init__(observation_space, features_dim)
        self.bf16 = bool(bf16)
        c, h, w = _channels_first(observation_space)
        if min(h, w) < 16:
            raise ValueError(f"ImageEncoder needs images of at least 16x16 pixels, got {h}x{w}")
        strides = tuple(int(s) for s in strides)
        if channels < 1 or not strides or min(strides) < 1:
            raise ValueError(f"channels must be >= 1 and strides a non-empty list of ints >= 1, "
                             f"got channels={channels}, strides={strides}")
        layers: list[nn.Module] = []
        for i, stride in enumerate(strides):
            layers += [nn.Conv2d(c if i == 0 else channels, channels, 3, stride=stride), nn.LeakyReLU()]
        self.convs = nn.Sequential(*layers, nn.Flatten())
        self.channels, self.strides = int(channels), strides
        with th.no_grad():
            try:
                n_flat = self.convs(th.zeros(1, c, h, w)).shape[1]
            except RuntimeError as exc:
                raise ValueError(f"strides {strides} shrink a {h}x{w} image to nothing") from exc
        self.head = nn.Sequential(nn.Linear(n_flat, features_dim), nn.LayerNorm(features_dim), nn.Tanh())
        for m in self.convs:
            if isinstance(m, nn.Conv2d):
                nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="leaky_relu")
                nn.init.zeros_(m.bias)

    def forward(self, observations: th.Tensor) -> th.Tensor:
        # channels-last activations: the CPU convolution kernels run faster on them (same results)
        x = observations.contiguous(memory_format=th.channels_last)
        if not self.bf16:
            return self.head(self.convs(x))
        with th.autocast("cpu", th.bfloat16):
            h = self.convs(x)
        return self.head(h.float())


class DetachedExtractor(BaseFeaturesExtractor):
    """Features of another module's encoder without gradient (an actor reading the critic's
    encoder, as SAC-AE and DrQ do: only the critic's loss trains it).

    ``shared_parameters()`` are the encoder's; optimisers of the module holding this one should
    leave them out (:func:`own_parameters`).
    """

    def __init__(self, encoder: BaseFeaturesExtractor):
        super().__init__(encoder._observation_space, encoder.features_dim)
        self.encoder = encoder

    def forward(self, observations: Any) -> th.Tensor:
        with th.no_grad():
            return self.encoder(observations)


def own_parameters(module: nn.Module) -> list[nn.Parameter]:
    """Parameters of ``module`` except those it reads through a :class:`DetachedExtractor`."""
    shared = {id(p) for m in module.modules() if isinstance(m, DetachedExtractor) for p in m.encoder.parameters()}
    return [p for p in module.parameters() if id(p) not in shared]


class KeySubsetExtractor(BaseFeaturesExtractor):
    """Features of a subset of the keys of a Dict observation, concatenated in key order.

    Args:
        observation_space: the Dict observation space.
        keys: keys to use (all keys when None).
        image_features_dim: output size of each image key's :class:`ImageEncoder`.
        image_encoder_kwargs: further :class:`ImageEncoder` arguments (e.g. ``THESIS_ENCODER``).
        encoders: modules to use for some keys instead of new ones (e.g. another extractor's
            image encoder wrapped in a :class:`DetachedExtractor`).
    """

    def __init__(self, observation_space: spaces.Dict, keys: Sequence[str] | None = None,
                 image_features_dim: int = 50, image_encoder_kwargs: dict[str, Any] | None = None,
                 encoders: dict[str, BaseFeaturesExtractor] | None = None):
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
            if encoders and key in encoders:
                extractors[key] = encoders[key]
                total += encoders[key].features_dim
            elif is_image_space(sub, check_channels=False, normalized_image=False) and len(sub.shape) == 3:
                extractors[key] = ImageEncoder(sub, image_features_dim, **(image_encoder_kwargs or {}))
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

    def mean_action(self, obs: th.Tensor | dict[str, th.Tensor]) -> th.Tensor:
        """Mean action ``tanh(MLP(features))``, shape (batch, act_dim)."""
        return self.mean_from_features(self.extract_features(obs, self.features_extractor))

    def mean_from_features(self, features: th.Tensor) -> th.Tensor:
        """:meth:`mean_action` from the features extractor's output."""
        return th.tanh(self.mu(self.latent_pi(features)))

    def mean_std(self, obs: th.Tensor | dict[str, th.Tensor]) -> tuple[th.Tensor, th.Tensor]:
        """Mean (batch, act_dim) and std (act_dim,) of π(·|o), without a distribution object."""
        return self.mean_action(obs), self.log_std().exp()

    def distribution(self, obs: th.Tensor | dict[str, th.Tensor]) -> Normal:
        """Action distribution π(·|o) (factorised Normal; sum ``log_prob`` over the last axis)."""
        mean, std = self.mean_std(obs)
        return Normal(mean, std.expand_as(mean))

    def forward(self, obs: th.Tensor | dict[str, th.Tensor], deterministic: bool = False) -> th.Tensor:
        dist = self.distribution(obs)
        action = dist.mean if deterministic else dist.sample()
        return action.clamp(-1.0, 1.0)

    def _predict(self, observation: th.Tensor | dict[str, th.Tensor], deterministic: bool = False) -> th.Tensor:
        return self(observation, deterministic)


def log_prob(dist: Normal, actions: th.Tensor) -> th.Tensor:
    """Log-likelihood of ``actions`` (batch, act_dim) under a factorised Normal, shape (batch,)."""
    return dist.log_prob(actions).sum(dim=-1)


_LOG_SQRT_2PI = math.log(math.sqrt(2 * math.pi))


def normal_log_prob(actions: th.Tensor, mean: th.Tensor, std: th.Tensor) -> th.Tensor:
    """:func:`log_prob` of ``Normal(mean, std)`` from its parameters (same operations, no object).

    ``std`` may be per-dimension (act_dim,) and is broadcast; returns shape (batch,).
    """
    return (-((actions - mean) ** 2) / (2 * std ** 2) - std.log() - _LOG_SQRT_2PI).sum(dim=-1)


def polyak_update_(params: Sequence[th.Tensor], target_params: Sequence[th.Tensor], tau: float) -> None:
    """In place ``target ← (1 − τ)·target + τ·param`` for every pair, in two fused calls
    (the operations of SB3's ``polyak_update``, without a Python loop over tensors)."""
    if len(params) != len(target_params):
        raise ValueError(f"{len(params)} parameters but {len(target_params)} target parameters")
    with th.no_grad():
        th._foreach_mul_(list(target_params), 1.0 - tau)
        th._foreach_add_(list(target_params), list(params), alpha=tau)


def fast_optimizer_kwargs(optimizer_class: type[th.optim.Optimizer], kwargs: dict[str, Any]) -> dict[str, Any]:
    """``kwargs`` plus ``fused=True`` for Adam/AdamW when the caller chose neither ``fused`` nor
    ``foreach`` (one kernel per parameter instead of a dozen small ops; same update rule)."""
    kwargs = dict(kwargs)
    if optimizer_class in (th.optim.Adam, th.optim.AdamW) and "fused" not in kwargs and "foreach" not in kwargs:
        kwargs["fused"] = True
    return kwargs


@contextlib.contextmanager
def frozen(module: nn.Module) -> Iterator[None]:
    """Parameters of ``module`` do not require gradients inside the block (graphs built there
    propagate gradients through the module to its inputs only), and are restored after."""
    trainable = [p for p in module.parameters() if p.requires_grad]
    for p in trainable:
        p.requires_grad_(False)
    try:
        yield
    finally:
        for p in trainable:
            p.requires_grad_(True)


def q_values(critic: nn.Module, obs: th.Tensor | dict[str, th.Tensor], actions: th.Tensor) -> th.Tensor:
    """Q values of every critic of an :class:`EnsembleCritic` or SB3 ``ContinuousCritic``,
    shape (n_critics, batch)."""
    if isinstance(critic, EnsembleCritic):
        return critic.q_values(obs, actions)
    return th.cat(critic(obs, actions), dim=1).t()


class EnsembleCritic(BaseModel):
    """``n_critics`` Q(s, a) MLPs evaluated together; a drop-in for SB3's ``ContinuousCritic``.

    Layer ``l`` of all critics is one weight ``[n_critics, in, out]`` and one bias
    ``[n_critics, 1, out]``; a forward pass is one ``baddbmm`` per layer for all critics. The
    layers are first built exactly as ``ContinuousCritic`` builds them (critic by critic, layer
    by layer) and then stacked, so a seed gives the same initial weights as SB3's critic.
    State dicts saved by a ``ContinuousCritic`` (keys ``qf{i}.{j}.weight``) load as well.

    Args:
        observation_space, action_space: spaces of the (wrapped) env.
        net_arch: hidden sizes of every Q MLP.
        features_extractor: observation encoder; ``features_dim`` its output size.
        activation_fn: activation after every hidden layer.
        normalize_images: divide image observations by 255.
        n_critics: number of Q networks.
        share_features_extractor: the encoder belongs to the actor: computed without gradient.
    """

    features_extractor: BaseFeaturesExtractor

    def __init__(self, observation_space: spaces.Space, action_space: spaces.Box, net_arch: Sequence[int],
                 features_extractor: BaseFeaturesExtractor, features_dim: int,
                 activation_fn: type[nn.Module] = nn.ReLU, normalize_images: bool = True, n_critics: int = 2,
                 share_features_extractor: bool = False):
        super().__init__(observation_space, action_space, features_extractor=features_extractor,
                         normalize_images=normalize_images)
        if n_critics < 1:
            raise ValueError(f"n_critics must be >= 1, got {n_critics}")
        self.net_arch = list(net_arch)
        self.n_critics = int(n_critics)
        self.share_features_extractor = bool(share_features_extractor)
        self.activation = activation_fn()
        in_dim = features_dim + get_action_dim(action_space)
        per_critic = [[m for m in create_mlp(in_dim, 1, self.net_arch, activation_fn) if isinstance(m, nn.Linear)]
                      for _ in range(self.n_critics)]
        self.n_layers = len(per_critic[0])
        for j in range(self.n_layers):
            w = th.stack([layers[j].weight.detach().t() for layers in per_critic])
            b = th.stack([layers[j].bias.detach() for layers in per_critic]).unsqueeze(1)
            self.register_parameter(f"w{j}", nn.Parameter(w.contiguous()))
            self.register_parameter(f"b{j}", nn.Parameter(b.contiguous()))

    def features(self, obs: th.Tensor | dict[str, th.Tensor]) -> th.Tensor:
        """Encoder output for ``obs`` (without gradient when the encoder is the actor's)."""
        with th.set_grad_enabled(th.is_grad_enabled() and not self.share_features_extractor):
            return self.extract_features(obs, self.features_extractor)

    def q_from_features(self, features: th.Tensor, actions: th.Tensor) -> th.Tensor:
        """Q values of every critic from encoder features, shape (n_critics, batch)."""
        x = th.cat([features, actions], dim=1)
        h = x.unsqueeze(0).expand(self.n_critics, *x.shape)
        for j in range(self.n_layers):
            h = th.baddbmm(getattr(self, f"b{j}"), h, getattr(self, f"w{j}"))
            if j < self.n_layers - 1:
                h = self.activation(h)
        return h.squeeze(-1)

    def q_values(self, obs: th.Tensor | dict[str, th.Tensor], actions: th.Tensor) -> th.Tensor:
        """Q values of every critic, shape (n_critics, batch)."""
        return self.q_from_features(self.features(obs), actions)

    def forward(self, obs: th.Tensor | dict[str, th.Tensor], actions: th.Tensor) -> tuple[th.Tensor, ...]:
        """One (batch, 1) tensor per critic, as ``ContinuousCritic.forward`` returns."""
        return tuple(self.q_values(obs, actions).unsqueeze(-1).unbind(0))

    def q1_forward(self, obs: th.Tensor | dict[str, th.Tensor], actions: th.Tensor) -> th.Tensor:
        """Q value of the first critic only, shape (batch, 1), encoder without gradient."""
        with th.no_grad():
            features = self.extract_features(obs, self.features_extractor)
        x = th.cat([features, actions], dim=1)
        for j in range(self.n_layers):
            x = th.addmm(getattr(self, f"b{j}")[0], x, getattr(self, f"w{j}")[0])
            if j < self.n_layers - 1:
                x = self.activation(x)
        return x

    def _load_from_state_dict(self, state_dict: dict[str, Any], prefix: str, *args: Any, **kwargs: Any) -> None:
        # a ContinuousCritic's Sequential holds its Linear layers at even indices (activations between)
        if f"{prefix}qf0.0.weight" in state_dict and f"{prefix}w0" not in state_dict:
            for j in range(self.n_layers):
                ws = [state_dict.pop(f"{prefix}qf{i}.{2 * j}.weight") for i in range(self.n_critics)]
                bs = [state_dict.pop(f"{prefix}qf{i}.{2 * j}.bias") for i in range(self.n_critics)]
                state_dict[f"{prefix}w{j}"] = th.stack([w.t() for w in ws])
                state_dict[f"{prefix}b{j}"] = th.stack(bs).unsqueeze(1)
        super()._load_from_state_dict(state_dict, prefix, *args, **kwargs)


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
