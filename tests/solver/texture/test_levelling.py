"""Seam levelling (solver/texture/levelling.py)."""

import numpy as np
import pytest

from solver.texture.levelling import level_field
from tests.solver.texture.test_shading import _sheet


def test_the_field_follows_the_overlap_and_continues_beyond_it():
    points, tris = _sheet(40, 0.2)
    x = points[:, 0]
    overlap = ((x > 0.08) & (x < 0.12)).astype(float)  # a seam band 4 cm wide
    diff = np.stack([0.1 + 0.2 * x, np.full_like(x, -0.05)], 1)  # a slow difference
    f = level_field(np.where(overlap[:, None] > 0, diff, np.nan), overlap, points, tris, 0.005)
    band = overlap > 0
    np.testing.assert_allclose(f[band], diff[band], atol=0.01)
    # the view's own side (x > 0.12) moves with its border, smoothly, no step
    own = x > 0.15
    assert np.abs(f[own, 1] + 0.05).max() < 0.005
    edge = np.abs(x - 0.12) < 0.011
    assert np.ptp(f[edge, 0]) < 0.02
    with pytest.raises(ValueError, match="overlap"):
        level_field(diff, overlap[:-1], points, tris, 0.01)


def test_with_a_decay_the_correction_fades_away_from_the_seam():
    points, tris = _sheet(40, 0.2)
    x = points[:, 0]
    overlap = (x < 0.04).astype(float)
    diff = np.full(len(x), 0.1)
    f = level_field(diff, overlap, points, tris, 0.005, decay=0.03)
    np.testing.assert_allclose(f[x < 0.03], 0.1, atol=0.01)
    assert 0.01 < f[np.isclose(x, 0.07)].mean() < 0.06  # a centimetre or three on
    assert np.abs(f[x > 0.17]).max() < 0.005           # far away: the photo as it was
    assert np.all(np.diff(f[np.isclose(points[:, 1], 0.1)]) <= 1e-12)  # falling, no step
    with pytest.raises(ValueError, match="decay"):
        level_field(diff, overlap, points, tris, 0.005, decay=0.004)
