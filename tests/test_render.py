"""Headless ray-caster: pixels land where the camera math says, batching, validation."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from lfd_envs.render import (
    BoxLayer,
    Camera,
    CapsuleChainLayer,
    Renderer,
    SphereLayer,
    TriangleMeshLayer,
    grid_triangles,
    save_png,
)

RED = (1.0, 0.0, 0.0)
GREEN = (0.0, 1.0, 0.0)
BLUE = (0.0, 0.0, 1.0)
BG = (0.2, 0.2, 0.2)
OBLIQUE = Camera(position=(0.3, -0.7, 0.8), look_at=(0.0, 0.0, 0.05), fov_y_deg=45.0)


def flat_renderer(size: int = 32, camera: Camera = OBLIQUE, **kw) -> Renderer:
    """ambient=1 -> unshaded colours, so pixels equal round(255 * colour)."""
    kw.setdefault("ground", False)
    return Renderer(size, size, camera, background=BG, ambient=1.0, **kw)


def u8(color) -> np.ndarray:
    return np.round(np.asarray(color) * 255).astype(np.uint8)


def cloth_grid(n: int = 10, size: float = 0.4, z: float = 0.0, shift=(0.0, 0.0)) -> np.ndarray:
    xs = np.linspace(-size / 2, size / 2, n)
    X, Y = np.meshgrid(xs + shift[0], xs + shift[1])  # column index along +x, row along +y
    return np.stack([X.ravel(), Y.ravel(), np.full(n * n, z)], axis=1).astype(np.float32)


# ---------------------------------------------------------------------------- camera
def test_project_centre_and_behind():
    uv = OBLIQUE.project([OBLIQUE.look_at, (0.3, -1.5, 1.6)], 32, 24)
    assert np.allclose(uv[0], (16.0, 12.0))
    assert np.all(np.isnan(uv[1]))  # behind the camera
    assert OBLIQUE.is_visible([OBLIQUE.look_at, (0.3, -1.5, 1.6), (50.0, 0.0, 0.0)], 32, 24).tolist() == [
        True,
        False,
        False,
    ]
    with pytest.raises(ValueError):
        Camera(position=(0, 0, 1), look_at=(0, 0, 0), up=(0, 0, 1))  # up parallel to view
    with pytest.raises(ValueError):
        Camera(position=(0, 0, 1), look_at=(0, 0, 1))
    with pytest.raises(ValueError):
        Camera(position=(0, 0, float("nan")))
    with pytest.raises(ValueError):
        Camera(position=(0, 0, 1), fov_y_deg=180)


@pytest.mark.parametrize("size", [32, 256])
def test_sphere_lands_on_projected_pixel(size):
    point = np.array([0.12, 0.05, 0.1])
    r = flat_renderer(size)
    img = r.render_single([SphereLayer(point[None, None], radii=0.03, colors=RED)])
    assert img.shape == (size, size, 3) and img.dtype == np.uint8
    row, col = OBLIQUE.pixel(point, size, size)
    assert np.array_equal(img[row, col], u8(RED))
    assert np.array_equal(img[0, 0], u8(BG)) and np.array_equal(img[-1, -1], u8(BG))
    # the sphere's projected extent matches the red pixel blob (within a pixel)
    red = np.argwhere(np.all(img == u8(RED), axis=-1))
    centre_uv = red.mean(axis=0)[::-1] + 0.5
    assert np.allclose(centre_uv, OBLIQUE.project(point, size, size), atol=max(1.0, size / 32))


def test_non_square_image_and_pixel_mapping():
    cam = Camera(position=(0.0, 0.0, 1.0), look_at=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov_y_deg=60.0)
    r = Renderer(48, 20, cam, background=BG, ambient=1.0, ground=False)
    pts = np.array([[[0.3, 0.2, 0.0], [-0.3, -0.15, 0.0]]], np.float32)
    img = r.render([SphereLayer(pts, 0.02, colors=[RED, GREEN])])[0]
    assert img.shape == (20, 48, 3)
    assert np.array_equal(img[cam.pixel(pts[0, 0], 48, 20)], u8(RED))
    assert np.array_equal(img[cam.pixel(pts[0, 1], 48, 20)], u8(GREEN))
    # +x is to the right, +y (camera up) is towards row 0
    assert cam.pixel(pts[0, 0], 48, 20)[1] > 24 and cam.pixel(pts[0, 0], 48, 20)[0] < 10


# ---------------------------------------------------------------------------- cloth
def test_cloth_front_and_back_colours():
    pts = cloth_grid(z=0.2)
    tri = grid_triangles(10, 10)
    cloth = TriangleMeshLayer(pts[None], tri, front_color=RED, back_color=BLUE)
    above = Camera(position=(0.05, 0.02, 1.0), look_at=(0.0, 0.0, 0.2), up=(0, 1, 0))
    below = Camera(position=(0.05, 0.02, -0.6), look_at=(0.0, 0.0, 0.2), up=(0, 1, 0))
    img_above = flat_renderer(camera=above).render_single([cloth])
    img_below = flat_renderer(camera=below).render_single([cloth])
    assert np.array_equal(img_above[16, 16], u8(RED))
    assert np.array_equal(img_below[16, 16], u8(BLUE))
    # reversing the winding swaps the sides
    flipped = TriangleMeshLayer(pts[None], tri[:, ::-1], front_color=RED, back_color=BLUE)
    assert np.array_equal(flat_renderer(camera=above).render_single([flipped])[16, 16], u8(BLUE))


def test_shaded_scene_looks_sane(tmp_path):
    """Default lighting and ground: cloth lit from above is brighter than its ambient level."""
    r = Renderer(64, 64, OBLIQUE, shadows=True, supersample=2)
    pts = cloth_grid(20, z=0.01)
    img = r.render_single(
        [
            TriangleMeshLayer(pts[None], grid_triangles(20, 20)),
            SphereLayer(np.array([[[0.0, 0.0, 0.15]]]), 0.03),
            BoxLayer(np.array([[0.3, 0.2, 0.05]]), half_extents=(0.05, 0.05, 0.05)),
        ]
    )
    row, col = OBLIQUE.pixel((0.1, -0.1, 0.01), 64, 64)
    front = np.asarray(r.render_single([TriangleMeshLayer(pts[None], grid_triangles(20, 20))])[row, col], float)
    assert front[0] > front[2] + 60  # reddish front colour
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 20  # shading, checker, shadows
    flat = Renderer(64, 64, OBLIQUE, smooth_shading=False).render_single(
        [TriangleMeshLayer(pts[None], grid_triangles(20, 20))]
    )
    assert np.abs(flat.astype(int) - r.render_single([TriangleMeshLayer(pts[None], grid_triangles(20, 20))])).max() < 80
    path = save_png(tmp_path / "scene.png", img, scale=2)
    from PIL import Image

    back = np.asarray(Image.open(path))
    assert back.shape == (128, 128, 3) and np.array_equal(back[::2, ::2], img)


def test_cloth_refit_follows_points_and_topology_change():
    r = flat_renderer()
    tri = grid_triangles(10, 10)
    a = r.render_single([TriangleMeshLayer(cloth_grid(shift=(-0.25, 0))[None], tri, RED, RED)])
    b = r.render_single([TriangleMeshLayer(cloth_grid(shift=(0.25, 0))[None], tri, RED, RED)])
    fresh = flat_renderer().render_single([TriangleMeshLayer(cloth_grid(shift=(0.25, 0))[None], tri, RED, RED)])
    assert not np.array_equal(a, b)
    assert np.array_equal(b, fresh)  # refitted BVH gives the same picture as a fresh build
    # a different resolution (topology) is rebuilt transparently
    c = r.render_single([TriangleMeshLayer(cloth_grid(6, shift=(0.25, 0))[None], grid_triangles(6, 6), RED, RED)])
    assert np.array_equal(c, fresh)


# ---------------------------------------------------------------------------- other primitives
def test_capsule_chain_and_box_pixels():
    r = flat_renderer()
    rope = np.array([[[-0.2, 0.0, 0.02], [0.0, 0.1, 0.02], [0.2, 0.0, 0.02]]], np.float32)
    box_c = np.array([[[0.0, -0.2, 0.05]]], np.float32)
    quat = np.array([0.0, 0.0, np.sin(np.pi / 8), np.cos(np.pi / 8)])  # 45 deg about z
    layers = [
        CapsuleChainLayer(rope, radius=0.02, colors=GREEN),
        BoxLayer(box_c, half_extents=(0.06, 0.02, 0.05), rotations=quat[None], colors=BLUE),
    ]
    img = r.render_single(layers)
    mid = 0.5 * (rope[0, 0] + rope[0, 1])
    assert np.array_equal(img[OBLIQUE.pixel(mid, 32, 32)], u8(GREEN))
    assert np.array_equal(img[OBLIQUE.pixel(box_c[0, 0], 32, 32)], u8(BLUE))
    # rotation as a matrix gives the same image as the quaternion
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    layers[1] = BoxLayer(box_c, half_extents=(0.06, 0.02, 0.05), rotations=R[None, None], colors=BLUE)
    assert np.array_equal(r.render_single(layers), img)


def test_warp_arrays_match_numpy():
    pts = np.stack([cloth_grid(8), cloth_grid(8, shift=(0.1, 0.05))])  # (2, 64, 3)
    pick = np.array([[[0.1, 0.1, 0.1]], [[-0.1, 0.0, 0.15]]], np.float32)
    tri = grid_triangles(8, 8)
    r = flat_renderer()
    ref = r.render([TriangleMeshLayer(pts, tri), SphereLayer(pick, 0.03)], num_worlds=2)
    wp_pts = wp.array(pts.reshape(-1, 3), dtype=wp.vec3, device="cpu")
    wp_pick = wp.array(pick.reshape(-1, 3), dtype=wp.vec3, device="cpu")
    out = flat_renderer().render([TriangleMeshLayer(wp_pts, tri), SphereLayer(wp_pick, 0.03)], num_worlds=2)
    assert np.array_equal(ref, out)


def test_box_layer_from_flat_warp_arrays():
    """The engine's layout: flat W*B arrays of vec3 / mat33 / quat."""
    W, B = 2, 2
    centers = np.array([[[0.1, 0.0, 0.04], [-0.1, 0.1, 0.03]], [[0.0, -0.1, 0.05], [0.2, 0.1, 0.02]]], np.float32)
    half = np.array([[[0.03, 0.02, 0.04], [0.05, 0.02, 0.03]], [[0.02, 0.02, 0.05], [0.04, 0.04, 0.02]]], np.float32)
    angle = np.array([[0.3, 0.0], [0.7, -0.4]])
    quat = np.stack([np.zeros_like(angle), np.zeros_like(angle), np.sin(angle / 2), np.cos(angle / 2)], -1)
    ref = flat_renderer().render([BoxLayer(centers, half, quat, colors=[RED, GREEN])])
    mats = np.zeros((W, B, 3, 3), np.float32)
    mats[..., 0, 0] = mats[..., 1, 1] = np.cos(angle)
    mats[..., 0, 1], mats[..., 1, 0], mats[..., 2, 2] = -np.sin(angle), np.sin(angle), 1.0
    for rot in (wp.array(mats.reshape(-1, 3, 3), dtype=wp.mat33), wp.array(quat.reshape(-1, 4), dtype=wp.quat)):
        layer = BoxLayer(
            wp.array(centers.reshape(-1, 3), dtype=wp.vec3),
            wp.array(half.reshape(-1, 3), dtype=wp.vec3),
            rot,
            colors=[RED, GREEN],
        )
        out = flat_renderer().render([layer], num_worlds=W)
        assert np.mean(np.any(out != ref, axis=-1)) < 0.002  # float32 vs float64 rotations at edges
    assert not np.array_equal(ref[0], ref[1])


# ---------------------------------------------------------------------------- batching
def test_batched_worlds_equal_single_renders():
    tri = grid_triangles(10, 10)
    cloth = np.stack([cloth_grid(shift=(-0.1, 0.0)), cloth_grid(z=0.05, shift=(0.15, 0.1))])
    pickers = np.array([[[0.0, 0.0, 0.1], [0.2, 0.2, 0.1]], [[-0.2, 0.1, 0.2], [0.1, -0.2, 0.05]]], np.float32)
    rope = np.stack([np.linspace([-0.3, -0.25, 0.01], [0.3, -0.2, 0.01], 12)] * 2).astype(np.float32)
    rope[1, :, 1] += 0.1
    table = BoxLayer(np.array([[0.0, 0.0, -0.02]]), half_extents=(0.5, 0.5, 0.02), colors=(0.5, 0.4, 0.3))
    blocks = BoxLayer(np.array([[[0.3, 0.0, 0.03]], [[0.25, 0.1, 0.03]]]), half_extents=(0.03, 0.03, 0.03))

    def layers(sel):
        return [
            TriangleMeshLayer(cloth[sel], tri),
            SphereLayer(pickers[sel], 0.02),
            CapsuleChainLayer(rope[sel], 0.01),
            table,
            blocks if sel == slice(None) else BoxLayer(blocks.centers[sel], blocks.half_extents),
        ]

    for size in (32, 96):
        r = Renderer(size, size, OBLIQUE, shadows=True)
        both = r.render(layers(slice(None)))
        assert both.shape == (2, size, size, 3)
        assert not np.array_equal(both[0], both[1])
        single = Renderer(size, size, OBLIQUE, shadows=True)
        for w in range(2):
            assert np.array_equal(both[w], single.render(layers(slice(w, w + 1)))[0])


def test_static_layers_shared_by_all_worlds():
    r = flat_renderer()
    quad = cloth_grid(4)
    shared = TriangleMeshLayer(quad, grid_triangles(4, 4), RED, RED, offset_by_world=False)
    spheres = SphereLayer(np.array([[0.25, 0.25, 0.05]]), 0.03, GREEN)  # (S, 3): same in every world
    imgs = r.render([shared, spheres], num_worlds=3)
    assert imgs.shape[0] == 3 and np.array_equal(imgs[0], imgs[2])
    per_world = TriangleMeshLayer(quad[None], grid_triangles(4, 4), RED, RED)
    assert np.array_equal(imgs[0], r.render_single([per_world, spheres]))


# ---------------------------------------------------------------------------- validation
def test_bad_input_raises_value_error():
    tri = grid_triangles(4, 4)
    good = cloth_grid(4)[None]
    r = flat_renderer()
    bad_pts = good.copy()
    bad_pts[0, 3, 2] = np.nan
    cases = [
        lambda: r.render([TriangleMeshLayer(bad_pts, tri)]),
        lambda: r.render([TriangleMeshLayer(good, tri + 100)]),  # index out of range
        lambda: r.render([TriangleMeshLayer(good, tri)], num_worlds=2),  # world count mismatch
        lambda: r.render([SphereLayer(np.zeros((2, 3, 3)), radii=[0.1, 0.2])]),  # radii length
        lambda: r.render([SphereLayer(np.zeros((1, 3, 3)), colors=[(1, 0, 0)] * 2)]),
        lambda: r.render([BoxLayer(np.zeros((1, 2, 3)), half_extents=(0.1, -0.1, 0.1))]),
        lambda: r.render([BoxLayer(np.zeros((1, 2, 3)), half_extents=(0.1, 0.1, 0.1), rotations=np.zeros((2, 3)))]),
        lambda: r.render(["not a layer"]),
        lambda: r.render([], num_worlds=0),
        lambda: r.render([SphereLayer(np.zeros((1, 1, 3))), SphereLayer(np.zeros((2, 1, 3)))]),
        lambda: TriangleMeshLayer(good, np.zeros((3, 2), int)),
        lambda: TriangleMeshLayer(good, tri, front_color=(2.0, 0.0)),
        lambda: TriangleMeshLayer(np.zeros((1, 0, 3)), tri),
        lambda: SphereLayer(np.zeros((1, 1, 3)), radii=0.0),
        lambda: SphereLayer(np.zeros((1, 1, 3)), radii=float("inf")),
        lambda: CapsuleChainLayer(np.zeros((1, 4, 2))),
        lambda: Renderer(0, 32),
        lambda: Renderer(32, 32, supersample=9),
        lambda: Renderer(32, 32, ambient=2.0),
        lambda: Renderer(32, 32, light_direction=(0, 0, 0)),
        lambda: save_png("/tmp/x.png", np.zeros((4, 4))),
    ]
    for k, case in enumerate(cases):
        with pytest.raises(ValueError):
            case()
    # the renderer is still usable after errors
    assert r.render([TriangleMeshLayer(good, tri)]).shape == (1, 32, 32, 3)


def test_reset_cache_rebuilds_and_keeps_output():
    tri = grid_triangles(10, 10)
    layers = [TriangleMeshLayer(cloth_grid()[None], tri), SphereLayer(np.zeros((1, 1, 3)) + 0.1, 0.02)]
    r = Renderer(32, 32, OBLIQUE)
    a = r.render(layers)
    old_mesh = r._mesh
    r.reset_cache()
    b = r.render(layers)
    assert r._mesh is not old_mesh and np.array_equal(a, b)


@pytest.mark.skipif(not wp.is_cuda_available(), reason="no CUDA device")
def test_cuda_matches_cpu():
    tri = grid_triangles(10, 10)
    cloth = np.stack([cloth_grid(), cloth_grid(z=0.05, shift=(0.1, 0.1))])
    layers = [
        TriangleMeshLayer(cloth, tri),
        SphereLayer(np.array([[[0.0, 0.0, 0.1]], [[0.1, 0.0, 0.2]]]), 0.03),
        CapsuleChainLayer(np.stack([np.linspace([-0.3, -0.25, 0.01], [0.3, -0.2, 0.01], 12)] * 2), 0.01),
        BoxLayer(np.array([[0.3, 0.0, 0.03]]), half_extents=(0.03, 0.03, 0.03)),
    ]
    cpu = Renderer(64, 64, OBLIQUE, shadows=True).render(layers)
    gpu = Renderer(64, 64, OBLIQUE, shadows=True, device="cuda:0").render(layers)
    assert gpu.shape == cpu.shape
    # fast-math differences may flip a few edge pixels
    assert np.mean(np.any(cpu != gpu, axis=-1)) < 0.01
    # warp inputs that already live on the GPU
    wp_cloth = wp.array(cloth.reshape(-1, 3), dtype=wp.vec3, device="cuda:0")
    layers[0] = TriangleMeshLayer(wp_cloth, tri)
    gpu2 = Renderer(64, 64, OBLIQUE, shadows=True, device="cuda:0").render(layers, num_worlds=2)
    assert np.array_equal(gpu2, gpu)
