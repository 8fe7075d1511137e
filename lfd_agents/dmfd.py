"""DMfD: Deformable Manipulation from Demonstrations, as a Stable-Baselines3 off-policy algorithm.

Off-policy actor-critic whose replay buffer starts full of demonstrations (SPEC §6, thesis
ch. 4, Algorithm 2):

* critics: twin Q, target ``y = r + γ(1-d)(min Q'(s', a') − α_t log π(a'|s'))`` with
  ``a' ~ π(·|s')`` (``target_ent_coef`` α_t = 0 in the original code), loss = sum of the MSEs;
* actor: ``L_π = (1 − w_E)·L_A + w_E·L_E`` with

  - ``L_A = mean_B[−log π(a_B|o) · w]``, ``w = B·softmax_B(A/λ)`` (batch-normalised exp(A/λ)),
    ``A = min Q(s, a_B) − min Q(s, a_π)`` (detached), ``a_B`` the stored action;
  - ``L_E = mean_B[α log π(a_π|o) − min Q(s, a_π)]`` with ``a_π ~ π(·|o)`` (reparameterised);

* probabilistic reference-state initialisation with an imitation reward
  (:class:`lfd_agents.rsi.ReferenceStateInit`, probability 0.2 for state and 0.3 for image
  observations by default, 0 disables);
* image observations: DMfD CNN encoder and pad-2 random-crop augmentation of ``obs`` and
  ``next_obs`` in every sampled batch; with ``"state+image"`` observations the actor sees only
  the image and the critics see state and image (asymmetric actor-critic).

Defaults follow SPEC §6 / thesis Table D.9: 1024-1024 MLPs, γ = 0.9, w_E = 0.1, α = 0.5,
batch 256, buffer 600k; λ = 2, lr 3e-4, τ = 0.005, actor weight decay 1e-4 from the original code.

Example::

    from lfd_agents import DMfD
    model = DMfD("MlpPolicy", env, demonstrations="datasets/ClothFoldDiagonalPinned-state")
    model.learn(100_000)
    action, _ = model.predict(obs, deterministic=True)
"""

from __future__ import annotations

import warnings
from typing import Any, ClassVar, Sequence

import gymnasium as gym
import torch as th
import torch.nn.functional as F
from gymnasium import spaces
from stable_baselines3.common.buffers import DictReplayBuffer, ReplayBuffer
from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
from stable_baselines3.common.policies import BasePolicy, ContinuousCritic
from stable_baselines3.common.save_util import load_from_zip_file
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor, FlattenExtractor
from stable_baselines3.common.type_aliases import GymEnv, ReplayBufferSamples, Schedule
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv
from torch import nn

from lfd_agents.augment import augment_observations, image_keys
from lfd_agents.demos import episodes_with_states, fill_replay_buffer, load_episodes
from lfd_agents.networks import (DictPolicyDefaults, EnsembleCritic, GaussianActor, ImagePolicyDefaults,
                                 KeySubsetExtractor, fast_optimizer_kwargs, frozen, normal_log_prob, polyak_update_,
                                 q_values)
from lfd_agents.rsi import ReferenceStateInit

DEFAULT_NET_ARCH = (1024, 1024)


# ----------------------------------------------------------------------------------- loss terms
AWR_WEIGHTINGS = ("softmax", "binary")
AWR_FITS = ("likelihood", "isotropic")


def awr_log_prob(actions: th.Tensor, mean: th.Tensor, std: th.Tensor, fit: str = "likelihood") -> th.Tensor:
    """Per-sample log-likelihood that the advantage-weighted term maximises (shape (B,)).

    ``"likelihood"`` (DMfD): log N(a; μ, σ) with the policy's per-dimension σ. Its gradient
    weights each action dimension's error by 1/σ²: dimensions the policy already fits tightly
    (σ small) dominate, and a hard one (a grasp flag that switches between two nearly equal
    states) gets a large σ and is left underfitted. ``"isotropic"``: the mean fits every
    dimension with one σ (the geometric mean of the policy's σ, detached), as a regression
    does, and each σ still fits its own dimension's errors (the mean detached there).
    """
    if fit == "likelihood":
        return normal_log_prob(actions, mean, std)
    if fit == "isotropic":
        log_std = th.broadcast_to(std.log(), mean.shape[-1:])
        iso = log_std.mean().exp().detach().expand_as(log_std)
        return normal_log_prob(actions, mean, iso) + normal_log_prob(actions, mean.detach(), std)
    raise ValueError(f"fit must be one of {AWR_FITS}, got {fit!r}")


def awr_weights(advantages: th.Tensor, temperature: float, weighting: str = "softmax") -> th.Tensor:
    """Per-sample weights of the advantage-weighted regression term.

    ``"softmax"`` (DMfD, AWAC): batch-normalised exp(A/λ), ``B · softmax(A/λ)`` (mean weight 1).
    ``"binary"`` (CRR's binary filter): 1 where A > 0, else 0 — stored actions no better than the
    policy's own are not imitated at all, whatever their share of the batch.
    """
    if temperature <= 0:
        raise ValueError(f"temperature must be > 0, got {temperature}")
    if weighting == "softmax":
        return th.softmax(advantages / temperature, dim=0) * advantages.shape[0]
    if weighting == "binary":
        return (advantages > 0).to(advantages.dtype)
    raise ValueError(f"weighting must be one of {AWR_WEIGHTINGS}, got {weighting!r}")


def dmfd_actor_loss(logp_buffer: th.Tensor, advantages: th.Tensor, logp_pi: th.Tensor, q_pi: th.Tensor, *,
                    temperature: float, ent_coef: float, entropy_weight: float,
                    weighting: str = "softmax") -> dict[str, th.Tensor]:
    """DMfD actor loss from per-sample terms (all shape (B,)).

    Returns a dict with ``loss`` = (1 − w_E)·L_A + w_E·L_E, ``awr_loss`` (L_A), ``entropy_loss``
    (L_E) and the detached ``weights`` (:func:`awr_weights` with ``weighting``).
    """
    weights = awr_weights(advantages.detach(), temperature, weighting).detach()
    l_a = -(logp_buffer * weights).mean()
    l_e = (ent_coef * logp_pi - q_pi).mean()
    return {"loss": (1.0 - entropy_weight) * l_a + entropy_weight * l_e, "awr_loss": l_a,
            "entropy_loss": l_e, "weights": weights}


def td_target(rewards: th.Tensor, dones: th.Tensor, next_q: th.Tensor, next_logp: th.Tensor, *,
              gamma: float, target_ent_coef: float) -> th.Tensor:
    """Bellman target ``r + γ(1 − d)(Q'(s', a') − α_t log π(a'|s'))`` (all shape (B,))."""
    return rewards + (1.0 - dones) * gamma * (next_q - target_ent_coef * next_logp)


def _cat_samples(a: ReplayBufferSamples, b: ReplayBufferSamples) -> ReplayBufferSamples:
    """Concatenate two sampled batches along the batch axis (Dict observations key by key)."""
    def cat(x: Any, y: Any) -> Any:
        if x is None or y is None:  # optional fields (e.g. n-step discounts)
            return None if x is None and y is None else _missing(x, y)
        if isinstance(x, dict):
            return {k: th.cat([x[k], y[k]]) for k in x}
        return th.cat([x, y])

    return type(a)(*(cat(x, y) for x, y in zip(a, b)))


def _ensemble_optimizer_state(old: dict[str, Any], critic: EnsembleCritic, current: dict[str, Any]) -> dict[str, Any]:
    """The state of an optimiser over a ``ContinuousCritic`` (encoder, then ``qf0``, ``qf1``, ...)
    re-laid out for the same critics as an :class:`EnsembleCritic` (``w0, b0, w1, ...``, then the
    encoder): per-parameter moment tensors are stacked like the weights; ``fused``/``foreach``
    come from the current optimiser."""
    n, n_layers = critic.n_critics, critic.n_layers
    n_fe = len(list(critic.features_extractor.parameters()))
    old_state = old["state"]

    def gather(ids: list[int], is_weight: bool) -> dict[str, Any] | None:
        states = [old_state.get(i) for i in ids]
        if any(s is None for s in states):
            return None
        out = {}
        for key, value in states[0].items():
            if not th.is_tensor(value) or value.dim() == 0:  # e.g. the step count (one tensor per parameter)
                out[key] = value.clone() if th.is_tensor(value) else value
            elif is_weight:
                out[key] = th.stack([s[key].t() for s in states])
            else:
                out[key] = th.stack([s[key] for s in states]).unsqueeze(1)
        return out

    state: dict[int, Any] = {}
    k = 0
    for j in range(n_layers):
        for kind in (0, 1):  # weight, bias of layer j of every critic
            moved = gather([n_fe + i * 2 * n_layers + 2 * j + kind for i in range(n)], kind == 0)
            if moved is not None:
                state[k] = moved
            k += 1
    for f in range(n_fe):
        if f in old_state:
            state[k] = {key: v.clone() if th.is_tensor(v) else v for key, v in old_state[f].items()}
        k += 1
    group = {**old["param_groups"][0], "params": list(range(k))}
    for key in ("fused", "foreach"):
        if key in current["param_groups"][0]:
            group[key] = current["param_groups"][0][key]
    return {"state": state, "param_groups": [group]}


def _missing(x: Any, y: Any) -> Any:
    raise ValueError("cannot mix batches with and without an optional field (different buffer classes)")


def _copy_buffer(src: ReplayBuffer | DictReplayBuffer, dst: ReplayBuffer | DictReplayBuffer) -> None:
    """Copy the filled rows of ``src`` to the start of the (larger) buffer ``dst``."""
    n = src.size()
    for name in ("observations", "next_observations", "actions", "rewards", "dones", "timeouts"):
        s_arr, d_arr = getattr(src, name), getattr(dst, name)
        if isinstance(s_arr, dict):
            for k in s_arr:
                d_arr[k][:n] = s_arr[k][:n]
        else:
            d_arr[:n] = s_arr[:n]
    dst.pos, dst.full = n % dst.buffer_size, n == dst.buffer_size


# ----------------------------------------------------------------------------------- policies
def _resolve_actor_keys(space: spaces.Space, actor_keys: Sequence[str] | str | None) -> list[str] | None:
    if not isinstance(space, spaces.Dict):
        return None
    if actor_keys == "auto":
        keys = list(space.spaces)
        return ["image"] if "image" in keys and len(keys) > 1 else None
    return None if actor_keys is None else list(actor_keys)


class DMfDPolicy(BasePolicy):
    """Gaussian actor + twin critics (+ target critics) with separate features extractors.

    The critics are one :class:`~lfd_agents.networks.EnsembleCritic` (all Q networks in one
    batched module; same initial weights for a seed as SB3's ``ContinuousCritic``).  Adam runs
    fused unless ``optimizer_kwargs`` choose ``foreach``/``fused`` themselves.

    Args:
        observation_space, action_space, lr_schedule: given by the algorithm.
        net_arch: hidden sizes, shared by actor and critics, or ``dict(pi=[...], qf=[...])``.
        activation_fn: MLP activation (ReLU for state, LeakyReLU for image policies).
        features_extractor_class / features_extractor_kwargs: observation encoder.
        actor_keys: Dict observations only — keys the actor sees; ``"auto"`` gives the actor just
            ``"image"`` when the observation also has other keys (asymmetric actor-critic); the
            critics always see every key.
        actor_weight_decay: Adam weight decay of the actor (1e-4 in DMfD).
        share_encoder: actor and critic read one image encoder instead of one each (DMfD);
            ``"auto"``: shared when there are images. An update then encodes the batch's
            observations once, for both losses, and takes one backward pass through the encoder
            for their sum (the critic's optimiser steps the encoder, the actor's the rest of the
            actor), so the actor's loss is that of the critic before its step, not after.
            Both losses train the encoder: stopping the actor's gradient, as SAC-AE and DrQ do,
            leaves the imitation term without a say in it, and on the toy pick-and-place the
            offline actor then fits the demonstrations several times worse.
            With ``"state+image"`` observations, whose critic also reads the state, separate
            encoders fitted the demonstrations' grasps on the diagonal folds more often (the
            harness's ``dmfd/image-v2`` recipe runs them).
            ``share_encoder=False`` with ``features_extractor_kwargs=THESIS_ENCODER``
            (:mod:`lfd_agents.networks`) is the thesis's image network.
        n_critics: number of Q networks (2).
        log_std_bounds: bounds of the state-independent log-std.
    """

    actor: GaussianActor
    critic: EnsembleCritic
    critic_target: EnsembleCritic

    def __init__(self, observation_space: spaces.Space, action_space: spaces.Box, lr_schedule: Schedule,
                 net_arch: Sequence[int] | dict[str, Sequence[int]] | None = None,
                 activation_fn: type[nn.Module] = nn.ReLU,
                 features_extractor_class: type[BaseFeaturesExtractor] = FlattenExtractor,
                 features_extractor_kwargs: dict[str, Any] | None = None,
                 actor_keys: Sequence[str] | str | None = "auto", normalize_images: bool = True,
                 optimizer_class: type[th.optim.Optimizer] = th.optim.Adam,
                 optimizer_kwargs: dict[str, Any] | None = None, actor_weight_decay: float = 1e-4,
                 n_critics: int = 2, log_std_bounds: tuple[float, float] = (-6.0, 0.0),
                 share_encoder: bool | str = "auto"):
        super().__init__(observation_space, action_space, features_extractor_class, features_extractor_kwargs,
                         optimizer_class=optimizer_class, optimizer_kwargs=optimizer_kwargs,
                         squash_output=True, normalize_images=normalize_images)
        if net_arch is None:
            net_arch = list(DEFAULT_NET_ARCH)
        if isinstance(net_arch, dict):
            self.net_arch_pi, self.net_arch_qf = list(net_arch["pi"]), list(net_arch["qf"])
        else:
            self.net_arch_pi = self.net_arch_qf = list(net_arch)
        self.net_arch = net_arch
        self.activation_fn = activation_fn
        self.actor_keys = _resolve_actor_keys(observation_space, actor_keys)
        self.actor_weight_decay = float(actor_weight_decay)
        self.n_critics = int(n_critics)
        self.log_std_bounds = tuple(log_std_bounds)
        if share_encoder not in (True, False, "auto"):
            raise ValueError(f"share_encoder must be True, False or 'auto', got {share_encoder!r}")
        self.share_encoder = bool(image_keys(observation_space)) if share_encoder == "auto" else share_encoder
        self._build(lr_schedule)

    def _extractor(self, keys: list[str] | None) -> BaseFeaturesExtractor:
        kwargs = dict(self.features_extractor_kwargs)
        if keys is not None:
            if not issubclass(self.features_extractor_class, KeySubsetExtractor):
                raise ValueError("actor_keys needs features_extractor_class=KeySubsetExtractor")
            kwargs["keys"] = keys
        return self.features_extractor_class(self.observation_space, **kwargs)

    def _shared_extractor(self, critic_fe: BaseFeaturesExtractor) -> BaseFeaturesExtractor:
        """The actor's view of the critic's encoder: its ``actor_keys`` (all when None), images
        through the critic's image encoders."""
        if self.actor_keys is None:
            return critic_fe
        if not isinstance(critic_fe, KeySubsetExtractor):
            raise ValueError("share_encoder with actor_keys needs features_extractor_class=KeySubsetExtractor")
        images = set(image_keys(self.observation_space))
        encoders = {k: critic_fe.extractors[k] for k in self.actor_keys if k in images}
        return KeySubsetExtractor(self.observation_space, keys=self.actor_keys, encoders=encoders)

    def _build(self, lr_schedule: Schedule) -> None:
        if self.share_encoder:  # the critic's encoder first, then the actor's view of it
            critic = self._make_critic()
            actor_fe = self._shared_extractor(critic.features_extractor)
        else:  # actor first: the initial weights of a seed stay those of separate encoders
            actor_fe = self._extractor(self.actor_keys)
        self.actor = GaussianActor(self.observation_space, self.action_space, self.net_arch_pi, actor_fe,
                                   actor_fe.features_dim, self.activation_fn, self.normalize_images,
                                   self.log_std_bounds)
        opt_kwargs = fast_optimizer_kwargs(self.optimizer_class, self.optimizer_kwargs)
        actor_kwargs = {**opt_kwargs, "weight_decay": self.actor_weight_decay}
        encoder = {id(p) for p in critic.features_extractor.parameters()} if self.share_encoder else set()
        actor_params = [p for p in self.actor.parameters() if id(p) not in encoder]  # the critic's optimiser has them
        self.actor.optimizer = self.optimizer_class(actor_params, lr=lr_schedule(1), **actor_kwargs)
        self.critic = critic if self.share_encoder else self._make_critic()
        self.critic_target = self._make_critic()
        self.critic_target.load_state_dict(self.critic.state_dict())
        self.critic_target.set_training_mode(False)
        self.critic.optimizer = self.optimizer_class(self.critic.parameters(), lr=lr_schedule(1), **opt_kwargs)

    def _make_critic(self) -> EnsembleCritic:
        fe = self._extractor(None)
        return EnsembleCritic(self.observation_space, self.action_space, self.net_arch_qf, fe, fe.features_dim,
                              self.activation_fn, self.normalize_images, self.n_critics,
                              share_features_extractor=False)

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(net_arch=self.net_arch, activation_fn=self.activation_fn,
                    features_extractor_class=self.features_extractor_class,
                    features_extractor_kwargs=self.features_extractor_kwargs, actor_keys=self.actor_keys,
                    optimizer_class=self.optimizer_class, optimizer_kwargs=self.optimizer_kwargs,
                    actor_weight_decay=self.actor_weight_decay, n_critics=self.n_critics,
                    log_std_bounds=self.log_std_bounds, share_encoder=self.share_encoder,
                    lr_schedule=self._dummy_schedule)
        return data

    def forward(self, obs: th.Tensor, deterministic: bool = False) -> th.Tensor:
        return self._predict(obs, deterministic)

    def _predict(self, observation: th.Tensor, deterministic: bool = False) -> th.Tensor:
        return self.actor(observation, deterministic)

    def set_training_mode(self, mode: bool) -> None:
        self.actor.set_training_mode(mode)
        self.critic.set_training_mode(mode)
        self.training = mode


class DMfDCnnPolicy(ImagePolicyDefaults, DMfDPolicy):
    """:class:`DMfDPolicy` for image observations (DMfD CNN encoder, LeakyReLU MLPs)."""


class DMfDMultiInputPolicy(DictPolicyDefaults, DMfDPolicy):
    """:class:`DMfDPolicy` for Dict observations (e.g. ``"state+image"``; asymmetric by default)."""


# ----------------------------------------------------------------------------------- algorithm
def _has_image(space: spaces.Space) -> bool:
    return bool(image_keys(space))


def _inner_dummy(venv: VecEnv) -> DummyVecEnv | None:
    while not isinstance(venv, DummyVecEnv) and hasattr(venv, "venv"):
        venv = venv.venv
    return venv if isinstance(venv, DummyVecEnv) else None


class DMfD(OffPolicyAlgorithm):
    """DMfD (module docstring). SB3 API: ``DMfD(policy, env, demonstrations=...)``, ``learn``,
    ``predict``, ``save``, ``load``.

    The defaults follow the paper (1024-1024 networks, no offline phase, λ 2, lr 3e-4). The
    settings the benchmark runs are the harness's recipes: ``dmfd/state-v2`` on the ``-v1`` ids
    (``dmfd/state-v1`` acting with its best checkpoint on validation variants) and ``dmfd/state-v0``
    on the ``-v0`` ids (``lfd_bench.recipes.load("dmfd/state-v2").make(env)``), and ``dmfd/image-v2``
    from pixels.

    Args:
        policy: ``"MlpPolicy"`` (state), ``"CnnPolicy"`` (image) or ``"MultiInputPolicy"``
            (``"state+image"``), or a :class:`DMfDPolicy` subclass.
        env: a Gymnasium env, env id or SB3 VecEnv.
        demonstrations: Minari dataset / path / id or list of episodes
            (:func:`lfd_agents.demos.load_episodes`); they pre-fill the replay buffer and are the
            reference states for RSI. ``None`` runs without demonstrations.
        learning_rate, buffer_size, learning_starts, batch_size, tau, gamma, train_freq,
            gradient_steps: as in SB3 ``SAC``; defaults 3e-4, 600k, 0, 256, 0.005, 0.9, 1, 1.
        entropy_weight: w_E, weight of the entropy term L_E (0.1).
        ent_coef: α, entropy coefficient inside L_E (0.5).
        awr_temperature: λ, advantage temperature of L_A (2.0, DMfD's value). It is measured in
            units of Q, so it should follow ``reward_scale``: the smaller λ is against the spread of
            the advantages in a batch, the fewer samples carry the weight and the more loosely
            the actor fits the stored actions (on the particle tasks with ``reward_scale`` 10,
            λ = 10 fits the demonstrations' pick points where λ = 2 often misses them).
        awr_weighting: how L_A weights the stored actions: ``"softmax"`` (DMfD: batch-normalised
            exp(A/λ)) or ``"binary"`` (CRR's filter 1[A > 0]: only actions the critic rates above
            the policy's own are imitated, so neither the agent's own failed attempts nor the bad
            steps of suboptimal demonstrations are; λ is then unused).
        awr_fit: how L_A fits the stored actions: ``"likelihood"`` (DMfD: log N(a; μ, σ) with
            the learned per-dimension σ) or ``"isotropic"`` (the mean fits every action dimension
            alike, as BC's regression does; see :func:`awr_log_prob`).
        target_ent_coef: entropy coefficient in the critic target (0.0 as in the original code).
        reward_scale: factor on every reward (demonstrations and online alike) before the critic
            sees it; it sets the size of Q, hence of the advantages against λ and of Q against α.
        rsi_prob: probability of a reference-state reset; ``"auto"`` = 0.3 for image and 0.2 for
            state observations when the demonstrations carry simulator states (else 0); 0 disables.
        imitation_reward_scale: factor on the RSI imitation reward.
        duplicate_demos: repeat the demonstrations to fill the buffer (``True``) or ``k`` times.
        augment: pad-and-random-crop image augmentation (``"auto"``: on when there are images).
        aug_pad: padding of the augmentation (2).
        offline_steps: gradient steps on the demonstration buffer before the first env step.
        demo_ratio: fraction of every batch drawn from a separate buffer that holds only the
            demonstrations (``None``: the demonstrations are written into the replay buffer and
            diluted by online data, as in the original code).  With a small budget the online
            data outnumbers the demonstrations within a few thousand steps and the advantage
            weighting then imitates mostly the agent's own actions; a fixed share (0.5 =
            symmetric sampling) keeps the demonstrations in every update.
    """

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {
        "MlpPolicy": DMfDPolicy, "CnnPolicy": DMfDCnnPolicy, "MultiInputPolicy": DMfDMultiInputPolicy}
    policy: DMfDPolicy
    actor: GaussianActor
    critic: EnsembleCritic
    critic_target: EnsembleCritic

    def __init__(self, policy: str | type[DMfDPolicy], env: GymEnv | str | None, demonstrations: Any = None,
                 learning_rate: float | Schedule = 3e-4, buffer_size: int = 600_000, learning_starts: int = 0,
                 batch_size: int = 256, tau: float = 0.005, gamma: float = 0.9,
                 train_freq: int | tuple[int, str] = 1, gradient_steps: int = 1, entropy_weight: float = 0.1,
                 ent_coef: float = 0.5, awr_temperature: float = 2.0, awr_weighting: str = "softmax",
                 awr_fit: str = "likelihood", target_ent_coef: float = 0.0,
                 reward_scale: float = 10.0, rsi_prob: float | str = "auto", imitation_reward_scale: float = 1.0,
                 duplicate_demos: bool | int = False, augment: bool | str = "auto", aug_pad: int = 2,
                 offline_steps: int = 0, demo_ratio: float | None = None, replay_buffer_class: Any = None,
                 replay_buffer_kwargs: dict[str, Any] | None = None, policy_kwargs: dict[str, Any] | None = None,
                 stats_window_size: int = 100, tensorboard_log: str | None = None, verbose: int = 0,
                 seed: int | None = None, device: th.device | str = "auto", _init_setup_model: bool = True):
        if not 0.0 <= entropy_weight <= 1.0:
            raise ValueError(f"entropy_weight (w_E) must be in [0, 1], got {entropy_weight}")
        if awr_temperature <= 0:
            raise ValueError(f"awr_temperature (λ) must be > 0, got {awr_temperature}")
        if awr_weighting not in AWR_WEIGHTINGS:
            raise ValueError(f"awr_weighting must be one of {AWR_WEIGHTINGS}, got {awr_weighting!r}")
        if awr_fit not in AWR_FITS:
            raise ValueError(f"awr_fit must be one of {AWR_FITS}, got {awr_fit!r}")
        if ent_coef < 0 or target_ent_coef < 0:
            raise ValueError("ent_coef and target_ent_coef must be >= 0")
        if aug_pad < 0 or offline_steps < 0:
            raise ValueError("aug_pad and offline_steps must be >= 0")
        if demo_ratio is not None and not 0.0 < float(demo_ratio) < 1.0:
            raise ValueError(f"demo_ratio must be None or in (0, 1), got {demo_ratio!r}")
        self.demo_ratio = None if demo_ratio is None else float(demo_ratio)
        self.demo_buffer: ReplayBuffer | DictReplayBuffer | None = None
        self.entropy_weight = float(entropy_weight)
        self.ent_coef = float(ent_coef)
        self.awr_temperature = float(awr_temperature)
        self.awr_weighting = awr_weighting
        self.awr_fit = awr_fit
        self.target_ent_coef = float(target_ent_coef)
        self.reward_scale = float(reward_scale)
        self.imitation_reward_scale = float(imitation_reward_scale)
        self.duplicate_demos = duplicate_demos
        self.augment = augment
        self.aug_pad = int(aug_pad)
        self.offline_steps = int(offline_steps)
        self._offline_done = False
        self._episodes = load_episodes(demonstrations)
        if isinstance(env, str):
            env = gym.make(env)
        self.rsi_prob = self._resolve_rsi(rsi_prob, env)
        env = self._wrap_rsi(env, seed)
        super().__init__(policy, env, learning_rate, buffer_size=buffer_size, learning_starts=learning_starts,
                         batch_size=batch_size, tau=tau, gamma=gamma, train_freq=train_freq,
                         gradient_steps=gradient_steps, replay_buffer_class=replay_buffer_class,
                         replay_buffer_kwargs=replay_buffer_kwargs, policy_kwargs=policy_kwargs,
                         stats_window_size=stats_window_size, tensorboard_log=tensorboard_log, verbose=verbose,
                         device=device, seed=seed, support_multi_env=True, sde_support=False,
                         supported_action_spaces=(spaces.Box,))
        if _init_setup_model:
            self._setup_model()

    # ------------------------------------------------------------------ set-up
    def _resolve_rsi(self, rsi_prob: float | str, env: Any) -> float:
        with_states = bool(episodes_with_states(self._episodes))
        if rsi_prob == "auto":
            if env is None or not with_states:
                return 0.0
            return 0.3 if _has_image(env.observation_space) else 0.2
        p = float(rsi_prob)
        if not 0.0 <= p <= 1.0:
            raise ValueError(f"rsi_prob must be in [0, 1] or 'auto', got {rsi_prob!r}")
        if p > 0 and not with_states:
            raise ValueError("rsi_prob > 0 needs demonstrations with per-step simulator states (infos['state'])")
        return p

    def _wrap_rsi(self, env: Any, seed: int | None) -> Any:
        if self.rsi_prob == 0 or env is None:
            return env

        def wrap(e: gym.Env, i: int) -> gym.Env:
            s = None if seed is None else seed + 7919 * i
            return ReferenceStateInit(e, self._episodes, self.rsi_prob, self.imitation_reward_scale, seed=s)

        if isinstance(env, VecEnv):
            dummy = _inner_dummy(env)
            if dummy is None:
                warnings.warn(f"reference-state initialisation needs per-env set_state; {type(env).__name__} "
                              "does not offer it, so RSI is disabled (use a DummyVecEnv or a single env)")
                self.rsi_prob = 0.0
                return env
            dummy.envs = [wrap(e, i) for i, e in enumerate(dummy.envs)]
            return env
        return wrap(env, 0)

    def _setup_model(self) -> None:
        super()._setup_model()
        self.actor, self.critic, self.critic_target = self.policy.actor, self.policy.critic, self.policy.critic_target
        use_aug = _has_image(self.observation_space) if self.augment == "auto" else bool(self.augment)
        self._aug_keys = image_keys(self.observation_space) if use_aug else []
        if self._episodes:
            self.add_demonstrations(self._episodes, duplicate=self.duplicate_demos)

    def add_demonstrations(self, demonstrations: Any, duplicate: bool | int = False) -> int:
        """Write demonstrations into the replay buffer, or into the demonstration buffer when
        ``demo_ratio`` is set (e.g. after ``load``); returns the count."""
        if self.demo_ratio is None:
            n = fill_replay_buffer(self.replay_buffer, demonstrations, duplicate=duplicate)
        else:
            episodes = load_episodes(demonstrations)
            size = sum(len(ep) for ep in episodes) + (self.demo_buffer.size() if self.demo_buffer else 0)
            old = self.demo_buffer
            cls = DictReplayBuffer if isinstance(self.observation_space, spaces.Dict) else ReplayBuffer
            # time-limit ends are not terminal, exactly as in the online replay buffer
            self.demo_buffer = cls(max(size, 1), self.observation_space, self.action_space, device=self.device,
                                   n_envs=1, handle_timeout_termination=True)
            if old is not None:
                _copy_buffer(old, self.demo_buffer)
            n = fill_replay_buffer(self.demo_buffer, episodes)
        if self.verbose:
            where = "replay" if self.demo_ratio is None else "demonstration"
            print(f"DMfD: {n} demonstration transitions in the {where} buffer")
        return n

    def sample_batch(self, batch_size: int) -> ReplayBufferSamples:
        """A training batch: from the replay buffer, or ``demo_ratio`` of it from the
        demonstration buffer and the rest from the online replay buffer (all demonstrations
        while the replay buffer is still empty)."""
        env = self._vec_normalize_env
        demos = self.demo_buffer
        if self.demo_ratio is None or demos is None or demos.size() == 0:
            return self.replay_buffer.sample(batch_size, env=env)
        n_online = int(round((1.0 - self.demo_ratio) * batch_size)) if self.replay_buffer.size() else 0
        if n_online == 0:
            return demos.sample(batch_size, env=env)
        return _cat_samples(demos.sample(batch_size - n_online, env=env),
                            self.replay_buffer.sample(n_online, env=env))

    def _excluded_save_params(self) -> list[str]:
        return super()._excluded_save_params() + ["actor", "critic", "critic_target", "_episodes", "demo_buffer"]

    def _get_torch_save_params(self) -> tuple[list[str], list[str]]:
        return ["policy", "actor.optimizer", "critic.optimizer"], []

    def set_parameters(self, load_path_or_dict: str | dict[str, Any], exact_match: bool = True,
                       device: th.device | str = "auto") -> None:
        """SB3 ``set_parameters``; also loads files saved when the critics were separate
        ``ContinuousCritic`` MLPs (weights and critic optimiser state are re-laid out)."""
        if isinstance(load_path_or_dict, dict):
            params = dict(load_path_or_dict)
        else:
            _, params, _ = load_from_zip_file(load_path_or_dict, device=device)
        old = params.get("critic.optimizer")
        if isinstance(self.critic, EnsembleCritic) and isinstance(old, dict) and old.get("param_groups"):
            current = self.critic.optimizer.state_dict()
            if len(old["param_groups"][0]["params"]) != len(current["param_groups"][0]["params"]):
                params["critic.optimizer"] = _ensemble_optimizer_state(old, self.critic, current)
        super().set_parameters(params, exact_match=exact_match, device=device)

    # ------------------------------------------------------------------ losses
    def augment_batch(self, data: ReplayBufferSamples) -> ReplayBufferSamples:
        """Random-shift the image entries of ``observations`` and ``next_observations``."""
        if not self._aug_keys:
            return data
        return data._replace(observations=augment_observations(data.observations, self._aug_keys, self.aug_pad),
                             next_observations=augment_observations(data.next_observations, self._aug_keys,
                                                                    self.aug_pad))

    def _min_q(self, critic: EnsembleCritic | ContinuousCritic, obs: Any, actions: th.Tensor) -> th.Tensor:
        return q_values(critic, obs, actions).min(dim=0).values

    def critic_loss(self, data: ReplayBufferSamples, features: th.Tensor | None = None) -> dict[str, th.Tensor]:
        """Sum over critics of MSE(Q_i(s, a_B), y); returns ``loss``, ``target`` and ``q`` (batch, n_critics)."""
        with th.no_grad():
            mean, std = self.actor.mean_std(data.next_observations)
            next_actions = mean + th.randn_like(mean) * std  # a' ~ π(·|s') (the draws of Normal.sample)
            next_q = self._min_q(self.critic_target, data.next_observations, next_actions)
            next_logp = normal_log_prob(next_actions, mean, std) if self.target_ent_coef else th.zeros_like(next_q)
            target = td_target(self.reward_scale * data.rewards.flatten(), data.dones.flatten(), next_q, next_logp,
                               gamma=self.gamma, target_ent_coef=self.target_ent_coef)
        q = q_values(self.critic, data.observations, data.actions) if features is None \
            else self.critic.q_from_features(features, data.actions)
        loss = F.mse_loss(q, target.expand_as(q), reduction="none").mean(dim=1).sum()
        return {"loss": loss, "target": target, "q": q.detach().t()}

    def actor_loss(self, data: ReplayBufferSamples, features: th.Tensor | None = None) -> dict[str, th.Tensor]:
        """DMfD actor loss on a batch (see :func:`dmfd_actor_loss`).

        The critic's parameters take no gradient from it (the actor's optimiser ignores them),
        and with ``entropy_weight == 0`` (AWAC) the entropy term, whose gradient is then
        multiplied by 0, is evaluated without a graph.
        """
        critic = self.critic
        shared = self.actor.features_extractor is critic.features_extractor
        if shared:  # one encoder for actor and critic: encode the observations once for both
            if features is None:
                features = critic.features(data.observations)
            mean, std = self.actor.mean_from_features(features), self.actor.log_std().exp()
            features = features.detach()
        else:
            mean, std = self.actor.mean_std(data.observations)
        with frozen(critic), th.set_grad_enabled(th.is_grad_enabled() and self.entropy_weight > 0):
            pi_actions = mean + th.randn_like(mean) * std  # reparameterised a_π ~ π(·|o)
            logp_pi = normal_log_prob(pi_actions, mean, std)
            if isinstance(critic, EnsembleCritic):  # encode the observations once for both action sets
                with th.no_grad():
                    if not shared:
                        features = critic.features(data.observations)
                    q_buffer = critic.q_from_features(features, data.actions).min(dim=0).values
                q_pi = critic.q_from_features(features, pi_actions).min(dim=0).values
            else:
                with th.no_grad():
                    q_buffer = self._min_q(critic, data.observations, data.actions)
                q_pi = self._min_q(critic, data.observations, pi_actions)
        advantages = q_buffer - q_pi.detach()
        out = dmfd_actor_loss(awr_log_prob(data.actions, mean, std, self.awr_fit), advantages, logp_pi, q_pi,
                              temperature=self.awr_temperature, ent_coef=self.ent_coef,
                              entropy_weight=self.entropy_weight, weighting=self.awr_weighting)
        out["advantages"] = advantages
        return out

    # ------------------------------------------------------------------ training
    _LOG_KEYS = ("critic_loss", "actor_loss", "awr_loss", "entropy_loss", "max_weight")

    def train(self, gradient_steps: int, batch_size: int = 256) -> None:
        self.policy.set_training_mode(True)
        self._update_learning_rate([self.actor.optimizer, self.critic.optimizer])
        critic_params = list(self.critic.parameters())
        target_params = list(self.critic_target.parameters())
        logs: list[th.Tensor] = []  # one small tensor per update, read once at the end (no per-update .item())
        joint = self.actor.features_extractor is self.critic.features_extractor
        for _ in range(gradient_steps):
            data = self.augment_batch(self.sample_batch(batch_size))
            if joint:  # one encoder: one forward and one backward pass through it for both losses
                features = self.critic.features(data.observations)
                critic, actor = self.critic_loss(data, features), self.actor_loss(data, features)
                self.critic.optimizer.zero_grad(set_to_none=True)
                self.actor.optimizer.zero_grad(set_to_none=True)
                (critic["loss"] + actor["loss"]).backward()
                self.critic.optimizer.step()
                self.actor.optimizer.step()
            else:
                critic = self.critic_loss(data)
                self.critic.optimizer.zero_grad(set_to_none=True)
                critic["loss"].backward()
                self.critic.optimizer.step()
                actor = self.actor_loss(data)
                self.actor.optimizer.zero_grad(set_to_none=True)
                actor["loss"].backward()
                self.actor.optimizer.step()
            polyak_update_(critic_params, target_params, self.tau)
            logs.append(th.stack([critic["loss"].detach(), actor["loss"].detach(), actor["awr_loss"].detach(),
                                  actor["entropy_loss"].detach(), actor["weights"].max()]))
        self._n_updates += gradient_steps
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        self.logger.record("train/log_std", self.actor.log_std().mean().item())
        if logs:
            for key, value in zip(self._LOG_KEYS, th.stack(logs).double().mean(dim=0).tolist()):
                self.logger.record(f"train/{key}", value)

    @property
    def offline_pending(self) -> bool:
        """Whether the offline phase (``offline_steps`` > 0) has yet to run."""
        return bool(self.offline_steps) and not self._offline_done

    def pretrain(self) -> None:
        """Run the offline phase now, if it has yet to run: ``offline_steps`` gradient steps on
        the demonstrations, no env step (``learn`` runs it otherwise). Lets a caller look at the
        policy the online phase starts from (e.g. score it as a checkpoint)."""
        if not self.offline_pending:
            return
        if getattr(self, "_logger", None) is None:  # learn() replaces it unless a logger was set
            from stable_baselines3.common.logger import configure

            self._logger = configure(None, [])
        self._run_offline_phase()

    def _run_offline_phase(self) -> None:
        if self.replay_buffer.size() == 0 and (self.demo_buffer is None or self.demo_buffer.size() == 0):
            warnings.warn("offline_steps > 0 but the replay buffer is empty (no demonstrations); skipping")
        else:
            self.train(self.offline_steps, self.batch_size)
        self._offline_done = True

    def _setup_learn(self, total_timesteps: int, callback: Any = None, reset_num_timesteps: bool = True,
                     tb_log_name: str = "run", progress_bar: bool = False):
        out = super()._setup_learn(total_timesteps, callback, reset_num_timesteps, tb_log_name, progress_bar)
        if self.offline_pending:
            self._run_offline_phase()
        return out

    def learn(self, total_timesteps: int, callback: Any = None, log_interval: int = 4, tb_log_name: str = "DMfD",
              reset_num_timesteps: bool = True, progress_bar: bool = False) -> "DMfD":
        return super().learn(total_timesteps=total_timesteps, callback=callback, log_interval=log_interval,
                             tb_log_name=tb_log_name, reset_num_timesteps=reset_num_timesteps,
                             progress_bar=progress_bar)
