"""Warp particle engine: position-based cloth, rope and rigid boxes with pickers, batched worlds.

Public API::

    from lfd_envs.sim import SimParams, SceneBuilder, ParticleSim
    b = SceneBuilder(); cloth = b.add_cloth(40, 40, 0.75, 0.75, center=(0, 0, 0.05))
    sim = ParticleSim(b, num_worlds=4, params=SimParams(), num_pickers=2)
    sim.step(picker_targets, grasp)   # (W, P, 3), (W, P)
    sim.step_frames(targets, grasps)  # (F, W, P, 3), (F, W, P): F frames, same bits as F steps
"""

from lfd_envs import _warp  # noqa: F401  (quiet Warp before first use)
from .builder import (BEND, SHEAR, STRETCH, ClothHandle, RigidBoxHandle, RopeHandle, SceneBuilder,
                      StaticBox)
from .engine import ParticleSim
from .params import GRASP_MODES, GRASP_TRIGGERS, SimParams

__all__ = [
    "SimParams",
    "GRASP_MODES",
    "GRASP_TRIGGERS",
    "SceneBuilder",
    "ClothHandle",
    "RopeHandle",
    "RigidBoxHandle",
    "StaticBox",
    "ParticleSim",
    "STRETCH",
    "SHEAR",
    "BEND",
]
