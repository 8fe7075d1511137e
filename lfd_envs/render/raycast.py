"""Warp kernels of the headless ray-caster.

One launch of :func:`render_kernel` shades every pixel of every world: thread ``(w, i, j)``
casts ``supersample**2`` primary rays through pixel ``(i, j)`` of world ``w`` and finds the
closest hit among

* the ground plane ``z = ground_z`` (checker pattern),
* oriented boxes (slab test in the box frame),
* the cloth triangle mesh (``wp.mesh_query_ray`` on one grouped ``wp.Mesh`` holding all worlds;
  group ``w`` is world ``w``, so a ray only traverses its own world's sub-tree),
* spheres and capsules ("round" primitives; a sphere is a capsule whose two ends coincide).

Boxes and round primitives are stored per layer and per world; every (layer, world) group has
an axis-aligned bound that is tested first, so a ray pays only for groups it passes near.
Shading is Lambert with one directional light plus ambient, optionally with a shadow ray.

The kernels are identical on ``cpu`` and ``cuda``; see :mod:`lfd_envs.render.renderer` for the
host side that packs the arrays.
"""

from __future__ import annotations

import warp as wp

# Rendering is never differentiated: skip adjoint code (faster compile, lets the C++ compiler
# inline the single-call helpers so the scene struct is not copied per ray).
wp.set_module_options({"enable_backward": False})

BIG = wp.constant(1.0e30)
EPS_T = wp.constant(1.0e-5)

#: Spheres/capsules are tested in clusters of this many consecutive primitives, each cluster
#: with its own per-world bounding box (the host computes the boxes).
ROUND_CLUSTER = wp.constant(8)

KIND_NONE = wp.constant(0)
KIND_GROUND = wp.constant(1)
KIND_BOX = wp.constant(2)
KIND_MESH = wp.constant(3)
KIND_ROUND = wp.constant(4)


@wp.struct
class SceneData:
    """Packed, device-resident description of all worlds' geometry (see renderer.py)."""

    num_worlds: int
    # ground plane
    ground_on: int
    ground_z: float
    ground_color: wp.vec3
    checker_size: float
    # triangle mesh (all worlds, grouped by world)
    has_mesh: int
    mesh_id: wp.uint64
    tris_per_world: int
    smooth: int  # interpolate vertex normals (1) or flat face normals (0)
    mesh_indices: wp.array(dtype=int)
    vertex_normals: wp.array(dtype=wp.vec3)
    face_front: wp.array(dtype=wp.vec3)
    face_back: wp.array(dtype=wp.vec3)
    # round primitives (spheres and capsules), per layer
    n_round_layers: int
    round_pt_off: wp.array(dtype=int)
    round_pt_stride: wp.array(dtype=int)
    round_prim_off: wp.array(dtype=int)
    round_prim_cnt: wp.array(dtype=int)
    round_bound_off: wp.array(dtype=int)
    round_bound_layer: wp.array(dtype=int)  # layer of each cluster bound (for round_cluster_bounds)
    round_lo: wp.array(dtype=wp.vec3)
    round_hi: wp.array(dtype=wp.vec3)
    pts: wp.array(dtype=wp.vec3)
    prim_a: wp.array(dtype=int)
    prim_b: wp.array(dtype=int)
    prim_r: wp.array(dtype=float)
    prim_color: wp.array(dtype=wp.vec3)
    # oriented boxes, per layer
    n_box_layers: int
    box_off: wp.array(dtype=int)
    box_stride: wp.array(dtype=int)
    box_cnt: wp.array(dtype=int)
    box_color_off: wp.array(dtype=int)
    box_lo: wp.array(dtype=wp.vec3)
    box_hi: wp.array(dtype=wp.vec3)
    box_center: wp.array(dtype=wp.vec3)
    box_rot: wp.array(dtype=wp.mat33)
    box_half: wp.array(dtype=wp.vec3)
    box_color: wp.array(dtype=wp.vec3)


@wp.struct
class ViewData:
    """Camera and lighting."""

    origin: wp.vec3
    forward: wp.vec3
    right: wp.vec3  # scaled by tan(fov_x / 2)
    up: wp.vec3  # scaled by tan(fov_y / 2)
    background: wp.vec3
    light_dir: wp.vec3  # unit, pointing towards the light
    ambient: float
    diffuse: float
    shadows: int
    max_dist: float


# ---------------------------------------------------------------------------- primitives
@wp.func
def safe_inv(d: float):
    if wp.abs(d) < 1.0e-12:
        if d < 0.0:
            return -1.0e12
        return 1.0e12
    return 1.0 / d


@wp.func
def ray_aabb(ro: wp.vec3, inv_d: wp.vec3, lo: wp.vec3, hi: wp.vec3, t_max: float):
    """True if the ray segment [0, t_max) touches the box [lo, hi]."""
    t1 = wp.cw_mul(lo - ro, inv_d)
    t2 = wp.cw_mul(hi - ro, inv_d)
    tn = wp.max(wp.max(wp.min(t1[0], t2[0]), wp.min(t1[1], t2[1])), wp.min(t1[2], t2[2]))
    tf = wp.min(wp.min(wp.max(t1[0], t2[0]), wp.max(t1[1], t2[1])), wp.max(t1[2], t2[2]))
    return tf >= wp.max(tn, 0.0) and tn < t_max


@wp.func
def ray_sphere(ro: wp.vec3, rd: wp.vec3, c: wp.vec3, r: float):
    """Nearest positive hit distance of a unit-direction ray with a sphere, or BIG."""
    oc = ro - c
    b = wp.dot(oc, rd)
    cc = wp.dot(oc, oc) - r * r
    h = b * b - cc
    if h < 0.0:
        return BIG
    s = wp.sqrt(h)
    t = -b - s
    if t > EPS_T:
        return t
    return BIG


@wp.func
def ray_capsule(ro: wp.vec3, rd: wp.vec3, a: wp.vec3, b: wp.vec3, r: float):
    """Nearest positive hit of a unit-direction ray with the capsule (a, b, r), or BIG.

    A degenerate capsule (a == b) is a sphere.
    """
    ba = b - a
    baba = wp.dot(ba, ba)
    if baba < 1.0e-14:
        return ray_sphere(ro, rd, a, r)
    oa = ro - a
    bard = wp.dot(ba, rd)
    baoa = wp.dot(ba, oa)
    rdoa = wp.dot(rd, oa)
    oaoa = wp.dot(oa, oa)
    qa = baba - bard * bard
    qb = baba * rdoa - baoa * bard
    qc = baba * oaoa - baoa * baoa - r * r * baba
    if qa > 1.0e-12 * baba:
        h = qb * qb - qa * qc
        if h < 0.0:
            return BIG  # misses the infinite cylinder, hence the capsule
        t = (-qb - wp.sqrt(h)) / qa
        y = baoa + t * bard
        if y > 0.0 and y < baba and t > EPS_T:
            return t
    # end caps
    return wp.min(ray_sphere(ro, rd, a, r), ray_sphere(ro, rd, b, r))


@wp.func
def ray_box_local(ro: wp.vec3, rd: wp.vec3, h: wp.vec3):
    """Entry distance of a ray (in the box frame) into the box [-h, h], or BIG."""
    inv = wp.vec3(safe_inv(rd[0]), safe_inv(rd[1]), safe_inv(rd[2]))
    t1 = wp.cw_mul(-h - ro, inv)
    t2 = wp.cw_mul(h - ro, inv)
    tn = wp.max(wp.max(wp.min(t1[0], t2[0]), wp.min(t1[1], t2[1])), wp.min(t1[2], t2[2]))
    tf = wp.min(wp.min(wp.max(t1[0], t2[0]), wp.max(t1[1], t2[1])), wp.max(t1[2], t2[2]))
    if tf >= tn and tn > EPS_T:
        return tn
    return BIG


@wp.func
def box_normal_local(p: wp.vec3, h: wp.vec3):
    """Outward normal of the box face nearest to the local surface point p."""
    ax = wp.abs(p[0]) / h[0]
    ay = wp.abs(p[1]) / h[1]
    az = wp.abs(p[2]) / h[2]
    if ax >= ay and ax >= az:
        return wp.vec3(wp.sign(p[0]), 0.0, 0.0)
    if ay >= az:
        return wp.vec3(0.0, wp.sign(p[1]), 0.0)
    return wp.vec3(0.0, 0.0, wp.sign(p[2]))


# ---------------------------------------------------------------------------- scene queries
@wp.func
def occluded(scene: SceneData, ro: wp.vec3, rd: wp.vec3, w: int, root: int, t_max: float):
    """Any-hit test used for shadow rays (the ground plane never occludes)."""
    inv_d = wp.vec3(safe_inv(rd[0]), safe_inv(rd[1]), safe_inv(rd[2]))
    W = scene.num_worlds
    for L in range(scene.n_box_layers):
        g = L * W + w
        if ray_aabb(ro, inv_d, scene.box_lo[g], scene.box_hi[g], t_max):
            base = scene.box_off[L] + w * scene.box_stride[L]
            for k in range(scene.box_cnt[L]):
                idx = base + k
                RT = wp.transpose(scene.box_rot[idx])
                t = ray_box_local(RT * (ro - scene.box_center[idx]), RT * rd, scene.box_half[idx])
                if t < t_max:
                    return True
    if scene.has_mesh != 0:
        if wp.mesh_query_ray_anyhit(scene.mesh_id, ro, rd, t_max, root):
            return True
    for L in range(scene.n_round_layers):
        base = scene.round_pt_off[L] + w * scene.round_pt_stride[L]
        p0 = scene.round_prim_off[L]
        cnt = scene.round_prim_cnt[L]
        ncl = (cnt + ROUND_CLUSTER - 1) // ROUND_CLUSTER
        gb = scene.round_bound_off[L] + w * ncl
        for cl in range(ncl):
            if ray_aabb(ro, inv_d, scene.round_lo[gb + cl], scene.round_hi[gb + cl], t_max):
                k0 = cl * ROUND_CLUSTER
                for k in range(k0, wp.min(k0 + ROUND_CLUSTER, cnt)):
                    q = p0 + k
                    t = ray_capsule(
                        ro, rd, scene.pts[base + scene.prim_a[q]], scene.pts[base + scene.prim_b[q]], scene.prim_r[q]
                    )
                    if t < t_max:
                        return True
    return False


@wp.func
def shade_ray(scene: SceneData, view: ViewData, ro: wp.vec3, rd: wp.vec3, w: int, root: int):
    """Colour (0..1 floats) seen along one primary ray of world w."""
    W = scene.num_worlds
    inv_d = wp.vec3(safe_inv(rd[0]), safe_inv(rd[1]), safe_inv(rd[2]))
    best_t = view.max_dist
    kind = KIND_NONE
    hit_idx = int(0)
    hit_base = int(0)
    hit_color = wp.vec3(0.0)
    hit_normal = wp.vec3(0.0, 0.0, 1.0)

    # ground plane
    if scene.ground_on != 0 and wp.abs(rd[2]) > 1.0e-9:
        t = (scene.ground_z - ro[2]) / rd[2]
        if t > EPS_T and t < best_t:
            best_t = t
            kind = KIND_GROUND

    # boxes
    for L in range(scene.n_box_layers):
        g = L * W + w
        if ray_aabb(ro, inv_d, scene.box_lo[g], scene.box_hi[g], best_t):
            base = scene.box_off[L] + w * scene.box_stride[L]
            for k in range(scene.box_cnt[L]):
                idx = base + k
                RT = wp.transpose(scene.box_rot[idx])
                t = ray_box_local(RT * (ro - scene.box_center[idx]), RT * rd, scene.box_half[idx])
                if t < best_t:
                    best_t = t
                    kind = KIND_BOX
                    hit_idx = idx
                    hit_base = scene.box_color_off[L] + k

    # cloth mesh
    mesh_face = int(0)
    mesh_sign = float(1.0)
    mesh_u = float(0.0)
    mesh_v = float(0.0)
    if scene.has_mesh != 0:
        mq = wp.mesh_query_ray(scene.mesh_id, ro, rd, best_t, root)
        if mq.result:
            if mq.t > EPS_T:
                best_t = mq.t
                kind = KIND_MESH
                mesh_face = mq.face
                mesh_sign = mq.sign
                mesh_u = mq.u
                mesh_v = mq.v
                hit_normal = mq.normal

    # spheres and capsules
    for L in range(scene.n_round_layers):
        base = scene.round_pt_off[L] + w * scene.round_pt_stride[L]
        p0 = scene.round_prim_off[L]
        cnt = scene.round_prim_cnt[L]
        ncl = (cnt + ROUND_CLUSTER - 1) // ROUND_CLUSTER
        gb = scene.round_bound_off[L] + w * ncl
        for cl in range(ncl):
            if ray_aabb(ro, inv_d, scene.round_lo[gb + cl], scene.round_hi[gb + cl], best_t):
                k0 = cl * ROUND_CLUSTER
                for k in range(k0, wp.min(k0 + ROUND_CLUSTER, cnt)):
                    q = p0 + k
                    t = ray_capsule(
                        ro, rd, scene.pts[base + scene.prim_a[q]], scene.pts[base + scene.prim_b[q]], scene.prim_r[q]
                    )
                    if t < best_t:
                        best_t = t
                        kind = KIND_ROUND
                        hit_idx = q
                        hit_base = base

    if kind == KIND_NONE:
        return view.background

    p = ro + best_t * rd
    if kind == KIND_GROUND:
        hit_normal = wp.vec3(0.0, 0.0, 1.0)
        hit_color = scene.ground_color
        if scene.checker_size > 0.0:
            cx = int(wp.floor(p[0] / scene.checker_size))
            cy = int(wp.floor(p[1] / scene.checker_size))
            if ((cx + cy) & 1) == 1:
                hit_color = hit_color * 0.9
    elif kind == KIND_BOX:
        R = scene.box_rot[hit_idx]
        pl = wp.transpose(R) * (p - scene.box_center[hit_idx])
        hit_normal = R * box_normal_local(pl, scene.box_half[hit_idx])
        hit_color = scene.box_color[hit_base]
    elif kind == KIND_MESH:
        f = mesh_face % scene.tris_per_world
        if mesh_sign > 0.0:
            hit_color = scene.face_front[f]
        else:
            hit_color = scene.face_back[f]
    else:
        a = scene.pts[hit_base + scene.prim_a[hit_idx]]
        b = scene.pts[hit_base + scene.prim_b[hit_idx]]
        ba = b - a
        baba = wp.dot(ba, ba)
        s = float(0.0)
        if baba > 1.0e-14:
            s = wp.clamp(wp.dot(p - a, ba) / baba, 0.0, 1.0)
        hit_normal = wp.normalize(p - (a + s * ba))
        hit_color = scene.prim_color[hit_idx]

    # two-sided: the geometric normal faces the viewer
    if wp.dot(hit_normal, rd) > 0.0:
        hit_normal = -hit_normal
    shade_normal = hit_normal
    if kind == KIND_MESH and scene.smooth != 0:
        f3 = mesh_face * 3
        ns = (
            mesh_u * scene.vertex_normals[scene.mesh_indices[f3]]
            + mesh_v * scene.vertex_normals[scene.mesh_indices[f3 + 1]]
            + (1.0 - mesh_u - mesh_v) * scene.vertex_normals[scene.mesh_indices[f3 + 2]]
        )
        len_ns = wp.length(ns)
        if len_ns > 1.0e-12:
            ns = ns / len_ns
            if wp.dot(ns, hit_normal) < 0.0:
                ns = -ns
            shade_normal = ns
    ndl = wp.max(wp.dot(shade_normal, view.light_dir), 0.0)
    if view.shadows != 0 and ndl > 0.0:
        if occluded(scene, p + hit_normal * 1.0e-4, view.light_dir, w, root, view.max_dist):
            ndl = 0.0
    return hit_color * (view.ambient + view.diffuse * ndl)


# ---------------------------------------------------------------------------- kernels
@wp.kernel
def round_cluster_bounds(
    scene: SceneData,
    lo: wp.array(dtype=wp.vec3),
    hi: wp.array(dtype=wp.vec3),
):
    """Bounding box of each cluster of ROUND_CLUSTER spheres/capsules, per layer and world."""
    g = wp.tid()
    L = scene.round_bound_layer[g]
    cnt = scene.round_prim_cnt[L]
    ncl = (cnt + ROUND_CLUSTER - 1) // ROUND_CLUSTER
    rel = g - scene.round_bound_off[L]
    w = rel // ncl
    cl = rel - w * ncl
    base = scene.round_pt_off[L] + w * scene.round_pt_stride[L]
    p0 = scene.round_prim_off[L]
    k0 = cl * ROUND_CLUSTER
    b_lo = wp.vec3(BIG)
    b_hi = wp.vec3(-BIG)
    for k in range(k0, wp.min(k0 + ROUND_CLUSTER, cnt)):
        q = p0 + k
        a = scene.pts[base + scene.prim_a[q]]
        b = scene.pts[base + scene.prim_b[q]]
        r = wp.vec3(scene.prim_r[q])
        b_lo = wp.min(b_lo, wp.min(a, b) - r)
        b_hi = wp.max(b_hi, wp.max(a, b) + r)
    lo[g] = b_lo
    hi[g] = b_hi


@wp.kernel
def accumulate_vertex_normals(
    points: wp.array(dtype=wp.vec3),
    indices: wp.array(dtype=int),
    normals: wp.array(dtype=wp.vec3),
):
    """Area-weighted vertex normals (``normals`` must be zeroed first; normalised when used)."""
    f = wp.tid()
    i = indices[3 * f]
    j = indices[3 * f + 1]
    k = indices[3 * f + 2]
    p = points[i]
    n = wp.cross(points[j] - p, points[k] - p)
    wp.atomic_add(normals, i, n)
    wp.atomic_add(normals, j, n)
    wp.atomic_add(normals, k, n)


@wp.kernel
def render_kernel(
    scene: SceneData,
    view: ViewData,
    supersample: int,
    cols_per_thread: int,
    out: wp.array4d(dtype=wp.uint8),
):
    """Thread (w, i, c) shades columns [c*cols_per_thread, ...) of row i of world w.

    On CPU one thread per row amortises the per-thread argument copies; on CUDA use 1.
    """
    w, i, c = wp.tid()
    height = out.shape[1]
    width = out.shape[2]
    root = int(-1)
    if scene.has_mesh != 0:
        root = wp.mesh_get_group_root(scene.mesh_id, w)
    inv_ss = 1.0 / float(supersample)
    j0 = c * cols_per_thread
    j1 = wp.min(j0 + cols_per_thread, width)
    for j in range(j0, j1):
        acc = wp.vec3(0.0)
        for sy in range(supersample):
            for sx in range(supersample):
                px = ((float(j) + (float(sx) + 0.5) * inv_ss) / float(width)) * 2.0 - 1.0
                py = 1.0 - ((float(i) + (float(sy) + 0.5) * inv_ss) / float(height)) * 2.0
                rd = wp.normalize(view.forward + px * view.right + py * view.up)
                acc = acc + shade_ray(scene, view, view.origin, rd, w, root)
        col = acc * (inv_ss * inv_ss)
        out[w, i, j, 0] = wp.uint8(wp.clamp(col[0] * 255.0 + 0.5, 0.0, 255.0))
        out[w, i, j, 1] = wp.uint8(wp.clamp(col[1] * 255.0 + 0.5, 0.0, 255.0))
        out[w, i, j, 2] = wp.uint8(wp.clamp(col[2] * 255.0 + 0.5, 0.0, 255.0))
