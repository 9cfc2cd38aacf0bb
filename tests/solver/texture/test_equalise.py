"""Colour equalisation between views (solver/texture/equalise.py)."""

import numpy as np
import pytest

from solver.texture.equalise import (
    apply_gains,
    default_reference,
    fit_gains,
    seam_difference,
)


def _two_views(n=4000, seed=0):
    """One texture seen by two views; the second with a known gain and offset per channel,
    a little noise, and texels each view alone sees."""
    rng = np.random.default_rng(seed)
    truth = rng.uniform(0.2, 0.8, (n, 3))
    gain, offset = np.array([0.8, 1.1, 0.9]), np.array([0.05, -0.03, 0.1])
    colours = np.stack([truth, truth * gain + offset + 0.005 * rng.standard_normal((n, 3))])
    weights = np.ones((2, n))
    weights[0, : n // 4] = 0.0   # only view 1 sees these
    weights[1, -n // 4:] = 0.0   # only view 0 sees these
    return colours, weights, gain, offset


def test_a_known_gain_and_offset_are_undone():
    colours, weights, gain, offset = _two_views()
    g, o = fit_gains(colours, weights, reference=0)
    np.testing.assert_array_equal(g[0], 1.0)
    np.testing.assert_array_equal(o[0], 0.0)
    # the weak pull toward gain 1 (equalise.PRIOR) leaves a few per cent of the step
    np.testing.assert_allclose(g[1], 1 / gain, rtol=0.05)
    np.testing.assert_allclose(o[1], -offset / gain, atol=0.03)
    fixed = apply_gains(colours, g, o)
    both = (weights > 0).all(axis=0)
    assert np.abs(fixed[0, both] - fixed[1, both]).mean() < 0.01
    assert np.abs(fixed[0, both].mean(axis=0) - fixed[1, both].mean(axis=0)).max() < 0.002
    assert np.abs(colours[0, both] - colours[1, both]).mean() > 0.03


def test_outliers_in_the_overlap_do_not_set_the_gains():
    colours, weights, gain, offset = _two_views(seed=1)
    both = np.flatnonzero((weights > 0).all(axis=0))
    colours[1, both[:150]] = 1.0  # a highlight only view 1 shows
    g, o = fit_gains(colours, weights, reference=0)
    np.testing.assert_allclose(g[1], 1 / gain, rtol=0.05)
    plain, _ = fit_gains(colours, weights, reference=0, iterations=1)
    assert np.abs(plain[1] - 1 / gain).max() > np.abs(g[1] - 1 / gain).max()


def test_groups_share_one_gain_and_a_view_without_overlap_is_left_alone():
    colours, weights, gain, offset = _two_views(seed=2)
    c = np.concatenate([colours, colours[1:]])
    w = np.concatenate([weights, weights[1:]])
    g, o = fit_gains(c, w, reference=0, groups=[0, 1, 1])
    np.testing.assert_allclose(g[1], g[2])
    np.testing.assert_allclose(g[1], 1 / gain, rtol=0.05)
    lone = np.concatenate([colours, colours[:1] * 0.5])
    wl = np.concatenate([weights[:, :], np.zeros((1, weights.shape[1]))])
    g, o = fit_gains(lone, wl, reference=0)
    np.testing.assert_allclose(g[2], 1.0)
    np.testing.assert_allclose(o[2], 0.0)


def test_the_reference_is_the_view_overlapping_the_others_most():
    w = np.zeros((3, 30))
    w[0, :20] = 1.0    # a side view
    w[1, 10:30] = 1.0  # the front: overlaps both sides
    w[2, 20:] = 1.0    # the other side
    w[0, :] += 0.0
    assert default_reference(w) == 1
    with pytest.raises(ValueError, match="reference"):
        fit_gains(np.zeros((2, 5, 3)), np.ones((2, 5)), reference=2)
    with pytest.raises(ValueError, match="weights"):
        fit_gains(np.zeros((2, 5, 3)), -np.ones((2, 5)))


def test_seam_difference_measures_the_step_in_the_band_only():
    n = 1000
    cells = np.arange(n) // 50
    colours = np.full((2, n, 3), 0.5)
    colours[1] += 0.05  # a 10 % step where the views blend ...
    colours[1, :500] = 0.9  # ... and a big one where view 1 has no say
    weights = np.ones((2, n))
    weights[1, :500] = 0.1  # a 9 % share: outside a 20 % band
    d = seam_difference(colours, weights, cells)
    assert d.texels == 500
    assert d.absolute == pytest.approx(0.05)
    assert d.relative == pytest.approx(0.05 / 0.525)
    # texel detail that cancels within a cell is no step
    detail = colours.copy()
    detail[1, 500:] = 0.5 + 0.1 * np.where(np.arange(500) % 2, 1, -1)[:, None]
    assert seam_difference(detail, weights, cells).absolute == pytest.approx(0.0, abs=1e-12)
    assert seam_difference(colours, weights * [[1], [0]], cells).texels == 0


def test_gains_applied_in_place_are_the_copy_s_values():
    colours, weights, _, _ = _two_views()
    colours = colours.astype(np.float32)
    g, o = fit_gains(colours, weights, reference=0)
    copy = apply_gains(colours, g, o)
    again = colours.copy()
    assert apply_gains(again, g, o, in_place=True) is again
    np.testing.assert_array_equal(again, copy)
    assert not np.array_equal(colours, copy)  # the copy left its input alone
