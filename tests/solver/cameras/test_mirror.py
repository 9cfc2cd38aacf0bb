"""One camera plus a flat mirror (seed 001, Hashimoto 1984, chapter 3)."""

import json

import numpy as np
import pytest

from solver import camera_from_dict
from solver.cameras.mirror import (
    IBUG_MIRROR,
    MirrorPlane,
    estimate_mirror,
    mirror_name,
    mirror_names,
    mirror_normal,
    pair_mirrored,
    reflected_camera,
    triangulate_mirror,
)
from solver.paths import ASSETS_DIR
from tests.solver.cameras.support import SIZE, K, dlt_camera

F1 = np.array([0.0, -1.0, 0.05])
# mirror beside and a little behind the head, facing head and camera
G = np.array([0.35, 0.05, 0.0])
NORMAL = np.array([-1.0, -0.6, 0.1]) / np.linalg.norm([-1.0, -0.6, 0.1])
LANDMARKS = ASSETS_DIR / "landmarks.json"



def setup(rng, n=30):
    cam = dlt_camera(F1, [0.25, 0.1, 0.0])
    plane = MirrorPlane.from_point_normal(G, NORMAL)
    head = rng.uniform([-0.08, -0.1, -0.12], [0.08, 0.02, 0.12], (n, 3))
    direct = cam.project(head)
    mirrored = cam.project(plane.reflect_points(head))
    # the scene is sensible: both images inside the photo, in front of the camera
    for px in (direct, mirrored):
        assert ((px > 0) & (px < SIZE)).all()
    assert (cam.depth(plane.reflect_points(head)) > 0).all()
    assert (plane.signed_distance(head) > 0).all() and plane.signed_distance(F1[None])[0] > 0
    return cam, plane, head, direct, mirrored


def angle(a, b):
    return np.degrees(np.arccos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1)))


def test_mirror_names():
    assert mirror_name("eye_outer_left") == "eye_outer_right"
    assert mirror_name("jaw_right_1") == "jaw_left_1"
    assert mirror_name("nose_tip") == "nose_tip"
    assert mirror_name("ibug01") == "ibug17"
    assert mirror_name("ibug9") == "ibug9"
    assert mirror_name("ibug37") == "ibug46"
    assert mirror_name("ibug41") == "ibug48"
    assert mirror_name("ibug32") == "ibug36"
    assert mirror_name("ibug66") == "ibug68"
    assert mirror_name("ibug58") == "ibug58"
    for i in range(1, 69):  # an involution
        assert IBUG_MIRROR[IBUG_MIRROR[i]] == i
    midline = {9, 28, 29, 30, 31, 34, 52, 58, 63, 67}
    assert {i for i in range(1, 69) if IBUG_MIRROR[i] == i} == midline
    with pytest.raises(ValueError, match="1 to 68"):
        mirror_name("ibug69")
    assert mirror_names({"mouth_corner_left": (1, 2), "subnasale": (3, 4)}) == {
        "mouth_corner_right": (1, 2), "subnasale": (3, 4)}


@pytest.mark.skipif(not LANDMARKS.exists(), reason="assets/landmarks.json not written yet")
def test_mirror_names_agree_with_the_landmark_set():
    entries = json.loads(LANDMARKS.read_text())["landmarks"]
    names = {e["name"] for e in entries}
    by_ibug = {e["ibug"]: e["name"] for e in entries if e.get("ibug") is not None}
    for e in entries:
        assert mirror_name(e["name"]) in names, e["name"]
        if e.get("ibug") is not None:
            assert mirror_name(e["name"]) == by_ibug[IBUG_MIRROR[e["ibug"]]], e["name"]


def test_plane_reflection():
    plane = MirrorPlane.from_point_normal(G, NORMAL)
    m = plane.matrix
    np.testing.assert_allclose(m @ m.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(m) == pytest.approx(-1.0)
    x = np.random.default_rng(0).normal(size=(5, 3))
    np.testing.assert_allclose(plane.reflect_points(plane.reflect_points(x)), x, atol=1e-14)
    # eq. 3.11 with any point G of the plane
    np.testing.assert_allclose(plane.reflect_points(x), G + (x - G) @ m.T, atol=1e-14)
    np.testing.assert_allclose(plane.signed_distance(plane.point[None]), [0.0], atol=1e-15)


def test_exact_mirror_and_landmarks():
    rng = np.random.default_rng(1)
    cam, plane, head, direct, mirrored = setup(rng)
    fit = estimate_mirror(cam, direct, mirrored, point_on_mirror=G)
    assert angle(fit.plane.normal, NORMAL) < 1e-6
    assert fit.plane.offset == pytest.approx(plane.offset, abs=1e-9)
    np.testing.assert_allclose(fit.points, head, atol=1e-8)
    assert fit.gaps.max() < 1e-8 and fit.normal_residual.max() < 1e-8
    # the mirrored view as a camera: centre F2 (eq. 3.11), det(R) = -1, sees the mirror image
    mc = fit.mirrored_camera
    assert mc.is_mirrored
    np.testing.assert_allclose(mc.centre, G + (F1 - G) @ plane.matrix.T, atol=1e-9)
    np.testing.assert_allclose(mc.project(head), mirrored, atol=1e-6)
    np.testing.assert_allclose(mc.decompose()[0], K, atol=1e-6)
    np.testing.assert_allclose(camera_from_dict(mc.to_dict()).project(head), mirrored,
                               atol=1e-6)
    # self-calibrating the mirrored view from the (head) points gives the same camera
    np.testing.assert_allclose(mc.refit(head, mirrored).matrix, mc.matrix, atol=1e-8)


def test_noisy_mirror_and_landmarks():
    rng = np.random.default_rng(2)
    cam, plane, head, direct, mirrored = setup(rng, n=40)
    noisy_d = direct + rng.normal(0, 0.3, direct.shape)
    noisy_m = mirrored + rng.normal(0, 0.3, mirrored.shape)
    fit = estimate_mirror(cam, noisy_d, noisy_m, point_on_mirror=G)
    assert angle(fit.plane.normal, NORMAL) < 0.5  # degrees
    assert np.median(fit.gaps) < 0.002 and fit.gaps.max() < 0.006
    err = np.linalg.norm(fit.points - head, axis=1)
    assert np.sqrt((err**2).mean()) < 0.005
    # a landmark mislabelled in the mirror image stands out by its gap
    bad_m = noisy_m.copy()
    bad_m[[3, 4]] = bad_m[[4, 3]]
    bad = estimate_mirror(cam, noisy_d, bad_m, point_on_mirror=G)
    assert set(np.argsort(bad.gaps)[-2:]) == {3, 4}


def test_mirror_distance_from_a_known_length():
    rng = np.random.default_rng(3)
    cam, plane, head, direct, mirrored = setup(rng)
    names = [f"p{i}" for i in range(len(head))]
    length = float(np.linalg.norm(head[0] - head[5]))
    fit = estimate_mirror(cam, direct, mirrored, names, known_length=("p0", "p5", length))
    assert fit.plane.offset == pytest.approx(plane.offset, abs=1e-9)
    np.testing.assert_allclose(fit.points, head, atol=1e-8)
    pts, gaps = triangulate_mirror(cam, fit.plane, direct, mirrored)
    np.testing.assert_allclose(pts, head, atol=1e-8)
    with pytest.raises(ValueError, match="exactly one"):
        estimate_mirror(cam, direct, mirrored)
    with pytest.raises(ValueError, match="must both be among"):
        estimate_mirror(cam, direct, mirrored, names, known_length=("p0", "nose", 0.1))


def test_pairs_from_labels_read_off_the_mirror_image():
    rng = np.random.default_rng(4)
    cam, plane, _, _, _ = setup(rng)
    head = {"eye_outer_left": [0.05, -0.08, 0.03], "eye_outer_right": [-0.05, -0.08, 0.03],
            "nose_tip": [0.0, -0.11, -0.01], "mouth_corner_left": [0.025, -0.09, -0.05],
            "mouth_corner_right": [-0.025, -0.09, -0.05]}
    x = np.array(list(head.values()))
    direct = dict(zip(head, cam.project(x).tolist(), strict=True))
    # in the mirror image the subject's left eye looks like a right eye: labels swap
    seen = cam.project(plane.reflect_points(x))
    labels = {mirror_name(k): v for k, v in zip(head, seen.tolist(), strict=True)}
    names, d, m = pair_mirrored(direct, labels)
    assert names == list(head)
    pts, gaps = triangulate_mirror(cam, plane, d, m)
    np.testing.assert_allclose(pts, x, atol=1e-8)
    # pairing by the raw labels instead would match left with right: large gaps
    _, wrong_gaps = triangulate_mirror(cam, plane, d, np.array([labels[k] for k in names]))
    assert wrong_gaps.max() > 0.005 and gaps.max() < 1e-9


def test_degenerate_pairs_raise():
    with pytest.raises(ValueError, match="at least 2"):
        mirror_normal([[0, 1.0, 0]], [[0.1, 1.0, 0]])
    p = np.array([[0.0, 1.0, 0.0], [0.1, 1.0, 0.0]])  # all rays in one plane
    with pytest.raises(ValueError, match="do not fix"):
        mirror_normal(p, p + [0.2, 0.0, 0.0])
    with pytest.raises(ValueError, match="DLT camera"):
        reflected_camera(object(), MirrorPlane.from_point_normal(G, NORMAL))
