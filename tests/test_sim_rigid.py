"""Particle engine: rigid boxes (shape matching) carried by pickers and stacked."""

from __future__ import annotations

import numpy as np

from lfd_envs.sim import ParticleSim, SceneBuilder, SimParams


def _pairwise(q: np.ndarray) -> np.ndarray:
    return np.linalg.norm(q[:, None] - q[None], axis=-1)


def _inside_obb(points, center, rot, he, shrink):
    local = (points - center) @ rot
    return np.all(np.abs(local) < he - shrink, axis=1)


def test_carried_box_moves_rigidly():
    b = SceneBuilder()
    box = b.add_rigid_box(center=(0, 0, 0.05), half_extents=(0.05, 0.05, 0.05), mass=0.2)
    sim = ParticleSim(b, params=SimParams(grasp_mode="radius", grasp_radius=0.03), num_pickers=1)
    for _ in range(20):
        sim.step(np.array([[[0.0, 0.0, 0.3]]]), np.zeros((1, 1), bool))
    q0 = sim.positions[0][box.indices]
    top = q0[np.argmax(q0[:, 2])]
    pick = np.array([0.0, 0.0, q0[:, 2].max()])
    sim.set_picker_positions(pick[None, None])
    pos = pick.copy()
    for k in range(60):
        pos = pos + (np.array([0.0, 0.0, 0.01]) if k < 20 else np.array([0.02, 0.01, 0.0]))
        sim.step(pos[None, None], np.ones((1, 1), bool))
    q = sim.positions[0][box.indices]
    assert q[:, 2].min() > 0.1  # lifted
    assert np.abs(_pairwise(q) - _pairwise(q0)).max() < 2e-3  # rigid
    c, r = sim.rigid_box_poses()
    assert np.allclose(r[0, 0] @ r[0, 0].T, np.eye(3), atol=1e-4)
    # the reported pose reproduces the particles
    rest = b._export()["rest"][box.indices]
    assert np.abs(rest @ r[0, 0].T + c[0, 0] - q).max() < 2e-3
    assert top is not None


def test_boxes_dropped_on_each_other_do_not_interpenetrate():
    b = SceneBuilder()
    b.add_rigid_box(center=(0, 0, 0.05), half_extents=(0.08, 0.05, 0.05), mass=0.3)
    b.add_rigid_box(center=(0.03, 0.01, 0.25), half_extents=(0.05, 0.04, 0.03), yaw=0.5, mass=0.1)
    b.add_rigid_box(center=(0.2, 0.0, 0.3), half_extents=(0.02, 0.02, 0.02), yaw=0.2, mass=0.05)
    sim = ParticleSim(b, num_pickers=0)
    he = sim.rigid_box_half_extents[0]
    ex = b._export()
    starts, counts = ex["rigid_start"], ex["rigid_count"]
    worst = 0.0
    for k in range(150):
        sim.step(np.zeros((1, 0, 3)))
        if k % 10 == 9:
            c, r = sim.rigid_box_poses()
            q = sim.positions[0]
            for a in range(3):
                for o in range(3):
                    if a == o:
                        continue
                    pts = q[starts[o]:starts[o] + counts[o]]
                    local = np.abs((pts - c[0, a]) @ r[0, a]) - he[a]
                    depth = -local.max(axis=1)  # > 0: inside box a
                    worst = max(worst, float(depth.max()))
    assert worst < 3e-3, worst
    c, _ = sim.rigid_box_poses()
    assert abs(c[0, 1, 2] - (0.1 + 0.03)) < 3e-3  # box 1 rests on box 0
    assert abs(c[0, 2, 2] - 0.02) < 3e-3  # box 2 rests on the ground
    assert np.all(sim.positions[0][:, 2] > -1e-4)


def test_box_pushed_into_another_box():
    """ThreeBoxes-style: a grasped box is dragged into a second one, which gets pushed."""
    b = SceneBuilder()
    b.add_rigid_box(center=(0, 0, 0.05), half_extents=(0.05, 0.05, 0.05), mass=0.2)
    b.add_rigid_box(center=(0.2, 0.01, 0.08), half_extents=(0.08, 0.08, 0.08), mass=0.3)
    sim = ParticleSim(b, params=SimParams(grasp_mode="radius", grasp_radius=0.06), num_pickers=1)
    pos = np.array([0.0, 0.0, 0.05])
    sim.set_picker_positions(pos[None, None])
    he = sim.rigid_box_half_extents[0]
    for k in range(40):
        pos = pos + np.array([0.01, 0.0, 0.0])
        sim.step(pos[None, None], np.ones((1, 1), bool))
        c, r = sim.rigid_box_poses()
        q = sim.positions[0]
        ex = b._export()
        s1, n1 = ex["rigid_start"][0], ex["rigid_count"][0]
        local = np.abs((q[s1:s1 + n1] - c[0, 1]) @ r[0, 1]) - he[1]
        assert (-local.max(axis=1)).max() < 5e-3
    c, _ = sim.rigid_box_poses()
    assert c[0, 1, 0] > 0.25  # the second box was pushed


def test_state_round_trip_with_grasped_box():
    b = SceneBuilder()
    b.add_rigid_box(center=(0, 0, 0.05), half_extents=(0.05, 0.05, 0.05))
    b.add_rigid_box(center=(0.15, 0, 0.05), half_extents=(0.04, 0.04, 0.04))
    b.add_cloth(5, 5, 0.2, 0.2, center=(0, 0.25, 0.01))
    sim = ParticleSim(b, params=SimParams(grasp_mode="radius", grasp_radius=0.06), num_pickers=1)
    pos = np.array([[[0.0, 0.0, 0.1]]])
    sim.set_picker_positions(pos)
    for _ in range(10):
        pos = pos + [0.01, 0.0, 0.005]
        sim.step(pos, np.ones((1, 1), bool))
    st = sim.get_state()
    acts = [(pos + [0.01 * k, 0.0, 0.0], np.array([[k < 5]])) for k in range(15)]
    for p, g in acts:
        sim.step(p, g)
    a = sim.positions
    ca, _ = sim.rigid_box_poses()
    sim.set_state(st)
    for p, g in acts:
        sim.step(p, g)
    cb, _ = sim.rigid_box_poses()
    assert np.array_equal(a, sim.positions) and np.array_equal(ca, cb)
