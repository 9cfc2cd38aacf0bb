"""Shading removal (solver/texture/shading.py) on a sheet with a known light field."""

import numpy as np
import pytest

from solver.texture.shading import (
    linear_to_srgb,
    remove_shading,
    shading_factor,
    smooth_on_mesh,
    srgb_to_linear,
)


def _sheet(n=60, size=0.2):
    s = np.linspace(0, size, n + 1)
    gx, gy = np.meshgrid(s, s, indexing="ij")
    points = np.stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)], -1)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    tris = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                           np.stack([a, c, d], -1).reshape(-1, 3)])
    return points, tris


def test_srgb_round_trip():
    x = np.linspace(0, 1, 101)
    np.testing.assert_allclose(linear_to_srgb(srgb_to_linear(x)), x, atol=1e-12)


def test_a_smooth_light_field_is_flattened_and_the_albedo_detail_kept():
    points, tris = _sheet()
    x, y = points[:, 0] / 0.2, points[:, 1] / 0.2
    albedo = np.where((np.floor(x * 30) + np.floor(y * 30)) % 2, 0.45, 0.35)  # 7 mm checks
    light = 0.5 + 0.9 * x  # a key light from one side: 0.5 .. 1.4
    linear = albedo[:, None] * light[:, None] * np.array([1.0, 0.8, 0.7])
    rgb = linear_to_srgb(linear)
    factor = shading_factor(rgb, points, tris, length=0.03)
    flat = srgb_to_linear(remove_shading(rgb, factor))[:, 0]
    inner = (x > 0.2) & (x < 0.8) & (y > 0.2) & (y < 0.8)  # the smoothing's edge effects

    def spread(v):  # low-frequency: column means across the light's direction
        _, bins = np.unique(np.floor(x[inner] * 10), return_inverse=True)
        means = np.bincount(bins, v[inner]) / np.bincount(bins)
        return (means.max() - means.min()) / means.mean()

    assert spread(linear[:, 0]) > 0.4
    assert spread(flat) < 0.1
    # the checks' contrast survives
    dark = inner & (albedo < 0.4)
    assert flat[~dark & inner].mean() / flat[dark].mean() == pytest.approx(0.45 / 0.35, rel=0.1)


def test_smoothing_keeps_a_constant_and_refuses_a_bad_length():
    points, tris = _sheet(10)
    np.testing.assert_allclose(smooth_on_mesh(np.full(len(points), 0.7), points, tris, 0.05),
                               0.7, atol=1e-9)
    with pytest.raises(ValueError, match="length"):
        smooth_on_mesh(np.ones(len(points)), points, tris, 0.0)
