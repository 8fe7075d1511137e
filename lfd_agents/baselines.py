"""Learning-from-demonstration baselines with the SB3 API (SPEC §6): SAC-LfD, BC and AWAC.

* :class:`SACLfD` — SB3 ``SAC`` whose replay buffer starts full of demonstrations (twin critics
  in one :class:`~lfd_agents.networks.EnsembleCritic`, fused Adam and an update step with
  the same arithmetic as SB3's but without its per-update overhead).
* :class:`BC` — behaviour cloning of demonstration actions (state, image or Dict observations;
  MSE on the mean of a :class:`~lfd_agents.networks.GaussianActor`); ``learn`` runs epochs
  over the dataset and never touches the env.
* :class:`AWAC` — advantage-weighted actor-critic: the DMfD machinery without the entropy term
  and without RSI, first ``offline_steps`` gradient steps on the demonstrations, then online.

Plain SB3 ``SAC``/``TD3``/``PPO`` run on every lfd env as they are (for 32×32 images pass
``policy_kwargs=dict(features_extractor_class=lfd_agents.ImageEncoder)``; SB3's NatureCNN
needs ≥ 36×36 pixels).
"""

from __future__ import annotations

import math
import time
from typing import Any, ClassVar

import numpy as np
import torch as th
import torch.nn.functional as F
from gymnasium import spaces
from stable_baselines3 import SAC
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.buffers import DictReplayBuffer, ReplayBuffer
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor, FlattenExtractor
from stable_baselines3.common.type_aliases import GymEnv, Schedule
from stable_baselines3.common.utils import polyak_update
from stable_baselines3.sac.policies import CnnPolicy as SACCnnPolicy
from stable_baselines3.sac.policies import MultiInputPolicy as SACMultiInputPolicy
from stable_baselines3.sac.policies import SACPolicy
from torch import nn

from lfd_agents.augment import augment_observations, image_keys
from lfd_agents.demos import fill_replay_buffer, load_episodes
from lfd_agents.dmfd import DMfD
from lfd_agents.networks import (DictPolicyDefaults, EnsembleCritic, GaussianActor, ImagePolicyDefaults,
                                 fast_optimizer_kwargs, frozen, normal_log_prob, polyak_update_, q_values)


# ----------------------------------------------------------------------------------- SAC-LfD
class _FastSACPolicyMixin:
    """SAC policy pieces for a fast update: the critics as one :class:`EnsembleCritic` (same
    initial weights for a seed as SB3's ``ContinuousCritic``) and fused Adam."""

    def __init__(self, *args: Any, optimizer_class: type[th.optim.Optimizer] = th.optim.Adam,
                 optimizer_kwargs: dict[str, Any] | None = None, **kwargs: Any):
        super().__init__(*args, optimizer_class=optimizer_class,
                         optimizer_kwargs=fast_optimizer_kwargs(optimizer_class, optimizer_kwargs or {}), **kwargs)

    def make_critic(self, features_extractor: BaseFeaturesExtractor | None = None) -> EnsembleCritic:
        critic_kwargs = self._update_features_extractor(self.critic_kwargs, features_extractor)
        return EnsembleCritic(**critic_kwargs).to(self.device)


class SACLfDPolicy(_FastSACPolicyMixin, SACPolicy):
    """SB3 ``SACPolicy`` with an :class:`EnsembleCritic` and fused Adam (state observations)."""


class SACLfDCnnPolicy(_FastSACPolicyMixin, SACCnnPolicy):
    """SB3 SAC ``CnnPolicy`` with an :class:`EnsembleCritic` and fused Adam."""


class SACLfDMultiInputPolicy(_FastSACPolicyMixin, SACMultiInputPolicy):
    """SB3 SAC ``MultiInputPolicy`` with an :class:`EnsembleCritic` and fused Adam."""


class SACLfD(SAC):
    """SB3 SAC with the replay buffer pre-filled with demonstrations ("replay-buffer spiking").

    The benchmark's settings: the recipes ``sac_lfd/state-v2`` (``-v1`` headline) and ``sac_lfd/state-v0`` (lfd_bench).

    The update is SB3 SAC's, operation for operation (same batches, same random draws, same
    losses for a seed), run with fused twin critics, fused Adam and the target update in two
    fused calls, without critic weight gradients in the actor's backward pass and without a
    ``.item()`` per update (logged values are read once per ``train`` call).  gSDE falls back
    to SB3's own ``train``.

    Args:
        policy, env: as for ``SAC``.
        demonstrations: anything :func:`lfd_agents.demos.load_episodes` accepts.
        duplicate_demos: repeat the demonstrations to fill the buffer (``True``) or ``k`` times.
        learning_starts: 0 by default (the buffer already holds data).
        reward_scale: factor on every reward (demonstrations and online alike) in the critic's
            target (1: SB3's SAC). SoftAgent and DMfD scale the rewards of every algorithm they
            compare on cloth and rope by 50; :class:`~lfd_agents.DMfD` defaults to 10.
        **kwargs: every other ``SAC`` argument.
    """

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {
        "MlpPolicy": SACLfDPolicy, "CnnPolicy": SACLfDCnnPolicy, "MultiInputPolicy": SACLfDMultiInputPolicy}

    def __init__(self, policy: Any, env: GymEnv | str | None, demonstrations: Any = None,
                 duplicate_demos: bool | int = False, learning_starts: int = 0, reward_scale: float = 1.0,
                 _init_setup_model: bool = True, **kwargs: Any):
        reward_scale = float(reward_scale)
        if not (math.isfinite(reward_scale) and reward_scale > 0):
            raise ValueError(f"reward_scale must be a finite number > 0, got {reward_scale}")
        self._episodes = load_episodes(demonstrations)
        self.duplicate_demos = duplicate_demos
        self.reward_scale = reward_scale
        if kwargs.get("use_sde") and reward_scale != 1.0:
            raise ValueError("reward_scale needs use_sde=False (gSDE trains with SB3's own update)")
        super().__init__(policy, env, learning_starts=learning_starts, _init_setup_model=False, **kwargs)
        if _init_setup_model:
            self._setup_model()

    def _setup_model(self) -> None:
        super()._setup_model()
        if self._episodes:
            fill_replay_buffer(self.replay_buffer, self._episodes, duplicate=self.duplicate_demos)

    def add_demonstrations(self, demonstrations: Any, duplicate: bool | int = False) -> int:
        """Write demonstrations into the replay buffer; returns the count."""
        return fill_replay_buffer(self.replay_buffer, demonstrations, duplicate=duplicate)

    def _excluded_save_params(self) -> list[str]:
        return super()._excluded_save_params() + ["_episodes"]

    def _action_log_prob(self, obs: Any) -> tuple[th.Tensor, th.Tensor]:
        """Squashed-Gaussian action and its log-likelihood (SB3's ``Actor.action_log_prob``,
        same operations and random draws, no distribution objects)."""
        mean, log_std, _ = self.actor.get_action_dist_params(obs)
        std = log_std.exp()
        gaussian = mean + th.randn_like(mean) * std
        actions = th.tanh(gaussian)
        logp = normal_log_prob(gaussian, mean, std)
        logp = logp - th.sum(th.log(1 - actions ** 2 + self.actor.action_dist.epsilon), dim=1)
        return actions, logp

    def train(self, gradient_steps: int, batch_size: int = 64) -> None:
        if self.use_sde:
            return super().train(gradient_steps, batch_size)
        self.policy.set_training_mode(True)
        optimizers = [self.actor.optimizer, self.critic.optimizer]
        if self.ent_coef_optimizer is not None:
            optimizers += [self.ent_coef_optimizer]
        self._update_learning_rate(optimizers)
        critic_params = list(self.critic.parameters())
        target_params = list(self.critic_target.parameters())
        learn_ent = self.ent_coef_optimizer is not None and self.log_ent_coef is not None
        logs: list[th.Tensor] = []  # (ent_coef, actor_loss, critic_loss[, ent_coef_loss]) per update
        for gradient_step in range(gradient_steps):
            data = self.replay_buffer.sample(batch_size, env=self._vec_normalize_env)  # type: ignore[union-attr]
            discounts = data.discounts if data.discounts is not None else self.gamma
            actions_pi, log_prob = self._action_log_prob(data.observations)
            log_prob = log_prob.reshape(-1, 1)
            if learn_ent:
                ent_coef = th.exp(self.log_ent_coef.detach())
                ent_coef_loss = -(self.log_ent_coef * (log_prob + self.target_entropy).detach()).mean()
                self.ent_coef_optimizer.zero_grad()
                ent_coef_loss.backward()
                self.ent_coef_optimizer.step()
            else:
                ent_coef = self.ent_coef_tensor
            with th.no_grad():
                next_actions, next_log_prob = self._action_log_prob(data.next_observations)
                next_q = q_values(self.critic_target, data.next_observations, next_actions).min(dim=0).values
                next_q = next_q.unsqueeze(1) - ent_coef * next_log_prob.reshape(-1, 1)
                rewards = data.rewards if self.reward_scale == 1.0 else self.reward_scale * data.rewards
                target_q = rewards + (1 - data.dones) * discounts * next_q
            current_q = q_values(self.critic, data.observations, data.actions)
            critic_loss = 0.5 * F.mse_loss(current_q, target_q.t().expand_as(current_q),
                                           reduction="none").mean(dim=1).sum()
            self.critic.optimizer.zero_grad()
            critic_loss.backward()
            self.critic.optimizer.step()
            with frozen(self.critic):  # the actor's loss needs dQ/da, not the critic's weight gradients
                min_qf_pi = q_values(self.critic, data.observations, actions_pi).min(dim=0).values.unsqueeze(1)
            actor_loss = (ent_coef * log_prob - min_qf_pi).mean()
            self.actor.optimizer.zero_grad()
            actor_loss.backward()
            self.actor.optimizer.step()
            if gradient_step % self.target_update_interval == 0:
                polyak_update_(critic_params, target_params, self.tau)
                if self.batch_norm_stats:
                    polyak_update(self.batch_norm_stats, self.batch_norm_stats_target, 1.0)
            values = [ent_coef.reshape(1), actor_loss.detach().reshape(1), critic_loss.detach().reshape(1)]
            if learn_ent:
                values.append(ent_coef_loss.detach().reshape(1))
            logs.append(th.cat(values))
        self._n_updates += gradient_steps
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        if logs:
            means = th.stack(logs).double().mean(dim=0).tolist()
            for key, value in zip(("ent_coef", "actor_loss", "critic_loss", "ent_coef_loss"), means):
                self.logger.record(f"train/{key}", value)


# ----------------------------------------------------------------------------------- AWAC
class AWAC(DMfD):
    """Advantage-weighted actor-critic (offline pre-training on demonstrations, then online).

    DMfD with ``entropy_weight=0`` (pure advantage-weighted regression actor), no RSI,
    ``offline_steps`` gradient steps on the demonstration buffer before the first env step,
    and SB3/AWAC defaults γ = 0.99, 256-256 networks. Every DMfD argument can be passed.
    The benchmark's settings: the recipes ``awac/state-v2`` (``-v1`` headline) and ``awac/state-v0`` (lfd_bench).
    """

    def __init__(self, policy: Any, env: GymEnv | str | None, demonstrations: Any = None,
                 offline_steps: int = 25_000, gamma: float = 0.99, entropy_weight: float = 0.0,
                 rsi_prob: float | str = 0.0, policy_kwargs: dict[str, Any] | None = None, **kwargs: Any):
        policy_kwargs = {"net_arch": [256, 256], **(policy_kwargs or {})}
        super().__init__(policy, env, demonstrations, offline_steps=offline_steps, gamma=gamma,
                         entropy_weight=entropy_weight, rsi_prob=rsi_prob, policy_kwargs=policy_kwargs, **kwargs)

    def learn(self, total_timesteps: int, callback: Any = None, log_interval: int = 4, tb_log_name: str = "AWAC",
              reset_num_timesteps: bool = True, progress_bar: bool = False) -> "AWAC":
        return super().learn(total_timesteps, callback, log_interval, tb_log_name, reset_num_timesteps, progress_bar)


# ----------------------------------------------------------------------------------- BC
class BCPolicy(BasePolicy):
    """Behaviour-cloning policy: a :class:`GaussianActor` whose mean is the action.

    Args:
        observation_space, action_space, lr_schedule: given by the algorithm.
        net_arch: hidden sizes (256-256).
        activation_fn, features_extractor_class, features_extractor_kwargs: encoder and MLP.
        actor_keys: Dict observations only — keys the policy sees (all when None).
    """

    def __init__(self, observation_space: spaces.Space, action_space: spaces.Box, lr_schedule: Schedule,
                 net_arch: list[int] | None = None, activation_fn: type[nn.Module] = nn.ReLU,
                 features_extractor_class: type[BaseFeaturesExtractor] = FlattenExtractor,
                 features_extractor_kwargs: dict[str, Any] | None = None, actor_keys: list[str] | None = None,
                 normalize_images: bool = True, optimizer_class: type[th.optim.Optimizer] = th.optim.Adam,
                 optimizer_kwargs: dict[str, Any] | None = None):
        super().__init__(observation_space, action_space, features_extractor_class, features_extractor_kwargs,
                         optimizer_class=optimizer_class, optimizer_kwargs=optimizer_kwargs, squash_output=True,
                         normalize_images=normalize_images)
        self.net_arch = list(net_arch) if net_arch is not None else [256, 256]
        self.activation_fn = activation_fn
        self.actor_keys = list(actor_keys) if actor_keys is not None else None
        kwargs = dict(self.features_extractor_kwargs)
        if self.actor_keys is not None:
            kwargs["keys"] = self.actor_keys
        fe = features_extractor_class(observation_space, **kwargs)
        self.actor = GaussianActor(observation_space, action_space, self.net_arch, fe, fe.features_dim,
                                   activation_fn, normalize_images)
        self.optimizer = optimizer_class(self.parameters(), lr=lr_schedule(1),
                                         **fast_optimizer_kwargs(optimizer_class, self.optimizer_kwargs))

    def _get_constructor_parameters(self) -> dict[str, Any]:
        data = super()._get_constructor_parameters()
        data.update(net_arch=self.net_arch, activation_fn=self.activation_fn,
                    features_extractor_class=self.features_extractor_class,
                    features_extractor_kwargs=self.features_extractor_kwargs, actor_keys=self.actor_keys,
                    optimizer_class=self.optimizer_class, optimizer_kwargs=self.optimizer_kwargs,
                    lr_schedule=self._dummy_schedule)
        return data

    def forward(self, obs: Any, deterministic: bool = True) -> th.Tensor:
        return self._predict(obs, deterministic)

    def _predict(self, observation: Any, deterministic: bool = True) -> th.Tensor:
        return self.actor(observation, deterministic=True)

    def mean_action(self, obs: Any) -> th.Tensor:
        """Predicted action in [-1, 1] (differentiable)."""
        return self.actor.mean_action(obs)


class BCCnnPolicy(ImagePolicyDefaults, BCPolicy):
    """:class:`BCPolicy` for image observations."""


class BCMultiInputPolicy(DictPolicyDefaults, BCPolicy):
    """:class:`BCPolicy` for Dict observations (every key, or ``actor_keys``)."""


class BC(BaseAlgorithm):
    """Behaviour cloning from a demonstration dataset, SB3 style.

    The benchmark's settings: the recipes ``bc/state-v1`` and ``bc/state-v0`` (lfd_bench).

    Args:
        policy: ``"MlpPolicy"``, ``"CnnPolicy"`` or ``"MultiInputPolicy"`` (or a BCPolicy class).
        env: env (or id) giving the observation/action spaces; ``learn`` does not step it.
        demonstrations: anything :func:`lfd_agents.demos.load_episodes` accepts.
        learning_rate: Adam learning rate (1e-3).
        batch_size: minibatch size (256).
        n_epochs: epochs run by each ``learn`` call unless ``epochs`` is given; ``None``
            (default) runs as many epochs as give ``default_updates`` gradient steps on the
            dataset.  A handful of epochs leaves a delta-mode policy near the demonstrations'
            mean action (idle for most of the horizon), which does nothing useful.
        default_updates: gradient steps of one ``learn`` call when ``n_epochs`` is None (10,000).
        augment: pad-and-random-crop augmentation of image inputs (``"auto"``: on for images).
        aug_pad: augmentation padding (2).
    """

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {
        "MlpPolicy": BCPolicy, "CnnPolicy": BCCnnPolicy, "MultiInputPolicy": BCMultiInputPolicy}
    policy: BCPolicy

    def __init__(self, policy: str | type[BCPolicy], env: GymEnv | str | None, demonstrations: Any = None,
                 learning_rate: float | Schedule = 1e-3, batch_size: int = 256, n_epochs: int | None = None,
                 default_updates: int = 10_000,
                 augment: bool | str = "auto", aug_pad: int = 2, policy_kwargs: dict[str, Any] | None = None,
                 tensorboard_log: str | None = None, verbose: int = 0, seed: int | None = None,
                 device: th.device | str = "auto", _init_setup_model: bool = True):
        super().__init__(policy, env, learning_rate, policy_kwargs=policy_kwargs, tensorboard_log=tensorboard_log,
                         verbose=verbose, device=device, support_multi_env=True, seed=seed,
                         supported_action_spaces=(spaces.Box,))
        if batch_size < 1 or (n_epochs is not None and n_epochs < 0) or default_updates < 1:
            raise ValueError("batch_size and default_updates must be >= 1 and n_epochs >= 0 (or None)")
        self.batch_size = int(batch_size)
        self.n_epochs = None if n_epochs is None else int(n_epochs)
        self.default_updates = int(default_updates)
        self.augment = augment
        self.aug_pad = int(aug_pad)
        self._episodes = load_episodes(demonstrations)
        self.dataset: ReplayBuffer | DictReplayBuffer | None = None
        self._epochs_done = 0  #: epochs run since the last learn(reset_num_timesteps=True)
        if _init_setup_model:
            self._setup_model()

    def _setup_model(self) -> None:
        self._setup_lr_schedule()
        self.set_random_seed(self.seed)
        self.policy = self.policy_class(self.observation_space, self.action_space, self.lr_schedule,
                                        **self.policy_kwargs).to(self.device)
        use_aug = bool(image_keys(self.observation_space)) if self.augment == "auto" else bool(self.augment)
        self._aug_keys = image_keys(self.observation_space) if use_aug else []
        self.dataset = None
        if self._episodes:
            self.set_demonstrations(self._episodes)

    def set_demonstrations(self, demonstrations: Any) -> int:
        """Replace the training set; returns the number of transitions."""
        episodes = load_episodes(demonstrations)
        n = sum(len(ep) for ep in episodes)
        if n == 0:
            raise ValueError("BC needs at least one demonstration transition")
        cls = DictReplayBuffer if isinstance(self.observation_space, spaces.Dict) else ReplayBuffer
        self.dataset = cls(n, self.observation_space, self.action_space, device=self.device, n_envs=1)
        return fill_replay_buffer(self.dataset, episodes)

    def _excluded_save_params(self) -> list[str]:
        return super()._excluded_save_params() + ["_episodes", "dataset"]

    def _get_torch_save_params(self) -> tuple[list[str], list[str]]:
        return ["policy", "policy.optimizer"], []

    def epochs_per_learn(self) -> int:
        """Epochs of one ``learn`` call: ``n_epochs``, or enough for ``default_updates`` steps."""
        if self.n_epochs is not None:
            return self.n_epochs
        batches = -(-self.dataset.size() // self.batch_size) if self.dataset is not None else 1
        return max(1, -(-self.default_updates // batches))

    def loss(self, observations: Any, actions: th.Tensor) -> th.Tensor:
        """MSE between the policy's mean action and the (scaled) demonstration actions."""
        return F.mse_loss(self.policy.mean_action(observations), actions)

    def learn(self, total_timesteps: int = 0, callback: Any = None, log_interval: int = 1, tb_log_name: str = "BC",
              reset_num_timesteps: bool = True, progress_bar: bool = False, *, epochs: int | None = None) -> "BC":
        """Run ``epochs`` epochs over the demonstrations; by default :meth:`epochs_per_learn`, of
        which a continuing call (``reset_num_timesteps=False``) runs only those not run yet.

        ``total_timesteps`` is accepted for harness compatibility and ignored (BC is offline): a
        harness that calls ``learn`` once per curve point trains the configured updates in all,
        however many curve points there are.
        """
        if self.dataset is None:
            raise RuntimeError("BC has no demonstrations; pass demonstrations= or call set_demonstrations()")
        if reset_num_timesteps:
            self._epochs_done = 0
        if epochs is not None:
            n_epochs = int(epochs)
        else:
            n_epochs = max(0, self.epochs_per_learn() - self._epochs_done)
        _, callback = self._setup_learn(0, callback, reset_num_timesteps, tb_log_name, progress_bar)
        callback.on_training_start(locals(), globals())
        self.policy.set_training_mode(True)
        n = self.dataset.size()
        start = time.time()
        for epoch in range(n_epochs):
            self._update_current_progress_remaining(epoch, max(n_epochs, 1))
            self._update_learning_rate(self.policy.optimizer)
            perm = np.random.permutation(n)
            losses = []  # tensors, read once per epoch
            for i in range(0, n, self.batch_size):
                data = self.dataset._get_samples(perm[i:i + self.batch_size])
                obs = augment_observations(data.observations, self._aug_keys, self.aug_pad)
                loss = self.loss(obs, data.actions)
                self.policy.optimizer.zero_grad()
                loss.backward()
                self.policy.optimizer.step()
                losses.append(loss.detach())
            self._n_updates += len(losses)
            self._epochs_done += 1
            self.logger.record("train/epoch", epoch + 1)
            self.logger.record("train/bc_loss", float(th.stack(losses).double().mean()))
            self.logger.record("train/n_updates", self._n_updates)
            self.logger.record("time/elapsed_s", time.time() - start)
            if log_interval and (epoch + 1) % log_interval == 0:
                self.logger.dump(step=self._n_updates)
        self.policy.set_training_mode(False)
        callback.on_training_end()
        return self
