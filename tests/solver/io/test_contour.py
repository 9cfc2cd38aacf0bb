"""Traced outlines (solver/io/contour.py): a contour too large is refused at once, a long one
is checked quickly and thinned for the fit with a notice."""

import time

import numpy as np

from solver import parse_landmarks
from solver.io.contour import (
    MAX_CONTOUR_POINTS,
    contour_array,
    thin_case_contours,
    thin_contour,
)
from tests.solver.io.support import H, W, parse_error


def _arc(n, length_px):
    t = np.linspace(0.0, np.pi, n)
    r = length_px / np.pi
    return np.column_stack([W / 2 + r * np.cos(t) * 0.9, H / 2 - r * np.sin(t) * 0.9])


def test_a_pathological_contour_is_refused_quickly(doc):
    doc["views"]["side"]["contour"] = _arc(100_000, 800).tolist()
    t0 = time.perf_counter()
    msg = parse_error(doc)
    assert time.perf_counter() - t0 < 1.0
    assert msg.startswith(f"case.json: views.side.contour: 100000 points; at most "
                          f"{MAX_CONTOUR_POINTS} are read")


def test_a_long_contour_is_checked_quickly_and_its_bad_points_named(doc):
    pts = _arc(MAX_CONTOUR_POINTS, 800)
    doc["views"]["side"]["contour"] = pts.tolist()
    t0 = time.perf_counter()
    case = parse_landmarks(doc, "case.json")
    assert time.perf_counter() - t0 < 1.5  # the schema's walk took 2 s per 20,000 points
    np.testing.assert_array_equal(case.views["side"].contour, pts)
    pts[7] = [W + 5.0, 10.0]
    pts[9] = [-1.0, 10.0]
    doc["views"]["side"]["contour"] = pts.tolist()
    assert parse_error(doc) == (f"case.json: views.side.contour[7]: ({W + 5:g}, 10) lies "
                                f"outside the {W}x{H} image (and 1 more point)")
    doc["views"]["side"]["contour"][3] = [1.0, "2"]  # not a number: the schema names it
    assert "views.side.contour[3][1]" in parse_error(doc)


def test_contour_array_takes_only_pairs_of_numbers():
    assert contour_array([[1, 2.5], [3, 4]]).shape == (2, 2)
    for bad in ([[1, True]], [[1, 2, 3]], [[1, None]], "x", [[1, "2"]]):
        assert contour_array(bad) is None


def test_thinning_keeps_one_point_per_spacing_and_both_ends():
    pts = np.column_stack([np.linspace(0, 100, 1001), np.zeros(1001)])  # 0.1 px apart
    thin = thin_contour(pts, 2.0)
    assert len(thin) == 51  # 0, 2, ..., 100
    np.testing.assert_allclose(np.diff(thin[:, 0]), 2.0, atol=0.11)
    assert (thin[0] == pts[0]).all() and (thin[-1] == pts[-1]).all()
    sparse = pts[::50]  # 5 px apart: nothing to thin
    np.testing.assert_array_equal(thin_contour(sparse, 2.0), sparse)


def test_thin_case_contours_says_what_it_did(doc):
    doc["views"]["side"]["contour"] = _arc(5000, 800).tolist()
    case = parse_landmarks(doc, "case.json")
    notes = thin_case_contours(case)
    assert len(notes) == 1 and notes[0].startswith("case.json: views.side.contour: 5000 "
                                                   "points thinned to ")
    assert 355 <= len(case.views["side"].contour) <= 361  # 720 px of outline, 2 px apart
    assert thin_case_contours(case) == []
