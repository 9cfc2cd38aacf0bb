"""Synthetic cases: known heads photographed by known cameras."""

import numpy as np
import pytest

from solver.landmarks_file import landmarks_to_dict, parse_landmarks
from solver.synthetic import make_case, resample_polyline, trace_silhouette


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
