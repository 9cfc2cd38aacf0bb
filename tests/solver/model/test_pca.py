"""PCA with the small-matrix trick (solver/pca.py) and the linear model (solver/linear_model.py)."""

import numpy as np
import pytest

from solver.model.linear_model import LinearModel
from solver.model.pca import PCA, fit_pca


def _samples(m, d, rank=None, seed=0):
    rng = np.random.default_rng(seed)
    rank = min(m, d) if rank is None else rank
    z = rng.standard_normal((m, rank)) * np.geomspace(3.0, 0.3, rank)
    return z @ rng.standard_normal((rank, d)) + rng.standard_normal(d)


def _same_direction(a, b):
    """Rows of a and b equal up to the sign of each row."""
    s = np.sign((a * b).sum(axis=1))
    return np.abs(a - s[:, None] * b).max()


def test_pca_reconstructs_training_set():
    x = _samples(12, 300)  # D >> M: the small-matrix path
    pca = fit_pca(x)
    assert pca.components.shape == (11, 300)  # M - 1 directions after centring
    c = pca.project(x)
    np.testing.assert_allclose(pca.reconstruct(c), x, atol=1e-10)
    cs = pca.project(x, standardized=True)
    np.testing.assert_allclose(pca.reconstruct(cs, standardized=True), x, atol=1e-10)
    np.testing.assert_allclose(cs, c / pca.stddevs, atol=1e-12)
    # Orthonormal directions, variances in decreasing order.
    np.testing.assert_allclose(pca.components @ pca.components.T, np.eye(11), atol=1e-10)
    assert np.all(np.diff(pca.variances) <= 0)


def test_pca_matches_covariance_eigendecomposition():
    x = _samples(15, 200, seed=1)
    pca = fit_pca(x)
    evals, evecs = np.linalg.eigh(np.cov(x, rowvar=False))
    order = np.argsort(evals)[::-1][: len(pca.variances)]
    np.testing.assert_allclose(pca.variances, evals[order], rtol=1e-9)
    assert _same_direction(pca.components, evecs[:, order].T) < 1e-8
    np.testing.assert_allclose(pca.mean, x.mean(axis=0), atol=1e-14)


def test_small_matrix_path_equals_ordinary_path():
    # D < M takes the ordinary covariance path; padding the same data with zero columns
    # to D >= M takes the small-matrix (Gram) path. Both must give the same model.
    x = _samples(40, 25, seed=2)
    ordinary = fit_pca(x)
    padded = fit_pca(np.hstack([x, np.zeros((40, 30))]))
    assert padded.components.shape[0] == ordinary.components.shape[0] == 25
    np.testing.assert_allclose(padded.variances, ordinary.variances, rtol=1e-9)
    assert _same_direction(padded.components[:, :25], ordinary.components) < 1e-8
    assert np.abs(padded.components[:, 25:]).max() < 1e-12


def test_pca_rank_deficient_and_truncated():
    x = _samples(30, 100, rank=4, seed=3)
    pca = fit_pca(x)
    assert len(pca.variances) == 4  # negligible directions dropped
    np.testing.assert_allclose(pca.reconstruct(pca.project(x)), x, atol=1e-9)
    first = fit_pca(x, n_components=2)
    np.testing.assert_allclose(first.variances, pca.variances[:2])
    # Projection onto the first k components equals truncating the full projection.
    np.testing.assert_allclose(pca.project(x, n_components=2), pca.project(x)[:, :2],
                               atol=1e-12)



@pytest.mark.parametrize(
    "data, match",
    [
        (np.zeros((1, 5)), "M >= 2"),
        (np.zeros(5), "M >= 2"),
        (np.array([[0.0, 1.0], [np.nan, 2.0], [1.0, 1.0]]), "NaN"),
    ],
)
def test_pca_bad_input(data, match):
    with pytest.raises(ValueError, match=match):
        fit_pca(data)


def test_pca_bad_arguments():
    pca = fit_pca(_samples(6, 20))
    with pytest.raises(ValueError, match="last axis"):
        pca.project(np.zeros(19))
    with pytest.raises(ValueError, match="n_components"):
        pca.project(np.zeros(20), n_components=99)
    assert isinstance(pca, PCA)


# ------------------------------------------------------------------------ LinearModel


def _model(v=7, k=3, seed=0, gamma_rows=None):
    rng = np.random.default_rng(seed)
    g = None if gamma_rows is None else rng.standard_normal((gamma_rows, k))
    return LinearModel(rng.standard_normal((v, 3)), rng.standard_normal((k, v, 3)),
                       rng.uniform(0.5, 2, k), tuple(f"m{i}" for i in range(k)), g)


def test_linear_model_instance_take_first():
    m = _model(gamma_rows=4)
    c = np.array([0.5, -1.0, 2.0])
    x = m.instance(c)
    np.testing.assert_allclose(x, m.mean + sum(c[i] * m.basis[i] for i in range(3)))
    idx = np.array([5, 0, 3])
    np.testing.assert_allclose(m.take(idx).instance(c), x[idx])
    assert m.take(idx).gamma is m.gamma
    f = m.first(2)
    assert f.n_coeffs == 2 and f.names == ("m0", "m1") and f.gamma.shape == (4, 2)
    np.testing.assert_allclose(f.instance(c[:2]), m.instance(np.r_[c[:2], 0.0]))
    with pytest.raises(ValueError, match="coeffs"):
        m.instance(np.zeros(2))

