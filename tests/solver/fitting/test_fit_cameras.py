"""The fit with photos from any camera (synthetic cases with known answers): perspective
photos at any angle, calibrated and self-calibrated (pinhole, DLT), mixed with orthographic
ones, one camera and a mirror (seed 001 ch. 3), the parallel-projection check (seed 001
ch. 2); and triangulation through pinhole cameras."""

import copy
import os
import subprocess
import sys

import numpy as np
import pytest

from solver import (
    FitOptions,
    LandmarkCase,
    OrthographicCamera,
    PinholeCamera,
    View,
    check_case,
    fit_dlt,
    fit_head,
    refit_landmarks,
    save_landmarks,
)
from solver.cameras.triangulate import projection_matrix, triangulate, viewing_rays
from solver.procrustes import similarity_procrustes
from solver.synthetic import (
    make_case,
    make_mirror_case,
    make_perspective_case,
    skin_error_mm,
    visible_landmarks,
)
from tests import ROOT
from tests.solver.cameras.support import dlt_camera


def normal_angle_deg(a, b):
    return float(np.degrees(np.arccos(np.clip(abs(np.dot(a, b)), 0.0, 1.0))))


def mirror_error_deg(model, res, truth):
    """Angle between the fitted and the true mirror normal, seen from the head: with a
    self-calibrated camera the fit's world is the head's own frame, so the fitted normal
    is turned by the similarity that takes the fitted head onto the true one."""
    sim = similarity_procrustes(res.world_vertices[model.skin],
                                truth.world_vertices[model.skin])
    normal = sim.rotation @ res.info["mirror"]["mirror"]["normal"]
    return normal_angle_deg(normal, truth.planes["mirror"].normal)


# ----------------------------------------------------------------------------- triangulation


def test_triangulation_through_pinhole_cameras():
    rng = np.random.default_rng(3)
    x = rng.uniform(-0.1, 0.1, (40, 3))
    size = (1500, 2000)
    cams = [PinholeCamera.look_at([0.0, -1.2, 0.1], [0, 0, 0], size, lens_mm=50),
            PinholeCamera.look_at([0.8, -0.9, 0.0], [0, 0, 0], size, lens_mm=70, k1=-0.08),
            dlt_camera([-0.7, -0.8, 0.3])]
    px = np.stack([c.project(x) for c in cams])
    tri = triangulate(cams, px)
    np.testing.assert_allclose(tri.points, x, atol=1e-9)
    assert np.nanmax(np.abs(tri.residuals)) < 1e-6 and tri.ray_gap.max() < 1e-9
    # two pinhole cameras alone, one with lens distortion, and a pinhole with an
    # orthographic camera
    np.testing.assert_allclose(triangulate(cams[:2], px[:2]).points, x, atol=1e-9)
    ortho = OrthographicCamera.nominal("orthographic-right", (1000, 1000))
    mixed = triangulate([cams[0], ortho], np.stack([px[0], ortho.project(x)]))
    np.testing.assert_allclose(mixed.points, x, atol=1e-9)
    # the matrix is K R [I | -C] in b-form; the rays leave the centre through the points
    p = projection_matrix(cams[0])
    np.testing.assert_allclose(p, cams[0].matrix / cams[0].matrix[2, 3], rtol=1e-12)
    origins, dirs = viewing_rays(cams[1], px[1])
    np.testing.assert_allclose(origins, np.broadcast_to(cams[1].centre, origins.shape))
    along = ((x - origins) * dirs).sum(axis=1)
    np.testing.assert_allclose(origins + along[:, None] * dirs, x, atol=1e-9)
    # with noise the triangulated points are as good as two 1-px rays allow
    noisy = px + rng.normal(size=px.shape)
    err = np.linalg.norm(triangulate(cams, noisy).points - x, axis=1)
    assert np.sqrt((err**2).mean()) < 1e-3
    with pytest.raises(ValueError, match="DLT, pinhole or orthographic"):
        projection_matrix(object())


# ----------------------------------------------------------------------------- perspective


def test_self_calibrated_photos_at_any_angle(model):
    case, truth = make_perspective_case(model, 7, n_views=3)
    res = fit_head(model, case)
    err = skin_error_mm(model, res.local_vertices, truth.local_vertices)
    assert err < 1.6 and err < 0.4 * skin_error_mm(model, model.vertices, truth.local_vertices)
    for name in case.views:
        cam = res.cameras[name]
        assert isinstance(cam, PinholeCamera) and not cam.is_mirrored
        # the stated lens is off by up to 5 % (sigma); the head fixes the rest
        assert cam.focal_px == pytest.approx(truth.cameras[name].focal_px, rel=0.1)
        assert res.info["rms_px"][name] < 2.0
        chk = res.info["projection"][name]
        assert chk["perspective"] and 0.0 < chk["epsilon"] < 0.5
    # self-calibration alternated with the shape at least once; approach 2 (orthographic
    # photos' method) is left out with perspective cameras
    assert res.info["iterations"]["calibration_rounds"] >= 1
    assert set(res.info["candidates"]) == {"approach1"}
    assert res.info["warnings"] == []
    # the gauge: the world is the head's frame, the cameras stand around it
    assert res.scale == 1.0 and np.abs(res.translation).max() == 0.0
    np.testing.assert_array_equal(res.rotation, np.eye(3))


def test_calibrated_photos_with_outlines_on_any_view(model):
    case, truth = make_perspective_case(model, 8, n_views=2, calibrated=True, contour=True)
    res = fit_head(model, case)
    for name, view in case.views.items():
        assert res.cameras[name] is view.camera
        assert res.info["contour_rms_px"][name] < 2.0  # every photo's outline was fitted
    assert skin_error_mm(model, res.local_vertices, truth.local_vertices) < 1.6
    # two calibrated cameras measure the head: placed and sized in their world
    assert res.scale == pytest.approx(truth.scale, rel=0.05)
    nose = model.landmarks["nose_tip"]
    assert np.linalg.norm(res.world_vertices[nose] - truth.world_vertices[nose]) < 0.004


def test_four_photos_of_mixed_kinds(model):
    # two self-calibrated pinhole photos, a DLT self-calibrated on the head, and one
    # calibrated pinhole photo (which places the head in its world, at the model's size)
    case, truth = make_perspective_case(model, 12, n_views=4)
    case.views["photo2"].camera_hints = {"kind": "dlt"}
    kept = case.views["photo3"]
    kept.camera, kept.calibrated, kept.camera_hints = truth.cameras["photo3"], True, {}
    res = fit_head(model, case)
    assert [res.cameras[n].kind for n in case.views] == ["pinhole", "pinhole", "dlt", "pinhole"]
    assert res.cameras["photo3"] is kept.camera
    assert skin_error_mm(model, res.local_vertices, truth.local_vertices) < 1.6
    # one calibrated camera cannot tell size from distance: the model's size is kept
    assert res.scale == 1.0
    nose = model.landmarks["nose_tip"]
    px = res.cameras["photo3"].project(res.world_vertices[[nose]])[0]
    assert np.linalg.norm(px - truth.pixels["photo3"]["nose_tip"]) < 3.0


def test_a_second_profile(model):
    # front, right and left orthographic photos, both profiles with their outline
    case, truth = make_case(model, 13, noise_px=1.0, views=("front", "right", "left"))
    res = fit_head(model, case)
    assert set(res.info["contour_rms_px"]) == {"right", "left"}
    assert max(res.info["contour_rms_px"].values()) < 2.0
    two, _ = make_case(model, 13, noise_px=1.0)
    err = skin_error_mm(model, res.local_vertices, truth.local_vertices)
    assert err < 1.2 and err < 1.1 * skin_error_mm(model, fit_head(model, two).local_vertices,
                                                   truth.local_vertices)


def test_orthographic_and_perspective_photos_together(model):
    case, truth = make_case(model, 6, noise_px=1.0)
    world = truth.world_vertices
    cam = PinholeCamera.look_at([0.6, -1.0, 0.05], world[model.skin].mean(axis=0), (1500, 2000),
                                lens_mm=70)
    names = visible_landmarks(model, world, cam)
    rng = np.random.default_rng(0)
    px = cam.project(world[[model.landmarks[n] for n in names]]) + rng.normal(size=(len(names), 2))
    views = dict(case.views)
    views["three-quarter"] = View("three-quarter", None, cam.size, None,
                                  dict(zip(names, px, strict=True)),
                                  camera_hints={"kind": "pinhole", "lens_mm": 70.0})
    res = fit_head(model, LandmarkCase(views))
    assert [res.cameras[n].kind for n in views] == ["orthographic", "orthographic", "pinhole"]
    assert skin_error_mm(model, res.local_vertices, truth.local_vertices) < 1.2
    assert set(res.info["projection"]) == {"three-quarter"}  # no camera distance given


# ----------------------------------------------------------------------------- mirror


@pytest.fixture(scope="module")
def mirror(model):
    case, truth = make_mirror_case(model, 1)
    return case, truth, fit_head(model, case)


def test_one_camera_and_a_mirror(model, mirror):
    case, truth, res = mirror
    info = res.info["mirror"]["mirror"]
    assert info["mirror_of"] == "front"
    assert mirror_error_deg(model, res, truth) < 1.0
    err = skin_error_mm(model, res.local_vertices, truth.local_vertices)
    assert err < 2.0 and err < 0.4 * skin_error_mm(model, model.vertices, truth.local_vertices)
    # the mirror view's camera is the real one reflected: same intrinsics, mirrored
    real, virtual = res.cameras["front"], res.cameras["mirror"]
    assert virtual.is_mirrored and not real.is_mirrored
    assert virtual.focal_px == real.focal_px
    assert real.focal_px == pytest.approx(truth.cameras["front"].focal_px, rel=0.1)
    # every landmark seen both directly and in the mirror has a small ray gap
    both = set(case.views["front"].points) & set(case.views["mirror"].points)
    assert set(info["ray_gap_px"]) == both and len(both) >= 10
    assert max(info["ray_gap_px"].values()) < 6.0 and info["flagged"] == []
    # the mirror shows the head in profile: the front photo's outline points are left out
    assert [w for w in res.info["warnings"] if "no meaning in a profile photo" not in w] == []
    assert res.info["rms_px"]["mirror"] < 2.0


def test_a_misplaced_mirror_landmark_is_flagged(model, mirror):
    case, truth, res = mirror
    moved = copy.deepcopy(case)
    both = [n for n in moved.views["mirror"].points if n in moved.views["front"].points]
    name = both[len(both) // 2]
    u, v = moved.views["mirror"].points[name]
    moved.views["mirror"].points[name] = (u, v + 25.0)  # across the mirror's epipolar lines
    bad = fit_head(model, moved)
    assert bad.info["mirror"]["mirror"]["flagged"] == [name]
    assert any(name in w and "mirror" in w for w in bad.info["warnings"])
    # the fast refit and a restart keep the mirror's camera and plane
    fast = refit_landmarks(model, moved, res)
    assert fast.cameras["mirror"] is res.cameras["mirror"]
    assert fast.info["refit_state"]["planes"]["mirror"]["offset"] == \
        res.info["refit_state"]["planes"]["mirror"]["offset"]
    again = fit_head(model, case, initial=res)
    assert mirror_error_deg(model, again, truth) < 1.0


def test_mirror_with_a_calibrated_camera(model):
    case, truth = make_mirror_case(model, 2, calibrated=True)
    res = fit_head(model, case)
    assert res.cameras["front"] is case.views["front"].camera
    plane = truth.planes["mirror"]
    fitted = res.info["mirror"]["mirror"]
    assert normal_angle_deg(fitted["normal"], plane.normal) < 0.5  # the camera's world
    # one camera cannot tell the head's size from its distance: the head keeps the model's
    # size (scale 1), and the mirror's distance from the camera scales with it
    assert res.scale == 1.0
    centre = truth.cameras["front"].centre
    d_fit = float(np.dot(fitted["normal"], centre) - fitted["offset_m"])
    d_true = float(plane.signed_distance(centre[None])[0])
    assert d_fit / d_true == pytest.approx(1.0 / truth.scale, rel=0.03)
    assert skin_error_mm(model, res.local_vertices, truth.local_vertices) < 2.0


def test_bad_mirror_views_are_named(model):
    case, _ = make_mirror_case(model, 1)
    ortho = copy.deepcopy(case)
    front = ortho.views["front"]
    front.camera = OrthographicCamera.nominal("orthographic-front", front.size)
    with pytest.raises(ValueError, match=r"view 'mirror' \(mirror of 'front'\).*perspective"):
        fit_head(model, ortho)
    lost = copy.deepcopy(case)
    lost.views["mirror"].mirror_of = "side"
    with pytest.raises(ValueError, match=r"view 'mirror': mirror_of names 'side'"):
        fit_head(model, lost)
    few = copy.deepcopy(case)
    keep = [n for n in few.views["mirror"].points if n not in few.views["front"].points]
    few.views["mirror"].points = {n: few.views["mirror"].points[n]
                                  for n in keep + list(few.views["mirror"].points)[:1]}
    assert len(few.views["mirror"].points) >= 3  # enough for a view, one pair only
    with pytest.raises(ValueError, match=r"view 'mirror'.*1 landmark\(s\) seen both "
                                         r"directly and in the mirror"):
        fit_head(model, few)


# ----------------------------------------------------------------------------- projection


def test_orthographic_photos_taken_too_close_are_warned_about(model):
    case, _ = make_case(model, 5, noise_px=1.0)
    near = fit_head(model, case, FitOptions(method="approach1", camera_distance_m=1.0))
    for name in case.views:
        chk = near.info["projection"][name]
        assert chk["exceeds"] and not chk["perspective"]
        # a head about 0.2 m deep seen from 1 m: epsilon = dL / (L + dL), about 18 %
        assert 0.05 < chk["epsilon"] < 0.3 and chk["min_distance_m"] > 10.0
    assert len(near.info["warnings"]) == 2
    assert all("parallel projection" in w for w in near.info["warnings"])
    far = fit_head(model, case, FitOptions(method="approach1", camera_distance_m=1000.0))
    assert not any(c["exceeds"] for c in far.info["projection"].values())
    assert far.info["warnings"] == []
    plain = fit_head(model, case, FitOptions(method="approach1"))
    assert plain.info["projection"] == {} and plain.info["warnings"] == []
    with pytest.raises(ValueError, match="options.camera_distance_m"):
        fit_head(model, case, FitOptions(camera_distance_m=-1.0))


def test_an_orthographic_photos_exif_lens_says_how_close_it_was_taken(model):
    """A phone's lens (27 mm) on a photo fitted as orthographic is warned about with the
    distance it implies; a lens long enough for the head to be ~250 m away (20000 mm) is
    not."""
    case, _ = make_case(model, 5, noise_px=1.0)
    phone = copy.deepcopy(case)
    phone.views["front"].camera_hints["lens_mm"] = 27.0
    near = fit_head(model, phone, FitOptions(method="approach1"))
    chk = near.info["projection"]["front"]
    assert chk["exceeds"] and 0.1 < chk["distance_m"] < 1.0 and "right" not in \
        near.info["projection"]
    assert [w for w in near.info["warnings"] if "parallel projection" in w] == [
        w for w in near.info["warnings"] if "27 mm lens" in w] != []
    tele = copy.deepcopy(case)
    tele.views["front"].camera_hints["lens_mm"] = 20000.0
    far = fit_head(model, tele, FitOptions(method="approach1"))
    assert not far.info["projection"]["front"]["exceeds"]
    assert far.info["projection"]["front"]["distance_m"] > 100.0
    assert not any("parallel projection" in w for w in far.info["warnings"])


def test_cli_prints_the_fit_warnings(tmp_path, model, mirror):
    case = copy.deepcopy(mirror[0])
    both = [n for n in case.views["mirror"].points if n in case.views["front"].points]
    name = both[len(both) // 2]
    u, v = case.views["mirror"].points[name]
    case.views["mirror"].points[name] = (u, v + 25.0)
    path = tmp_path / "mirror.json"
    save_landmarks(case, path)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.run([sys.executable, "-m", "solver", "fit", str(path), "--out",
                           str(tmp_path / "head.obj"), "--quiet"], cwd=ROOT,
                          capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.startswith("warning:")
             and "no meaning in a profile photo" not in ln]
    assert len(lines) == 1 and name in lines[0]



# ----------------------------------------------------------------------------- passpoints


def with_passpoints(model, case, truth, name, keep):
    """``case`` with view ``name``'s camera to be computed (a DLT) from eight passpoints of
    a box around the head, seen through its true camera, and only its first ``keep``
    landmarks. Returns (case, the DLT the passpoints give)."""
    case = copy.deepcopy(case)
    view = case.views[name]
    skin = truth.world_vertices[model.skin]
    centre = 0.5 * (skin.min(axis=0) + skin.max(axis=0))
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)],
                       dtype=np.float64)
    xyz = centre + 0.06 * corners * np.array([1.0, 1.3, 0.8])
    uv = truth.cameras[name].project(xyz)
    names = [f"box_{i}" for i in range(len(xyz))]
    case.passpoints = dict(zip(names, xyz, strict=True))
    case.views[name] = View(name, None, view.size, None,
                            dict(list(view.points.items())[:keep]),
                            camera_hints={"kind": "dlt"},
                            passpoints=dict(zip(names, uv, strict=True)))
    return case, fit_dlt(xyz, uv, view.size).camera


def fit_with_passpoints(model, case, truth, name, keep):
    """Fit ``with_passpoints(...)``'s case after checking the file accepts it; the fitted
    camera of ``name`` must stay the passpoints' DLT (too few landmarks to refine it).
    Returns (the case fitted, the FitResult)."""
    case, dlt = with_passpoints(model, case, truth, name, keep)
    assert check_case(case) == []
    res = fit_head(model, case)
    pts = truth.world_vertices[model.skin][::200]
    np.testing.assert_allclose(res.cameras[name].project(pts), dlt.project(pts), atol=1e-9)
    return case, res


def test_a_passpoint_camera_needs_few_landmarks(model):
    # the file exempts a view with passpoints from the per-view floor; so does the fit,
    # and the camera stays the passpoints' DLT (too few landmarks to refine it)
    case, truth = make_perspective_case(model, 7, n_views=2)
    _, res = fit_with_passpoints(model, case, truth, "photo1", 2)
    assert len(res.residuals["photo1"].names) == 2
    assert res.info["rms_px"]["photo1"] < 3.0 and res.info["warnings"] == []
    assert skin_error_mm(model, res.local_vertices, truth.local_vertices) < \
        0.7 * skin_error_mm(model, model.vertices, truth.local_vertices)


def test_a_passpoint_view_without_landmarks_is_skipped_with_a_warning(model):
    case, truth = make_perspective_case(model, 7, n_views=3)
    none, res = fit_with_passpoints(model, case, truth, "photo2", 0)
    assert res.residuals["photo2"].names == [] and res.residuals["photo2"].pixels.size == 0
    assert [w for w in res.info["warnings"] if "'photo2'" in w and "no usable" in w]
    assert skin_error_mm(model, res.local_vertices, truth.local_vertices) < 1.6
    # the fast path keeps the view out too, with its camera
    again = refit_landmarks(model, none, res)
    assert again.residuals["photo2"].names == [] and "photo2" in again.cameras


def test_a_self_calibrated_view_keeps_its_minimum(model):
    case, truth = make_perspective_case(model, 7, n_views=2)
    for keep, need in ((2, 4), (3, 4)):  # what the pinhole refit needs (the one rule)
        few = copy.deepcopy(case)
        few.views["photo1"].points = dict(list(few.views["photo1"].points.items())[:keep])
        assert any(p[0] == "views.photo1.points" for p in check_case(few))
        with pytest.raises(ValueError, match=rf"view 'photo1'.*at least {need}"):
            fit_head(model, few)
    # passpoints on another view do not lift it, nor does a total of too few
    mixed, _ = with_passpoints(model, case, truth, "photo0", 2)
    mixed.views["photo1"].points = dict(list(mixed.views["photo1"].points.items())[:2])
    with pytest.raises(ValueError, match=r"view 'photo1'.*at least 4"):
        fit_head(model, mixed)
    both, _ = with_passpoints(model, case, truth, "photo0", 2)
    both, _ = with_passpoints(model, both, truth, "photo1", 2)
    with pytest.raises(ValueError, match=r"4 usable landmarks in all; the fit needs at "
                                         r"least 6"):
        fit_head(model, both)



def test_refit_says_anew_which_views_it_skips(model):
    # a view the full fit skipped (no landmark) is no longer reported as skipped once a
    # landmark is dragged onto it; the full fit's other warnings are kept
    case, truth = make_perspective_case(model, 7, n_views=3)
    none, res = fit_with_passpoints(model, case, truth, "photo2", 0)
    skip = [w for w in res.info["warnings"] if "'photo2'" in w and "no usable" in w]
    assert skip
    res.info["refit_state"]["warnings"] = ["kept from the full fit"]
    none.views["photo2"].points = dict(case.views["photo2"].points)
    again = refit_landmarks(model, none, res)
    assert not [w for w in again.info["warnings"] if "no usable" in w]
    assert "kept from the full fit" in again.info["warnings"]
    assert len(again.residuals["photo2"].names) == len(case.views["photo2"].points)
