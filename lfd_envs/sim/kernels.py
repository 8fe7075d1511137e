"""Warp kernels of the particle engine (see :mod:`lfd_envs.sim.engine` for the pipeline).

Layout: all worlds share one flat particle array; particle ``i`` belongs to world ``i // N``
(``N`` particles per world).  Per-world topology arrays (constraint CSR, colours, object ids)
are indexed with the world-local index ``li = i - w*N``.

Determinism: every kernel writes only data owned by its thread (its particle, its constraint's
two particles within one colour, its world or its rigid box) and reads data that no other
thread of the same launch writes, so results do not depend on thread scheduling (CPU or CUDA);
there are no float atomics.  Kernels with ``total``/``chunk`` arguments process items
``[tid*chunk, (tid+1)*chunk)``: one thread for everything on CPU, one item per thread on CUDA.
"""

from __future__ import annotations

import warp as wp

wp.set_module_options({"enable_backward": False})

EPS = wp.constant(1.0e-9)


# ----------------------------------------------------------------------------- helpers
@wp.func
def cell_hash(cx: int, cy: int, cz: int, mask: int) -> int:
    h = (wp.uint32(cx) * wp.uint32(73856093)) ^ (wp.uint32(cy) * wp.uint32(19349663)) ^ (
        wp.uint32(cz) * wp.uint32(83492791)
    )
    return int(h & wp.uint32(mask))


@wp.func
def cell_of(p: wp.vec3, inv_h: float) -> wp.vec3i:
    return wp.vec3i(int(wp.floor(p[0] * inv_h)), int(wp.floor(p[1] * inv_h)), int(wp.floor(p[2] * inv_h)))


@wp.func
def set_axis(v: wp.vec3, axis: int, value: float) -> wp.vec3:
    if axis == 0:
        return wp.vec3(value, v[1], v[2])
    if axis == 1:
        return wp.vec3(v[0], value, v[2])
    return wp.vec3(v[0], v[1], value)


@wp.func
def sign_nz(x: float) -> float:
    if x < 0.0:
        return -1.0
    return 1.0


@wp.func
def box_contact(x: wp.vec3, xp: wp.vec3, r: float, c: wp.vec3, rot: wp.mat33, he: wp.vec3, ccd: int) -> wp.vec3:
    """Project point ``x`` (radius ``r``) out of an oriented box.

    With ``ccd`` the segment ``xp -> x`` (``xp``: position at the start of the substep) is tested
    against the inflated box: a particle that entered or crossed it is put back on the face it
    entered through, so nothing tunnels through thin planks whatever its speed.
    """
    rt = wp.transpose(rot)
    xl = rt * (x - c)
    pl = rt * (xp - c)
    e = he + wp.vec3(r, r, r)
    inside = (wp.abs(xl[0]) < e[0]) and (wp.abs(xl[1]) < e[1]) and (wp.abs(xl[2]) < e[2])
    prev_out = (wp.abs(pl[0]) >= e[0]) or (wp.abs(pl[1]) >= e[1]) or (wp.abs(pl[2]) >= e[2])
    if ccd != 0 and prev_out:
        d = xl - pl
        t_enter = float(-1.0e30)
        t_exit = float(1.0e30)
        axis = int(-1)
        hit = int(1)
        for a in range(3):
            if wp.abs(d[a]) < 1.0e-12:
                if wp.abs(pl[a]) >= e[a]:
                    hit = 0
            else:
                t1 = (-e[a] - pl[a]) / d[a]
                t2 = (e[a] - pl[a]) / d[a]
                tn = wp.min(t1, t2)
                tf = wp.max(t1, t2)
                if tn > t_enter:
                    t_enter = tn
                    axis = a
                t_exit = wp.min(t_exit, tf)
        if hit != 0 and axis >= 0 and t_enter <= t_exit and t_enter >= 0.0 and t_enter <= 1.0:
            xl = set_axis(xl, axis, -sign_nz(d[axis]) * e[axis])
            return c + rot * xl
        if not inside:
            return x
    if inside:
        # nearest face
        pen0 = e[0] - wp.abs(xl[0])
        pen1 = e[1] - wp.abs(xl[1])
        pen2 = e[2] - wp.abs(xl[2])
        if pen0 <= pen1 and pen0 <= pen2:
            xl = set_axis(xl, 0, sign_nz(xl[0]) * e[0])
        elif pen1 <= pen2:
            xl = set_axis(xl, 1, sign_nz(xl[1]) * e[1])
        else:
            xl = set_axis(xl, 2, sign_nz(xl[2]) * e[2])
        return c + rot * xl
    return x


@wp.func
def box_exit_above(x: wp.vec3, r: float, c: wp.vec3, rot: wp.mat33, he: wp.vec3, floor: float) -> wp.vec3:
    """Project point ``x`` (radius ``r``) out of an oriented box through the nearest face whose
    exit point is at least ``floor`` high (a box sunk into the table must not push a particle
    out through its bottom, under the table); ``x`` itself if no face qualifies."""
    rt = wp.transpose(rot)
    xl = rt * (x - c)
    e = he + wp.vec3(r, r, r)
    best = float(1.0e30)
    out = x
    for a in range(3):
        for k in range(2):
            side = float(2 * k - 1)
            cand = c + rot * set_axis(xl, a, side * e[a])
            pen = wp.abs(side * e[a] - xl[a])
            if cand[2] >= floor and pen < best:
                best = pen
                out = cand
    return out


# ----------------------------------------------------------------------------- substep start
@wp.kernel
def predict(
    q: wp.array(dtype=wp.vec3),
    q_prev: wp.array(dtype=wp.vec3),
    v: wp.array(dtype=wp.vec3),
    inv_mass: wp.array(dtype=float),
    attach: wp.array(dtype=wp.int32),
    attach_off: wp.array(dtype=wp.vec3),
    pick_start: wp.array(dtype=wp.vec3),
    pick_end: wp.array(dtype=wp.vec3),
    fric: wp.array(dtype=wp.vec3),
    w_eff: wp.array(dtype=float),
    num_particles: int,
    num_pickers: int,
    alpha: float,
    gravity: float,
    dt: float,
    damp: float,
    max_speed: float,
    total: int,
    chunk: int,
):
    """Substep start: remember the substep-start positions, clear the friction accumulators,
    move grasped particles with their picker (interpolated by ``alpha``) and integrate free
    particles (gravity, damping, speed clamp)."""
    tid = wp.tid()
    for i in range(tid * chunk, wp.min(tid * chunk + chunk, total)):
        xp = q[i]
        q_prev[i] = xp
        fric[i] = wp.vec3(0.0, 0.0, 0.0)
        a = attach[i]
        wi = inv_mass[i]
        if a >= 0:
            wi = 0.0
        w_eff[i] = wi
        if a >= 0:
            k = (i // num_particles) * num_pickers + a
            q[i] = wp.lerp(pick_start[k], pick_end[k], alpha) + attach_off[i]
        elif wi > 0.0:
            vi = (v[i] + wp.vec3(0.0, 0.0, gravity * dt)) * damp
            s = wp.length(vi)
            if s > max_speed:
                vi = vi * (max_speed / s)
            v[i] = vi
            q[i] = xp + vi * dt


# ----------------------------------------------------------------------------- neighbour search
@wp.kernel
def build_grid(
    q: wp.array(dtype=wp.vec3),
    sc_r: wp.array(dtype=float),
    grid_params: wp.array(dtype=float),
    num_particles: int,
    table_size: int,
    cell_start: wp.array(dtype=wp.int32),
    cell_end: wp.array(dtype=wp.int32),
    sorted_idx: wp.array(dtype=wp.int32),
    sorted_q: wp.array(dtype=wp.vec3),
    sorted_r: wp.array(dtype=float),
):
    """Counting sort of one world's self-colliding particles into a spatial hash (one thread per world)."""
    w = wp.tid()
    inv_h = 1.0 / grid_params[0]
    mask = table_size - 1
    base = w * num_particles
    tb = w * table_size
    for c in range(table_size):
        cell_start[tb + c] = 0
    for li in range(num_particles):
        i = base + li
        if sc_r[i] > 0.0:
            ci = cell_of(q[i], inv_h)
            h = cell_hash(ci[0], ci[1], ci[2], mask)
            cell_start[tb + h] = cell_start[tb + h] + 1
    s = int(0)
    for c in range(table_size):
        cnt = cell_start[tb + c]
        cell_start[tb + c] = s
        cell_end[tb + c] = s
        s = s + cnt
    for li in range(num_particles):
        i = base + li
        if sc_r[i] > 0.0:
            ci = cell_of(q[i], inv_h)
            h = cell_hash(ci[0], ci[1], ci[2], mask)
            slot = cell_end[tb + h]
            sorted_idx[base + slot] = li
            sorted_q[base + slot] = q[i]
            sorted_r[base + slot] = sc_r[i]
            cell_end[tb + h] = slot + 1


@wp.kernel
def build_neighbors(
    q: wp.array(dtype=wp.vec3),
    sc_r: wp.array(dtype=float),
    obj: wp.array(dtype=wp.int32),
    rest: wp.array(dtype=wp.vec3),
    grid_params: wp.array(dtype=float),
    num_particles: int,
    table_size: int,
    max_nbr: int,
    cell_start: wp.array(dtype=wp.int32),
    cell_end: wp.array(dtype=wp.int32),
    sorted_idx: wp.array(dtype=wp.int32),
    sorted_q: wp.array(dtype=wp.vec3),
    sorted_r: wp.array(dtype=float),
    nbr: wp.array(dtype=wp.int32),
    nbr_d: wp.array(dtype=float),
    nbr_count: wp.array(dtype=wp.int32),
    total: int,
    chunk: int,
):
    """Per particle: the ``max_nbr`` closest self-collision candidates, sorted by (distance, index).

    The result does not depend on the traversal order of the hash table, so it is identical
    whether a world is simulated alone or in a batch.  Pairs of the same object whose rest
    distance is below their collision distance are filtered (FleX SelfCollideFilter).
    """
    tid = wp.tid()
    for i in range(tid * chunk, wp.min(tid * chunk + chunk, total)):
        ri = sc_r[i]
        if ri <= 0.0:
            nbr_count[i] = 0
            continue
        w = i // num_particles
        li = i - w * num_particles
        base = w * num_particles
        tb = w * table_size
        mask = table_size - 1
        h = grid_params[0]
        fac = grid_params[1]
        inv_h = 1.0 / h
        p = q[i]
        oi = obj[li]
        resti = rest[i]
        off = i * max_nbr
        ci = cell_of(p, inv_h)
        sx = int(1)
        sy = int(1)
        sz = int(1)
        if p[0] * inv_h - float(ci[0]) < 0.5:
            sx = -1
        if p[1] * inv_h - float(ci[1]) < 0.5:
            sy = -1
        if p[2] * inv_h - float(ci[2]) < 0.5:
            sz = -1
        count = int(0)
        for a in range(2):
            for b in range(2):
                for c in range(2):
                    hc = cell_hash(ci[0] + a * sx, ci[1] + b * sy, ci[2] + c * sz, mask)
                    for s in range(cell_start[tb + hc], cell_end[tb + hc]):
                        rsum = ri + sorted_r[base + s]
                        cut = rsum * fac
                        dv = sorted_q[base + s] - p
                        d2 = wp.dot(dv, dv)
                        if d2 >= cut * cut:
                            continue
                        lj = sorted_idx[base + s]
                        if lj == li:
                            continue
                        if obj[lj] == oi:
                            rd = rest[base + lj] - resti
                            if wp.dot(rd, rd) < rsum * rsum:
                                continue
                        dup = int(0)
                        for t in range(count):
                            if nbr[off + t] == lj:
                                dup = 1
                        if dup != 0:
                            continue
                        pos = int(-1)
                        if count < max_nbr:
                            pos = count
                            count = count + 1
                        else:
                            last = nbr_d[off + max_nbr - 1]
                            if d2 < last or (d2 == last and lj < nbr[off + max_nbr - 1]):
                                pos = max_nbr - 1
                        if pos < 0:
                            continue
                        while pos > 0:
                            pd = nbr_d[off + pos - 1]
                            pj = nbr[off + pos - 1]
                            if pd > d2 or (pd == d2 and pj > lj):
                                nbr_d[off + pos] = pd
                                nbr[off + pos] = pj
                                pos = pos - 1
                            else:
                                break
                        nbr_d[off + pos] = d2
                        nbr[off + pos] = lj
        nbr_count[i] = count


# ----------------------------------------------------------------------------- solver
@wp.func
def project_distance(xi: wp.vec3, xj: wp.vec3, wi: float, wj: float, k: float, rest: float):
    """PBD distance projection; returns the new positions of both particles."""
    wsum = wi + wj
    if wsum > 0.0:
        d = xi - xj
        l = wp.length(d)
        if l > EPS:
            s = k * (l - rest) / (l * wsum)
            return xi - (wi * s) * d, xj + (wj * s) * d
    return xi, xj


@wp.func
def project_distance_xpbd(xi: wp.vec3, xj: wp.vec3, wi: float, wj: float, alpha_tilde: float, rest: float,
                          lam: float):
    """XPBD distance projection (Macklin et al. 2016) with time-scaled compliance
    ``alpha_tilde = compliance / h**2``; returns both new positions and the updated multiplier."""
    wsum = wi + wj
    if wsum > 0.0:
        d = xi - xj
        l = wp.length(d)
        if l > EPS:
            dlam = (-(l - rest) - alpha_tilde * lam) / (wsum + alpha_tilde)
            n = d / l
            return xi + (wi * dlam) * n, xj - (wj * dlam) * n, lam + dlam
    return xi, xj, lam


@wp.struct
class Compliance:
    """XPBD mode of one constraint type: ``enabled`` 0 keeps the PBD stiffness; else every
    constraint has compliance ``alpha_tilde / kscale`` (per-constraint factor, e.g. the
    resolution-aware bending) and a Lagrange multiplier in ``multipliers`` (reset each substep)."""

    enabled: int
    alpha_tilde: float
    multipliers: wp.array(dtype=float)


@wp.func
def constraint_alpha(compliance: Compliance, kscale: float) -> float:
    return compliance.alpha_tilde / wp.max(kscale, 1.0e-6)


@wp.kernel
def zero_floats(a: wp.array(dtype=float), total: int, chunk: int):
    """``a[:total] = 0`` (chunked like the particle kernels)."""
    tid = wp.tid()
    for i in range(tid * chunk, wp.min(tid * chunk + chunk, total)):
        a[i] = 0.0


@wp.kernel
def solve_constraints(
    con_ij: wp.array(dtype=wp.vec2i),
    con_rest: wp.array(dtype=float),
    con_kscale: wp.array(dtype=float),
    stiffness: float,
    color_offset: int,
    color_count: int,
    num_cons: int,
    num_particles: int,
    q: wp.array(dtype=wp.vec3),
    w_eff: wp.array(dtype=float),
    compliance: Compliance,
):
    """PBD (or XPBD, see :class:`Compliance`) projection of the distance constraints of one
    colour, one constraint per thread (``dim = num_worlds * color_count``; GPU variant).
    Constraints of one colour share no particle, so each constraint writes its two particles
    race-free."""
    t = wp.tid()
    w = t // color_count
    c = color_offset + (t - w * color_count)
    base = w * num_particles
    ij = con_ij[c]
    i = base + ij[0]
    j = base + ij[1]
    k = w * num_cons + c
    if compliance.enabled != 0:
        xi, xj, lam = project_distance_xpbd(q[i], q[j], w_eff[i], w_eff[j], constraint_alpha(compliance, con_kscale[k]),
                                            con_rest[k], compliance.multipliers[k])
        compliance.multipliers[k] = lam
    else:
        xi, xj = project_distance(q[i], q[j], w_eff[i], w_eff[j], stiffness * con_kscale[k], con_rest[k])
    q[i] = xi
    q[j] = xj


@wp.kernel
def solve_constraints_serial(
    con_ij: wp.array(dtype=wp.vec2i),
    con_rest: wp.array(dtype=float),
    con_kscale: wp.array(dtype=float),
    stiffness: float,
    color_offset: int,
    color_count: int,
    num_cons: int,
    num_particles: int,
    q: wp.array(dtype=wp.vec3),
    w_eff: wp.array(dtype=float),
    num_worlds: int,
    compliance: Compliance,
):
    """Same as :func:`solve_constraints` with one thread looping over all worlds and constraints
    of the colour, in order (CPU variant: CPU launches are serial, and this avoids per-thread
    overhead).  Unrolled by four: the particles of four constraints are loaded before any is
    stored (constraints of one colour share no particle, so this is the same arithmetic with
    more instruction-level parallelism)."""
    if compliance.enabled != 0:
        for w in range(num_worlds):
            base = w * num_particles
            for c in range(color_offset, color_offset + color_count):
                ij = con_ij[c]
                i = base + ij[0]
                j = base + ij[1]
                k = w * num_cons + c
                xi, xj, lam = project_distance_xpbd(q[i], q[j], w_eff[i], w_eff[j],
                                                    constraint_alpha(compliance, con_kscale[k]), con_rest[k],
                                                    compliance.multipliers[k])
                compliance.multipliers[k] = lam
                q[i] = xi
                q[j] = xj
        return
    for w in range(num_worlds):
        base = w * num_particles
        rbase = w * num_cons
        n4 = color_count // 4
        for t in range(n4):
            c = color_offset + 4 * t
            ij0 = con_ij[c]
            ij1 = con_ij[c + 1]
            ij2 = con_ij[c + 2]
            ij3 = con_ij[c + 3]
            i0 = base + ij0[0]
            j0 = base + ij0[1]
            i1 = base + ij1[0]
            j1 = base + ij1[1]
            i2 = base + ij2[0]
            j2 = base + ij2[1]
            i3 = base + ij3[0]
            j3 = base + ij3[1]
            a0, b0 = project_distance(q[i0], q[j0], w_eff[i0], w_eff[j0], stiffness * con_kscale[rbase + c], con_rest[rbase + c])
            a1, b1 = project_distance(q[i1], q[j1], w_eff[i1], w_eff[j1], stiffness * con_kscale[rbase + c + 1], con_rest[rbase + c + 1])
            a2, b2 = project_distance(q[i2], q[j2], w_eff[i2], w_eff[j2], stiffness * con_kscale[rbase + c + 2], con_rest[rbase + c + 2])
            a3, b3 = project_distance(q[i3], q[j3], w_eff[i3], w_eff[j3], stiffness * con_kscale[rbase + c + 3], con_rest[rbase + c + 3])
            q[i0] = a0
            q[j0] = b0
            q[i1] = a1
            q[j1] = b1
            q[i2] = a2
            q[j2] = b2
            q[i3] = a3
            q[j3] = b3
        for c in range(color_offset + 4 * n4, color_offset + color_count):
            ij = con_ij[c]
            i = base + ij[0]
            j = base + ij[1]
            xi, xj = project_distance(q[i], q[j], w_eff[i], w_eff[j], stiffness * con_kscale[rbase + c], con_rest[rbase + c])
            q[i] = xi
            q[j] = xj


@wp.struct
class ParticleArrays:
    """Per-particle arrays of all worlds for :func:`solve_particles` (flat: world ``w`` owns
    ``[w * particles_per_world, (w + 1) * particles_per_world)``)."""

    particles_per_world: int
    positions: wp.array(dtype=wp.vec3)  # solved in place
    snapshot: wp.array(dtype=wp.vec3)  # positions at the start of the pass (Jacobi partners)
    substep_start: wp.array(dtype=wp.vec3)  # positions at the start of the substep
    inverse_mass: wp.array(dtype=float)  # 0 for pinned or picker-held particles
    attached_picker: wp.array(dtype=wp.int32)  # -1 when free
    radius: wp.array(dtype=float)  # contact radius against boxes and the ground
    friction_displacement: wp.array(dtype=wp.vec3)  # accumulated contact corrections
    picker_push: wp.array(dtype=wp.vec3)  # accumulated picker-sphere pushes of the substep
    pusher: wp.array(dtype=wp.int32)  # the picker (in its world) that pushed last


@wp.struct
class SelfCollision:
    """Particle-particle contacts: radii, neighbour lists and their parameters."""

    radius: wp.array(dtype=float)  # 0: the particle does not self-collide
    relaxation: float
    static_friction: float
    dynamic_friction: float
    max_neighbors: int
    neighbors: wp.array(dtype=wp.int32)  # world-local ids, max_neighbors per particle
    neighbor_count: wp.array(dtype=wp.int32)


@wp.struct
class Tethers:
    """Per-particle tether to an anchor particle (-1: none) with its maximum length."""

    anchor: wp.array(dtype=wp.int32)
    length: wp.array(dtype=float)


@wp.struct
class RigidBoxes:
    """Dynamic rigid boxes of all worlds (``boxes_per_world`` each) and the box of every
    world-local particle (-1: not part of a box)."""

    boxes_per_world: int
    position: wp.array(dtype=wp.vec3)
    rotation: wp.array(dtype=wp.mat33)
    half_extents: wp.array(dtype=wp.vec3)
    kinematic: wp.array(dtype=wp.int32)  # held or pinned: does not yield in box-box contacts
    box_of_particle: wp.array(dtype=wp.int32)


@wp.struct
class StaticBoxes:
    """Static boxes of all worlds (``boxes_per_world`` each; zero half extents: unused slot)."""

    boxes_per_world: int
    position: wp.array(dtype=wp.vec3)
    rotation: wp.array(dtype=wp.mat33)
    half_extents: wp.array(dtype=wp.vec3)


@wp.struct
class PickerSpheres:
    """Pickers as sphere colliders (``enabled`` 0: they touch nothing); ``position`` holds every
    world's pickers at the current substep."""

    pickers_per_world: int
    position: wp.array(dtype=wp.vec3)
    velocity: wp.array(dtype=wp.vec3)  # picker velocities during the current frame (m/s)
    radius: float
    enabled: int


@wp.kernel
def picker_substep_positions(start: wp.array(dtype=wp.vec3), end: wp.array(dtype=wp.vec3), alpha: float,
                             inv_frame_dt: float, out: wp.array(dtype=wp.vec3), velocity: wp.array(dtype=wp.vec3)):
    """Picker centres at the end of a substep (the same interpolation as :func:`predict`) and
    their velocities during the frame."""
    k = wp.tid()
    out[k] = wp.lerp(start[k], end[k], alpha)
    velocity[k] = (end[k] - start[k]) * inv_frame_dt


@wp.func
def push_out_of_sphere(x: wp.vec3, r: float, c: wp.vec3, radius: float) -> wp.vec3:
    """Project point ``x`` (radius ``r``) out of the sphere of ``radius`` around ``c``."""
    d = x - c
    dmin = radius + r
    l2 = wp.dot(d, d)
    if l2 >= dmin * dmin:
        return x
    if l2 < 1.0e-18:
        return c + wp.vec3(0.0, 0.0, dmin)
    return c + d * (dmin / wp.sqrt(l2))


@wp.func
def sphere_push_on_box(s: wp.vec3, radius: float, center: wp.vec3, rot: wp.mat33, he: wp.vec3) -> wp.vec3:
    """Translation that moves an oriented box (``center``, ``rot``, half extents ``he``) out of
    the sphere of ``radius`` around ``s`` (zero when they do not overlap)."""
    sl = wp.transpose(rot) * (s - center)
    closest = wp.vec3(wp.clamp(sl[0], -he[0], he[0]), wp.clamp(sl[1], -he[1], he[1]), wp.clamp(sl[2], -he[2], he[2]))
    d = sl - closest
    l = wp.length(d)
    if l >= radius:
        return wp.vec3(0.0, 0.0, 0.0)
    if l > 1.0e-9:
        return rot * (d * (-(radius - l) / l))
    # sphere centre inside the box: out along the axis of least penetration
    pen0 = he[0] - wp.abs(sl[0])
    pen1 = he[1] - wp.abs(sl[1])
    pen2 = he[2] - wp.abs(sl[2])
    move = wp.vec3(0.0, 0.0, 0.0)
    if pen0 <= pen1 and pen0 <= pen2:
        move = set_axis(move, 0, -sign_nz(sl[0]) * (pen0 + radius))
    elif pen1 <= pen2:
        move = set_axis(move, 1, -sign_nz(sl[1]) * (pen1 + radius))
    else:
        move = set_axis(move, 2, -sign_nz(sl[2]) * (pen2 + radius))
    return rot * move


@wp.kernel
def solve_particles(
    particles: ParticleArrays,
    collision: SelfCollision,
    tethers: Tethers,
    boxes: RigidBoxes,
    static_boxes: StaticBoxes,
    pickers: PickerSpheres,
    sc_on: int,
    skip_kinematic: int,
    total: int,
    chunk: int,
):
    """Per-particle pass (Jacobi: partners are read from ``particles.snapshot``, each particle
    writes only itself): self-collision pairs, tethers, rigid boxes, picker spheres, ground and
    static boxes (with continuous collision against the substep start), friction bookkeeping."""
    tid = wp.tid()
    for i in range(tid * chunk, wp.min(tid * chunk + chunk, total)):
        wi = particles.inverse_mass[i]
        if wi == 0.0 and (particles.attached_picker[i] < 0 or skip_kinematic != 0):
            continue  # pinned (or, in a release relaxation, any kinematic particle)
        w = i // particles.particles_per_world
        li = i - w * particles.particles_per_world
        base = w * particles.particles_per_world
        x = particles.positions[i]
        r = particles.radius[i]
        if wi > 0.0:
            if sc_on != 0:
                ri = collision.radius[i]
                if ri > 0.0:
                    off = i * collision.max_neighbors
                    xpi = particles.substep_start[i]
                    for tn in range(collision.neighbor_count[i]):
                        j = base + collision.neighbors[off + tn]
                        wj = particles.inverse_mass[j]
                        dmin = ri + collision.radius[j]
                        d = x - particles.snapshot[j]
                        l2 = wp.dot(d, d)
                        if l2 < dmin * dmin and l2 > 1.0e-18:
                            l = wp.sqrt(l2)
                            x = x + d * (collision.relaxation * (dmin - l) / l * wi / (wi + wj))
                            if collision.static_friction > 0.0 or collision.dynamic_friction > 0.0:
                                pen = dmin - l
                                share = wi / (wi + wj)
                                n = d / l
                                # position-based Coulomb friction (Macklin et al. 2014): remove
                                # (part of) the tangential displacement relative to the partner
                                dr = (x - xpi) - (particles.snapshot[j] - particles.substep_start[j])
                                dtan = dr - wp.dot(dr, n) * n
                                dtl = wp.length(dtan)
                                if dtl > 1.0e-12:
                                    if dtl > collision.static_friction * pen:
                                        dtan = dtan * wp.min(1.0, collision.dynamic_friction * pen / dtl)
                                    x = x - dtan * share
            ta = tethers.anchor[i]
            if ta >= 0:
                d = x - particles.snapshot[ta]
                l = wp.length(d)
                tl = tethers.length[i]
                if l > tl:
                    x = x - d * ((l - tl) / l)
        x0 = x  # contact corrections from here on feed the friction model
        if wi > 0.0:
            # dynamic rigid boxes (one-way for cloth/rope, half-half between boxes)
            mybox = boxes.box_of_particle[li]
            mykin = int(0)
            if mybox >= 0:
                mykin = boxes.kinematic[w * boxes.boxes_per_world + mybox]
            for b in range(boxes.boxes_per_world):
                if b != mybox:
                    kb = w * boxes.boxes_per_world + b
                    xn = box_contact(x, x, r, boxes.position[kb], boxes.rotation[kb], boxes.half_extents[kb], 0)
                    if mybox >= 0:
                        # box-box: split the correction; a held/pinned box does not yield
                        f = float(0.5)
                        if boxes.kinematic[kb] != 0 and mykin == 0:
                            f = 1.0
                        elif mykin != 0 and boxes.kinematic[kb] == 0:
                            f = 0.0
                        x = x + f * (xn - x)
                    else:
                        x = xn
            if pickers.enabled != 0:
                for p in range(pickers.pickers_per_world):
                    c = pickers.position[w * pickers.pickers_per_world + p]
                    reach = pickers.radius + r
                    d = x - c
                    if wp.dot(d, d) < reach * reach:  # inside: the rare case (the test is push_out_of_sphere's)
                        xn = push_out_of_sphere(x, r, c, pickers.radius)
                        if xn[0] != x[0] or xn[1] != x[1] or xn[2] != x[2]:
                            particles.picker_push[i] = particles.picker_push[i] + (xn - x)
                            particles.pusher[i] = p
                        x = xn
        # ground and static boxes
        if x[2] < r:
            x = wp.vec3(x[0], x[1], r)
        if static_boxes.boxes_per_world > 0:
            xp = particles.substep_start[i]
            for s in range(static_boxes.boxes_per_world):
                ks = w * static_boxes.boxes_per_world + s
                he = static_boxes.half_extents[ks]
                if he[0] > 0.0:
                    xn = box_contact(x, xp, r, static_boxes.position[ks], static_boxes.rotation[ks], he, 1)
                    if xn[2] < r:  # pushed out under the table: leave through a face above it
                        xn = box_exit_above(x, r, static_boxes.position[ks], static_boxes.rotation[ks], he, r)
                    x = xn
        particles.friction_displacement[i] = particles.friction_displacement[i] + (x - x0)
        particles.positions[i] = x


@wp.kernel
def shape_match(
    q: wp.array(dtype=wp.vec3),
    rest: wp.array(dtype=wp.vec3),
    inv_mass: wp.array(dtype=float),
    attach: wp.array(dtype=wp.int32),
    rigid_start: wp.array(dtype=wp.int32),
    rigid_count: wp.array(dtype=wp.int32),
    num_particles: int,
    num_boxes: int,
    kin_weight: float,
    box_quat: wp.array(dtype=wp.quat),
    box_pos: wp.array(dtype=wp.vec3),
    box_rot: wp.array(dtype=wp.mat33),
    box_kin: wp.array(dtype=wp.int32),
    box_he: wp.array(dtype=wp.vec3),
    pickers: PickerSpheres,
    box_push: wp.array(dtype=wp.vec3),
    box_pusher_velocity: wp.array(dtype=wp.vec3),
):
    """Shape matching of one rigid box (one thread per world x box): best rigid transform of the
    rest shape onto the current particles (grasped/pinned particles weigh ``kin_weight``), then
    free particles are moved onto the rigid shape.  Rotation by warm-started iterative extraction
    (Mueller et al. 2016) so it is smooth and deterministic.  With colliding pickers, a box that
    nothing holds is then pushed as a whole out of every picker sphere (sphere against the box's
    faces, so a picker cannot slip between its surface particles); ``box_push`` accumulates the
    translations of the substep that pushed the box out of pickers and of the table, and
    ``box_pusher_velocity`` is the velocity of what pushed last (zero: the table), for
    :func:`update_velocity`.  Last, a free box is lifted out of the table if it entered it."""
    kb = wp.tid()
    w = kb // num_boxes
    b = kb - w * num_boxes
    start = w * num_particles + rigid_start[b]
    n = rigid_count[b]
    c = wp.vec3(0.0, 0.0, 0.0)
    c0 = wp.vec3(0.0, 0.0, 0.0)
    wsum = float(0.0)
    kin = int(0)
    for k in range(n):
        i = start + k
        m = float(1.0)
        if attach[i] >= 0 or inv_mass[i] == 0.0:
            m = kin_weight
            kin = 1
        c = c + m * q[i]
        c0 = c0 + m * rest[i]
        wsum = wsum + m
    c = c / wsum
    c0 = c0 / wsum
    A = wp.mat33(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    for k in range(n):
        i = start + k
        m = float(1.0)
        if attach[i] >= 0 or inv_mass[i] == 0.0:
            m = kin_weight
        A = A + m * wp.outer(q[i] - c, rest[i] - c0)
    qt = box_quat[kb]
    a0 = wp.vec3(A[0, 0], A[1, 0], A[2, 0])
    a1 = wp.vec3(A[0, 1], A[1, 1], A[2, 1])
    a2 = wp.vec3(A[0, 2], A[1, 2], A[2, 2])
    for it in range(8):
        R = wp.quat_to_matrix(qt)
        r0 = wp.vec3(R[0, 0], R[1, 0], R[2, 0])
        r1 = wp.vec3(R[0, 1], R[1, 1], R[2, 1])
        r2 = wp.vec3(R[0, 2], R[1, 2], R[2, 2])
        om = (wp.cross(r0, a0) + wp.cross(r1, a1) + wp.cross(r2, a2)) * (
            1.0 / (wp.abs(wp.dot(r0, a0) + wp.dot(r1, a1) + wp.dot(r2, a2)) + 1.0e-9)
        )
        wl = wp.length(om)
        if wl < 1.0e-9:
            break
        qt = wp.normalize(wp.quat_from_axis_angle(om / wl, wl) * qt)
    R = wp.quat_to_matrix(qt)
    if pickers.enabled != 0 and kin == 0:  # pickers first: the table, immovable, has the last word
        for p in range(pickers.pickers_per_world):
            kp = w * pickers.pickers_per_world + p
            t = sphere_push_on_box(pickers.position[kp], pickers.radius, c - R * c0, R, box_he[kb])
            if t[0] != 0.0 or t[1] != 0.0 or t[2] != 0.0:
                c = c + t
                box_push[kb] = box_push[kb] + t
                box_pusher_velocity[kb] = pickers.velocity[kp]
    if kin == 0:
        # a free box hitting the table fast (dropped, tumbling) would end the iteration with a
        # corner below it: lift the whole box so that no particle centre is under the table top
        lift = float(0.0)
        for k in range(n):
            lift = wp.max(lift, -(c + R * (rest[start + k] - c0))[2])
        c = c + wp.vec3(0.0, 0.0, lift)
        if lift > 0.0 and pickers.enabled != 0:
            box_push[kb] = box_push[kb] + wp.vec3(0.0, 0.0, lift)
            box_pusher_velocity[kb] = wp.vec3(0.0, 0.0, 0.0)
    box_quat[kb] = qt
    box_rot[kb] = R
    box_kin[kb] = kin
    box_pos[kb] = c - R * c0
    for k in range(n):
        i = start + k
        if attach[i] < 0 and inv_mass[i] > 0.0:
            q[i] = c + R * (rest[i] - c0)


# ----------------------------------------------------------------------------- substep end
@wp.struct
class ContactPushes:
    """What colliding pickers (and the table, for boxes) pushed in the current substep, for
    :func:`update_velocity`; accumulated by :func:`solve_particles` and :func:`shape_match`,
    cleared at every substep start."""

    particles_per_world: int
    boxes_per_world: int
    box_of_particle: wp.array(dtype=wp.int32)  # per particle of a world: its box, -1 if none
    particle_push: wp.array(dtype=wp.vec3)  # sum of the picker-sphere pushes of each particle (m)
    pusher: wp.array(dtype=wp.int32)  # the picker (in its world) that pushed a particle last
    box_push: wp.array(dtype=wp.vec3)  # sum of the translations of each box out of pickers / the table
    box_pusher_velocity: wp.array(dtype=wp.vec3)  # velocity of what pushed a box last (table: 0)


@wp.func
def inelastic_push(vi: wp.vec3, push: wp.vec3, inv_dt: float, pusher_v: wp.vec3) -> wp.vec3:
    """Velocity ``vi`` (from the position change of a substep) with the share of a contact push
    ``push`` (m, accumulated over the substep) replaced by an inelastic contact: the velocity
    without the push keeps all its parts, except along the push, where it becomes at least the
    pusher's velocity ``pusher_v`` (carried along) and no more unless it already was (no
    restitution)."""
    pl = wp.length(push)
    if pl < 1.0e-12:
        return vi
    n = push / pl
    v0 = vi - push * inv_dt
    v0n = wp.dot(v0, n)
    return v0 + (wp.max(v0n, wp.dot(pusher_v, n)) - v0n) * n


@wp.kernel
def update_velocity(
    q: wp.array(dtype=wp.vec3),
    q_prev: wp.array(dtype=wp.vec3),
    v: wp.array(dtype=wp.vec3),
    inv_mass: wp.array(dtype=float),
    attach: wp.array(dtype=wp.int32),
    fric: wp.array(dtype=wp.vec3),
    inv_dt: float,
    mu_s: float,
    mu_k: float,
    max_speed: float,
    pickers: PickerSpheres,
    pushes: ContactPushes,
    total: int,
    chunk: int,
):
    """Substep end: velocities from the position change, with the accumulated contact corrections
    applied as Coulomb friction (``mu_s``/``mu_k``), clamped to ``max_speed``; pinned particles
    get zero velocity.

    With colliding pickers (the FleX-like settings) the contacts of what a picker pushed in the
    substep are inelastic: for a particle, the normal part of all its contact corrections (the
    picker's, the table's, ...) does not become velocity beyond the picker's; for a free box,
    the same holds for its push as a whole out of pickers and the table
    (:func:`inelastic_push`). A contact projection left alone becomes a velocity ``correction /
    substep_dt``: a particle squeezed between a picker and the table, or left inside a picker
    by a release, is moved centimetres in one substep and shot away at metres per second.
    (Made inelastic everywhere, the table's contacts let a rope tangle into a self-sustaining
    whirl of 5-10 m/s under random actions; they keep the plain projection.)"""
    tid = wp.tid()
    for i in range(tid * chunk, wp.min(tid * chunk + chunk, total)):
        att = attach[i]
        if att < 0 and inv_mass[i] == 0.0:
            v[i] = wp.vec3(0.0, 0.0, 0.0)
            continue
        vi = (q[i] - q_prev[i]) * inv_dt
        if att < 0:
            f = fric[i]
            fl = wp.length(f)
            w = i // pushes.particles_per_world
            if fl > 1.0e-12:
                n = f / fl
                dvn = fl * inv_dt
                vn = wp.dot(vi, n)
                vt = vi - vn * n
                if pickers.enabled != 0 and wp.length(pushes.particle_push[i]) > 0.0:
                    # pushed by a picker: inelastic, at least and at most as fast as the picker
                    pusher = pickers.velocity[w * pickers.pickers_per_world + pushes.pusher[i]]
                    vn = wp.max(vn - dvn, wp.dot(pusher, n))
                vtl = wp.length(vt)
                if vtl <= mu_s * dvn:
                    vt = wp.vec3(0.0, 0.0, 0.0)
                else:
                    vt = vt * wp.max(0.0, 1.0 - mu_k * dvn / vtl)
                vi = vn * n + vt
            if pickers.enabled != 0:
                b = pushes.box_of_particle[i - w * pushes.particles_per_world]
                if b >= 0:
                    kb = w * pushes.boxes_per_world + b
                    vi = inelastic_push(vi, pushes.box_push[kb], inv_dt, pushes.box_pusher_velocity[kb])
        s = wp.length(vi)
        if s > max_speed:
            vi = vi * (max_speed / s)
        v[i] = vi


# ----------------------------------------------------------------------------- tethers
@wp.kernel
def update_tethers(
    inv_mass: wp.array(dtype=float),
    attach: wp.array(dtype=wp.int32),
    obj: wp.array(dtype=wp.int32),
    box_of: wp.array(dtype=wp.int32),
    rest: wp.array(dtype=wp.vec3),
    num_particles: int,
    slack: float,
    enabled: int,
    anchors: wp.array(dtype=wp.int32),
    tether_anchor: wp.array(dtype=wp.int32),
    tether_len: wp.array(dtype=float),
):
    """Long-range attachments (one thread per world): every free cloth/rope particle is tethered
    to the kinematic particle (pinned or grasped) of its object that is closest in rest space,
    with maximum distance = rest distance x (1 + slack)."""
    w = wp.tid()
    base = w * num_particles
    na = int(0)
    if enabled != 0:
        for li in range(num_particles):
            i = base + li
            if box_of[li] < 0 and (attach[i] >= 0 or inv_mass[i] == 0.0):
                anchors[base + na] = li
                na = na + 1
    for li in range(num_particles):
        i = base + li
        best = int(-1)
        bd = float(1.0e30)
        if box_of[li] < 0 and attach[i] < 0 and inv_mass[i] > 0.0:
            oi = obj[li]
            ri = rest[i]
            for k in range(na):
                lj = anchors[base + k]
                if obj[lj] == oi:
                    d = wp.length(rest[base + lj] - ri)
                    if d < bd:
                        bd = d
                        best = lj
        if best >= 0:
            tether_anchor[i] = base + best
            tether_len[i] = bd * (1.0 + slack)
        else:
            tether_anchor[i] = -1
            tether_len[i] = 0.0


# ----------------------------------------------------------------------------- release relaxation
@wp.kernel
def relax_prepare(
    q: wp.array(dtype=wp.vec3),
    q_prev: wp.array(dtype=wp.vec3),
    inv_mass: wp.array(dtype=float),
    attach: wp.array(dtype=wp.int32),
    box_of: wp.array(dtype=wp.int32),
    world_flag: wp.array(dtype=wp.int32),
    w_eff: wp.array(dtype=float),
    num_particles: int,
    total: int,
    chunk: int,
):
    """Solver weights of a position-only relaxation: free cloth/rope particles of the flagged
    worlds keep their inverse mass, every other particle gets 0 (is left untouched); the
    relaxing particles' substep start is their current position (no velocity is derived)."""
    tid = wp.tid()
    for i in range(tid * chunk, wp.min(tid * chunk + chunk, total)):
        w = i // num_particles
        li = i - w * num_particles
        wi = float(0.0)
        if world_flag[w] != 0:
            q_prev[i] = q[i]
            if attach[i] < 0 and box_of[li] < 0:
                wi = inv_mass[i]
        w_eff[i] = wi


# ----------------------------------------------------------------------------- grasping
@wp.kernel
def grasp_update(
    q: wp.array(dtype=wp.vec3),
    inv_mass: wp.array(dtype=float),
    attach: wp.array(dtype=wp.int32),
    attach_off: wp.array(dtype=wp.vec3),
    picker_pos: wp.array(dtype=wp.vec3),
    events: wp.array(dtype=wp.int32),
    num_particles: int,
    num_pickers: int,
    grasp_radius: float,
    closest_only: int,
):
    """Process grasp (event 1) and release (event 2) of every picker of one world (thread per world).
    Releases first, then grasps in picker order, so results do not depend on scheduling."""
    w = wp.tid()
    base = w * num_particles
    for p in range(num_pickers):
        if events[w * num_pickers + p] == 2:
            for li in range(num_particles):
                i = base + li
                if attach[i] == p:
                    attach[i] = -1
                    attach_off[i] = wp.vec3(0.0, 0.0, 0.0)
    r2 = grasp_radius * grasp_radius
    for p in range(num_pickers):
        k = w * num_pickers + p
        if events[k] == 1:
            pp = picker_pos[k]
            best = int(-1)
            bd = r2
            for li in range(num_particles):
                i = base + li
                if attach[i] < 0 and inv_mass[i] > 0.0:
                    d = q[i] - pp
                    d2 = wp.dot(d, d)
                    if d2 <= r2:
                        if closest_only == 0:
                            attach[i] = p
                            attach_off[i] = d
                        elif d2 < bd or best < 0:
                            best = li
                            bd = d2
            if best >= 0:
                attach[base + best] = p
                attach_off[base + best] = q[base + best] - pp
