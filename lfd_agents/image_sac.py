"""SAC from pixels with one encoder for actor and critic and augmented batches (the base of DrQ and CURL).

* the critic owns the image encoder and trains it; the actor reads the same encoder without
  gradient (:class:`~lfd_agents.networks.DetachedExtractor`), as in SAC-AE, DrQ and CURL;
* every sampled batch is randomly shifted (:func:`lfd_agents.augment.random_shift`): the
  critic's target is the mean over ``n_target_augs`` shifts of ``next_obs`` and its loss the
  mean over ``n_q_augs`` shifts of ``obs`` (DrQ's K and M; 1 and 1 give plain shifted SAC);
* the actor and the entropy coefficient are updated after the critic, on the first shift of
  ``obs`` encoded by the updated encoder; the target critic's heads follow the critic by
  ``tau``, its encoder by ``encoder_tau``.

The twin critics are one :class:`~lfd_agents.networks.EnsembleCritic` and Adam runs fused, as
in :class:`~lfd_agents.SACLfD`, which this class extends (so demonstrations and
``reward_scale`` are available too).
"""

from __future__ import annotations

from typing import Any, ClassVar

import torch as th
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import ReplayBufferSamples, Schedule
from stable_baselines3.common.utils import polyak_update
from stable_baselines3.sac.policies import LOG_STD_MAX, LOG_STD_MIN, SACPolicy

from lfd_agents.augment import augment_observations, image_keys
from lfd_agents.baselines import SACLfD, _FastSACPolicyMixin
from lfd_agents.networks import (DetachedExtractor, DictPolicyDefaults, EnsembleCritic, ImagePolicyDefaults,
                                 frozen, normal_log_prob, own_parameters, polyak_update_)


class SharedEncoderSACPolicy(_FastSACPolicyMixin, SACPolicy):
    """SB3 ``SACPolicy`` whose actor reads the critic's encoder without gradient.

    The critic (an :class:`EnsembleCritic`) and its optimiser own the encoder; the actor's
    optimiser holds only the actor's MLP. The target critic has its own copy of the encoder.
    """

    def __init__(self, *args: Any, share_features_extractor: bool = False, **kwargs: Any):
        # the critic must compute its features with gradient: the sharing is done in _build
        super().__init__(*args, share_features_extractor=False, **kwargs)

    def _build(self, lr_schedule: Schedule) -> None:
        self.critic = self.make_critic(features_extractor=None)
        self.critic.optimizer = self.optimizer_class(self.critic.parameters(), lr=lr_schedule(1),
                                                     **self.optimizer_kwargs)
        self.actor = self.make_actor(features_extractor=DetachedExtractor(self.critic.features_extractor))
        self.actor.optimizer = self.optimizer_class(own_parameters(self.actor), lr=lr_schedule(1),
                                                    **self.optimizer_kwargs)
        self.critic_target = self.make_critic(features_extractor=None)
        self.critic_target.load_state_dict(self.critic.state_dict())
        self.critic_target.set_training_mode(False)


class SharedEncoderCnnPolicy(ImagePolicyDefaults, SharedEncoderSACPolicy):
    """:class:`SharedEncoderSACPolicy` for images (:class:`~lfd_agents.ImageEncoder`, LeakyReLU MLPs)."""


class SharedEncoderMultiInputPolicy(DictPolicyDefaults, SharedEncoderSACPolicy):
    """:class:`SharedEncoderSACPolicy` for Dict observations (images and vectors)."""


def repeat_augmented(obs: Any, n: int, keys: list[str | None], pad: int, generator: th.Generator | None) -> Any:
    """``n`` independently shifted copies of a batch, concatenated along the batch axis
    (copy ``i`` is rows ``i·B … (i+1)·B − 1``; non-image entries are repeated)."""
    copies = [augment_observations(obs, keys, pad, generator) for _ in range(n)]
    if isinstance(obs, dict):
        return {k: th.cat([c[k] for c in copies]) for k in obs}
    return th.cat(copies)


class ImageSAC(SACLfD):
    """SAC on augmented image batches with a shared encoder (module docstring).

    Args:
        policy: ``"CnnPolicy"`` (images) or ``"MultiInputPolicy"`` (Dict with images), or a
            :class:`SharedEncoderSACPolicy` subclass.
        env: env, id or VecEnv.
        n_target_augs: K, shifts of ``next_obs`` averaged in the critic's target.
        n_q_augs: M, shifts of ``obs`` averaged in the critic's loss.
        aug_pad: the shift's padding in pixels (shifts of up to ±``aug_pad``).
        encoder_tau: Polyak coefficient of the target encoder (``None``: ``tau``).
        learning_starts: env steps before the first update (100; SB3's SAC default).
        **kwargs: every :class:`~lfd_agents.SACLfD` (so SB3 ``SAC``) argument.
    """

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {
        "CnnPolicy": SharedEncoderCnnPolicy, "MultiInputPolicy": SharedEncoderMultiInputPolicy}
    policy: SharedEncoderSACPolicy
    critic: EnsembleCritic
    critic_target: EnsembleCritic

    def __init__(self, policy: Any, env: Any, n_target_augs: int = 1, n_q_augs: int = 1, aug_pad: int = 2,
                 encoder_tau: float | None = None, learning_starts: int = 100, _init_setup_model: bool = True,
                 **kwargs: Any):
        for name, value in (("n_target_augs", n_target_augs), ("n_q_augs", n_q_augs)):
            if int(value) < 1:
                raise ValueError(f"{name} must be >= 1, got {value!r}")
        if int(aug_pad) < 0:
            raise ValueError(f"aug_pad must be >= 0, got {aug_pad!r}")
        if encoder_tau is not None and not 0.0 < float(encoder_tau) <= 1.0:
            raise ValueError(f"encoder_tau must be None or in (0, 1], got {encoder_tau!r}")
        if kwargs.get("use_sde"):
            raise ValueError(f"{type(self).__name__} does not support use_sde")
        self.n_target_augs, self.n_q_augs, self.aug_pad = int(n_target_augs), int(n_q_augs), int(aug_pad)
        self.encoder_tau = None if encoder_tau is None else float(encoder_tau)
        super().__init__(policy, env, learning_starts=learning_starts, _init_setup_model=False, **kwargs)
        if not image_keys(self.observation_space):
            raise ValueError(f"{type(self).__name__} learns from images; the observation space "
                             f"{self.observation_space} has none (use obs_mode='image' or 'state+image')")
        if _init_setup_model:
            self._setup_model()

    def _setup_model(self) -> None:
        super()._setup_model()
        self._aug_keys = image_keys(self.observation_space)
        self.aug_generator = th.Generator(device=self.device)
        self.aug_generator.manual_seed(0 if self.seed is None else int(self.seed))

    def _excluded_save_params(self) -> list[str]:
        return super()._excluded_save_params() + ["aug_generator"]

    # ------------------------------------------------------------------ pieces of an update
    def augment(self, obs: Any, n: int) -> Any:
        """``n`` shifted copies of ``obs`` (:func:`repeat_augmented`, shifts from ``aug_generator``)."""
        return repeat_augmented(obs, n, self._aug_keys, self.aug_pad, self.aug_generator)

    def sample_from_features(self, features: th.Tensor) -> tuple[th.Tensor, th.Tensor]:
        """Squashed-Gaussian action and its log-likelihood from encoder features (SB3's
        ``Actor.action_log_prob`` after the features extractor)."""
        latent = self.actor.latent_pi(features)
        mean = self.actor.mu(latent)
        std = th.clamp(self.actor.log_std(latent), LOG_STD_MIN, LOG_STD_MAX).exp()
        gaussian = mean + th.randn_like(mean) * std
        actions = th.tanh(gaussian)
        logp = normal_log_prob(gaussian, mean, std)
        return actions, logp - th.log(1 - actions ** 2 + self.actor.action_dist.epsilon).sum(dim=1)

    def target_q(self, data: ReplayBufferSamples, ent_coef: th.Tensor, next_obs_augs: Any | None = None) -> th.Tensor:
        """Critic target, shape (B,): ``mean_k [r + γ(1 − d)(min Q'(s'_k, a'_k) − α log π(a'_k|s'_k))]``
        over the K shifted ``s'_k`` (``next_obs_augs``: K·B rows, drawn when None), ``a'_k ~ π(·|s'_k)``."""
        k, b = self.n_target_augs, data.actions.shape[0]
        if next_obs_augs is None:
            next_obs_augs = self.augment(data.next_observations, k)
        with th.no_grad():
            next_actions, next_logp = self.sample_from_features(self.critic.features(next_obs_augs))
            next_q = self.critic_target.q_values(next_obs_augs, next_actions).min(dim=0).values
            rewards = self.reward_scale * data.rewards.flatten()
            discounts = data.discounts.flatten() if data.discounts is not None else self.gamma
            y = rewards.repeat(k) + (1 - data.dones.flatten().repeat(k)) * (
                discounts.repeat(k) if th.is_tensor(discounts) else discounts) * (next_q - ent_coef * next_logp)
            return y.view(k, b).mean(dim=0)

    def critic_loss(self, data: ReplayBufferSamples, target: th.Tensor, obs_augs: Any) -> th.Tensor:
        """``0.5 Σ_critics mean_{m, batch} (Q_i(s_m, a) − target)²`` over the M shifted ``s_m`` (M·B rows)."""
        m = self.n_q_augs
        q = self.critic.q_values(obs_augs, data.actions.repeat(m, 1))
        return 0.5 * ((q - target.repeat(m)) ** 2).mean(dim=1).sum()

    def auxiliary_update(self, data: ReplayBufferSamples, obs_augs: Any) -> th.Tensor | None:
        """Hook after the critic's step (CURL's contrastive update); returns a loss to log."""
        return None

    def _ent_coef(self) -> th.Tensor:
        return th.exp(self.log_ent_coef.detach()) if self.ent_coef_optimizer is not None else self.ent_coef_tensor

    def _target_update(self) -> None:
        heads = [p for n, p in self.critic.named_parameters() if not n.startswith("features_extractor.")]
        heads_t = [p for n, p in self.critic_target.named_parameters() if not n.startswith("features_extractor.")]
        polyak_update_(heads, heads_t, self.tau)
        polyak_update_(list(self.critic.features_extractor.parameters()),
                       list(self.critic_target.features_extractor.parameters()),
                       self.tau if self.encoder_tau is None else self.encoder_tau)
        if self.batch_norm_stats:
            polyak_update(self.batch_norm_stats, self.batch_norm_stats_target, 1.0)

    def _optimizers(self) -> list[th.optim.Optimizer]:
        optimizers = [self.actor.optimizer, self.critic.optimizer]
        return optimizers + ([self.ent_coef_optimizer] if self.ent_coef_optimizer is not None else [])

    def train(self, gradient_steps: int, batch_size: int = 64) -> None:
        self.policy.set_training_mode(True)
        self._update_learning_rate(self._optimizers())
        learn_ent = self.ent_coef_optimizer is not None and self.log_ent_coef is not None
        logs: list[th.Tensor] = []
        for gradient_step in range(gradient_steps):
            data = self.replay_buffer.sample(batch_size, env=self._vec_normalize_env)  # type: ignore[union-attr]
            ent_coef = self._ent_coef()
            obs_augs = self.augment(data.observations, self.n_q_augs)
            critic_loss = self.critic_loss(data, self.target_q(data, ent_coef), obs_augs)
            self.critic.optimizer.zero_grad(set_to_none=True)
            critic_loss.backward()
            self.critic.optimizer.step()
            aux = self.auxiliary_update(data, obs_augs)
            first = {k: v[:batch_size] for k, v in obs_augs.items()} if isinstance(obs_augs, dict) \
                else obs_augs[:batch_size]
            with th.no_grad():
                features = self.critic.features(first)
            actions_pi, log_prob = self.sample_from_features(features)
            with frozen(self.critic):  # dQ/da only
                min_q = self.critic.q_from_features(features, actions_pi).min(dim=0).values
            actor_loss = (ent_coef * log_prob - min_q).mean()
            self.actor.optimizer.zero_grad(set_to_none=True)
            actor_loss.backward()
            self.actor.optimizer.step()
            values = [ent_coef.reshape(1), actor_loss.detach().reshape(1), critic_loss.detach().reshape(1)]
            if learn_ent:
                ent_coef_loss = -(self.log_ent_coef * (log_prob.detach() + self.target_entropy)).mean()
                self.ent_coef_optimizer.zero_grad()
                ent_coef_loss.backward()
                self.ent_coef_optimizer.step()
                values.append(ent_coef_loss.detach().reshape(1))
            if gradient_step % self.target_update_interval == 0:
                self._target_update()
            if aux is not None:
                values.append(aux.detach().reshape(1))
            logs.append(th.cat(values))
        self._n_updates += gradient_steps
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        if logs:
            keys = ["ent_coef", "actor_loss", "critic_loss"] + (["ent_coef_loss"] if learn_ent else [])
            keys += [self._aux_log_key] if len(logs[0]) > len(keys) else []
            for key, value in zip(keys, th.stack(logs).double().mean(dim=0).tolist()):
                self.logger.record(f"train/{key}", value)

    _aux_log_key = "aux_loss"
