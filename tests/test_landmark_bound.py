"""The benchmarks' landmark bound (bench/landmark_bound.py): it must be the error of the
best estimator, so it is checked against one: the exact posterior mean of the linearised
problem, on heads drawn from the prior."""

import numpy as np
import pytest

from bench.landmark_bound import landmark_bound_mm, landmark_rows, similarity_projector
from solver.landmarks_file import LandmarkCase, View
from solver.synthetic import make_case, make_perspective_case


def test_similarity_projector_spans_moves_and_scale():
    pts = np.random.default_rng(0).normal(size=(50, 3))
    q = similarity_projector(pts)
    assert q.shape == (150, 7)
    np.testing.assert_allclose(q.T @ q, np.eye(7), atol=1e-10)
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])  # about z
    moved = 0.01 * (pts - pts.mean(axis=0)) @ rot.T + 0.02 * pts + [0.1, -0.2, 0.3]
    d = moved.reshape(-1)
    assert np.linalg.norm(d - q @ (q.T @ d)) < 1e-10 * np.linalg.norm(d)


def test_bound_is_the_error_of_the_posterior_mean(model):
    """Draw heads from the prior, observe the landmarks through the linearised cameras
    with noise, take the exact posterior mean: its RMS skin error (similarity removed, as
    the bound does) matches the bound."""
    case, truth = make_perspective_case(model, 5, n_views=2, calibrated=True)
    noise = 1.0
    bound = landmark_bound_mm(model, case, truth, noise)
    basis = model.identity.basis
    k = basis.shape[0]
    rows = landmark_rows(model, case, truth)
    post = np.linalg.solve(np.eye(k) + rows.T @ rows / noise**2, rows.T / noise**2)
    skin = basis[:, model.skin, :].reshape(k, -1)
    q = similarity_projector(truth.local_vertices[model.skin])
    rng = np.random.default_rng(1)
    sq = []
    for _ in range(300):
        c = rng.normal(size=k)
        est = post @ (rows @ c + noise * rng.normal(size=len(rows)))
        d = (c - est) @ skin
        d = d - q @ (q.T @ d)
        sq.append(float(d @ d) / len(model.skin))
    assert bound == pytest.approx(1000.0 * np.sqrt(np.mean(sq)), rel=0.08)


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
