"""CURL: SAC from pixels with a contrastive auxiliary loss (Laskin, Srinivas and Abbeel, 2020).

The critic's encoder is the query encoder; the target critic's encoder is the momentum key
encoder (Polyak-averaged towards the query encoder with ``encoder_tau``, never trained by
gradient). After every critic step, the query encoder and a bilinear matrix W take a step on

    logits_ij = q_i^T W k_j − max_j(q_i^T W k_j),  L = CrossEntropy(logits, labels = i)

where q_i encodes one random crop (shift) of observation i (the crop the critic saw) and k_j a
second, independent crop of observation j through the key encoder: the positive pair of anchor
i is the diagonal entry, the other observations of the batch are its negatives (InfoNCE). The
actor reads the query encoder without gradient. Crops are random shifts of ±``aug_pad`` pixels
(for 32×32 images; CURL crops 84×84 out of 100×100).
"""

from __future__ import annotations

from typing import Any, ClassVar

import torch as th
import torch.nn.functional as F
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.type_aliases import ReplayBufferSamples, Schedule
from torch import nn

from lfd_agents.image_sac import ImageSAC, SharedEncoderSACPolicy
from lfd_agents.networks import DictPolicyDefaults, ImagePolicyDefaults


def contrastive_logits(queries: th.Tensor, keys: th.Tensor, w: th.Tensor) -> th.Tensor:
    """CURL's bilinear logits ``q_i^T W k_j`` minus each row's maximum, shape (B, B); the
    positive pair of row i is column i."""
    logits = queries @ w @ keys.t()
    return logits - logits.max(dim=1, keepdim=True).values


def contrastive_loss(queries: th.Tensor, keys: th.Tensor, w: th.Tensor) -> th.Tensor:
    """InfoNCE: cross-entropy of :func:`contrastive_logits` with the diagonal as labels."""
    logits = contrastive_logits(queries, keys, w)
    return F.cross_entropy(logits, th.arange(logits.shape[0], device=logits.device))


class CURLPolicy(SharedEncoderSACPolicy):
    """:class:`~lfd_agents.image_sac.SharedEncoderSACPolicy` plus CURL's bilinear matrix ``W``
    (features_dim × features_dim, uniform in [0, 1) at start as in CURL)."""

    def _build(self, lr_schedule: Schedule) -> None:
        super()._build(lr_schedule)
        dim = self.critic.features_extractor.features_dim
        self.contrastive_w = nn.Parameter(th.rand(dim, dim))


class CURLCnnPolicy(ImagePolicyDefaults, CURLPolicy):
    """:class:`CURLPolicy` for images."""


class CURLMultiInputPolicy(DictPolicyDefaults, CURLPolicy):
    """:class:`CURLPolicy` for Dict observations with images."""


class CURL(ImageSAC):
    """CURL (module docstring), SB3 ``SAC`` API.

    Args:
        policy, env: as for SB3 ``SAC`` (``"CnnPolicy"`` or ``"MultiInputPolicy"``).
        encoder_tau: Polyak coefficient of the key encoder (0.05, CURL's).
        contrastive_lr: Adam learning rate of the contrastive step (query encoder and W; 1e-3).
        aug_pad: maximal shift of a crop in pixels (2).
        **kwargs: every other :class:`~lfd_agents.image_sac.ImageSAC` / SB3 ``SAC`` argument.
    """

    policy_aliases: ClassVar[dict[str, type[BasePolicy]]] = {
        "CnnPolicy": CURLCnnPolicy, "MultiInputPolicy": CURLMultiInputPolicy}
    policy: CURLPolicy
    _aux_log_key = "contrastive_loss"

    def __init__(self, policy: Any, env: Any, encoder_tau: float = 0.05, contrastive_lr: float = 1e-3,
                 aug_pad: int = 2, **kwargs: Any):
        if not float(contrastive_lr) > 0:
            raise ValueError(f"contrastive_lr must be > 0, got {contrastive_lr!r}")
        self.contrastive_lr = float(contrastive_lr)
        super().__init__(policy, env, encoder_tau=encoder_tau, aug_pad=aug_pad, **kwargs)

    def _setup_model(self) -> None:
        super()._setup_model()
        params = list(self.critic.features_extractor.parameters()) + [self.policy.contrastive_w]
        self.contrastive_optimizer = th.optim.Adam(params, lr=self.contrastive_lr)

    def _get_torch_save_params(self) -> tuple[list[str], list[str]]:
        state_dicts, tensors = super()._get_torch_save_params()
        return state_dicts + ["contrastive_optimizer"], tensors

    def contrastive_loss(self, obs_anchor: Any, obs_positive: Any) -> th.Tensor:
        """InfoNCE of query codes of ``obs_anchor`` against key codes of ``obs_positive``."""
        queries = self.critic.features(obs_anchor)
        with th.no_grad():
            keys = self.critic_target.features(obs_positive)
        return contrastive_loss(queries, keys, self.policy.contrastive_w)

    def auxiliary_update(self, data: ReplayBufferSamples, obs_augs: Any) -> th.Tensor:
        b = data.actions.shape[0]
        anchor = {k: v[:b] for k, v in obs_augs.items()} if isinstance(obs_augs, dict) else obs_augs[:b]
        loss = self.contrastive_loss(anchor, self.augment(data.observations, 1))
        self.contrastive_optimizer.zero_grad(set_to_none=True)
        loss.backward()
        self.contrastive_optimizer.step()
        return loss
