"""lfd_envs: Gymnasium environments for robot learning from demonstrations.

Importing the package registers every env id, so both of these work::

    import gymnasium as gym
    env = gym.make("lfd_envs:ClothFoldDiagonal-v0")   # no prior import needed
    import lfd_envs; env = gym.make("ClothFoldDiagonal-v0")

Every particle task also has a ``-v1`` id, recommended for new work: the same env class with
``physics="flex_like"``, engine settings closer to FleX (:mod:`lfd_envs.physics`,
:data:`FLEX_LIKE_SIM_OPTIONS`: colliding pickers, small solver steps without tethers, 1 cm
thickness; 1 m/s pick-and-place). The ``-v0`` ids (``physics="fast"``) are faster and carry the
results measured on them.
"""

from lfd_envs.registration import (ENV_SPECS, FLEX_LIKE_PICK_PLACE_SPEED, FLEX_LIKE_SIM_OPTIONS, MUJOCO_ENV_IDS,
                                   PARTICLE_ENV_IDS, register_all)

register_all()

__version__ = "0.1.0"
__all__ = ["ENV_SPECS", "PARTICLE_ENV_IDS", "MUJOCO_ENV_IDS", "FLEX_LIKE_SIM_OPTIONS", "FLEX_LIKE_PICK_PLACE_SPEED",
           "register_all", "__version__"]
