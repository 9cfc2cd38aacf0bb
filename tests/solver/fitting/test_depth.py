"""The detector's depth of mirror pairs (solver/fitting/depth.py): which pairs, the rows'
residuals and Jacobian, and a fit that holds the turn of a head the pixels barely show."""

import copy

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from solver import fit_head
from solver.cameras import OrthographicCamera
from solver.fitting.depth import DepthPairRows, depth_rows, mirror_pairs
from solver.fitting.options import check_options
from solver.fitting.views import prepare_views
from solver.io.landmark_set import load_landmark_set
from solver.synthetic import make_case, make_mirror_case


def test_mirror_pairs_take_usable_right_left_counterparts_only():
    names = ["eye_right", "nose_tip", "eye_left", "brow_right", "brow_left", "lip_right"]
    usable = np.array([True, True, True, True, False, True])
    assert mirror_pairs(names, usable).tolist() == [[0, 2]]
    assert mirror_pairs(names[:2], usable[:2]).shape == (0, 2)


def test_depth_rows_give_the_depth_differences_and_their_jacobian():
    cam = OrthographicCamera.nominal("orthographic-front", (768, 1024))
    rng = np.random.default_rng(3)
    world = rng.normal(scale=0.05, size=(4, 3))
    toward = -cam.rotation[2]
    depth = cam.scale * world @ toward
    pairs = np.array([[0, 1], [2, 3]])
    rows = DepthPairRows(np.arange(4), pairs, depth[[1, 3]] - depth[[0, 2]], cam, [1.0, 4.0])
    np.testing.assert_allclose(rows.residuals(world), 0.0, atol=1e-9)
    moved = world.copy()
    moved[1] += 0.001 * toward  # 1 mm toward the camera: the pair's difference grows
    np.testing.assert_allclose(rows.residuals(moved), [-cam.scale * 0.001, 0.0], atol=1e-9)
    blk = rows.block(moved)
    assert blk.sq == pytest.approx((cam.scale * 0.001) ** 2)
    # d(prediction)/dx: the residual's change for a small step is -g . step
    step = rng.normal(scale=1e-4, size=(4, 3))
    change = rows.residuals(moved + step) - rows.residuals(moved)
    pred = -np.einsum("mcj,mcj->m", blk.g, step[blk.idx])
    np.testing.assert_allclose(change, pred, atol=1e-9)


def test_depth_rows_leave_out_mirror_views_and_the_camera_they_share(model):
    case, _ = make_mirror_case(model, 5, calibrated=True)
    for view in case.views.values():
        view.depth = {n: float(i) for i, n in enumerate(view.points)}
        view.uncertainty = {n: 5.0 for n in view.points}  # a depth's sigma is a share of it
    views, _ = prepare_views(model, case, check_options(None, model))
    front, mirror = (next(v for v in views if v.name == n) for n in ("front", "mirror"))
    assert depth_rows(mirror, 0, views) is None
    assert depth_rows(front, 0, views) is None  # its copies lift across the image only
    assert depth_rows(front, 0, [front]) is not None  # the same photo without its mirror


def _turned_front_case(model, yaw_deg):
    """A front photo of a head turned ``yaw_deg`` about the vertical whose landmarks, as
    uncertain as a detector's (6 px), were placed as if it were not turned (the turn a
    detector's systematic errors can hide), with or without their true depths."""
    case, truth = make_case(model, 41, noise_px=1.0, rotation_deg=0.0, views=("front",))
    turn = Rotation.from_euler("z", yaw_deg, degrees=True).as_matrix()
    view = case.views["front"]
    cam = view.camera
    lms = load_landmark_set()
    local = truth.local_vertices
    world = truth.scale * local @ (turn @ truth.rotation).T + truth.translation
    names = list(view.points)
    idx = [lms.vertices[lms.canonical(n)] for n in names]
    x = world[idx]
    px = cam.project(truth.world_vertices[idx])
    view.points = {n: tuple(p) for n, p in zip(names, px, strict=True)}
    view.uncertainty = {n: 6.0 for n in names}
    depth = cam.scale * x @ -cam.rotation[2]
    with_depth = copy.deepcopy(case)
    with_depth.views["front"].depth = {n: float(d) for n, d in zip(names, depth, strict=True)}
    return case, with_depth, turn @ truth.rotation


def _yaw_off(result, true_rotation):
    rel = Rotation.from_matrix(result.rotation @ true_rotation.T)
    return abs(rel.as_euler("zxy", degrees=True)[0])


def test_the_depths_hold_the_turn_of_a_head_in_a_front_photo(model):
    flat, deep, truth = _turned_front_case(model, 6.0)
    off = {label: _yaw_off(fit_head(model, c), truth)
           for label, c in (("flat", flat), ("depth", deep))}
    assert off["flat"] > 4.0 and off["depth"] < 2.0, off


def _perspective_case_with_depth(model, seed, noise_px=4.0, depth_px=0.5):
    """A case of two self-calibrated pinhole photos (``make_perspective_case``), its
    landmarks uncertain by ``noise_px``, and a copy whose landmarks carry their depth
    along each camera's axis as a face mesh gives it (px at the head's distance,
    ``depth_px`` of noise)."""
    from solver.synthetic import make_perspective_case

    case, truth = make_perspective_case(model, np.random.default_rng(seed), n_views=2,
                                        noise_px=noise_px)
    world = truth.scale * truth.local_vertices @ truth.rotation.T + truth.translation
    rng = np.random.default_rng(seed + 100)
    deep = copy.deepcopy(case)
    for name, view in deep.views.items():
        cam = truth.cameras[name]
        names = list(view.points)
        zc = cam.to_camera(world[[model.landmarks[n] for n in names]])[:, 2]
        depth = -cam.focal_px * zc / zc.mean() + depth_px * rng.normal(size=len(names))
        view.depth = {n: float(d) for n, d in zip(names, depth, strict=True)}
        view.uncertainty = {n: noise_px for n in names}
    flat = copy.deepcopy(deep)
    for view in flat.views.values():
        view.depth = {}
    return flat, deep, truth, world


def test_depth_rows_of_a_pinhole_photo_measure_along_its_axis(model):
    # at the true head and camera the rows hold the depths to well under a pixel
    # (measured along each point's ray instead: 1.5 and 4.8 px RMS)
    _, deep, truth, world = _perspective_case_with_depth(model, 0, depth_px=0.0)
    lms = load_landmark_set()
    for name, view in deep.views.items():
        names = list(view.depth)
        pairs = mirror_pairs(names, np.ones(len(names), bool))
        d = np.array([view.depth[n] for n in names])
        rows = DepthPairRows(np.arange(len(names)), pairs, d[pairs[:, 1]] - d[pairs[:, 0]],
                             truth.cameras[name], np.ones(len(pairs)))
        x = world[[lms.vertices[n] for n in names]]
        assert len(pairs) >= 10 and np.sqrt(np.mean(rows.residuals(x) ** 2)) < 0.8, name


def test_the_depths_of_pinhole_photos_help_their_fit(model):
    from solver.synthetic import skin_error_mm

    errors = []
    for seed in (0, 2, 4):
        flat, deep, truth, _ = _perspective_case_with_depth(model, seed)
        errors.append([skin_error_mm(model, fit_head(model, c).local_vertices,
                                     truth.local_vertices) for c in (flat, deep)])
    errors = np.array(errors)
    assert errors[:, 1].mean() < errors[:, 0].mean() - 0.05, errors
