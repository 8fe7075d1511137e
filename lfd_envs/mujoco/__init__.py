"""MuJoCo tasks: obstructed manipulation (MoPA-RL scenes) and the NIST board (SPEC §5).

Shared machinery:

* :mod:`lfd_envs.mujoco.rendering` -- headless OpenGL backend choice (EGL, else OSMesa) and
  renderer creation. Importing this package configures ``MUJOCO_GL`` *before* ``mujoco``
  is imported, so do not import ``mujoco`` ahead of ``lfd_envs.mujoco`` if you rely on it.
* :mod:`lfd_envs.mujoco.base` -- :class:`~lfd_envs.mujoco.base.MujocoEnv`, the base env
  (model loading, joint-position-delta servo control, start-pose noise, observation modes,
  goal-conditioned ``GoalEnv`` variant, state save/restore, rendering).
* :mod:`lfd_envs.mujoco.planning` -- :class:`~lfd_envs.mujoco.planning.PlanningMixin`, the
  planning interface of every obstructed env (collision checking on a private ``MjData``,
  joint-path execution).

Tasks: :mod:`~lfd_envs.mujoco.push2d` (``Push2DObstacle-v0``) and the Sawyer tasks.
"""

from lfd_envs.mujoco.rendering import configure_gl_backend

configure_gl_backend()

__all__ = ["configure_gl_backend"]
