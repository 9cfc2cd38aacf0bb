"""The multi-view texture bake (solver/texture/bake.py) on small synthetic meshes with coded
photos, plus checks on the real head model."""

import numpy as np
import pytest

from solver import FitResult, OrthographicCamera
from solver.io.export import texture_atlas
from solver.texture.bake import (
    CLOTHES_MODES,
    BakeOptions,
    bake_fit_texture,
    bake_photo_size,
    bake_texture,
    bake_tiles,
)
from solver.texture.uvs import resolve_parts, uv_raster, uv_tiles
from tests.solver.texture.support import H, W, coded_photo, two_sheets, uv_sphere


def texel_colours(model, tex, size, **kw):
    r = uv_raster(model, size, **kw)
    return r, tex.reshape(-1, 3)[r.texel]


# ---------------------------------------------------------------------------------------
# the bake
# ---------------------------------------------------------------------------------------

def test_coded_photo_lands_on_the_right_texels():
    m = uv_sphere()
    cam = OrthographicCamera.nominal("orthographic-front", (W, H))
    tex = bake_texture(m, m.vertices, [(coded_photo(), cam)], 128, mirror=False)
    assert tex.shape == (128, 128, 3) and tex.dtype == np.float32
    r, got = texel_colours(m, tex, 128)
    pts = r.interp @ m.vertices
    normal = pts / np.linalg.norm(pts, axis=1, keepdims=True)
    px = cam.project(pts)
    front = -normal[:, 1] > 0.5
    assert front.sum() > 1000
    np.testing.assert_allclose(got[front, 0], px[front, 0] / W, atol=1e-4)
    np.testing.assert_allclose(got[front, 1], px[front, 1] / H, atol=1e-4)


def test_perspective_camera_bakes_within_a_fraction_of_a_pixel():
    from solver.cameras.dlt import DLTCamera

    w, h = 192, 256
    k = np.array([[300.0, 0, w / 2], [0, 300.0, h / 2], [0, 0, 1]])
    rot = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # front view, as orthographic-front
    cam = DLTCamera.from_krc(k, rot, [0.0, -0.6, 0.0], (w, h))
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    img = np.stack([xx / w, yy / h, np.full_like(xx, 0.5)], -1).astype(np.float32)
    m = uv_sphere()
    tex = bake_texture(m, m.vertices, [(img, cam)], 256)
    r, got = texel_colours(m, tex, 256)
    pts = r.interp @ m.vertices
    n = pts / np.linalg.norm(pts, axis=1, keepdims=True)
    facing = np.einsum("ij,ij->i", n, cam.toward_camera(pts)) > 0.5
    assert facing.sum() > 1000
    err_px = np.abs(got[facing, :2] - cam.project(pts[facing]) / [w, h]) * [w, h]
    assert err_px.max() < 0.1


def test_red_left_blue_right_and_smooth_fill_of_the_unseen_back():
    m = uv_sphere()
    cam = OrthographicCamera.nominal("orthographic-front", (W, H))
    img = np.zeros((H, W, 3), np.float32)
    img[:, : W // 2, 0] = 1.0  # image left = subject's right (-X): red
    img[:, W // 2:, 2] = 1.0   # image right = subject's left (+X): blue
    tex = bake_texture(m, m.vertices, [(img, cam)], 128, mirror=False)
    r, got = texel_colours(m, tex, 128)
    pts = r.interp @ m.vertices
    n = pts / np.linalg.norm(pts, axis=1, keepdims=True)
    front = -n[:, 1] > 0.5  # squarely seen: weight above BakeOptions.fill_weight
    assert np.all(got[front & (n[:, 0] < -0.15)] @ [1, 0, -1] > 0.95)  # red
    assert np.all(got[front & (n[:, 0] > 0.15)] @ [1, 0, -1] < -0.95)  # blue
    # The back is seen by no photo: filled, within the seen range, and following the rim
    # (red side stays reddish, blue side bluish).
    back = n[:, 1] > 0.3
    assert np.isfinite(got).all() and got.min() >= 0 and got.max() <= 1 + 1e-6
    sides = back & (np.abs(n[:, 2]) < 0.5)  # away from the poles, where the rim flips
    assert np.all(got[sides & (n[:, 0] < -0.7)] @ [1, 0, -1] > 0.2)
    assert np.all(got[sides & (n[:, 0] > 0.7)] @ [1, 0, -1] < -0.2)
    assert np.allclose(got.sum(axis=1), 1.0, atol=1e-4)  # every texel a red/blue blend
    # smooth: neighbouring filled texels differ little (the photo edge itself is sharp)
    grid = np.full((128, 128), np.nan)
    grid.flat[r.texel[back]] = got[back, 0]
    step = np.nanmax(np.abs(np.diff(grid, axis=1)))
    assert step < 0.1


def test_hole_fill_takes_the_value_between_its_rim():
    m = two_sheets()
    cam = OrthographicCamera.nominal("orthographic-front", (W, H))
    img = np.ones((H, W, 4), np.float32)
    # left half dark, right half bright; the back sheet's middle is hidden by the front
    # sheet, so its hole must bridge the two smoothly
    img[:, : W // 2, :3] = 0.2
    img[:, W // 2:, :3] = 0.8
    tex = bake_texture(m, m.vertices, [(img, cam)], 128, parts=["Head and Neck"])
    r, got = texel_colours(m, tex, 128, parts=["Head and Neck"])
    pts = r.interp @ m.vertices
    hidden = (np.abs(pts[:, 0]) < 0.025) & (np.abs(pts[:, 2]) < 0.025)
    assert hidden.sum() > 50
    g = got[hidden, 0]
    assert g.min() > 0.2 + 1e-3 and g.max() < 0.8 - 1e-3  # strictly between the rims
    # monotone across the hole from the dark to the bright side
    order = np.argsort(pts[hidden, 0])
    xs, gs = pts[hidden, 0][order], g[order]
    assert np.corrcoef(xs, gs)[0, 1] > 0.9
    # no texel inside the island is left at the background mean colour
    assert np.all(np.isfinite(got))


def test_occluded_texels_do_not_receive_the_front_colour():
    m = two_sheets()
    cam = OrthographicCamera.nominal("orthographic-front", (W, H))
    px = cam.project(np.array([[-0.03, 0, 0.03], [0.03, 0, -0.03]]))
    img = np.zeros((H, W, 3), np.float32)
    img[..., 2] = 1.0  # blue everywhere ...
    u0, v0 = np.round(px[0]).astype(int)  # pixels whose centres the sheet covers
    u1, v1 = np.round(px[1]).astype(int)
    img[v0:v1, u0:u1] = [1.0, 0.0, 0.0]  # ... red where the front sheet is
    tex = bake_texture(m, m.vertices, [(img, cam)], 128)
    r, got = texel_colours(m, tex, 128)
    pts = r.interp @ m.vertices
    front = pts[:, 1] < 0
    inner = (np.abs(pts[:, 0]) < 0.025) & (np.abs(pts[:, 2]) < 0.025)
    assert np.all(got[front & inner, 0] > 0.99)          # the front sheet is red
    behind = ~front & inner
    assert behind.sum() > 50
    assert np.all(got[behind, 2] > 0.9) and np.all(got[behind, 0] < 0.1)  # not red
    # Without the front sheet in the depth buffer the same texels would be red.
    only = bake_texture(m, m.vertices, [(img, cam)], 128, parts=["Head and Neck"],
                        occluders=["Head and Neck"])
    r2, got2 = texel_colours(m, only, 128, parts=["Head and Neck"])
    p2 = r2.interp @ m.vertices
    inner2 = (np.abs(p2[:, 0]) < 0.025) & (np.abs(p2[:, 2]) < 0.025)
    assert np.all(got2[inner2, 0] > 0.99)


def _stripes():
    img = np.zeros((H, W, 3), np.float32)
    red = (np.arange(W) // 6) % 2 == 0
    img[:, red, 0] = 1.0
    img[:, ~red, 2] = 1.0
    return img


def test_mirrored_profile_fills_the_far_side():
    m = uv_sphere()
    cam = OrthographicCamera.nominal("orthographic-right", (W, H))  # sees -X
    img = _stripes()
    r = uv_raster(m, 256)
    pts = r.interp @ m.vertices
    n = pts / np.linalg.norm(pts, axis=1, keepdims=True)
    # the right camera ignores x: a far-side point and its mirror image share a pixel
    px = cam.project(pts)
    expect_red = (np.floor(px[:, 0]) // 6) % 2 == 0
    edge = np.abs(px[:, 0] / 6 - np.round(px[:, 0] / 6)) < 0.15  # stripe borders blend
    far = (n[:, 0] > 0.7) & ~edge
    assert far.sum() > 500
    near = (n[:, 0] < -0.7) & ~edge

    def red_match(tex, sel):
        got = tex.reshape(-1, 3)[r.texel][sel]
        return np.mean((got[:, 0] > got[:, 2]) == expect_red[sel])

    mirrored = bake_texture(m, m.vertices, [(img, cam)], 256)  # mirror=True: auto
    assert red_match(mirrored, near) > 0.99
    assert red_match(mirrored, far) > 0.99
    plain = bake_texture(m, m.vertices, [(img, cam)], 256, mirror=False)
    assert red_match(plain, near) > 0.99
    assert red_match(plain, far) < 0.8  # the smooth fill cannot invent the stripes
    # per-view flags say the same
    np.testing.assert_array_equal(
        bake_texture(m, m.vertices, [(img, cam)], 256, mirror=[True]), mirrored)
    np.testing.assert_array_equal(
        bake_texture(m, m.vertices, [(img, cam)], 256, mirror=[False]), plain)
    # the front photo is never mirrored
    front = OrthographicCamera.nominal("orthographic-front", (W, H))
    a = bake_texture(m, m.vertices, [(coded_photo(), front)], 64, mirror=True)
    b = bake_texture(m, m.vertices, [(coded_photo(), front)], 64, mirror=False)
    np.testing.assert_array_equal(a, b)


def test_mirror_uses_the_fitted_similarity():
    m = uv_sphere()
    ang = np.radians(25)
    rot = np.array([[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1]])
    scale, trans = 1.1, np.array([0.01, -0.02, 0.03])
    world = scale * m.vertices @ rot.T + trans
    cam = OrthographicCamera.nominal("orthographic-right", (W, H))
    img = coded_photo()
    # colours coded by position differ between the direct and the mirrored pass by design:
    # no equalisation, which would match them
    tex = bake_texture(m, world, [(img, cam)], 128, similarity=(scale, rot, trans),
                       options=BakeOptions(equalise=False))
    r, got = texel_colours(m, tex, 128)
    local = r.interp @ m.vertices
    n_local = local / np.linalg.norm(local, axis=1, keepdims=True)
    toward = -cam.rotation[2]
    direct = (n_local @ rot.T) @ toward
    mirrored = (n_local * [-1, 1, 1]) @ rot.T @ toward
    only_mirror = (direct < 0) & (mirrored > 0.6)
    assert only_mirror.sum() > 200
    p_mirror = scale * (local * [-1, 1, 1]) @ rot.T + trans
    px = cam.project(p_mirror[only_mirror])
    np.testing.assert_allclose(got[only_mirror, 0], px[:, 0] / W, atol=1e-3)
    np.testing.assert_allclose(got[only_mirror, 1], px[:, 1] / H, atol=1e-3)


def test_feathering_keeps_the_photo_background_off_the_outline():
    """The fitted sphere is 5 % larger than the disc in the photo: near its outline the
    photo shows background (red). The outline feather fades the photo there, so the rim
    leans on the head's colour (blue) from further in instead."""
    m = uv_sphere()
    cam = OrthographicCamera.nominal("orthographic-front", (W, H))
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    rho = np.hypot(xx - W / 2, yy - H / 2) / cam.scale  # metres from the centre
    img = np.zeros((H, W, 3), np.float32)
    img[rho < 0.095] = [0, 0, 1]
    img[rho >= 0.095] = [1, 0, 0]
    r = uv_raster(m, 128)
    pts = r.interp @ m.vertices
    rim = (pts[:, 1] < 0) & (np.hypot(pts[:, 0], pts[:, 2]) > 0.093)
    assert rim.sum() > 100
    red = {}
    for feather in (0.0, BakeOptions().feather):
        tex = bake_texture(m, m.vertices, [(img, cam)], 128, mirror=False,
                           options=BakeOptions(feather=feather))
        red[feather] = tex.reshape(-1, 3)[r.texel][rim, 0].mean()
    assert red[0.0] > 0.15  # without fading the background shows on the rim
    assert red[BakeOptions().feather] < 0.5 * red[0.0]


def test_bake_from_a_fit_result_uses_its_pose_and_cameras():
    m = uv_sphere()
    ang = np.radians(-30)
    rot = np.array([[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1]])
    cams = {"front": OrthographicCamera.nominal("orthographic-front", (W, H)),
            "right": OrthographicCamera.nominal("orthographic-right", (W, H))}
    n = len(m.vertices)
    result = FitResult("combined", 0.9, rot, np.array([0.0, 0.01, 0.0]), np.zeros(0),
                       np.zeros(0), (), np.zeros((n, 3)), m.vertices, cams, {}, np.zeros(n))
    images = {"front": coded_photo(), "right": _stripes()}
    # a sphere has no cheeks or chin to tell clothes by (test_clothes.py bakes a head)
    got = bake_fit_texture(m, result, images, 64, options=BakeOptions(clothes="keep"))
    want = bake_tiles(m, result.world_vertices, [(images["front"], cams["front"]),
                                                 (images["right"], cams["right"])], 64,
                      similarity=(0.9, rot, result.translation))
    assert sorted(got) == [1001]
    np.testing.assert_array_equal(got[1001], want[1001])
    with pytest.raises(ValueError, match="'left'"):
        bake_fit_texture(m, result, {"left": coded_photo()}, 64)


def test_bleed_outside_islands_and_mean_elsewhere():
    m = two_sheets()
    cam = OrthographicCamera.nominal("orthographic-front", (W, H))
    tex = bake_texture(m, m.vertices, [(coded_photo(), cam)], 128,
                       options=BakeOptions(bleed=3))
    r = uv_raster(m, 128, bleed=3)
    flat = tex.reshape(-1, 3)
    np.testing.assert_array_equal(flat[r.bleed_to], flat[r.bleed_from])
    assert r.mask.flat[r.bleed_from].all() and not r.mask.flat[r.bleed_to].any()
    rest = np.ones(128 * 128, bool)
    rest[r.texel] = False
    rest[r.bleed_to] = False
    assert rest.sum() > 100
    np.testing.assert_allclose(flat[rest], flat[r.texel].mean(axis=0)[None].repeat(
        rest.sum(), 0), atol=1e-5)


def test_alpha_zero_pixels_are_ignored():
    m = uv_sphere()
    cam = OrthographicCamera.nominal("orthographic-front", (W, H))
    img = np.ones((H, W, 4), np.float32)
    img[..., :3] = 0.3
    img[:, : W // 2] = [1.0, 0.0, 0.0, 0.0]  # red but transparent: must not show
    tex = bake_texture(m, m.vertices, [(img, cam)], 64, mirror=False)
    got = tex.reshape(-1, 3)[uv_raster(m, 64).texel]
    np.testing.assert_allclose(got, 0.3, atol=1e-5)


def test_pixels_outside_keep_are_not_baked_and_a_wrong_mask_is_named():
    m = uv_sphere()
    cam = OrthographicCamera.nominal("orthographic-front", (W, H))
    img = np.full((H, W, 3), 0.3, np.float32)
    img[:, : W // 2] = [1.0, 0.0, 0.0]  # red, but outside the mask: must not show
    keep = np.ones((H, W), bool)
    keep[:, : W // 2] = False
    tiles = bake_tiles(m, m.vertices, [(img, cam)], 64, mirror=False, keep=[keep])
    got = tiles[1001].reshape(-1, 3)[uv_raster(m, 64).texel]
    np.testing.assert_allclose(got, 0.3, atol=1e-5)
    with pytest.raises(ValueError, match=r"keep\[0\]: mask of shape \(64, 96\)"):
        bake_tiles(m, m.vertices, [(img, cam)], 64, keep=[keep[:64]])
    with pytest.raises(ValueError, match="keep: 2 masks for 1 views"):
        bake_tiles(m, m.vertices, [(img, cam)], 64, keep=[keep, keep])


def test_tiles_and_parts():
    m = two_sheets()
    m.loop_uv[m.face_loop_start[m.face_part == 1][0]:] += [1.0, 0.0]  # back sheet -> 1002
    assert uv_tiles(m) == (1001, 1002)
    assert resolve_parts(m, ["head and neck"]) == ((1,), ("Head and Neck",))
    cam = OrthographicCamera.nominal("orthographic-front", (W, H))
    tiles = bake_tiles(m, m.vertices, [(coded_photo(), cam)], 64)
    assert sorted(tiles) == [1001, 1002]
    one = bake_texture(m, m.vertices, [(coded_photo(), cam)], 64, tile=1002)
    np.testing.assert_allclose(one, tiles[1002], atol=1e-6)
    atlas, loop_uv, textured = texture_atlas(m, tiles)  # the OBJ's one image
    assert atlas.shape == (64, 128, 3)
    np.testing.assert_array_equal(atlas[:, :64], tiles[1001])
    np.testing.assert_array_equal(atlas[:, 64:], tiles[1002])
    assert textured.all()
    np.testing.assert_allclose(loop_uv, m.loop_uv * [0.5, 1.0])
    with pytest.raises(ValueError, match="tile"):
        bake_texture(m, m.vertices, [(coded_photo(), cam)], 64)
    with pytest.raises(ValueError, match="parts"):
        bake_tiles(m, m.vertices, [(coded_photo(), cam)], 64, parts=["Teeth"])


def test_a_hole_in_one_tile_is_filled_from_what_another_tile_sees():
    """The smooth fill is the mesh's, not a tile's: the sphere's unseen back half moved to
    its own UV tile (sharing the sides' vertices with the seen front half) is filled as in
    one tile, red on the subject's right and blue on the left, not the grey of a tile
    filled from nothing of its own."""
    one = uv_sphere()
    split = uv_sphere()
    back = np.repeat(split.loop_uv[split.face_loop_start, 0] < 0.5, split.face_loop_total)
    split.loop_uv[back] += [1.0, 0.0]  # longitudes 0-180 degrees (+Y, the back): 1002
    assert uv_tiles(split) == (1001, 1002)
    cam = OrthographicCamera.nominal("orthographic-front", (W, H))
    img = np.zeros((H, W, 3), np.float32)
    img[:, : W // 2, 0] = 1.0  # image left = subject's right (-X): red
    img[:, W // 2:, 2] = 1.0
    whole = bake_texture(one, one.vertices, [(img, cam)], 128, mirror=False)
    tiles = bake_tiles(split, split.vertices, [(img, cam)], 128, mirror=False)
    for tile in (1001, 1002):
        r = uv_raster(split, 128, tile=tile)
        np.testing.assert_allclose(tiles[tile].reshape(-1, 3)[r.texel],
                                   whole.reshape(-1, 3)[r.texel], atol=1e-4)
    r = uv_raster(split, 128, tile=1002)
    pts = r.interp @ split.vertices
    got = tiles[1002].reshape(-1, 3)[r.texel]
    sides = np.abs(pts[:, 2]) < 0.05
    assert np.all(got[sides & (pts[:, 0] < -0.07)] @ [1, 0, -1] > 0.2)
    assert np.all(got[sides & (pts[:, 0] > 0.07)] @ [1, 0, -1] < -0.2)


def test_bad_input_names_the_culprit():
    m = uv_sphere()
    cam = OrthographicCamera.nominal("orthographic-front", (W, H))
    good = coded_photo()
    with pytest.raises(ValueError, match=r"views\[0\].*shape"):
        bake_texture(m, m.vertices, [(good[..., 0], cam)], 32)
    with pytest.raises(ValueError, match=r"views\[1\].*96x128"):
        bake_texture(m, m.vertices, [(good, cam), (good[:, :50], cam)], 32)
    nan = good.copy()
    nan[3, 4, 1] = np.nan
    with pytest.raises(ValueError, match=r"views\[0\].*NaN"):
        bake_texture(m, m.vertices, [(nan, cam)], 32)
    with pytest.raises(ValueError, match=r"views\[0\].*camera"):
        bake_texture(m, m.vertices, [(good, "front")], 32)
    bad = m.vertices.copy()
    bad[5, 1] = np.nan
    with pytest.raises(ValueError, match="world_vertices.*row 5"):
        bake_texture(m, bad, [(good, cam)], 32)
    with pytest.raises(ValueError, match="world_vertices.*expected"):
        bake_texture(m, m.vertices[:-1], [(good, cam)], 32)
    with pytest.raises(ValueError, match="size"):
        bake_texture(m, m.vertices, [(good, cam)], 0)
    with pytest.raises(ValueError, match="views"):
        bake_texture(m, m.vertices, [], 32)
    with pytest.raises(ValueError, match="similarity"):
        bake_texture(m, m.vertices, [(good, cam)], 32, similarity=(1.0, np.eye(2), 0))
    with pytest.raises(ValueError, match="BakeOptions.power"):
        BakeOptions(power=0)


def test_clothes_modes_are_spelt_as_a_shell_takes_them():
    assert CLOTHES_MODES == ("leave-out", "keep") and BakeOptions().clothes == "leave-out"
    assert all(" " not in s for s in CLOTHES_MODES)  # no quoting in a shell
    for bad in ("leave out", "Keep", "", None):
        with pytest.raises(ValueError, match="BakeOptions.clothes"):
            BakeOptions(clothes=bad)


# ---------------------------------------------------------------------------------------
# the real head model
# ---------------------------------------------------------------------------------------

def test_real_head_photos_coloured_by_height(model):
    world = model.vertices
    w, h = 192, 256
    views = []
    for view in ("orthographic-front", "orthographic-right"):
        cam = OrthographicCamera.nominal(view, (w, h))
        # colour = world height: the photo's row v maps to z = (h/2 - v) / scale
        z = (h / 2 - (np.arange(h) + 0.5)) / cam.scale
        shade = np.clip((z + 0.15) / 0.3, 0, 1).astype(np.float32)
        img = np.repeat(shade[:, None, None], w, axis=1).repeat(3, axis=2)
        views.append((img, cam))
    tiles = bake_tiles(model, world, views, 256)
    assert sorted(tiles) == [1001, 1002]
    for tile, tex in tiles.items():
        r = uv_raster(model, 256, tile=tile)
        pts = r.interp @ world
        expect = np.clip((pts[:, 2] + 0.15) / 0.3, 0, 1)
        got = tex.reshape(-1, 3)[r.texel, 0]
        assert np.corrcoef(expect, got)[0, 1] > 0.95, tile
        assert np.median(np.abs(expect - got)) < 0.02, tile


def test_real_head_front_photo_lands_on_front_facing_skin(model):
    """A fitted-like pose (rotated, scaled, moved): every skin texel that faces the front
    camera squarely gets exactly the photo colour at its projection (ICT's winding gives
    outward normals, and the occlusion test hides no visible skin but the ears' folds)."""
    ang = np.radians(5)
    rot = np.array([[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1]])
    scale, trans = 1.05, np.array([0.01, 0.0, -0.02])
    world = scale * model.vertices @ rot.T + trans
    w, h = 192, 256
    cam = OrthographicCamera.nominal("orthographic-front", (w, h), scale=0.6 * h / 0.3)
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    img = np.stack([xx / w, yy / h, np.full_like(xx, 0.5)], -1).astype(np.float32)
    tiles = bake_tiles(model, world, [(img, cam)], 256, similarity=(scale, rot, trans))
    # vertex normals, computed independently of the bake
    tri_v, _, tri_f = model.triangles()
    skin = tri_v[np.isin(model.face_part[tri_f], resolve_parts(model)[0])]
    p = world[skin]
    fn = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    vn = np.zeros_like(world)
    for k in range(3):
        np.add.at(vn, skin[:, k], fn)
    for tile, tex in tiles.items():
        r = uv_raster(model, 256, tile=tile)
        pts = r.interp @ world
        n = r.interp @ vn
        facing = -n[:, 1] / np.linalg.norm(n, axis=1) > 0.6
        # leave out the cut at the neck's bottom: an outline in the photo, where the
        # weight rightly fades (BakeOptions.feather)
        facing &= pts[:, 2] > world[:, 2].min() + 0.04
        assert facing.sum() > 500, tile
        err = np.abs(tex.reshape(-1, 3)[r.texel, :2] - cam.project(pts) / [w, h]).max(axis=1)
        assert np.mean(err[facing] < 0.01) > 0.99, tile


def test_threads_bake_the_texture_of_one_thread(model, monkeypatch):
    """Any number of threads (``BakeOptions.threads``: blocks of texels, each photo's
    depth buffer and levelling, each tile's blend) bakes the same texture, bit for bit:
    two tiles, a profile used mirrored and levelled to the front."""
    from solver.texture import bake

    monkeypatch.setattr(bake, "SAMPLE_BLOCK", 4099)  # several blocks per tile
    rng = np.random.default_rng(3)
    views = [(rng.random((256, 192, 3), dtype=np.float32),
              OrthographicCamera.nominal(v, (192, 256)))
             for v in ("orthographic-front", "orthographic-right")]
    one = bake_tiles(model, model.vertices, views, 128, options=BakeOptions(threads=1))
    for threads in (2, 3, 0):
        many = bake_tiles(model, model.vertices, views, 128,
                          options=BakeOptions(threads=threads))
        assert sorted(many) == sorted(one) == [1001, 1002]
        for tile, tex in one.items():
            np.testing.assert_array_equal(many[tile], tex)
    with pytest.raises(ValueError, match="BakeOptions.threads"):
        BakeOptions(threads=-1)


def test_a_reduced_photo_is_sampled_where_the_full_one_would_be():
    m = two_sheets()
    cam = OrthographicCamera.nominal("orthographic-front", (W, H))
    full = coded_photo()
    half = full.reshape(H // 2, 2, W // 2, 2, 3).mean(axis=(1, 3))  # 2x2 box reduction
    r = uv_raster(m, 64)
    a = bake_texture(m, m.vertices, [(full, cam)], 64, tile=1001, raster=r)
    b = bake_texture(m, m.vertices, [(half, cam)], 64, tile=1001, raster=r)
    seen = r.texel  # the coded colour is linear in (u, v): box-reducing leaves it
    assert np.abs(a.reshape(-1, 3)[seen] - b.reshape(-1, 3)[seen]).max() < 0.02
    with pytest.raises(ValueError, match=r"image is 48x48 pixels but its camera expects "
                                         r"96x128 \(or that photo reduced\)"):
        bake_texture(m, m.vertices, [(full[:48, :48], cam)], 64, tile=1001, raster=r)


def test_bake_photo_size_reduces_big_photos_only():
    assert bake_photo_size((768, 1024), 1024) == (768, 1024)
    assert bake_photo_size((11000, 11000), 1024) == (4096, 4096)
    assert bake_photo_size((11000, 5500), 128) == (2048, 1024)


# ---------------------------------------------------------------------------------------
# equalisation between photos
# ---------------------------------------------------------------------------------------

def _sphere_photo(view, colour_of, size=(192, 192)):
    """An orthographic photo of the radius-0.1 sphere at the origin coloured by
    ``colour_of(points (n, 3)) -> (n, 3)``, the background grey."""
    w, h = size
    cam = OrthographicCamera.nominal(view, size)
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    px = np.stack([xx.ravel(), yy.ravel()], 1)
    rot = np.asarray(cam.rotation)
    # the pixel's line: points p with project(p) = px; p = a u-axis + b v-axis + t dir
    u0 = cam.project(np.zeros((1, 3)))[0]
    a = (px[:, 0] - u0[0]) / cam.scale
    b = (px[:, 1] - u0[1]) / cam.scale
    r2 = a * a + b * b
    hit = r2 < 0.1 ** 2
    depth = -np.sqrt(np.maximum(0.1 ** 2 - r2, 0))  # the near side, toward the camera
    pts = a[:, None] * rot[0] + b[:, None] * rot[1] + depth[:, None] * rot[2]
    img = np.full((h * w, 3), 0.5)
    img[hit] = colour_of(pts[hit])
    return img.reshape(h, w, 3).astype(np.float32), cam


def test_photos_with_another_exposure_meet_without_a_step():
    from solver.texture.bake import bake_samples, equalised_colours, view_reference
    from solver.texture.equalise import seam_difference

    m = uv_sphere(n_lon=96, n_lat=48)

    def colour_of(p):  # skin-like: slow colour changes and some detail
        return np.stack([0.65 + 0.15 * np.sin(25 * p[:, 2]), 0.45 + 0.1 * np.cos(30 * p[:, 0]),
                         0.35 + 0.1 * np.sin(20 * p[:, 1] + 1)], 1)

    front = _sphere_photo("orthographic-front", colour_of)
    side_img, side_cam = _sphere_photo("orthographic-right",
                                       lambda p: colour_of(p) * [0.8, 0.85, 0.9] + 0.03)
    views = [front, (side_img, side_cam)]
    opts = BakeOptions(mirror_weight=0.0)  # no mirrored pass: the sphere's colours are not
    samples = bake_samples(m, m.vertices, views, 128, options=opts)  # symmetric
    s = samples[1001]
    cells = s.raster.texel // 4  # 4-texel runs along a row
    before = seam_difference(s.colours, s.weights, cells)
    after = seam_difference(equalised_colours(samples, m.vertices, opts)[1001], s.weights,
                            cells)
    assert before.relative > 0.08
    assert after.relative < 0.01
    # and so in the texture: across the band the colour changes no faster than the
    # photos' own detail (equalised) against a visible step (not)
    r = s.raster
    pts = r.interp @ m.vertices
    n = pts / np.linalg.norm(pts, axis=1, keepdims=True)
    truth = colour_of(pts * (0.1 / np.linalg.norm(pts, axis=1, keepdims=True)))
    if view_reference(samples) == 1:  # the views tie on a sphere: the profile may lead
        truth = truth * [0.8, 0.85, 0.9] + 0.03
    band = (n[:, 1] < -0.2) & (n[:, 0] < -0.2) & (np.abs(n[:, 2]) < 0.5)
    assert band.sum() > 200
    err = {}
    for equalise in (False, True):
        tex = bake_texture(m, m.vertices, views, 128,
                           options=BakeOptions(mirror_weight=0.0, equalise=equalise))
        err[equalise] = np.abs(tex.reshape(-1, 3)[r.texel][band] - truth[band]).mean()
    assert err[True] < 0.01 < err[False], err


def test_texels_sampled_in_blocks_give_the_texture_of_one_block(monkeypatch):
    """The bake samples a tile's texels a block at a time (``SAMPLE_BLOCK``, to bound its
    memory): any block size gives the same texture, bit for bit."""
    from solver.texture import bake

    m = uv_sphere()
    views = [(coded_photo(), OrthographicCamera.nominal("orthographic-front", (W, H))),
             (_stripes(), OrthographicCamera.nominal("orthographic-right", (W, H)))]
    n = len(uv_raster(m, 128).texel)
    monkeypatch.setattr(bake, "SAMPLE_BLOCK", n)
    whole = bake_texture(m, m.vertices, views, 128)
    monkeypatch.setattr(bake, "SAMPLE_BLOCK", 997)  # blocks not dividing the texels
    assert n > 3 * 997
    np.testing.assert_array_equal(bake_texture(m, m.vertices, views, 128), whole)
