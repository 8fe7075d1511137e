"""Nothing leaves the scene: held objects cannot be pressed through the table, particles caught
inside a static box leave it above the table, and random delta actions never push anything
under the table or into a static box (checked every frame)."""

from __future__ import annotations

import numpy as np
import pytest

from tools.escapes import check_task, static_box_depth
from lfd_envs.sim import ParticleSim, SceneBuilder, SimParams


def test_grasped_box_pressed_into_the_table_stays_on_it_and_is_not_launched():
    b = SceneBuilder()
    box = b.add_rigid_box(center=(0, 0, 0.05), half_extents=(0.08, 0.05, 0.05), mass=0.1)
    sim = ParticleSim(b, params=SimParams(grasp_mode="radius", grasp_radius=0.03), num_pickers=1)
    sim.set_picker_positions(np.array([[[0.0, 0.0, 0.3]]]))
    for _ in range(20):
        sim.step(np.array([[[0.0, 0.0, 0.3]]]), np.zeros((1, 1), bool))
    top = sim.positions[0][box.indices][:, 2].max()
    pos = np.array([0.0, 0.0, top])
    sim.set_picker_positions(pos[None, None])
    for _ in range(30):  # keep pressing down, 1 cm per frame: commanded 20 cm below the table in the end
        pos = pos - np.array([0.0, 0.0, 0.01])
        sim.step(pos[None, None], np.ones((1, 1), bool))
        assert sim.attached.max() == 0
        assert sim.positions[0][:, 2].min() >= 0.0
    assert sim.picker_positions[0, 0, 2] > top - 0.01  # the table stopped the picker
    for _ in range(50):
        sim.step(sim.picker_positions, np.zeros((1, 1), bool))
    q, v = sim.positions[0], sim.velocities[0]
    assert q[:, 2].min() >= 0.0 and q[:, 2].max() < top + 0.01  # released where it was, not thrown
    assert np.abs(v).max() < 0.05


def test_held_cloth_particle_is_not_pressed_under_the_table():
    b = SceneBuilder()
    cloth = b.add_cloth(8, 8, 0.2, 0.2, center=(0, 0, 0.01))
    sim = ParticleSim(b, params=SimParams(grasp_radius=0.05), num_pickers=1)
    start = sim.positions[0][cloth.index(4, 4)].astype(np.float64) + [0.0, 0.0, 0.04]
    sim.set_picker_positions(start[None, None])
    sim.step(start[None, None], np.ones((1, 1), bool))
    held = int(np.argmax(sim.attached[0] >= 0))
    for k in range(20):
        sim.step((start - [0.0, 0.0, 0.01 * (k + 1)])[None, None], np.ones((1, 1), bool))
    clearance = sim.held_clearance()[0, 0]
    assert abs(clearance) < 1e-4  # the held particle rests on the table, the picker stopped there
    assert sim.positions[0][held, 2] > 0.0
    assert np.isinf(ParticleSim(b, num_pickers=1).held_clearance()).all()  # nothing held


def test_particles_inside_a_sunk_static_box_leave_above_the_table():
    """A box sunk 2 cm into the table (the diagonal fold's pin block): its nearest face for a
    particle caught low inside it is the bottom one, under the table; it must leave elsewhere."""
    b = SceneBuilder()
    b.add_static_box(center=(0.25, 0.25, 0.02), half_extents=(0.1, 0.1, 0.04))
    b.add_rope(3, 0.02, start=(0.0, 0.0, 0.01), direction=(1, 0, 0))
    sim = ParticleSim(b, num_pickers=0)
    sim.set_particles(0, [[0.23, 0.25, 0.005], [0.24, 0.25, 0.005], [0.25, 0.25, 0.005]])
    for _ in range(5):
        sim.step(np.zeros((1, 0, 3)))
        q = sim.positions
        assert q[..., 2].min() > 0.0
        assert static_box_depth(q, sim.static_boxes).max() <= 1e-5


@pytest.mark.parametrize("env_id", ["StraightenRope-v0", "ClothFold-v0", "ClothFoldDiagonalPinned-v0",
                                    "ClothFoldDiagonalUnpinned-v0", "DryCloth-v0", "ThreeBoxes-v0",
                                    "StraightenRope-v1", "ThreeBoxes-v1"])
def test_random_delta_actions_never_escape(env_id):
    r = check_task(env_id, steps=240, worlds=3, seed=1)
    assert r["frames"] >= 240  # every frame of every world checked
    assert r["escaped"] == 0, r
