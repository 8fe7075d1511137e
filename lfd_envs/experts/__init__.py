"""Scripted experts (oracles) for every task.

``make_expert(env)`` returns an object with the SB3 policy interface::

    expert = make_expert(env)
    obs, info = env.reset(seed=0)
    action, _ = expert.predict(obs, deterministic=True)

Experts notice a new episode by themselves (the env's ``episode_count``, see
:mod:`lfd_envs.experts.episodes`); ``expert.reset()`` is still allowed.

Experts may read the privileged simulator state of ``env.unwrapped``; they work for every
picker count and action mode their task supports (see each expert's docstring).
"""

from __future__ import annotations

import importlib
from typing import Any, Protocol

import gymnasium as gym
import numpy as np

#: env class name -> "module:ExpertClass"
EXPERTS: dict[str, str] = {
    "StraightenRopeEnv": "lfd_envs.experts.rope:StraightenRopeExpert",
    "ClothFoldEnv": "lfd_envs.experts.cloth_fold:ClothFoldExpert",
    "ClothFoldDiagonalEnv": "lfd_envs.experts.cloth_fold_diagonal:ClothFoldDiagonalExpert",
    "DryClothEnv": "lfd_envs.experts.dry_cloth:DryClothExpert",
    "ThreeBoxesEnv": "lfd_envs.experts.three_boxes:ThreeBoxesExpert",
    "Push2DObstacleEnv": "lfd_envs.experts.push2d:Push2DExpert",
    "SawyerPushObstacleEnv": "lfd_envs.experts.sawyer:SawyerPushExpert",
    "SawyerLiftObstacleEnv": "lfd_envs.experts.sawyer:SawyerLiftExpert",
    "SawyerAssemblyObstacleEnv": "lfd_envs.experts.sawyer:SawyerAssemblyExpert",
    "NistBoardInsertEnv": "lfd_envs.experts.nist:NistInsertExpert",
}


class Expert(Protocol):
    """What :func:`make_expert` returns."""

    def reset(self) -> None: ...

    def predict(self, observation: Any, state: Any = None, episode_start: Any = None,
                deterministic: bool = True) -> tuple[np.ndarray, None]: ...


def make_expert(env: gym.Env, **kwargs: Any) -> Expert:
    """Scripted expert for ``env`` (a made env, wrappers allowed)."""
    base = env.unwrapped
    for cls in type(base).__mro__:
        target = EXPERTS.get(cls.__name__)
        if target is not None:
            module, name = target.split(":")
            return getattr(importlib.import_module(module), name)(env, **kwargs)
    raise ValueError(f"no scripted expert for {type(base).__name__}; experts exist for {sorted(EXPERTS)}")


__all__ = ["make_expert", "Expert", "EXPERTS"]
