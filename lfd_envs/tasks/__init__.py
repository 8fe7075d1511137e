"""Particle tasks (Warp engine): rope, cloth folds and the shared batched machinery.

Modules: :mod:`~lfd_envs.tasks.particle_task` (what a task describes),
:mod:`~lfd_envs.tasks.picker_actions` (delta / pick-and-place actions),
:mod:`~lfd_envs.tasks.particle_batch` (W worlds in one engine),
:mod:`~lfd_envs.tasks.particle_env` (single and vector Gymnasium envs),
:mod:`~lfd_envs.tasks.cloth_task` (shared square-cloth parts), and one module per task.
Nothing heavy is imported here; ``gymnasium.make`` imports the task module it needs.
"""

from lfd_envs import _warp  # noqa: E402,F401  (quiet Warp before it initialises)
