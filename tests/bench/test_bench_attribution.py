"""bench/bench_attribution.py: the true silhouette of a render's alpha, outline points moved
onto it, the photos-only case as each attribution changes it, and copies of it moved."""

import json

import numpy as np
import pytest

from bench.bench_attribution import (
    ATTRIBUTIONS,
    COPY_PX,
    attributed,
    main,
    moved_copy,
    onto_silhouette,
    true_silhouette,
)
from solver.io.case import LandmarkCase, View


def _disc(radius=60.0, centre=(100.0, 90.0), shape=(180, 200)):
    """A render's alpha of a disc, anti-aliased: 0.5 at ``radius`` from ``centre`` (photo
    pixels; pixel (r, c) at (c + 0.5, r + 0.5))."""
    v, u = np.mgrid[0:shape[0], 0:shape[1]] + 0.5
    d = np.hypot(u - centre[0], v - centre[1])
    return np.round(np.clip(radius - d + 0.5, 0, 1) * 255).astype(np.uint8)


def test_the_true_silhouette_is_the_alphas_half_level_densely():
    line = true_silhouette(_disc())
    r = np.hypot(line[:, 0] - 100.0, line[:, 1] - 90.0)
    assert np.abs(r - 60.0).max() < 0.1
    # every 0.1 px: a full turn of the circle
    assert len(line) == pytest.approx(2 * np.pi * 60 / 0.1, rel=0.1)
    with pytest.raises(ValueError, match="no silhouette"):
        true_silhouette(np.zeros((10, 10), np.uint8))


def test_outline_points_moved_onto_the_silhouette_keep_their_order_and_place():
    a = np.linspace(0, np.pi, 40)
    off = 3.0 * np.sin(7 * a)  # up to 3 px in and out
    points = np.stack([100 + (60 + off) * np.cos(a), 90 + (60 + off) * np.sin(a)], axis=1)
    moved = onto_silhouette(points, true_silhouette(_disc()))
    assert np.abs(np.hypot(moved[:, 0] - 100, moved[:, 1] - 90) - 60).max() < 0.1
    # along the outline they stay where they were (moved across it only)
    assert np.abs(np.arctan2(moved[:, 1] - 90, moved[:, 0] - 100) - a).max() < 0.01


def _case_and_truth():
    alpha = _disc()
    front = View("front", "front.png", (200, 180), None,
                 {"eye_outer_right": (70.0, 80.0), "nose_tip": (101.0, 100.0),
                  "profile_only": (5.0, 5.0)},
                 contour=np.array([[40.0, 91.0], [100.0, 27.0], [163.0, 90.0]]),
                 uncertainty={"eye_outer_right": 2.0, "nose_tip": 3.0})
    side = View("right", "side.png", (200, 180), None, {"nose_tip": (150.0, 100.0)},
                contour=np.array([[100.0, 33.0], [157.0, 90.0]]))
    truth = {"landmark_names": json.dumps({"front": ["eye_outer_right", "nose_tip"],
                                           "side": ["nose_tip"]}),
             "exact_front": np.array([[72.0, 81.0], [100.0, 101.0]]),
             "head_alpha_front": alpha, "head_alpha_side": alpha}
    return LandmarkCase({"front": front, "right": side}), truth


def test_each_attribution_changes_only_what_it_names():
    case, truth = _case_and_truth()
    cases = attributed(case, truth)
    assert list(cases) == list(ATTRIBUTIONS)
    detected, exact, clicks = cases["detected"], cases["front exact"], cases["front exact clicks"]
    assert detected.views["front"].points == case.views["front"].points
    assert exact.views["front"].points == {"eye_outer_right": (72.0, 81.0),
                                           "nose_tip": (100.0, 101.0),
                                           "profile_only": (5.0, 5.0)}
    assert exact.views["front"].uncertainty == case.views["front"].uncertainty
    assert clicks.views["front"].uncertainty == {}
    assert exact.views["right"].points == case.views["right"].points  # the profile as detected
    np.testing.assert_array_equal(exact.views["front"].contour, case.views["front"].contour)
    for label in ("true outlines", "both"):
        for name in ("front", "right"):
            c = cases[label].views[name].contour
            assert np.abs(np.hypot(c[:, 0] - 100, c[:, 1] - 90) - 60).max() < 0.1
    assert cases["both"].views["front"].points == exact.views["front"].points
    # the case itself is left as it was
    np.testing.assert_array_equal(case.views["front"].contour[0], [40.0, 91.0])


def test_a_three_quarter_front_beside_a_profile_is_attributed_as_the_front():
    # a head turned in its photos (bench_lens --yaw) is detected so
    case, truth = _case_and_truth()
    case.views["three_quarter_left"] = case.views.pop("front")
    exact = attributed(case, truth)["front exact"].views
    assert exact["three_quarter_left"].points["nose_tip"] == (100.0, 101.0)
    assert exact["right"].points == case.views["right"].points


def test_photos_not_detected_as_a_front_and_a_profile_are_said():
    case, truth = _case_and_truth()
    case.views["left"] = case.views.pop("front")  # two profiles
    with pytest.raises(ValueError, match=r"not a front \(or a three-quarter view\) and a"):
        attributed(case, truth)
    case, truth = _case_and_truth()
    case.views["three_quarter_left"] = case.views.pop("right")  # no profile
    with pytest.raises(ValueError, match="and a profile"):
        attributed(case, truth)


def test_a_moved_copy_moves_every_point_by_a_tenth_of_a_pixel_or_so_and_leaves_the_case():
    case, _ = _case_and_truth()
    moved = moved_copy(case, np.random.default_rng(0))
    again = moved_copy(case, np.random.default_rng(0))
    offsets = []
    for name, view in case.views.items():
        m = moved.views[name]
        assert set(m.points) == set(view.points)
        offsets += [np.subtract(m.points[n], p) for n, p in view.points.items()]
        offsets += list(m.contour - view.contour)
        assert m.points == again.views[name].points  # seeded
    offsets = np.abs(np.array(offsets))
    assert (offsets > 0).all() and offsets.max() < 5 * COPY_PX
    assert case.views["front"].points["nose_tip"] == (101.0, 100.0)  # the case as it was


def test_copies_move_as_far_as_asked_and_a_distance_not_positive_is_refused(capsys):
    case, _ = _case_and_truth()
    far = moved_copy(case, np.random.default_rng(0), 0.3)
    near = moved_copy(case, np.random.default_rng(0))
    ratio = np.subtract(far.views["front"].points["nose_tip"], (101.0, 100.0)) \
        / np.subtract(near.views["front"].points["nose_tip"], (101.0, 100.0))
    np.testing.assert_allclose(ratio, 0.3 / COPY_PX)
    for bad in ("0", "-0.3"):
        with pytest.raises(SystemExit):
            main(["--copy-px", bad])
        assert "--copy-px: a positive number of pixels" in capsys.readouterr().err
