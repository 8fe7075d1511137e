"""lfd_envs: Gymnasium environments for robot learning from demonstrations.

Importing the package registers every env id, so both of these work::

    import gymnasium as gym
    env = gym.make("lfd_envs:ClothFoldDiagonal-v0")   # no prior import needed
    import lfd_envs; env = gym.make("ClothFoldDiagonal-v0")
"""

from lfd_envs.registration import ENV_SPECS, MUJOCO_ENV_IDS, PARTICLE_ENV_IDS, register_all

register_all()

__version__ = "0.1.0"
__all__ = ["ENV_SPECS", "PARTICLE_ENV_IDS", "MUJOCO_ENV_IDS", "register_all", "__version__"]
