"""Pickers as sphere colliders (``SimParams(picker_collision=True)``): they push cloth and boxes,
do not pass through them at the top delta-action speed (1 cm per frame), still grasp, and
touch nothing with the option off."""

from __future__ import annotations

import numpy as np
import pytest

from lfd_envs.sim import ParticleSim, SceneBuilder, SimParams

PICKER_RADIUS = 0.05


def _trampoline(collide: bool) -> tuple[ParticleSim, object]:
    b = SceneBuilder()
    c = b.add_cloth(21, 21, 0.6, 0.6, center=(0, 0, 0.3))
    b.pin([c.index(0, 0), c.index(0, 20), c.index(20, 0), c.index(20, 20)])
    sim = ParticleSim(b, params=SimParams(picker_collision=collide, picker_radius=PICKER_RADIUS), num_pickers=1)
    for _ in range(100):  # let it sag
        sim.step(np.array([[[0.0, 0.0, 0.1]]]), np.zeros((1, 1), bool))
    return sim, c


@pytest.mark.parametrize("collide", [False, True])
def test_picker_rising_under_a_hanging_cloth_lifts_it_only_as_a_collider(collide):
    sim, cloth = _trampoline(collide)
    sag = sim.positions[0][cloth.index(10, 10), 2]
    pos = np.array([0.0, 0.0, 0.1])
    sim.set_picker_positions(pos[None, None])
    for _ in range(30):  # 1 cm per frame, up to 17 cm above the sagging centre
        pos = pos + [0.0, 0.0, 0.01]
        sim.step(pos[None, None], np.zeros((1, 1), bool))
        if collide:
            gap = np.linalg.norm(sim.positions[0] - pos, axis=1).min()
            assert gap > PICKER_RADIUS + 0.005, gap  # never inside the sphere (particle radius 6.25 mm)
    centre = sim.positions[0][cloth.index(10, 10), 2]
    if collide:
        assert centre > pos[2] + PICKER_RADIUS  # carried on top of the sphere, not passed through
    else:
        assert abs(centre - sag) < 0.01  # the sphere went through without touching it


def test_colliding_picker_still_grasps_and_lifts_the_cloth():
    b = SceneBuilder()
    c = b.add_cloth(16, 16, 0.3, 0.3, center=(0, 0, 0.01))
    sim = ParticleSim(b, params=SimParams(picker_collision=True, picker_radius=PICKER_RADIUS), num_pickers=1)
    pos = np.array([0.0, 0.0, 0.2])
    sim.set_picker_positions(pos[None, None])
    for _ in range(20):  # lowered with the flag on (SoftGym's rule): grasps on contact
        pos[2] = max(PICKER_RADIUS, pos[2] - 0.01)
        sim.step(pos[None, None], np.ones((1, 1), bool))
    assert (sim.attached[0] >= 0).sum() == 1
    for _ in range(30):
        pos[2] += 0.01
        sim.step(pos[None, None], np.ones((1, 1), bool))
    assert sim.positions[0][:, 2].max() > 0.2


def test_colliding_picker_pushes_a_box():
    b = SceneBuilder()
    box = b.add_rigid_box(center=(0.0, 0, 0.05), half_extents=(0.05, 0.05, 0.05), mass=0.1)
    sim = ParticleSim(b, params=SimParams(picker_collision=True, picker_radius=0.02), num_pickers=1)
    for _ in range(20):
        sim.step(np.array([[[-0.2, 0.0, 0.05]]]), np.zeros((1, 1), bool))
    x0 = sim.positions[0][box.indices][:, 0].mean()
    pos = np.array([-0.2, 0.0, 0.05])
    sim.set_picker_positions(pos[None, None])
    for _ in range(30):  # 1 cm per frame into the box, 15 cm past its near face
        pos = pos + [0.01, 0.0, 0.0]
        sim.step(pos[None, None], np.zeros((1, 1), bool))
    q = sim.positions[0][box.indices]
    assert q[:, 0].mean() - x0 > 0.15  # pushed along (the picker went 17.5 cm past first contact)
    assert np.linalg.norm(q - pos, axis=1).min() > 0.02


def test_colliding_picker_cannot_press_a_box_into_the_table():
    b = SceneBuilder()
    b.add_rigid_box(center=(0.0, 0, 0.05), half_extents=(0.05, 0.05, 0.05), mass=0.1)
    sim = ParticleSim(b, params=SimParams(picker_collision=True, picker_radius=0.02), num_pickers=1)
    pos = np.array([0.01, 0.0, 0.2])
    sim.set_picker_positions(pos[None, None])
    for _ in range(30):  # 1 cm per frame down to the table (a picker stays its radius above it)
        pos[2] = max(0.02, pos[2] - 0.01)
        sim.step(pos[None, None], np.zeros((1, 1), bool))
        assert sim.positions[0][:, 2].min() > 0.0
    assert abs(sim.picker_positions[0, 0, 2] - 0.12) < 2e-3  # stopped on the box top (0.1 + its radius)
    assert abs(sim.rigid_box_poses()[0][0, 0, 2] - 0.05) < 2e-3


def test_particle_squeezed_between_picker_and_table_is_not_shot_away():
    """A colliding picker pressed onto a rope end lying on the table squeezes it sideways out of
    the gap. The push is a position projection; without the inelastic contact handling it became
    a velocity of push / substep (2.3 m/s here with a picker descending at 0.5 m/s, and rope ends
    shot 0.2 m across the table by pick-and-place moves); with it nothing moves much faster than
    the picker."""
    from lfd_envs import FLEX_LIKE_SIM_OPTIONS

    params = SimParams(**{**FLEX_LIKE_SIM_OPTIONS, "picker_radius": 0.02, "particle_radius": 0.0125})
    b = SceneBuilder()
    rope = b.add_rope(21, 0.5, start=(-0.25, 0.0, 0.0125), direction=(1.0, 0.0, 0.0))
    sim = ParticleSim(b, params=params, num_pickers=1)
    for _ in range(30):  # settle, picker out of the way
        sim.step(np.array([[[0.0, 0.0, 0.3]]]), np.zeros((1, 1), bool))
    start = sim.positions[0][rope.indices[0]].astype(np.float64) + np.array([0.003, 0.0, 0.1])
    low = np.array([start[0], start[1], params.picker_radius])  # the picker touches the table
    sim.set_picker_positions(start[None, None])
    fastest = 0.0
    for p in [start + (low - start) * k / 20 for k in range(1, 21)] + [low] * 30:
        sim.step(p[None, None], np.zeros((1, 1), bool))
        fastest = max(fastest, float(np.linalg.norm(sim.velocities[0], axis=1).max()))
    assert fastest < 1.0, fastest
