"""Physical-plausibility checks of one world's particle-engine state (``set_state`` input).

The layout (keys, shapes, dtypes, finiteness) and the plain ranges (masses, radii, positions
within 100 m) are checked by :meth:`~lfd_envs.tasks.particle_batch.ParticleBatch.check_state`;
these checks refuse states no simulation of these scenes produces and that would send the
solver into a blow-up or an endless contact fight, each with a ``ValueError`` naming the key:

* particle speeds above :data:`SPEED_BOUND` (the engine clamps speeds to ``max_speed``, 10 m/s
  by default, before it projects constraints);
* particles more than :data:`BELOW_TABLE_TOLERANCE` below the table top ``z = 0`` (ground
  contacts keep every particle above it);
* rigid-box orientations that are not rotations (``box_quat`` not of norm 1, ``box_rot`` not
  orthonormal);
* rigid boxes that interpenetrate by more than :data:`BOX_OVERLAP_TOLERANCE` (a box placed inside
  another; boxes in contact overlap by at most a particle radius).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

#: largest accepted particle speed (m/s)
SPEED_BOUND = 1000.0
#: how far (m) below the table top ``z = 0`` a particle may be
BELOW_TABLE_TOLERANCE = 0.05
#: accepted deviation of a box quaternion's norm from 1 (and of ``box_rot`` from orthonormal)
ROTATION_TOLERANCE = 0.01
#: largest accepted interpenetration depth (m) of two rigid boxes
BOX_OVERLAP_TOLERANCE = 0.02

__all__ = ["check_particle_values", "check_boxes_apart", "box_overlap_depth", "SPEED_BOUND",
           "BELOW_TABLE_TOLERANCE", "BOX_OVERLAP_TOLERANCE"]


def check_particle_values(state: Mapping[str, np.ndarray]) -> None:
    """All checks of the module docstring on one world's engine state (keys without ``sim/``)."""
    speeds = np.linalg.norm(np.asarray(state["velocities"], np.float64), axis=-1)
    if speeds.size and speeds.max() > SPEED_BOUND:
        raise ValueError(f"state['sim/velocities']: particle speeds must be <= {SPEED_BOUND} m/s, "
                         f"got up to {float(speeds.max()):.3g} m/s")
    heights = np.asarray(state["positions"], np.float64)[:, 2]
    if heights.size and heights.min() < -BELOW_TABLE_TOLERANCE:
        raise ValueError(f"state['sim/positions']: particles must not lie more than {BELOW_TABLE_TOLERANCE} m "
                         f"below the table top z = 0, got z = {float(heights.min()):.3g} m "
                         f"({int(np.sum(heights < -BELOW_TABLE_TOLERANCE))} particles)")
    check_box_rotations(np.asarray(state["box_quat"], np.float64), np.asarray(state["box_rot"], np.float64))
    check_boxes_apart("sim/box_pos", np.asarray(state["box_pos"], np.float64),
                      np.asarray(state["box_rot"], np.float64),
                      np.asarray(state["box_half_extents"], np.float64))


def check_box_rotations(quats: np.ndarray, rots: np.ndarray) -> None:
    """``box_quat`` rows are unit quaternions and ``box_rot`` matrices orthonormal."""
    if quats.size == 0:
        return
    norms = np.linalg.norm(quats, axis=-1)
    bad = np.abs(norms - 1.0) > ROTATION_TOLERANCE
    if np.any(bad):
        raise ValueError(f"state['sim/box_quat'] must hold unit quaternions (norm 1 +- {ROTATION_TOLERANCE}), "
                         f"got norm {float(norms[bad][0])} for box {int(np.flatnonzero(bad)[0])}")
    error = np.abs(np.einsum("bki,bkj->bij", rots, rots) - np.eye(3)).max(axis=(1, 2))
    if np.any(error > ROTATION_TOLERANCE):
        raise ValueError(f"state['sim/box_rot'] must hold rotation matrices (orthonormal), box "
                         f"{int(np.argmax(error))} is off by {float(error.max())}")


def box_overlap_depth(c0: np.ndarray, r0: np.ndarray, h0: np.ndarray, c1: np.ndarray, r1: np.ndarray,
                      h1: np.ndarray) -> float:
    """Interpenetration depth (m) of two oriented boxes (centre, rotation whose columns are the
    local axes, half extents): the smallest overlap of their projections over the 15
    separating-axis candidates; ``<= 0`` when they are apart."""
    axes = [r0[:, i] for i in range(3)] + [r1[:, i] for i in range(3)]
    axes += [np.cross(r0[:, i], r1[:, j]) for i in range(3) for j in range(3)]
    d = c1 - c0
    depth = np.inf
    for axis in axes:
        n = float(np.linalg.norm(axis))
        if n < 1e-9:  # parallel edges: the face axes already cover this direction
            continue
        a = axis / n
        reach = np.abs(r0.T @ a) @ h0 + np.abs(r1.T @ a) @ h1
        depth = min(depth, reach - abs(float(d @ a)))
    return float(depth)


def check_boxes_apart(key: str, centers: np.ndarray, rots: np.ndarray, half_extents: np.ndarray) -> None:
    """``ValueError`` naming ``key`` if two boxes interpenetrate by more than
    :data:`BOX_OVERLAP_TOLERANCE`."""
    for i in range(len(centers)):
        for j in range(i + 1, len(centers)):
            depth = box_overlap_depth(centers[i], rots[i], half_extents[i], centers[j], rots[j], half_extents[j])
            if depth > BOX_OVERLAP_TOLERANCE:
                raise ValueError(f"state[{key!r}]: rigid boxes {i} and {j} interpenetrate by {depth:.3f} m "
                                 f"(at most {BOX_OVERLAP_TOLERANCE} m is accepted)")
