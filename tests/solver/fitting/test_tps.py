"""Thin-plate splines (solver/tps.py) and similarity Procrustes (solver/procrustes.py)."""

import numpy as np
import pytest

from solver.fitting.tps import ThinPlateSpline
from solver.geometry import rotation_from_vector
from solver.procrustes import Similarity, similarity_procrustes


def _cloud(n, seed=0, size=0.1):
    return np.random.default_rng(seed).standard_normal((n, 3)) * size


# ----------------------------------------------------------------------------- TPS


def test_tps_hits_control_points():
    src = _cloud(40)
    dst = src + 0.01 * np.random.default_rng(1).standard_normal(src.shape)
    tps = ThinPlateSpline.fit(src, dst)
    np.testing.assert_allclose(tps.apply(src), dst, atol=1e-12)


def test_tps_reproduces_affine_map_exactly():
    rng = np.random.default_rng(2)
    src = _cloud(30, seed=3)
    a = np.eye(3) + 0.3 * rng.standard_normal((3, 3))
    b = rng.standard_normal(3)
    tps = ThinPlateSpline.fit(src, src @ a.T + b)
    pts = _cloud(5000, seed=4, size=0.3)
    np.testing.assert_allclose(tps.apply(pts), pts @ a.T + b, atol=1e-9, rtol=0)
    assert np.abs(tps.weights).max() < 1e-9  # no bending at all
    assert abs(tps.bending_energy()) < 1e-12


def test_tps_units_invariance():
    # The same deformation described in millimetres instead of metres (lambda scaled too).
    src = _cloud(25, seed=5)
    dst = src + 0.005 * np.random.default_rng(6).standard_normal(src.shape)
    pts = _cloud(100, seed=7)
    m = ThinPlateSpline.fit(src, dst, regularization=0.002).apply(pts)
    mm = ThinPlateSpline.fit(src * 1000, dst * 1000, regularization=2.0).apply(pts * 1000)
    np.testing.assert_allclose(mm / 1000, m, atol=1e-12)


def test_tps_regularization_trades_fit_for_smoothness():
    src = _cloud(40, seed=8)
    dst = src + 0.01 * np.random.default_rng(9).standard_normal(src.shape)
    misfit, energy = [], []
    for lam in (0.0, 0.001, 0.01, 0.1, 1.0):
        tps = ThinPlateSpline.fit(src, dst, regularization=lam)
        misfit.append(np.abs(tps.apply(src) - dst).max())
        energy.append(tps.bending_energy())
    assert misfit[0] < 1e-12
    assert all(a < b for a, b in zip(misfit, misfit[1:], strict=False))
    assert all(a > b for a, b in zip(energy, energy[1:], strict=False))
    # Very strong smoothing: the least-squares affine map.
    tps = ThinPlateSpline.fit(src, dst, regularization=1e9)
    p = np.hstack([np.ones((len(src), 1)), src])
    coef = np.linalg.lstsq(p, dst, rcond=None)[0]
    np.testing.assert_allclose(tps.apply(src), p @ coef, atol=1e-8)


def test_tps_apply_chunked_equals_unchunked():
    src = _cloud(300, seed=10)
    dst = src + 0.01 * np.random.default_rng(11).standard_normal(src.shape)
    tps = ThinPlateSpline.fit(src, dst)
    pts = _cloud(26719, seed=12)
    whole = tps.apply(pts, chunk=len(pts))
    np.testing.assert_allclose(tps.apply(pts, chunk=997), whole, atol=1e-14)
    np.testing.assert_allclose(tps.apply(pts), whole, atol=1e-14)
    assert tps.apply(np.zeros((0, 3))).shape == (0, 3)


def test_tps_smooth_between_control_points():
    # A bump on a grid of control points: the interpolant stays within the targets' range.
    g = np.linspace(-1, 1, 5)
    src = np.array([(x, y, z) for x in g for y in g for z in (-0.5, 0.5)])
    dst = src.copy()
    dst[:, 2] += 0.1 * np.exp(-(src[:, 0] ** 2 + src[:, 1] ** 2) * 3)
    tps = ThinPlateSpline.fit(src, dst)
    pts = np.random.default_rng(13).uniform(-1, 1, (2000, 3)) * [1, 1, 0.5]
    dz = tps.apply(pts)[:, 2] - pts[:, 2]
    assert dz.max() < 0.11 and dz.min() > -0.02


@pytest.mark.parametrize(
    "src, dst, lam, match",
    [
        (np.zeros((5, 3)), np.zeros((4, 3)), 0.0, "does not match"),
        (np.zeros((3, 3)), np.zeros((3, 3)), 0.0, "at least 4"),
        (np.zeros((5, 2)), np.zeros((5, 2)), 0.0, r"shape \(n, 3\)"),
        (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2, 1, 0.0]]),
         np.zeros((5, 3)), 0.0, "coplanar"),
        (np.vstack([_cloud(5), _cloud(1)]), _cloud(6, seed=1), 0.0, "coincide"),
        (_cloud(5), _cloud(5, seed=1), -1.0, "regularization"),
        (_cloud(5), _cloud(5, seed=1), float("nan"), "regularization"),
    ],
)
def test_tps_bad_input(src, dst, lam, match):
    with pytest.raises(ValueError, match=match):
        ThinPlateSpline.fit(src, dst, regularization=lam)


def test_tps_nan_rejected_with_name():
    src = _cloud(6)
    bad = src.copy()
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match="source: row 2"):
        ThinPlateSpline.fit(bad, src)
    with pytest.raises(ValueError, match="target: row 2"):
        ThinPlateSpline.fit(src, bad)
    with pytest.raises(ValueError, match="points: row 2"):
        ThinPlateSpline.fit(src, src).apply(bad)


def test_tps_duplicates_allowed_with_regularization():
    src = np.vstack([_cloud(6), _cloud(6)[:1]])
    dst = _cloud(7, seed=2)
    tps = ThinPlateSpline.fit(src, dst, regularization=0.01)
    assert np.isfinite(tps.apply(src)).all()


# ------------------------------------------------------------------------ Procrustes


def _random_rotation_2d(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


@pytest.mark.parametrize("dim", [2, 3])
def test_procrustes_recovers_known_similarity(dim):
    rng = np.random.default_rng(20 + dim)
    x = rng.standard_normal((30, dim))
    rot = rotation_from_vector([0.3, -1.1, 0.7]) if dim == 3 else _random_rotation_2d(2.5)
    y = 1.7 * x @ rot.T + np.arange(1, dim + 1)
    sim = similarity_procrustes(x, y)
    assert sim.scale == pytest.approx(1.7, abs=1e-12)
    np.testing.assert_allclose(sim.rotation, rot, atol=1e-12)
    np.testing.assert_allclose(sim.translation, np.arange(1, dim + 1), atol=1e-12)
    assert np.linalg.det(sim.rotation) == pytest.approx(1.0)
    assert sim.rms < 1e-12
    np.testing.assert_allclose(sim.apply(x), y, atol=1e-12)
    np.testing.assert_allclose(sim.inverse().apply(y), x, atol=1e-12)
    m = sim.matrix()
    np.testing.assert_allclose((np.c_[x, np.ones(len(x))] @ m.T)[:, :dim], y, atol=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
def test_procrustes_weights_ignore_outliers(dim):
    rng = np.random.default_rng(30 + dim)
    x = rng.standard_normal((40, dim))
    rot = rotation_from_vector([0.2, 0.1, -0.4]) if dim == 3 else _random_rotation_2d(-0.6)
    y = 0.8 * x @ rot.T + 0.5
    y[:5] += 3.0 * rng.standard_normal((5, dim))  # outliers
    w = np.ones(40)
    w[:5] = 0.0
    sim = similarity_procrustes(x, y, weights=w)
    assert sim.scale == pytest.approx(0.8, abs=1e-12)
    np.testing.assert_allclose(sim.rotation, rot, atol=1e-12)
    # Unweighted, the outliers spoil the fit.
    assert abs(similarity_procrustes(x, y).scale - 0.8) > 1e-3
    # Weights scale-invariant; matches the closed form of a weighted fit.
    sim2 = similarity_procrustes(x, y, weights=7 * w)
    np.testing.assert_allclose(sim2.translation, sim.translation, atol=1e-12)


def test_procrustes_weighted_noise_fit_is_least_squares():
    # The closed form must be the least-squares optimum: perturbing it raises the cost.
    rng = np.random.default_rng(40)
    x = rng.standard_normal((25, 3))
    y = 1.2 * x @ rotation_from_vector([0.5, 0.2, 0.1]).T + 0.1 * rng.standard_normal((25, 3))
    w = rng.uniform(0.1, 2.0, 25)
    sim = similarity_procrustes(x, y, weights=w)

    def cost(s, r, t):
        return float(w @ ((s * x @ r.T + t - y) ** 2).sum(1))

    best = cost(sim.scale, sim.rotation, sim.translation)
    for _ in range(20):
        d = 1e-4 * rng.standard_normal(7)
        r = rotation_from_vector(d[1:4]) @ sim.rotation
        assert cost(sim.scale * (1 + d[0]), r, sim.translation + d[4:]) > best
    assert sim.rms == pytest.approx(np.sqrt(best / w.sum()))


def test_procrustes_rigid_and_reflection():
    rng = np.random.default_rng(50)
    x = rng.standard_normal((10, 3))
    rot = rotation_from_vector([0.0, 0.4, 0.0])
    sim = similarity_procrustes(x, 2.0 * x @ rot.T, with_scale=False)
    assert sim.scale == 1.0
    np.testing.assert_allclose(sim.rotation, rot, atol=1e-12)
    # A mirrored target still yields a proper rotation.
    mirrored = x * [-1, 1, 1]
    assert np.linalg.det(similarity_procrustes(x, mirrored).rotation) == pytest.approx(1.0)
    assert isinstance(sim, Similarity)


@pytest.mark.parametrize(
    "src, dst, w, match",
    [
        (np.zeros((4, 3)), np.zeros((5, 3)), None, "does not match"),
        (np.ones((4, 3)), np.ones((4, 3)), None, "coincide"),
        (np.c_[np.arange(4.0), np.zeros(4), np.zeros(4)], np.zeros((4, 3)), None, "collinear"),
        (np.eye(3), np.eye(3), np.array([1.0, -1.0, 1.0]), "non-negative"),
        (np.eye(3), np.eye(3), np.zeros(3), "all zero"),
        (np.eye(3), np.eye(3), np.ones(2), "weights"),
        (np.zeros((4, 4)), np.zeros((4, 4)), None, r"\(n, 2\) or \(n, 3\)"),
        (np.array([[0.0, np.nan, 0.0], [1, 0, 0], [0, 1, 0]]), np.eye(3), None, "source: row 0"),
    ],
)
def test_procrustes_bad_input(src, dst, w, match):
    with pytest.raises(ValueError, match=match):
        similarity_procrustes(src, dst, weights=w)
