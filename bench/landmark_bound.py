"""The least RMS skin error any fit can reach from a case's landmarks (a Bayes bound).

    from bench.landmark_bound import landmark_bound_mm
    bound = landmark_bound_mm(model, case, truth, noise_px=1.0)

The synthetic heads are drawn from the model's prior (identity coefficients c ~ N(0, I))
and their landmarks are projected with Gaussian noise sigma. Linearised at the true head,
each landmark pixel is ``J_i c + noise``; the posterior covariance of c is then
``S = (I + J^T J / sigma^2)^-1``, and no estimator has a smaller expected squared error
than the posterior mean, whose error has covariance S. Spread over the skin and with the
similarity the benchmarks align away removed, ``sqrt(trace(P B S B^T P) / N)`` is the RMS
error to expect from the best possible use of those landmarks (P: the projection that
removes a small similarity of the skin; B: the skin's basis, metres per coefficient).

The bound knows the head's pose and every camera, which a fit must estimate, so a fit can
only be worse. It leaves out outlines, whose information depends on how a user traces
them. It tells an estimator that wastes information (far above the bound) from a setup
that has too little (the bound itself above a target).
"""

import numpy as np


def similarity_projector(points):
    """Orthonormal basis Q (3N, 7) of the displacements of ``points`` (N, 3) by a small
    similarity: three translations, three rotations about the centroid, one scale."""
    x = np.asarray(points, dtype=np.float64)
    x = x - x.mean(axis=0)
    n = len(x)
    gens = []
    for k in range(3):
        t = np.zeros((n, 3))
        t[:, k] = 1.0
        gens.append(t)
        axis = np.zeros(3)
        axis[k] = 1.0
        gens.append(np.cross(axis, x))
    gens.append(x)
    q, _ = np.linalg.qr(np.stack([g.reshape(-1) for g in gens], axis=1))
    return q


def landmark_rows(model, case, truth):
    """The landmark pixels' linear dependence on the identity coefficients at the true
    head and cameras: (2L, K) pixels per unit coefficient, L the landmarks of all views."""
    basis = model.identity.basis  # (K, V, 3)
    k = basis.shape[0]
    world = truth.scale * truth.local_vertices @ truth.rotation.T + truth.translation
    blocks = [np.zeros((0, k))]
    for name, view in case.views.items():
        verts = np.array([model.landmarks[n] for n in view.points], dtype=np.int64)
        if len(verts) == 0:
            continue
        jac = np.asarray(truth.cameras[name].jacobian(world[verts]))  # (n, 2, 3)
        moved = truth.scale * basis[:, verts, :] @ truth.rotation.T  # (K, n, 3)
        blocks.append(np.einsum("nij,knj->nik", jac, moved).reshape(-1, k))
    return np.vstack(blocks)


def landmark_bound_mm(model, case, truth, noise_px=1.0):
    """Expected RMS skin error (mm) of the posterior mean given the case's landmarks.

    Parameters
    ----------
    model : HeadModel
    case : LandmarkCase
        Its views' landmark names (``view.points``) say which landmarks each photo shows.
    truth : SyntheticTruth
        The true head (pose, coefficients) and cameras (``truth.cameras[view name]``).
    noise_px : float
        Landmark noise, pixels (standard deviation per coordinate), > 0.

    Returns
    -------
    float, millimetres
    """
    if not noise_px > 0:
        raise ValueError(f"noise_px: must be > 0, got {noise_px!r}")
    basis = model.identity.basis  # (K, V, 3)
    k = basis.shape[0]
    rows = landmark_rows(model, case, truth)
    cov = np.linalg.inv(np.eye(k) + rows.T @ rows / noise_px**2)
    # the benchmarks compare heads in the model's frame and size (truth.local_vertices)
    skin = basis[:, model.skin, :].reshape(k, -1)  # (K, 3N) metres
    q = similarity_projector(truth.local_vertices[model.skin])
    skin = skin - (skin @ q) @ q.T
    mse = np.einsum("kj,kl,lj->", skin, cov, skin) / len(model.skin)
    return 1000.0 * float(np.sqrt(max(mse, 0.0)))
