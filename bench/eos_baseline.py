"""An eos-style landmark fit, the open baseline the issue on real faces compares against.

    from bench.eos_baseline import eos_heads
    heads = eos_heads(model, case)       # {lambda: local vertices (V, 3)}, one photo's fit

eos (Huber et al. 2016, `fit_shape_and_pose` without its contour and expression steps:
"front landmarks only, identity only, its best lambda of 1-100", as the issue measured it)
fits one photo: a scaled orthographic camera estimated from the model's landmark vertices
and the photo's landmarks (the affine camera by least squares, its 2 x 3 part made the
nearest scaled pair of orthonormal rows), then the identity coefficients by regularised
linear least squares, ``(A^T A / s^2 + lambda I) c = A^T b / s^2`` with eos' detector
standard deviation s = sqrt(3) px, the two steps repeated. It uses the landmarks eos maps
without its contour step: every one but the jaw's outline (iBUG 1-8 and 10-17).
"""

import numpy as np

from solver.io.landmark_set import load_landmark_set

#: eos' default landmark standard deviation, pixels (its ``detector_standard_deviation``).
DETECTOR_SIGMA_PX = np.sqrt(3.0)
#: The regularisation weights tried; a case reports its best (the issue: "its best lambda
#: of 1-100").
LAMBDAS = (1.0, 3.0, 10.0, 30.0, 100.0)
#: Camera and shape steps alternated.
ITERATIONS = 10
#: iBUG numbers eos fits only through its contour step (the jaw's outline).
CONTOUR_IBUG = tuple(range(1, 9)) + tuple(range(10, 18))


def eos_view(case):
    """The photo an eos fit takes: the view named "front", else the one with most
    landmarks (the first of a tie)."""
    if "front" in case.views:
        return "front"
    return max(case.views, key=lambda name: len(case.views[name].points))


def view_landmarks(model, view):
    """(pixels (n, 2), model vertices (n,)) of a view's landmarks that eos fits."""
    lms = model.landmark_set
    contour = {load_landmark_set().ibug[i] for i in CONTOUR_IBUG}
    px, verts = [], []
    for key, p in view.points.items():
        name = lms.canonical(key)
        if name is None or name in contour or name not in lms.vertices:
            continue
        px.append(p)
        verts.append(lms.vertices[name])
    return np.asarray(px, dtype=np.float64).reshape(-1, 2), np.asarray(verts, dtype=np.intp)


def scaled_orthographic(points, pixels):
    """(scale s, rotation rows R (2, 3), translation t (2,)) with ``pixels ~ s R points +
    t``: the affine camera by least squares, its 2 x 3 part replaced by the nearest scaled
    pair of orthonormal rows (points (n, 3), pixels (n, 2), n >= 4)."""
    x = np.hstack([points, np.ones((len(points), 1))])
    affine = np.linalg.lstsq(x, pixels, rcond=None)[0].T  # (2, 4)
    u, sv, vt = np.linalg.svd(affine[:, :3], full_matrices=False)
    rows = u @ vt
    scale = float(sv.mean())
    t = pixels.mean(axis=0) - scale * rows @ points.mean(axis=0)
    return scale, rows, t


def eos_fit(model, pixels, vertices, lam, iterations=ITERATIONS, n_coeffs=None):
    """Identity coefficients (K,) of an eos fit of ``pixels`` (n, 2) at the model's
    ``vertices`` (n,) with regularisation ``lam``."""
    basis = model.identity.basis[:n_coeffs, vertices]  # (K, n, 3)
    mean = model.vertices[vertices]
    c = np.zeros(len(basis))
    w, prior = 1.0 / DETECTOR_SIGMA_PX ** 2, lam * np.eye(len(basis))
    for _ in range(iterations):
        scale, rows, t = scaled_orthographic(mean + np.tensordot(c, basis, axes=1), pixels)
        a = scale * np.einsum("ij,knj->nik", rows, basis).reshape(-1, len(basis))
        b = (pixels - t - scale * mean @ rows.T).reshape(-1)
        c = np.linalg.solve(w * a.T @ a + prior, w * a.T @ b)
    return c


def eos_heads(model, case, lambdas=LAMBDAS):
    """{lambda: local vertices (V, 3)} of eos fits of the case's :func:`eos_view`; empty
    when that photo has fewer than 4 landmarks eos fits."""
    pixels, vertices = view_landmarks(model, case.views[eos_view(case)])
    if len(vertices) < 4:
        return {}
    return {lam: model.vertices + np.tensordot(eos_fit(model, pixels, vertices, lam),
                                               model.identity.basis, axes=1)
            for lam in lambdas}
