"""Value checks of the MuJoCo part of a ``get_state()`` dict (magnitudes and quaternions).

``set_state`` first checks the layout (keys, shapes, dtypes, finiteness); these checks then
refuse values no simulation of these scenes produces, before anything is written, so that a
typo such as ``qpos[0] = 1e6`` or an all-zero quaternion raises a ``ValueError`` naming the key
instead of sending MuJoCo into a warning-and-reset or a blow-up. The bounds are generous (the
scenes are about 1 m across and the robots move at a few m/s):

* positions (``qpos`` entries that are not quaternions, ``mocap_pos``): ``|x| <= 100`` (m or rad);
* velocities (``qvel``): ``|v| <= 1000`` (m/s or rad/s);
* controls (``ctrl``): inside ``ctrlrange`` for limited actuators, else ``|u| <= 100``;
* applied forces and activations (``qfrc_applied``, ``xfrc_applied``, ``act``): ``|f| <= 1e6``;
* quaternions (of free and ball joints in ``qpos``, ``mocap_quat``): norm within 1 +- 0.01.
"""

from __future__ import annotations

from collections.abc import Mapping

import mujoco
import numpy as np

from lfd_envs.core.state import check_range

#: largest accepted |qpos| (non-quaternion entries) and |mocap_pos| (m or rad)
POSITION_BOUND = 100.0
#: largest accepted |qvel| (m/s or rad/s)
VELOCITY_BOUND = 1000.0
#: largest accepted |ctrl| of an actuator without a control range
CONTROL_BOUND = 100.0
#: largest accepted applied force/torque or activation
FORCE_BOUND = 1e6
#: accepted deviation of a quaternion's norm from 1
QUAT_NORM_TOLERANCE = 0.01

__all__ = ["check_mujoco_state", "POSITION_BOUND", "VELOCITY_BOUND", "CONTROL_BOUND", "FORCE_BOUND"]


def quaternion_slices(model: mujoco.MjModel) -> list[slice]:
    """``qpos`` slices holding the quaternions of free and ball joints."""
    out = []
    for j in range(model.njnt):
        adr = int(model.jnt_qposadr[j])
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            out.append(slice(adr + 3, adr + 7))
        elif model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL:
            out.append(slice(adr, adr + 4))
    return out


def check_quaternions(key: str, quats: np.ndarray) -> None:
    """``ValueError`` naming ``key`` unless every row of ``quats`` ``(..., 4)`` is a unit quaternion."""
    norms = np.linalg.norm(np.asarray(quats, np.float64).reshape(-1, 4), axis=1)
    bad = np.abs(norms - 1.0) > QUAT_NORM_TOLERANCE
    if np.any(bad):
        raise ValueError(f"state[{key!r}] must hold unit quaternions (norm 1 +- {QUAT_NORM_TOLERANCE}), "
                         f"got norm {float(norms[bad][0])}")


def check_qpos(model: mujoco.MjModel, qpos: np.ndarray) -> None:
    """Quaternion entries are unit quaternions, every other entry is within :data:`POSITION_BOUND`."""
    plain = np.ones(qpos.shape, bool)
    for sl in quaternion_slices(model):
        check_quaternions("sim/qpos", qpos[sl])
        plain[sl] = False
    check_range("sim/qpos", qpos[plain], -POSITION_BOUND, POSITION_BOUND)


def check_ctrl(model: mujoco.MjModel, ctrl: np.ndarray) -> None:
    """Limited actuators inside their ``ctrlrange``, the others within :data:`CONTROL_BOUND`."""
    limited = np.asarray(model.actuator_ctrllimited, bool)
    low, high = model.actuator_ctrlrange[:, 0], model.actuator_ctrlrange[:, 1]
    outside = limited & ((ctrl < low - 1e-9) | (ctrl > high + 1e-9))
    if np.any(outside):
        i = int(np.flatnonzero(outside)[0])
        raise ValueError(f"state['sim/ctrl'][{i}] must lie in the actuator's ctrlrange "
                         f"[{low[i]}, {high[i]}], got {float(ctrl[i])}")
    check_range("sim/ctrl", ctrl[~limited], -CONTROL_BOUND, CONTROL_BOUND)


def check_mujoco_state(model: mujoco.MjModel, sim: Mapping[str, np.ndarray]) -> None:
    """Check the MuJoCo fields present in ``sim`` (keys without the ``sim/`` prefix; layout
    already checked); ``ValueError`` naming the key."""
    if "qpos" in sim:
        check_qpos(model, np.asarray(sim["qpos"]))
    if "qvel" in sim:
        check_range("sim/qvel", sim["qvel"], -VELOCITY_BOUND, VELOCITY_BOUND)
    if "ctrl" in sim:
        check_ctrl(model, np.asarray(sim["ctrl"]))
    if "mocap_pos" in sim:
        check_range("sim/mocap_pos", sim["mocap_pos"], -POSITION_BOUND, POSITION_BOUND)
    if "mocap_quat" in sim:
        check_quaternions("sim/mocap_quat", sim["mocap_quat"])
    for key in ("act", "qfrc_applied", "xfrc_applied"):
        if key in sim:
            check_range(f"sim/{key}", sim[key], -FORCE_BOUND, FORCE_BOUND)
