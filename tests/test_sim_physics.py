"""Particle engine: physical quality (stretch, resting contact, tunnelling, folding, stability)."""

from __future__ import annotations

import numpy as np
import pytest

from lfd_envs.sim import ParticleSim, SceneBuilder, SimParams


def _strain(q: np.ndarray, nx: int, ny: int, dx: float, dy: float) -> tuple[float, float]:
    g = q.reshape(ny, nx, 3)
    h = np.linalg.norm(np.diff(g, axis=1), axis=-1) / dx - 1.0
    v = np.linalg.norm(np.diff(g, axis=0), axis=-1) / dy - 1.0
    col = np.linalg.norm(np.diff(g, axis=0), axis=-1).sum(0) / (dy * (ny - 1)) - 1.0
    return float(max(h.max(), v.max())), float(col.max())


@pytest.mark.parametrize("n", [20, 40])
def test_hanging_cloth_stretch_below_10_percent(n):
    b = SceneBuilder()
    c = b.add_cloth(n, n, 0.6, 0.6, center=(0, 0, 1.0))
    b.pin([c.corners[0], c.corners[1]])
    sim = ParticleSim(b, num_pickers=0)
    for _ in range(250):
        sim.step(np.zeros((1, 0, 3)))
    q = sim.positions[0]
    edge_strain, length_strain = _strain(q, n, n, *c.spacing)
    assert edge_strain <= 0.10, edge_strain
    assert length_strain <= 0.10, length_strain
    assert q[:, 2].min() < 0.6  # it really hangs


def test_cloth_rests_on_table_and_energy_settles():
    table_h = 0.2
    b = SceneBuilder()
    b.add_static_box(center=(0, 0, table_h / 2), half_extents=(0.6, 0.6, table_h / 2))
    b.add_cloth(20, 20, 0.5, 0.5, center=(0.05, 0, table_h + 0.3), yaw=0.4)
    p = SimParams()
    sim = ParticleSim(b, params=p, num_pickers=0)
    ke = []
    for _ in range(200):
        sim.step(np.zeros((1, 0, 3)))
        ke.append(float((sim.velocities ** 2).sum()))
    z = sim.positions[0, :, 2]
    r = p.particle_radius
    assert np.all(z >= table_h - 1e-5), z.min()
    assert np.all(np.abs(z - table_h) <= r + 1e-4), (z.min(), z.max())
    assert ke[-1] < 1e-6 and max(ke[-20:]) < 1e-4


def _carry_over_plank(n: int, seed_yaw: float = 0.0):
    """Cloth beside a DryCloth-like plank; a picker carries its near edge over the plank at the
    maximum picker speed (0.08 m per frame).  Returns per-frame positions."""
    plank_x, top = 0.0, 0.3
    b = SceneBuilder()
    b.add_static_box(center=(plank_x, 0, top / 2), half_extents=(0.01, 0.6, top / 2))
    c = b.add_cloth(n, n, 0.6, 0.6, center=(-0.35, 0, 0.01), yaw=seed_yaw)
    p = SimParams(grasp_mode="radius", grasp_radius=0.05)
    sim = ParticleSim(b, params=p, num_pickers=1)
    q0 = sim.positions[0]
    grab = q0[c.index(n // 2, n - 1)]  # middle of the edge nearest to the plank
    start = np.array([grab[0], grab[1], grab[2]])
    sim.set_picker_positions(start[None, None])
    path = [start]
    cur = start.copy()
    # up (to 0.45), across (to x=0.15) then down to 0.15, at 0.08 m/frame
    for target in ([cur[0], cur[1], 0.45], [0.15, cur[1], 0.45], [0.15, cur[1], 0.15]):
        target = np.array(target)
        while np.linalg.norm(target - cur) > 1e-9:
            d = target - cur
            step = d if np.linalg.norm(d) <= 0.08 else d / np.linalg.norm(d) * 0.08
            cur = cur + step
            path.append(cur.copy())
    frames = [sim.positions[0]]
    for k, tgt in enumerate(path[1:]):
        sim.step(tgt[None, None], np.ones((1, 1), bool))
        frames.append(sim.positions[0])
    for _ in range(60):  # let it settle hanging over the plank
        sim.step(path[-1][None, None], np.ones((1, 1), bool))
        frames.append(sim.positions[0])
    return np.array(frames), plank_x, top


def test_no_tunnelling_through_plank_at_max_picker_speed():
    frames, px, top = _carry_over_plank(20)
    x, z = frames[..., 0], frames[..., 2]
    # never inside the plank (2 cm thick)
    inside = (np.abs(x - px) < 0.01) & (z < top)
    assert not inside.any()
    # a particle that stays well below the top edge cannot change side
    side = np.sign(x - px)
    low = (z[1:] < top - 0.03) & (z[:-1] < top - 0.03)
    crossed = (side[1:] != side[:-1]) & low
    assert not crossed.any()
    # and the test really exercises the plank: particles started on the -x side, many of them
    # went over the top (the whole cloth is whipped over at 8 m/s)
    assert (side[0] < 0).all() and (side[-1] > 0).sum() > 100


@pytest.mark.parametrize("n,size", [(16, 0.3), (40, 0.6)])
def test_folded_cloth_does_not_pass_through_itself(n, size):
    """Two pickers carry one edge over the opposite edge at SoftGym's maximum picker speed
    (0.01 m per frame per axis), release, settle: the layers stay apart."""
    b = SceneBuilder()
    c = b.add_cloth(n, n, size, size, center=(0, 0, 0.01))
    p = SimParams()
    sim = ParticleSim(b, params=p, num_pickers=2)
    q0 = sim.positions[0].astype(np.float64)
    pos = np.stack([q0[c.corners[0]], q0[c.corners[1]]])[None]  # the y = -size/2 edge
    sim.set_picker_positions(pos)
    grasp = np.ones((1, 2), bool)
    for dv in ((0, 0, 0.2 * size), (0, 1.05 * size, 0), (0, 0, -0.17 * size)):
        dv = np.asarray(dv, float)
        steps = int(np.ceil(np.abs(dv).max() / 0.01))
        for _ in range(steps):
            pos = pos + dv / steps
            sim.step(pos, grasp)
    for _ in range(60):
        sim.step(pos, np.zeros((1, 2), bool))
    q = sim.positions[0]
    assert q[:, 2].max() > 0.015  # folded: there is a second layer
    rest = b._export()["rest"]
    rd = np.linalg.norm(rest[:, None] - rest[None], axis=-1)
    dd = np.linalg.norm(q[:, None] - q[None], axis=-1)
    dist = p.self_collision_spacing_factor * min(c.spacing)
    far = rd > 2.5 * min(c.spacing)  # pairs on different layers / far apart in the cloth
    assert dd[far].min() >= 0.9 * dist, (dd[far].min(), dist)


def test_random_picker_motion_10k_frames_stays_finite():
    rng = np.random.default_rng(0)
    b = SceneBuilder()
    b.add_static_box(center=(0.25, 0, 0.05), half_extents=(0.01, 0.3, 0.05))
    b.add_cloth(6, 6, 0.2, 0.2, center=(0, 0, 0.02))
    sim = ParticleSim(b, params=SimParams(grasp_mode="radius"), num_pickers=2)
    pos = np.array([[[0.0, -0.05, 0.02], [0.0, 0.05, 0.02]]])
    sim.set_picker_positions(pos)
    grasp = np.zeros((1, 2), bool)
    for k in range(10_000):
        pos = np.clip(pos + rng.uniform(-0.08, 0.08, size=pos.shape), [-0.4, -0.4, 0.0], [0.4, 0.4, 0.4])
        if k % 7 == 0:
            grasp = rng.random((1, 2)) < 0.5
        sim.step(pos, grasp)
        if k % 500 == 0:
            assert np.all(np.isfinite(sim.positions))
    q = sim.positions
    assert np.all(np.isfinite(q)) and np.all(np.isfinite(sim.velocities))
    assert q[..., 2].min() >= 0.0 and np.abs(q).max() < 5.0


def test_picker_dragging_cloth_into_plank_cannot_pull_it_through():
    """The picker itself goes through the plank at 8 m/s; the grasped and dragged particles stay
    on their side (continuous collision against the substep start)."""
    b = SceneBuilder()
    b.add_static_box(center=(0.0, 0, 0.15), half_extents=(0.01, 0.6, 0.15))
    c = b.add_cloth(12, 12, 0.3, 0.3, center=(-0.2, 0, 0.01))
    sim = ParticleSim(b, params=SimParams(grasp_mode="radius", grasp_radius=0.04), num_pickers=1)
    start = sim.positions[0][c.index(6, 11)].astype(np.float64)
    sim.set_picker_positions(start[None, None])
    pos = start.copy()
    for k in range(12):
        pos = pos + np.array([0.08, 0.0, 0.01 if k < 5 else 0.0])
        sim.step(pos[None, None], np.ones((1, 1), bool))
        x = sim.positions[0, :, 0]
        assert np.all(x <= -0.01 + 1e-5), x.max()
    assert sim.attached.max() == 0  # still grasped, just stuck behind the plank


def test_rope_lifted_by_one_end_keeps_its_length():
    b = SceneBuilder()
    r = b.add_rope(41, 0.5, start=(-0.25, 0, 0.02), direction=(1, 0, 0))
    sim = ParticleSim(b, params=SimParams(grasp_radius=0.03), num_pickers=1)
    end = sim.positions[0][r.ends[0]].astype(np.float64)
    sim.set_picker_positions(end[None, None])
    pos = end.copy()
    for k in range(150):
        pos = pos + ([0.0, 0.0, 0.01] if k < 60 else [0.0, 0.0, 0.0])
        sim.step(pos[None, None], np.ones((1, 1), bool))
    q = sim.positions[0][r.indices]
    seg = np.linalg.norm(np.diff(q, axis=0), axis=1)
    assert abs(seg.sum() / 0.5 - 1.0) < 0.05
    assert q[-1, 2] < q[0, 2]  # hangs below the held end
    assert np.all(q[:, 2] >= sim.params.particle_radius - 1e-5)


def _diagonal_fold_release(relaxation: int) -> tuple[float, float]:
    """One picker carries a corner of a 20x20 cloth onto the opposite corner, holds, releases.
    Returns the max particle speed before the release and in the frame after it."""
    from tools.cloth_bounds import carry_corner_over

    sim, goal = carry_corner_over(SimParams(release_relaxation=relaxation))
    before = float(np.linalg.norm(sim.velocities[0], axis=1).max())
    sim.step(goal[None, None], np.zeros((1, 1), bool))  # release, picker at rest
    return before, float(np.linalg.norm(sim.velocities[0], axis=1).max())


def test_release_does_not_kick_the_cloth():
    """The constraint error around a held corner (pressed onto the lower layer) must not turn
    into a velocity jump on release (picker at rest: speeds stay below 0.5 m/s)."""
    before, after = _diagonal_fold_release(SimParams().release_relaxation)
    assert before < 0.5 and after < 0.5, (before, after)
    _, kicked = _diagonal_fold_release(0)  # the scenario really has a kick without relaxation
    assert kicked > 1.0, kicked


def test_coarse_cloth_fold_stays_folded():
    """A 15x15 cloth (5.4 cm spacing) folded in half by two pickers along an arc stays folded
    after release (resolution-aware bending + cloth-on-cloth friction)."""
    n, size = 15, 0.75
    b = SceneBuilder()
    c = b.add_cloth(n, n, size, size, center=(0, 0, 0.00625))
    sim = ParticleSim(b, num_pickers=2)
    q0 = sim.positions[0].astype(np.float64)
    pos = np.stack([q0[c.corners[0]], q0[c.corners[1]]])[None]
    sim.set_picker_positions(pos)
    theta = np.pi * np.arange(1, 81) / 80
    path = np.repeat(pos[None], len(theta), axis=0)
    path[..., 1] = -0.5 * size * np.cos(theta)[:, None, None]
    path[..., 2] = 0.5 * size * np.sin(theta)[:, None, None] + 0.0163
    path = np.concatenate([path, np.repeat(path[-1:], 160, axis=0)])
    grasp = np.arange(len(path)) < 90
    sim.step_frames(path, np.broadcast_to(grasp[:, None, None], (len(path), 1, 2)))
    grid = sim.positions[0].reshape(n, n, 3)
    moved_edge_y = grid[0, :, 1].mean()
    gap = np.linalg.norm(grid[: n // 2] - grid[::-1][: n // 2], axis=-1).mean()
    assert moved_edge_y > 0.3 * size, moved_edge_y  # unfolded it would be at -0.5 * size
    assert gap < 0.13 * size, gap  # without friction and bend scaling: 0.15 * size
    assert grid[..., 2].max() < 0.2 * size  # no open loop standing up (before the fix: 0.24 * size)


@pytest.mark.parametrize("trigger, lifts", [("level", True), ("edge", False)])
def test_picker_lowered_with_flag_on_grasps_on_contact(trigger, lifts):
    """SoftGym's rule ("level", the default): a picker whose grasp flag is already on grasps as
    soon as a particle is within reach and lifts the cloth; with "edge" only a flag change grasps."""
    b = SceneBuilder()
    b.add_cloth(10, 10, 0.3, 0.3, center=(0, 0, 0.01))
    sim = ParticleSim(b, params=SimParams(grasp_trigger=trigger, grasp_radius=0.04), num_pickers=1)
    start = sim.positions[0, 0] + np.array([0.0, 0.0, 0.2])  # high above a corner, out of reach
    sim.set_picker_positions(start[None, None])
    on = np.ones((1, 1), bool)
    path = [start + np.array([0, 0, -0.2 * k / 20]) for k in range(1, 21)]  # lower onto it ...
    path += [path[-1] + np.array([0, 0, 0.3 * k / 30]) for k in range(1, 31)]  # ... and lift
    for pos in path:
        sim.step(pos[None, None], on)
    assert (sim.attached[0] >= 0).any() == lifts
    assert (sim.positions[0, :, 2].max() > 0.25) == lifts


def test_v1_release_moves_no_particle_more_than_5_mm():
    """-v1 settings: a 20x20 cloth (coarse-cloth rules apply) folded corner onto corner, held
    until it settles, then released: no particle moves more than 5 mm in the release frame
    (measured 3.7 mm; with the shear exponent 3 it was 9.8 mm)."""
    from tools.cloth_bounds import release

    moved = release("v1")
    assert moved["particles held"] >= 1
    assert moved["largest move in the release frame (mm)"] <= 5.0, moved
