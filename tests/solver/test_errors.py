"""Input checks (solver/errors.py): points as float arrays, one line naming what is wrong."""

import warnings

import numpy as np
import pytest

from solver.errors import as_points


def test_as_points_names_the_first_row_that_is_not_finite():
    pts = np.zeros((5, 3))
    np.testing.assert_array_equal(as_points(pts, "pts"), pts)
    for bad in (np.nan, np.inf, -np.inf):
        p = pts.copy()
        p[3, 1] = bad
        p[4, 2] = bad
        with pytest.raises(ValueError, match=r"^pts: row 3 is not finite"):
            as_points(p, "pts")
    # +inf and -inf in one array: their sum is NaN, still caught
    p = pts.copy()
    p[1, 0], p[2, 0] = np.inf, -np.inf
    with pytest.raises(ValueError, match="row 1"):
        as_points(p, "pts")


def test_as_points_keeps_huge_finite_values_without_a_warning():
    big = np.full((4, 3), 1e308)
    big[0] = -1e308
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a bad-input line must come alone, no warning
        np.testing.assert_array_equal(as_points(big, "big"), big)
        with pytest.raises(ValueError, match="row 2"):
            as_points(np.array([[0, 0, 0], [1e308, 1, 1], [np.inf, 0, 0], [-np.inf, 0, 0.0]]),
                      "p")


def test_as_points_checks_shape_and_count():
    with pytest.raises(ValueError, match=r"^p: expected an array of shape \(n, 3\)"):
        as_points(np.zeros((4, 2)), "p")
    with pytest.raises(ValueError, match="needs at least 2 points, got 1"):
        as_points(np.zeros((1, 3)), "p", min_count=2)
    assert as_points([[1, 2]], "uv", dim=2).dtype == np.float64
