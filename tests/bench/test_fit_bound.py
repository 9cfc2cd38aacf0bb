"""The benchmarks' bound (bench/fit_bound.py): it must be the error of the best
estimator, so it is checked against one (the exact posterior mean of the linearised
problem, on heads drawn from the prior, with nuisances it must estimate too), and its
outline rows against silhouettes traced anew from a changed head."""

import numpy as np
import pytest

from bench.fit_bound import (
    fit_bound_mm,
    information,
    outline_rows,
    posterior_covariance,
    similarity_projector,
    skin_error_mm,
)
from solver import LandmarkCase, View
from solver.synthetic import make_case, make_perspective_case, trace_silhouette


def test_similarity_projector_spans_moves_and_scale():
    pts = np.random.default_rng(0).normal(size=(50, 3))
    q = similarity_projector(pts)
    assert q.shape == (150, 7)
    np.testing.assert_allclose(q.T @ q, np.eye(7), atol=1e-10)
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])  # about z
    moved = 0.01 * (pts - pts.mean(axis=0)) @ rot.T + 0.02 * pts + [0.1, -0.2, 0.3]
    d = moved.reshape(-1)
    assert np.linalg.norm(d - q @ (q.T @ d)) < 1e-10 * np.linalg.norm(d)


def _monte_carlo_error_mm(model, truth, rows, prior, k, noise, draws=300):
    """RMS skin error (similarity removed) of the exact posterior mean: coefficients
    drawn from N(0, I), nuisances from their priors, or far from zero where flat."""
    skin = model.identity.basis[:, model.skin, :].reshape(k, -1)
    q = similarity_projector(truth.local_vertices[model.skin])
    h = rows.T @ rows / noise**2 + np.diag(prior)
    rng = np.random.default_rng(1)
    sq = []
    for _ in range(draws):
        spread = np.where(prior > 0, 1.0 / np.sqrt(np.maximum(prior, 1e-300)), 50.0)
        theta = spread * rng.normal(size=len(prior))
        y = rows @ theta + noise * rng.normal(size=len(rows))
        est = np.linalg.lstsq(h, rows.T @ y / noise**2, rcond=None)[0]
        d = (theta[:k] - est[:k]) @ skin
        d = d - q @ (q.T @ d)
        sq.append(float(d @ d) / len(model.skin))
    return 1000.0 * np.sqrt(np.mean(sq))


def _data_rows(info, prior):
    """Rows whose Gram matrix is the data part of an information matrix."""
    w, v = np.linalg.eigh(info - np.diag(prior))
    return (v * np.sqrt(np.clip(w, 0.0, None))).T


def test_landmark_bound_is_the_error_of_the_posterior_mean(model):
    """Pose and cameras known: only the coefficients' prior."""
    case, truth = make_perspective_case(model, 5, n_views=2, calibrated=True)
    k = model.identity.basis.shape[0]
    info = information(model, case, truth, 1.0, outlines=False, pose=False, cameras=False)
    assert info.shape == (k, k)
    bound = fit_bound_mm(model, case, truth, outlines=False, pose=False, cameras=False)
    rows = _data_rows(info, np.ones(k))
    assert bound == pytest.approx(
        _monte_carlo_error_mm(model, truth, rows, np.ones(k), k, 1.0), rel=0.03)


def test_bound_with_nuisances_is_the_error_of_the_posterior_mean(model):
    """Free pose and a free pinhole camera (flat but for the focal prior): the Schur
    complement the bound uses equals the error of estimating everything jointly."""
    case, truth = make_perspective_case(model, 7, n_views=2, calibrated=False)
    k = model.identity.basis.shape[0]
    info = information(model, case, truth, 1.0, outlines=False, pose=False)
    assert info.shape[0] == k + 14  # two cameras of 7 parameters
    prior = np.diag(info).copy()
    prior[:k] = 1.0
    prior[k:] = 0.0
    prior[k], prior[k + 7] = 1 / 0.05**2, 1 / 0.05**2  # the stated lenses' priors
    rows = _data_rows(info, prior)
    bound = skin_error_mm(model, truth, posterior_covariance(info, k))
    assert bound == pytest.approx(fit_bound_mm(model, case, truth, outlines=False, pose=False))
    # the nuisances' draws are bounded by their priors only where they have one
    assert bound == pytest.approx(
        _monte_carlo_error_mm(model, truth, rows, prior, k, 1.0), rel=0.03)


def test_outline_rows_predict_the_traced_silhouette(model):
    """Change the head a little, trace its outline anew: each traced point moves across
    the outline by what its row predicts (to within the raster's half pixel)."""
    case, truth = make_perspective_case(model, 3, n_views=2, calibrated=True, contour=True)
    name = "photo1"
    cam = truth.cameras[name]
    verts, across, pts = outline_rows(model, case, truth, name)
    assert len(verts) > 0.8 * len(case.views[name].contour)
    k = model.identity.basis.shape[0]
    rng = np.random.default_rng(2)
    step = 0.4 * rng.normal(size=k)
    moved_local = truth.local_vertices + np.einsum("k,kvj->vj", step, model.identity.basis)
    world0 = truth.world_vertices
    world1 = truth.scale * moved_local @ truth.rotation.T + truth.translation
    predicted = np.einsum("ni,ni->n", across, cam.project(world1[verts])
                          - cam.project(world0[verts]))
    # where the new outline crosses the traced points' normals
    measured = _crossing(pts, across, trace_silhouette(model, world1, cam))
    ok = np.isfinite(measured)
    assert ok.mean() > 0.9
    assert np.std(predicted) > 2.0  # a change the raster can see
    err = measured[ok] - predicted[ok]
    assert np.sqrt(np.mean(err**2)) < 0.25 * np.std(predicted[ok])


def _crossing(points, normals, line, reach=15.0):
    """Signed distance along each normal from each point to the polyline ``line``
    (nan where the normal line does not cross it within ``reach`` pixels)."""
    a, b = line[:-1], line[1:]
    out = np.full(len(points), np.nan)
    for i, (p, n) in enumerate(zip(points, normals, strict=True)):
        # solve p + s n = a + t (b - a), 0 <= t <= 1
        d = b - a
        den = n[0] * d[:, 1] - n[1] * d[:, 0]
        good = np.abs(den) > 1e-12
        r = a - p
        s = np.where(good, (r[:, 0] * d[:, 1] - r[:, 1] * d[:, 0]) / np.where(good, den, 1), np.inf)
        t = np.where(good, (r[:, 0] * n[1] - r[:, 1] * n[0]) / np.where(good, den, 1), -1)
        hit = good & (t >= 0) & (t <= 1) & (np.abs(s) <= reach)
        if hit.any():
            out[i] = s[hit][np.argmin(np.abs(s[hit]))]
    return out


def test_bound_orders_what_the_fit_is_given(model):
    case, truth = make_perspective_case(model, 4, n_views=2, calibrated=False, contour=True)
    full = fit_bound_mm(model, case, truth)
    assert full < fit_bound_mm(model, case, truth, outlines=False)  # outlines inform
    assert full > fit_bound_mm(model, case, truth, cameras=False)  # free cameras cost
    # with every camera free the head's pose is a gauge: knowing it changes nothing
    assert fit_bound_mm(model, case, truth, pose=False) == pytest.approx(full, rel=1e-6)
    known = fit_bound_mm(model, case, truth, cameras=False)
    assert fit_bound_mm(model, case, truth, cameras=False, pose=False) < known
    # the orthographic pair: its cameras' scale, spin and framing are free
    ocase, otruth = make_case(model, 4, noise_px=1.0)
    assert fit_bound_mm(model, ocase, otruth) > fit_bound_mm(model, ocase, otruth,
                                                             cameras=False)


def landmark_bound_mm(model, case, truth, noise_px):
    return fit_bound_mm(model, case, truth, noise_px, outlines=False, pose=False,
                        cameras=False)


def test_bound_falls_with_more_landmarks_and_less_noise(model):
    case, truth = make_case(model, 3, noise_px=1.0)
    both = landmark_bound_mm(model, case, truth, 1.0)
    front = LandmarkCase({"front": case.views["front"]}, "<front only>")
    assert landmark_bound_mm(model, front, truth, 1.0) > both
    assert landmark_bound_mm(model, case, truth, 0.5) < both
    # no landmarks at all: the prior's own spread over the skin, the mean head's error
    empty = LandmarkCase({"front": View("front", None, (768, 1024), None, {}, None)},
                         "<none>")
    assert 3.0 < landmark_bound_mm(model, empty, truth, 1.0) < 8.0
    with pytest.raises(ValueError, match="noise_px"):
        landmark_bound_mm(model, case, truth, 0.0)
