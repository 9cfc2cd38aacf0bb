"""Outline rows (solver/fitting/outline.py ContourRows): which vertices become rows, and the
trimming of rows the mesh cannot follow; and the staged fit that keeps perspective
outlines from latching onto the wrong rim."""

import numpy as np
import pytest

from solver import FitOptions, OrthographicCamera, PinholeCamera, fit_head
from solver.fitting.engine import Engine
from solver.fitting.outline import (
    CONTOUR_KEEP_SIGMAS,
    SOFT_CUT,
    ContourRows,
    OutlinePointRows,
    candidate_mesh,
    shared_edges,
)
from solver.fitting.rows import PointRows
from solver.fitting.shape_icp import ShapeProblem
from solver.fitting.views import State, prepare_views
from solver.model.linear_model import LinearModel
from solver.synthetic import make_perspective_case, skin_error_mm

# Pixel = 1000 * (x, y) + (0, 0): a metre of x is 1000 pixels.
CAMERA = OrthographicCamera(np.eye(3), 1000.0, (0.0, 0.0), (400, 400))


def _tube(radius=0.05, around=16, rings=16, length=0.3, axis_y=0.05):
    """A closed-around, open-ended tube along x (rings 20 px apart), its axis at
    y = ``axis_y``: (vertices (V, 3), faces (F, 3), edges (E, 4)). Seen through CAMERA its
    outline is the lines v = 1000 (axis_y +- radius), drawn by the edges along the top and
    bottom vertex of each ring."""
    th = 2 * np.pi * np.arange(around) / around
    x = np.linspace(0.0, length, rings)
    verts = np.stack([np.repeat(x, around), axis_y + radius * np.tile(np.cos(th), rings),
                      radius * np.tile(np.sin(th), rings)], axis=1)
    i, j = np.meshgrid(np.arange(rings - 1), np.arange(around), indexing="ij")
    a, b = i * around + j, i * around + (j + 1) % around
    c, d = a + around, b + around
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3),
                            np.stack([a, d, c], -1).reshape(-1, 3)])
    return verts, faces, shared_edges(faces, len(verts))


def _u_outline(top, bottom=(), u0=30.0, step=40.0):
    """A traced outline running left along the tube's top (v = 100 + ``top`` offsets),
    around its left end and right along its bottom (v = 0 - ``bottom`` offsets)."""
    ut = u0 + step * np.arange(len(top))[::-1]
    ub = u0 + step * np.arange(len(bottom))
    top_pts = np.stack([ut, 100.0 + np.asarray(top, float)[::-1]], 1)
    end = np.array([[5.0, 80.0], [0.0, 50.0], [5.0, 20.0]])
    bottom_pts = np.stack([ub, 0.0 - np.asarray(bottom, float)], 1).reshape(-1, 2)
    return np.vstack([top_pts, end, bottom_pts])


def _rows(top, bottom=(), tube=None, camera=CAMERA, step=40.0, **kw):
    verts, faces, edges = _tube() if tube is None else tube
    rows = ContourRows(np.arange(len(verts)), _u_outline(top, bottom, step=step), camera,
                       faces=faces,
                       edges=edges, **kw)
    rows.update(verts)
    return rows, verts


def test_every_traced_point_gives_one_row_across_the_silhouette():
    top, bottom = [0.5, -0.4, 0.3, -0.6, 0.2], [0.7, -0.2]
    rows, verts = _rows(top, bottom)
    # the U's end crosses no rim (the tube is open there): rows for the top and bottom only
    assert len(rows.points) == 7
    # r = n . (q - X), X where the line from q along the outline's normal n meets the
    # silhouette v = 100 (or 0): r = (q_v - 100) / n_v
    q, n = rows.targets, rows.row_normals
    line = np.where(q[:, 1] > 50.0, 100.0, 0.0)
    np.testing.assert_allclose(rows.residuals(verts), (q[:, 1] - line) / n[:, 1], atol=1e-9)
    # positive outside; away from the U's end the normal is across the tube
    inner = np.abs(n[:, 1]) > 0.999
    assert inner.sum() >= 4
    expected = dict(zip(map(tuple, _u_outline(top, bottom)),
                        list(top[::-1]) + [0, 0, 0] + list(bottom), strict=True))
    np.testing.assert_allclose(rows.residuals(verts)[inner],
                               [expected[tuple(p)] for p in q[inner]], atol=1e-3)
    # each row sits on an edge along the tube, halfway between two rings (u = 30 + 40 k)
    np.testing.assert_allclose(rows.fractions, 0.5, atol=0.02)
    assert np.all(np.abs(verts[rows.ends[:, 0], 0] - verts[rows.ends[:, 1], 0]) > 0.019)


def test_the_outermost_rim_is_the_silhouette():
    # a second, thinner tube inside the first: its rim (v = 10 and 90) is hidden
    outer = _tube()
    inner = _tube(radius=0.04)
    n = len(outer[0])
    both = (np.vstack([outer[0], inner[0]]), np.vstack([outer[1], inner[1] + n]),
            np.vstack([outer[2], inner[2] + [n, n, len(outer[1]), len(outer[1])]]))
    rows, verts = _rows([0.5, -0.4, 0.3], [0.2], tube=both)
    assert len(rows.points) == 4 and np.all(rows.ends < n)
    q, nn = rows.targets, rows.row_normals
    line = np.where(q[:, 1] > 50.0, 100.0, 0.0)
    np.testing.assert_allclose(rows.residuals(verts), (q[:, 1] - line) / nn[:, 1], atol=1e-9)


def test_a_point_the_mesh_cannot_follow_is_trimmed_at_three_sigma():
    offsets = [0.5, -0.4, 0.3, -0.6, 0.2, 0.5, -0.3, 4.0]
    far = tuple(_u_outline(offsets, step=35.0)[0])  # the 4 px one (drawn first)
    rows, _ = _rows(offsets, step=35.0)  # defaults: keep 3 px, 3 x median
    assert far not in map(tuple, rows.targets) and len(rows.points) == 7
    # within the keep distance a point stays, however small the median
    rows, _ = _rows(offsets, step=35.0, keep_distance=5.0)
    assert far in map(tuple, rows.targets)
    # beyond 3 x the median but within the keep distance: noise, kept
    rows, _ = _rows([2.5, 0.1, 0.1, 0.1, 0.1])
    assert len(rows.points) == 5
    # beyond max_distance: no crossing, no row
    rows, _ = _rows([0.1, 0.1, 25.0], max_distance=20.0)
    assert len(rows.points) == 2


def test_a_row_fades_out_across_the_cut_off():
    """Near the cut-off (here the 3 px keep distance) a point's row loses its weight
    smoothly and the cost counts the rest of it at the cut-off: a point a hair either side
    of the limit weighs and costs about the same."""
    def weight_and_cost(x):
        rows, verts = _rows([0.5, -0.4, 0.3, -0.6, 0.2, 0.5, -0.3, x], step=35.0)
        far = tuple(_u_outline([0.5, -0.4, 0.3, -0.6, 0.2, 0.5, -0.3, x], step=35.0)[0])
        at = [tuple(p) for p in rows.targets]
        w = rows.row_weights[at.index(far)] if far in at else 0.0
        return w / rows.point_weights[0], \
            rows.block(verts, jacobian=False).sq + rows.unmatched_cost()

    assert SOFT_CUT > 0
    assert weight_and_cost(3.0 * (1 - SOFT_CUT) - 0.01)[0] == pytest.approx(1.0)
    assert weight_and_cost(3.0 * (1 + SOFT_CUT) + 0.01)[0] == 0.0
    (w1, c1), (w2, c2) = weight_and_cost(2.999), weight_and_cost(3.001)
    assert 0.4 < w2 < w1 < 0.6 and w1 - w2 < 0.01
    assert abs(c1 - c2) < 0.01 * c1


def test_a_point_without_a_row_costs_the_cut_off():
    """A truncated quadratic: a head cannot lower its cost by losing rows."""
    offsets = [0.5, -0.4, 0.3, -0.6, 0.2, 0.5, -0.3, 4.0]
    rows, verts = _rows(offsets, step=35.0)
    # the 4 px point and the U's end (3 points, no rim there) have no row; the cut-off is
    # the keep distance (3 x the median is less)
    assert len(rows.pixels) - len(rows.points) == 4 and rows.cap == pytest.approx(3.0)
    missing = np.setdiff1d(np.arange(len(rows.pixels)), rows.points)
    assert rows.unmatched_cost() == pytest.approx(rows.point_weights[missing].sum() * 9.0)
    # kept, the far point's own residual counts instead, and it is more than the cut-off
    kept, _ = _rows(offsets, step=35.0, keep_distance=5.0)
    assert kept.block(verts, jacobian=False).sq + kept.unmatched_cost() > \
        rows.block(verts, jacobian=False).sq + rows.unmatched_cost()
    # no rim within reach: every point at max_distance
    verts2 = verts + [0.0, 0.5, 0.0]
    rows.update(verts2)
    assert len(rows.points) == 0 and rows.cap == 20.0
    assert rows.unmatched_cost() == pytest.approx(rows.point_weights.sum() * 400.0)


def test_the_joint_cost_counts_outline_points_without_rows(model):
    case, truth = make_perspective_case(model, 3, n_views=2, calibrated=True, contour=True)
    opts = FitOptions()
    views, _ = prepare_views(model, case, opts)
    eng = Engine.for_fit(model, views, opts)
    joint = eng.joint(eng.views)
    state = State(truth.rotation, truth.identity_coeffs.copy(), dict(truth.cameras),
                  truth.scale, truth.translation.copy())
    total = joint.cost(state)
    x = joint.world(state)
    data = extra = 0.0
    for _, kind, rows in joint.groups:
        data += rows.block(x[rows.vertices], jacobian=False).sq
        if kind == "contour":
            extra += rows.unmatched_cost()
            assert len(rows.points) < len(rows.pixels)  # the ends at the neck's cut meet no rim
    assert extra > 0.0
    assert total == pytest.approx(data + extra + eng.prior_cost(state.coeffs))


def test_an_outline_that_meets_no_rim_gives_an_empty_block():
    # traced 60 px above the tube, through a perspective camera (whose projection of no
    # points is an error): no rows, and a problem with other rows still solves
    verts, faces, edges = _tube()
    cam = PinholeCamera(800.0, [[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]], [0.15, 0.05, 0.6],
                        (400, 300))
    far = cam.project(np.stack([np.linspace(0.02, 0.28, 9), np.full(9, 0.2), np.zeros(9)], 1))
    rows = ContourRows(np.arange(len(verts)), far, cam, faces=faces, edges=edges)
    rows.update(verts)
    blk = rows.block(verts)
    assert len(rows.points) == 0 and blk.nrows == 0 and blk.sq == 0.0
    assert len(rows.residuals(verts)) == 0 and len(rows.pairs(verts)[1]) == 0
    mode = 1e-3 * np.random.default_rng(0).standard_normal((1,) + verts.shape)
    lin = LinearModel(verts, mode, np.ones(1), ("m",))
    points = PointRows(np.arange(len(verts)), verts + [0.0, 0.0, 0.001])
    fit = ShapeProblem(lin, [rows, points]).solve()
    assert fit.translation[2] == pytest.approx(0.001, abs=1e-9)


def test_dense_points_share_the_weight_of_the_outline_they_stand_for():
    verts, faces, edges = _tube()
    sparse = _u_outline([0.0] * 5)  # 40 px apart
    dense = np.stack([np.arange(290.0, 9.0, -1.0), np.full(281, 100.0)], axis=1)
    for pts, expected in ((sparse[:5], 2.0), (dense, 2.0 / 6.0)):  # inner points
        rows = ContourRows(np.arange(len(verts)), pts, CAMERA, weights=2.0, faces=faces,
                           edges=edges)
        np.testing.assert_allclose(rows.point_weights[1:-1], expected)
    # the same point twice is one point; one distinct point is no outline
    rows = ContourRows(np.arange(len(verts)), np.repeat(sparse, 2, axis=0), CAMERA,
                       faces=faces, edges=edges)
    assert len(rows.pixels) == len(sparse)
    with pytest.raises(ValueError, match="at least 2 distinct points"):
        ContourRows(np.arange(len(verts)), [[1.0, 2.0], [1.0, 2.0]], CAMERA, faces=faces,
                    edges=edges)


def test_row_derivatives_match_finite_differences():
    # Through a perspective camera looking down the tube's side, with the rows fixed.
    verts, faces, edges = _tube()
    cam = PinholeCamera(800.0, [[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]], [0.15, 0.05, 0.6],
                        (400, 300))
    outline = cam.project(np.stack([np.linspace(0.02, 0.28, 9), np.full(9, 0.1013),
                                    np.zeros(9)], axis=1))
    rows = ContourRows(np.arange(len(verts)), outline, cam, faces=faces, edges=edges)
    rows.update(verts)
    blk = rows.block(verts)
    assert len(rows.points) >= 7 and blk.idx.shape == (len(rows.points), 2)
    assert np.any((rows.fractions > 0.05) & (rows.fractions < 0.95))
    eps = 1e-7
    for k in range(len(rows.points)):
        for c in range(2):
            for axis in range(3):
                moved = verts.copy()
                moved[blk.idx[k, c], axis] += eps
                fd = -(rows.residuals(moved)[k] - rows.residuals(verts)[k]) / eps
                assert fd == pytest.approx(blk.g[k, c, axis], rel=1e-4, abs=1e-3)


def test_at_the_true_head_the_rows_are_as_close_as_the_tracing(model):
    """A traced point is at most half a pixel off the true silhouette (the photo's pixel
    grid); a row measures that, not the chords between points (which cut the nose or the
    chin by a few pixels)."""
    skin = np.asarray(model.skin, dtype=np.int64)
    faces, edges = candidate_mesh(model, skin)
    for seed in (1000, 1002):
        case, truth = make_perspective_case(model, seed, n_views=2, noise_px=0.0,
                                            calibrated=True, contour=True)
        world = truth.world_vertices[skin]
        for name, view in case.views.items():
            rows = ContourRows(np.arange(len(skin)), view.contour, truth.cameras[name],
                               faces=faces, edges=edges)
            rows.update(world)
            r = rows.residuals(world)
            assert len(r) >= 0.9 * len(view.contour)
            assert np.sqrt(np.mean(r**2)) < 0.35 and np.abs(r).max() < 1.0


def test_the_engine_keeps_rows_within_three_sigmas_of_its_noise(model):
    case, _ = make_perspective_case(model, 3, n_views=2, calibrated=True, contour=True)
    for noise in (0.5, 2.0):
        views, _ = prepare_views(model, case, FitOptions(noise_px=noise))
        eng = Engine.for_fit(model, views, FitOptions(noise_px=noise))
        assert eng.contour_keep == pytest.approx(CONTOUR_KEEP_SIGMAS * noise)
        joint = eng.joint(eng.views)
        kept = [rows.keep_distance for _, kind, rows in joint.groups if kind == "contour"]
        assert kept == [pytest.approx(CONTOUR_KEEP_SIGMAS * noise)] * 2


def test_outlines_of_two_perspective_photos_do_not_latch_onto_the_wrong_rim(model):
    """Seed 1000 of bench_perspective's two calibrated photos: fitted from the mean head
    with landmarks and outlines at once, the outline rows pulled a cheek onto the jaw's
    line and the fit settled 1.56 mm from the true head; landmarks first, then the
    outlines found anew on that head (and rows the mesh cannot follow trimmed), it lands
    within 1 mm."""
    case, truth = make_perspective_case(model, 1000, n_views=2, calibrated=True,
                                        contour=True)
    res = fit_head(model, case)
    assert skin_error_mm(model, res.local_vertices, truth.local_vertices) < 1.0
    for name in case.views:
        assert res.info["contour_rms_px"][name] < 1.5


def test_outline_points_measure_across_the_silhouette_and_slide_along_it():
    verts, faces, edges = _tube()
    px = np.array([[97.0, 103.0], [183.0, 98.0], [250.0, -4.0], [120.0, 160.0]])
    rows = OutlinePointRows(np.arange(len(verts)), px, CAMERA, np.ones(4), faces, edges,
                            max_distance=20.0)
    rows.update(verts)
    # the fourth point is 60 px from every rim: no row, and it counts as at the cut-off
    assert rows.points.tolist() == [0, 1, 2]
    assert rows.unmatched_cost() == pytest.approx(20.0**2)
    # signed distance across the outline, positive outside, along the outward normal
    np.testing.assert_allclose(rows.residuals(verts), [3.0, -2.0, 4.0], atol=1e-9)
    np.testing.assert_allclose(rows.row_normals, [[0, 1], [0, 1], [0, -1]], atol=1e-9)
    # the tube moved 13 px along its axis (along the outline): the points slide, no change
    moved = verts + [0.013, 0.0, 0.0]
    rows.update(moved)
    np.testing.assert_allclose(rows.residuals(moved), [3.0, -2.0, 4.0], atol=1e-9)
    # moved 1 px up (v + 1): the top points come 1 px nearer, the bottom one 1 px farther
    up = verts + [0.0, 0.001, 0.0]
    rows.update(up)
    np.testing.assert_allclose(rows.residuals(up), [2.0, -3.0, 5.0], atol=1e-9)


def test_outline_point_rows_have_the_derivative_of_their_residuals():
    verts, faces, edges = _tube()
    px = np.array([[97.0, 103.0], [183.0, 98.0], [250.0, -4.0]])
    rows = OutlinePointRows(np.arange(len(verts)), px, CAMERA, [1.0, 2.0, 0.5], faces, edges)
    rows.update(verts)
    block = rows.block(verts)
    assert block.sq == pytest.approx(float(np.dot([1.0, 2.0, 0.5], [9.0, 4.0, 16.0])))
    rng = np.random.default_rng(3)
    step = 1e-6 * rng.normal(size=verts.shape)
    predicted = -np.einsum("kcj,kcj->k", block.g, step[block.idx])
    np.testing.assert_allclose(rows.residuals(verts + step) - rows.residuals(verts),
                               predicted, atol=1e-9)


def test_the_nearest_rim_not_the_outermost_is_a_landmarks_outline():
    # two tubes, one inside the other's outline in the photo (a cheek inside an ear):
    # a point 2 px off the inner tube's outline is matched to it, not to the outer one's
    inner = _tube(radius=0.03, axis_y=0.05)
    outer = _tube(radius=0.05, axis_y=0.05)
    verts = np.vstack([inner[0], outer[0] + [0.0, 0.0, -0.2]])
    n = len(inner[0])
    faces = np.vstack([inner[1], outer[1] + n])
    edges = shared_edges(faces, len(verts))
    rows = OutlinePointRows(np.arange(len(verts)), [[150.0, 82.0]], CAMERA, [1.0], faces,
                            edges)
    rows.update(verts)
    np.testing.assert_allclose(rows.residuals(verts), [2.0], atol=1e-9)
    assert np.all(rows.ends < n)


def test_rows_on_the_body_weigh_its_scale():
    verts, faces, edges = _tube()
    body = verts[:, 0] > 0.15  # the tube's right half stands for the body below the neck
    rows, _ = _rows([0.5, -0.4, 0.3, -0.6, 0.2], [0.7, -0.2], weights=2.0, body=body,
                    body_scale=0.25)
    on_body = verts[rows.selected, 0] > 0.15
    np.testing.assert_array_equal(rows.body_rows, on_body)
    assert on_body.any() and not on_body.all()
    plain, _ = _rows([0.5, -0.4, 0.3, -0.6, 0.2], [0.7, -0.2], weights=2.0)
    np.testing.assert_allclose(rows.row_weights, np.where(on_body, 0.25, 1.0)
                               * plain.row_weights)
    assert not plain.body_rows.any()
