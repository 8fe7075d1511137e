"""Test helper: steer the single picker of a delta-mode particle env towards a point."""

import numpy as np


def steer_picker(env, target, steps: int, grasp: bool = True) -> None:
    """``steps`` delta actions moving picker 0 straight at ``target`` (full speed, clipped),
    with the grasp flag on (``grasp``) or off."""
    u = env.unwrapped
    reach = u.picker_actions.step_size * u.picker_actions.action_repeat  # metres per step at |a| = 1
    for _ in range(steps):
        move = np.clip((np.asarray(target) - u.picker_positions[0]) / reach, -1, 1)
        env.step(np.r_[move, 1.0 if grasp else -1.0].astype(np.float32))
