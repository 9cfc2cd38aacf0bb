"""Synthetic cases: known heads photographed by known cameras."""

import numpy as np
import pytest

from solver import PinholeCamera, landmarks_to_dict, parse_landmarks
from solver.geometry import rotation_from_vector
from solver.synthetic import (
    make_case,
    make_hand_placed_case,
    make_mirror_case,
    make_perspective_case,
    resample_polyline,
    skin_error_mm,
    skin_squared_distances,
    trace_silhouette,
    vertex_normals,
)


@pytest.fixture(scope="module")
def case_truth(model):
    return make_case(model, 7, noise_px=0.0)


def test_views_landmarks_and_truth(model, case_truth):
    case, truth = case_truth
    assert set(case.views) == {"front", "right"}
    np.testing.assert_allclose(truth.local_vertices, model.identity.instance(truth.identity_coeffs))
    world = truth.world_vertices
    for name, view in case.views.items():
        w, h = view.size
        assert h == 1024
        side = name
        expected = {e["name"] for e in model.landmark_info if side in e["views"]}
        assert set(view.points) == expected
        cam = truth.cameras[name]
        for lm, uv in view.points.items():
            assert 0 <= uv[0] <= w and 0 <= uv[1] <= h
            # noise-free: the projection of the landmark vertex
            np.testing.assert_allclose(uv, cam.project(world[[model.landmarks[lm]]])[0],
                                       atol=1e-9)
    # each photo has its own scale and offset
    f, r = truth.cameras["front"], truth.cameras["right"]
    assert f.scale != r.scale and not np.allclose(f.offset, r.offset)
    # the case is a valid landmarks document
    again = parse_landmarks(landmarks_to_dict(case), "<synthetic>", model)
    assert again.views["front"].points == case.views["front"].points


def test_noise_level(model):
    case, truth = make_case(model, 3, noise_px=2.0)
    d = np.concatenate([np.array(list(case.views[v].points.values()))
                        - np.array([truth.pixels[v][n] for n in case.views[v].points])
                        for v in case.views])
    assert 1.6 < d.std() < 2.4


def test_seeds_reproduce(model):
    a, ta = make_case(model, 11)
    b, tb = make_case(model, 11)
    c, _ = make_case(model, 12)
    assert a == b
    np.testing.assert_array_equal(ta.identity_coeffs, tb.identity_coeffs)
    assert a != c


def test_contour_is_the_head_outline_without_the_neck_cut(model, case_truth):
    case, truth = case_truth
    contour = case.views["right"].contour
    assert contour.shape == (100, 2)
    assert case.views["front"].contour is None
    cam = truth.cameras["right"]
    world = truth.world_vertices
    # Drawing order: from the front of the neck (the face looks to the image's right in a
    # right view) over the head to the nape.
    assert contour[0, 0] > contour[-1, 0]
    # The midsagittal chain of the true head lies on the traced outline (nose, forehead,
    # skull); the median distance is a fraction of a pixel.
    chain = cam.project(world[model.profile_chain])
    dense = resample_polyline(truth.contour["right"], 4000)
    d = np.min(np.linalg.norm(chain[:, None] - dense[None], axis=2), axis=1)
    assert np.median(d) < 1.0
    # Nothing was traced along the neck's cut: the outline is open there (its ends are a
    # neck's depth apart) and its lowest point is one of its ends.
    assert np.linalg.norm(contour[0] - contour[-1]) > 150.0
    assert int(np.argmax(contour[:, 1])) in (0, 99)
    # The outline encloses the projected skin: every skin vertex is inside or on it.
    skin_px = cam.project(world[model.skin])
    assert skin_px[:, 1].min() >= truth.contour["right"][:, 1].min() - 1.0


def test_left_view_and_single_view(model):
    case, truth = make_case(model, 5, views=("front", "left"), in_plane_deg=5.0,
                            contour_points=60)
    assert case.views["left"].contour.shape == (60, 2)
    assert all("left" in e["views"] for e in model.landmark_info
               if e["name"] in case.views["left"].points)
    tilt = np.degrees(truth.cameras["left"].in_plane_angle)
    assert 0 < abs(tilt) <= 5.0
    # in the left view the face looks to the image's left: drawing starts there
    contour = case.views["left"].contour
    assert contour[0, 0] < contour[-1, 0]
    only, _ = make_case(model, 5, views=("front",))
    assert set(only.views) == {"front"}


def test_trace_silhouette_matches_projection_extent(model):
    _, truth = make_case(model, 2, noise_px=0.0)
    cam = truth.cameras["right"]
    out = trace_silhouette(model, truth.world_vertices, cam)
    px = cam.project(truth.world_vertices[model.skin])
    # the top of the head and the tip of the nose are on the outline, within a pixel
    assert abs(out[:, 1].min() - px[:, 1].min()) < 1.0
    assert abs(out[:, 0].max() - px[:, 0].max()) < 1.0


def test_bad_arguments(model):
    with pytest.raises(ValueError, match="unknown view"):
        make_case(model, 0, views=("top",))
    with pytest.raises(ValueError, match="coeffs"):
        make_case(model, 0, coeffs=np.zeros(500))


# ----------------------------------------------------------------------------- perspective


@pytest.fixture(scope="module")
def perspective(model):
    return make_perspective_case(model, 4, n_views=3, noise_px=0.0, contour=True,
                                 contour_points=80)


def test_perspective_photos_show_what_faces_them(model, perspective):
    case, truth = perspective
    assert list(case.views) == ["photo0", "photo1", "photo2"]
    world = truth.world_vertices
    normals = vertex_normals(model, world)
    skin = world[model.skin]
    for name, view in case.views.items():
        cam = truth.cameras[name]
        assert isinstance(cam, PinholeCamera) and 35.0 <= cam.lens_mm <= 85.0
        assert view.camera is None and view.camera_hints["kind"] == "pinhole"
        assert view.camera_hints["lens_mm"] == pytest.approx(cam.lens_mm, rel=0.25)
        centre = 0.5 * (skin.min(axis=0) + skin.max(axis=0))
        assert 0.5 <= np.linalg.norm(cam.centre - centre) <= 2.0
        # the head is as tall as in the orthographic cases' 1024-px photos
        assert 768.0 * 0.97 <= np.ptp(cam.project(skin)[:, 1]) <= 922.0 * 1.03
        # noise free: every landmark is its vertex's projection, and that vertex faces the
        # camera; the landmarks it does not show face away or are hidden
        verts = np.array([model.landmarks[n] for n in view.points])
        np.testing.assert_allclose(np.array(list(view.points.values())),
                                   cam.project(world[verts]), atol=1e-9)
        facing = np.einsum("ij,ij->i", normals[verts], cam.toward_camera(world[verts]))
        assert (facing > 0).all()
        left_out = [e["name"] for e in model.landmark_info if e["name"] not in view.points]
        lv = np.array([model.landmarks[n] for n in left_out])
        away = np.einsum("ij,ij->i", normals[lv], cam.toward_camera(world[lv])) <= 0
        assert away.mean() > 0.5  # most are on the far side, the rest covered
        assert view.contour.shape == (80, 2)
    # the first photo looks at the face, the others from either side (up to 45 degrees)
    yaw = {n: np.degrees(np.arctan2(truth.cameras[n].centre[0], -truth.cameras[n].centre[1]))
           for n in case.views}
    assert abs(yaw["photo0"]) < 15.0
    assert 15.0 < abs(yaw["photo1"]) < 50.0 and 15.0 < abs(yaw["photo2"]) < 50.0
    assert np.sign(yaw["photo1"]) != np.sign(yaw["photo2"])
    # a three-quarter view misses landmarks on the far side that the front photo shows
    far = "left" if yaw["photo1"] < 0 else "right"
    assert any(n.endswith(far) for n in case.views["photo0"].points
               if n not in case.views["photo1"].points)
    # a valid version-2 landmarks document
    again = parse_landmarks(landmarks_to_dict(case), "<synthetic>", model)
    assert again.views["photo1"].points == case.views["photo1"].points


def test_perspective_case_calibrated_and_seeded(model):
    a, ta = make_perspective_case(model, 9, n_views=2, calibrated=True, focal_prior=None)
    b, _ = make_perspective_case(model, 9, n_views=2, calibrated=True, focal_prior=None)
    assert a == b
    for name, view in a.views.items():
        assert view.camera is ta.cameras[name] and view.camera_fixed
    # the same seed gives the orthographic cases' head
    _, tortho = make_case(model, 9)
    np.testing.assert_array_equal(ta.identity_coeffs, tortho.identity_coeffs)
    with pytest.raises(ValueError, match="n_views"):
        make_perspective_case(model, 0, n_views=0)


def test_mirror_case_is_one_photo_with_a_mirrored_camera(model):
    case, truth = make_mirror_case(model, 3, noise_px=0.0)
    front, mirror = case.views["front"], case.views["mirror"]
    assert mirror.mirror_of == "front" and mirror.size == front.size
    plane = truth.planes["mirror"]
    real, virtual = truth.cameras["front"], truth.cameras["mirror"]
    assert virtual.is_mirrored and not real.is_mirrored
    world = truth.world_vertices
    # a mirror landmark is where the real camera sees the reflected point, named by the
    # subject's true side; the mirror shows the subject's left (the mirror is at +x)
    verts = np.array([model.landmarks[n] for n in mirror.points])
    np.testing.assert_allclose(np.array(list(mirror.points.values())),
                               real.project(plane.reflect_points(world[verts])), atol=1e-6)
    assert sum(n.endswith("_left") for n in mirror.points) > \
        sum(n.endswith("_right") for n in mirror.points)
    # both images of the head lie inside the one photo, apart
    w, h = front.size
    for pts in (front.points, mirror.points):
        p = np.array(list(pts.values()))
        assert (p >= 0).all() and (p[:, 0] <= w).all() and (p[:, 1] <= h).all()
    du = np.mean([u for u, _ in mirror.points.values()]) - \
        np.mean([u for u, _ in front.points.values()])
    assert abs(du) > 0.2 * w
    # the mirror faces the camera and the head
    assert plane.signed_distance(real.centre[None])[0] > 0
    assert plane.signed_distance(world[model.skin]).min() > 0
    again = parse_landmarks(landmarks_to_dict(case), "<synthetic>", model)
    assert again.views["mirror"].mirror_of == "front"


def test_a_hand_placed_case_has_nominal_cameras_and_the_side_seen_from_its_own_yaw(model):
    from solver import OrthographicCamera

    case, head = make_hand_placed_case(model, 1, side_deg=75.0, noise_px=0.0)
    lms = model.landmark_set
    front, side = case.views["front"], case.views["side"]
    for view, kind in ((front, "orthographic-front"), (side, "orthographic-right")):
        assert np.allclose(view.camera.rotation,
                           OrthographicCamera.nominal(kind, view.size).rotation)
    seen = OrthographicCamera.turned("orthographic-right", side.size, 75.0)
    names = list(side.points)
    assert np.allclose(np.array([side.points[n] for n in names]),
                       seen.project(head[[lms.vertices[n] for n in names]]))
    assert all(model.vertices[lms.vertices[n], 0] <= 0.005 for n in names)
    assert len(front.points) > len(names) >= 20


def test_the_skin_is_scored_after_a_similarity_vertex_by_vertex(model):
    truth = model.vertices
    moved = 1.2 * truth @ rotation_from_vector((0.1, -0.2, 0.3)).T + [0.01, 0.02, -0.03]
    assert skin_squared_distances(model, moved, truth).max() < 1e-20  # size and pose: none
    assert skin_error_mm(model, moved, truth) < 1e-7
    bumped = truth.copy()
    one = int(model.skin[100])
    bumped[one, 0] += 0.01  # one skin vertex 10 mm off
    d2 = skin_squared_distances(model, bumped, truth)
    assert d2.shape == (len(model.skin),) and int(np.argmax(d2)) == 100
    assert np.sqrt(d2[100]) == pytest.approx(0.01, rel=1e-3)  # the alignment barely moves
    assert skin_error_mm(model, bumped, truth) == pytest.approx(
        1000.0 * np.sqrt(d2.mean()), rel=1e-12)
