"""XPBD compliance and "small steps" (many substeps of one iteration): a material that does not
change with the solver counts, and cloth held together without tethers."""

from __future__ import annotations

import numpy as np
import pytest

from tools.cloth_stretch import SMALL_STEPS, hang
from lfd_envs.sim import ParticleSim, SceneBuilder, SimParams


def _cantilever_droop(params: SimParams, frames: int = 400) -> float:
    """Tip droop (m) of a 0.15 m cloth strip clamped along one short edge (spacing of the
    40-particle diagonal-fold cloth)."""
    nx, ny, dx = 9, 6, 0.75 / 39
    b = SceneBuilder()
    c = b.add_cloth(nx, ny, dx * (nx - 1), dx * (ny - 1), center=(0, 0, 0.5))
    b.pin([c.index(j, i) for j in range(ny) for i in range(2)])
    sim = ParticleSim(b, params=params, num_pickers=0)
    for _ in range(frames):
        sim.step(np.zeros((1, 0, 3)))
    q = sim.positions[0]
    return 0.5 - float(np.mean([q[c.index(j, nx - 1), 2] for j in range(ny)]))


def test_compliant_bending_does_not_depend_on_the_substep_count():
    xpbd = [_cantilever_droop(SimParams(substeps=n, bend_compliance=3e-3, **SMALL_STEPS)) for n in (10, 20, 40)]
    pbd = [_cantilever_droop(SimParams(substeps=n, bend_stiffness=0.2, **SMALL_STEPS)) for n in (10, 20, 40)]
    assert max(xpbd) - min(xpbd) < 2e-3, xpbd  # measured 0.6 mm
    assert max(pbd) - min(pbd) > 1e-2, pbd  # a PBD stiffness stiffens with more projections (measured 2.3 cm)
    assert min(xpbd) > 0.05  # it does bend


def test_zero_compliance_is_the_rigid_projection():
    b = SceneBuilder()
    c = b.add_cloth(12, 12, 0.3, 0.3, center=(0, 0, 0.6))
    b.pin([c.index(0, 0), c.index(0, 11)])
    runs = []
    for params in (SimParams(substeps=4, stretch_stiffness=1.0, **SMALL_STEPS),
                   SimParams(substeps=4, stretch_compliance=0.0, **SMALL_STEPS)):
        sim = ParticleSim(b, params=params, num_pickers=0)
        for _ in range(60):
            sim.step(np.zeros((1, 0, 3)))
        runs.append(sim.positions[0])
    assert np.abs(runs[0] - runs[1]).max() < 1e-4


def test_small_steps_hang_a_cloth_without_tethers():
    """40x40 cloth, 0.6 m, hung by two corners with tethers off: worst edge <= 10 %, mean <= 1 %
    with 20 substeps of one iteration (measured 5.3 % / 0.06 %; the default 2 x 5 without
    tethers: 81 % / 1.05 %)."""
    small = hang(40, SimParams(substeps=20, **SMALL_STEPS))
    assert small["worst"] <= 0.10 and small["mean"] <= 0.01, small
    loose = hang(40, SimParams(tethers=False))
    assert loose["worst"] > 0.3, loose  # what the small steps fix


def test_resolution_aware_substeps_hang_an_80x80_cloth_as_stiffly_as_a_40x40_one():
    """The -v1 solver (substeps_reference_resolution=40) runs 57 substeps for an 80x80 cloth:
    worst edge <= 10 %, mean <= 1 % (measured 5.1 % / 0.04 %); the same 20 substeps as 40x40
    leave 38 %."""
    from lfd_envs.registration import FLEX_LIKE_SIM_OPTIONS

    v1 = hang(80, SimParams(**FLEX_LIKE_SIM_OPTIONS))
    assert v1["substeps"] == 57
    assert v1["worst"] <= 0.10 and v1["mean"] <= 0.01, v1
    fixed = hang(80, SimParams(substeps=20, **SMALL_STEPS), frames=120)
    assert fixed["worst"] > 0.2, fixed  # what the resolution-aware substeps fix


def test_resolution_aware_substeps():
    p = SimParams(substeps=20, substeps_reference_resolution=40)
    assert [p.for_resolution(n).substeps for n in (0, 36, 40, 41, 80)] == [20, 20, 20, 21, 57]
    scaled = p.for_resolution(80)
    assert scaled.substeps_reference_resolution is None and scaled.for_resolution(80) == scaled
    assert SimParams(substeps=20).for_resolution(80).substeps == 20  # no reference: unchanged
    with pytest.raises(ValueError):
        SimParams(substeps_reference_resolution=1)


def _bend_scales(params: SimParams, side: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    b = SceneBuilder()
    b.add_cloth(side, side, 0.3, 0.3, center=(0, 0, 0.1))
    b.add_rope(10, 0.3, start=(0, 0, 0.3))
    sim = ParticleSim(b, params=params, num_pickers=0)
    return sim._con_kscale.numpy()[: sim._nnz], sim._con_type, sim._con_cloth_side


def test_coarse_cloth_bends_more_easily_with_a_reference_resolution():
    """(n / n_ref) ** exponent on the bend and shear constraints of a cloth coarser than the
    reference (one exponent each); stretch, the rope and cloth at the reference are untouched."""
    p = SimParams(bend_reference_spacing=None, bend_reference_resolution=40, bend_resolution_exponent=4.0,
                  shear_resolution_exponent=3.0)
    scale, typ, side = _bend_scales(p, 20)
    cloth_bend, cloth_shear = (typ == 2) & (side == 20), (typ == 1) & (side == 20)
    assert cloth_bend.any() and cloth_shear.any()
    assert np.allclose(scale[cloth_bend], 0.5 ** 4)
    assert np.allclose(scale[cloth_shear], 0.5 ** 3)
    assert np.allclose(scale[~(cloth_bend | cloth_shear)], 1.0)  # stretch and the rope's bends
    assert ((typ == 2) & (side == 0)).any()  # the rope has bend constraints, left as they were
    assert np.allclose(_bend_scales(p, 40)[0], 1.0)
    assert np.allclose(_bend_scales(SimParams(bend_reference_spacing=None), 20)[0], 1.0)
    with pytest.raises(ValueError):
        SimParams(bend_reference_resolution=1)
    with pytest.raises(ValueError):
        SimParams(bend_resolution_exponent=-1.0)
    with pytest.raises(ValueError):
        SimParams(shear_resolution_exponent=float("nan"))


@pytest.mark.parametrize("value", [-1.0, float("nan"), "soft"])
def test_bad_compliance_is_refused(value):
    with pytest.raises((ValueError, TypeError)):
        SimParams(bend_compliance=value)


def test_fine_cloth_bend_constraints_keep_the_reference_length_in_metres():
    """Finer than the reference: bend constraints span round(2 n / n_ref) particles (4 at 80
    against 40) and are scaled by the substeps at the reference over those that run; the rope
    and cloth at the reference keep distance-2 constraints."""
    p = SimParams(substeps=20, substeps_reference_resolution=40, bend_reference_spacing=None,
                  bend_reference_resolution=40)
    b = SceneBuilder()
    c = b.add_cloth(80, 80, 0.3, 0.3, center=(0, 0, 0.1))
    b.add_rope(10, 0.3, start=(0, 0, 0.3))
    sim = ParticleSim(b, params=p, num_pickers=0)
    e = b._export(40)
    cloth_bend = (e["con_type"] == 2) & (e["con_i"] < c.count)
    assert cloth_bend.sum() == 2 * 80 * (80 - 4)
    assert np.allclose(e["con_rest"][cloth_bend], 4 * c.spacing[0])
    assert np.all(np.abs(e["con_j"][cloth_bend] - e["con_i"][cloth_bend]) % 4 == 0)
    rope_bend = (e["con_type"] == 2) & ~cloth_bend
    assert np.allclose(e["con_rest"][rope_bend], 2 * 0.3 / 9)
    scale, typ, side = _bend_scales(p, 80)
    assert sim.substeps == 57
    assert np.allclose(scale[(typ == 2) & (side == 80)], 20 / 57)
    assert np.allclose(scale[~((typ == 2) & (side == 80))], 1.0)
    assert b.bend_spans(40) == (4,) and b.bend_spans(None) == (2,)
    # at or below the reference the layout is the one built without a reference
    b40 = SceneBuilder()
    b40.add_cloth(40, 40, 0.3, 0.3)
    assert b40.topology_key(40) == b40.topology_key(None)


def test_bend_span_is_fixed_at_construction():
    b = SceneBuilder()
    b.add_cloth(80, 80, 0.3, 0.3, center=(0, 0, 0.1))
    sim = ParticleSim(b, params=SimParams(bend_reference_resolution=40), num_pickers=0)
    with pytest.raises(ValueError, match="bend_reference_resolution"):
        sim.set_params(SimParams())
    assert sim.params.bend_reference_resolution == 40
    sim.set_params(SimParams(bend_reference_resolution=40, bend_stiffness=0.5))  # same spans: fine

