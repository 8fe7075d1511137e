"""Particle engine: parameters, builder and input validation."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from lfd_envs.sim import ParticleSim, SceneBuilder, SimParams


def test_params_defaults_and_validation():
    p = SimParams()
    assert p.frame_dt == pytest.approx(0.01)
    assert p.substep_dt == pytest.approx(p.frame_dt / p.substeps)
    with pytest.raises(TypeError):
        SimParams(not_a_field=1)  # unknown field
    with pytest.raises(ValueError):
        SimParams(frame_dt=-0.01)
    with pytest.raises(ValueError):
        SimParams(substeps=0)
    with pytest.raises(ValueError):
        SimParams(stretch_stiffness=1.5)
    with pytest.raises(ValueError):
        SimParams(grasp_mode="magnet")
    with pytest.raises(ValueError):
        SimParams(particle_radius=float("nan"))
    with pytest.raises(TypeError):
        SimParams(iterations=2.5)
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.substeps = 3


def test_cloth_handle_topology():
    b = SceneBuilder()
    h = b.add_cloth(5, 4, 0.4, 0.3, center=(0.1, 0.2, 0.05), yaw=0.3)
    assert h.shape == (4, 5) and h.count == 20 and b.num_particles == 20
    assert h.triangles.shape == (2 * 4 * 3, 3)
    assert h.corners == (0, 4, 19, 15)
    pos = b._export()["positions"]
    # consistent winding: every triangle's normal points to +z (front) for the flat cloth
    t = h.triangles
    n = np.cross(pos[t[:, 1]] - pos[t[:, 0]], pos[t[:, 2]] - pos[t[:, 0]])
    assert np.all(n[:, 2] > 0)
    assert np.allclose(pos.mean(0), (0.1, 0.2, 0.05))
    r = b.add_rope(11, 0.5, start=(0, 0, 0.1))
    assert r.ends == (20, 30)
    with pytest.raises(ValueError):
        b.add_cloth(1, 4, 0.1, 0.1)
    with pytest.raises(ValueError):
        b.add_static_box((0, 0, 0), (0.1, -0.1, 0.1))
    with pytest.raises(IndexError):
        b.pin([1000])


def _sim(**kw):
    b = SceneBuilder()
    b.add_cloth(4, 4, 0.2, 0.2, center=(0, 0, 0.05))
    return ParticleSim(b, num_worlds=2, num_pickers=2, **kw)


def test_step_input_validation():
    sim = _sim()
    good = np.zeros((2, 2, 3))
    sim.step(good, np.zeros((2, 2), bool))
    with pytest.raises(ValueError, match=r"\(2, 2, 3\)"):
        sim.step(np.zeros((2, 3)), np.zeros((2, 2), bool))
    bad = good.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        sim.step(bad)
    bad[0, 0, 0] = np.inf
    with pytest.raises(ValueError):
        sim.step(bad)
    with pytest.raises(ValueError, match=r"\(2, 2\)"):
        sim.step(good, np.zeros(2, bool))
    with pytest.raises(ValueError):
        sim.step(good, np.full((2, 2), np.nan))
    with pytest.raises(ValueError):
        sim.step("not an array")
    # still usable after bad input
    sim.step(good, np.ones((2, 2), bool))
    assert np.all(np.isfinite(sim.positions))
    with pytest.raises(TypeError):
        ParticleSim(SceneBuilder(), params={"substeps": 2})
    with pytest.raises(ValueError):
        ParticleSim(SceneBuilder())  # empty scene
    with pytest.raises(IndexError):
        sim.get_state(world=5)


def test_mismatched_topology_rejected():
    a, b = SceneBuilder(), SceneBuilder()
    a.add_cloth(4, 4, 0.2, 0.2)
    b.add_cloth(5, 4, 0.2, 0.2)
    with pytest.raises(ValueError, match="topology"):
        ParticleSim([a, b])
    sim = ParticleSim([a])
    with pytest.raises(ValueError, match="topology"):
        sim.reset_world(0, b)


def test_properties_shapes():
    sim = _sim()
    assert sim.positions.shape == (2, 16, 3)
    assert sim.velocities.shape == (2, 16, 3)
    assert sim.picker_positions.shape == (2, 2, 3)
    assert sim.grasped.shape == (2, 2) and sim.grasped.dtype == bool
    assert sim.num_worlds == 2 and sim.num_particles == 16 and sim.device == "cpu"
    assert sim.particle_q.shape == (32,)
    c, r = sim.rigid_box_poses()
    assert c.shape == (2, 0, 3) and r.shape == (2, 0, 3, 3)
