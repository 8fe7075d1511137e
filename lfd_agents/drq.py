"""DrQ: SAC from pixels regularised by image augmentation (Kostrikov, Yarats and Fergus, 2020).

SAC with one encoder for actor and critic (trained by the critic only) and random shifts of
±``aug_pad`` pixels (replicate-pad and crop back): the critic's target is averaged over K
shifts of the next observation and its loss over M shifts of the observation (K = M = 2):

    y = 1/K Σ_k [r + γ(1 − d)(min_i Q'_i(aug_k(s'), a'_k) − α log π(a'_k | aug_k(s')))]
        with a'_k ~ π(·|aug_k(s'))
    L_Q = 1/M Σ_m ½ Σ_i (Q_i(aug_m(s), a) − y)²

The update machinery is :class:`lfd_agents.image_sac.ImageSAC`'s.

Example::

    from lfd_agents import DrQ
    model = DrQ("CnnPolicy", gym.make("lfd_envs:ClothFoldDiagonal-v0"), seed=0)
    model.learn(10_000)
"""

from __future__ import annotations

from typing import Any

from lfd_agents.image_sac import ImageSAC


class DrQ(ImageSAC):
    """DrQ (module docstring): :class:`~lfd_agents.image_sac.ImageSAC` with K = M = 2.

    Args:
        policy, env: as for SB3 ``SAC`` (``"CnnPolicy"`` or ``"MultiInputPolicy"``).
        n_target_augs: K, shifts of the next observation averaged in the target (2).
        n_q_augs: M, shifts of the observation averaged in the Q loss (2).
        aug_pad: maximal shift in pixels (2 for 32×32 images; DrQ: 4 for 84×84).
        **kwargs: every other :class:`~lfd_agents.image_sac.ImageSAC` / SB3 ``SAC`` argument.
    """

    def __init__(self, policy: Any, env: Any, n_target_augs: int = 2, n_q_augs: int = 2, aug_pad: int = 2,
                 **kwargs: Any):
        super().__init__(policy, env, n_target_augs=n_target_augs, n_q_augs=n_q_augs, aug_pad=aug_pad, **kwargs)
