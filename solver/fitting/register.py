"""3-D to 3-D registration of a linear head model to a point cloud (thesis §4.3.3).

The ICP alternates closest-point correspondences (model vertex -> nearest cloud point,
KD-tree built once on the cloud, far pairs rejected) with a Gauss-Newton step of the
shape-ICP (eq. 39/43). It runs in stages, each starting where the last one stopped:

1. similarity only, on a subsample of vertices: like the thesis' profile fit (§4.4.1),
   the pose comes first, since letting the shape move while the pose is wrong makes the
   regions bend to make up for it;
2. similarity + shape on a subsample, first with an extra stiffness prior that is relaxed
   step by step (annealing), then without it, to convergence;
3. similarity + shape on all vertices, which only has to polish.

Two departures from the thesis make it fast and robust: the point-to-plane distance (plus
a little point-to-point) converges in a handful of steps where point-to-point crawls along
the surface, and the annealing keeps folds such as the under-chin from locking into wrong
correspondences. Cloud points on the cloud's boundary are not used as targets, so a
partial scan's edge does not drag the vertices beyond it.
"""

import time

import numpy as np
from scipy.spatial import cKDTree

from ..errors import as_points
from ..geometry import check_rotation
from .rows import ClosestPointRows
from .shape_icp import ShapeProblem


def initial_similarity(model_points, cloud):
    """A rough start: identity rotation, centroids matched, scale from RMS radii.

    Parameters
    ----------
    model_points : ndarray, shape (n, 3)
    cloud : ndarray, shape (m, 3)

    Returns
    -------
    scale : float
    rotation : ndarray, shape (3, 3)
    translation : ndarray, shape (3,)
    """
    mc = model_points.mean(axis=0)
    cc = cloud.mean(axis=0)
    rm = np.sqrt(((model_points - mc) ** 2).sum(axis=1).mean())
    rc = np.sqrt(((cloud - cc) ** 2).sum(axis=1).mean())
    if rm <= 0 or rc <= 0:
        raise ValueError("cloud: all points coincide; cannot estimate a scale")
    s = rc / rm
    return s, np.eye(3), cc - s * mc


def estimate_normals(points, k=16, tree=None, workers=1, with_boundary=False):
    """Unit normals of a point cloud from the local covariance of each point's neighbours.

    Parameters
    ----------
    points : array_like, shape (m, 3)
    k : int
        Neighbours per point (including itself).
    tree : scipy.spatial.cKDTree, optional
        A tree built on ``points``.
    workers : int
    with_boundary : bool
        Also return a boundary score per point.

    Returns
    -------
    normals : ndarray, shape (m, 3)
        The eigenvector of the smallest eigenvalue of each neighbourhood's covariance
        (sign arbitrary: the point-to-plane cost does not need it).
    boundary : ndarray, shape (m,), only with ``with_boundary``
        Distance, within the tangent plane, from the point to the centroid of its
        neighbours divided by their mean distance: about 0-0.4 inside a surface, above
        0.5 on its edge (the neighbours all lie on one side).
    """
    pts = as_points(points, "points", min_count=3)
    k = int(min(max(k, 3), len(pts)))
    tree = cKDTree(pts) if tree is None else tree
    dist, idx = tree.query(pts, k=k, workers=workers)
    nb = pts[idx]  # (m, k, 3)
    centroid = nb.mean(axis=1)
    nb -= centroid[:, None, :]
    normals = smallest_eigenvectors(np.matmul(nb.transpose(0, 2, 1), nb))
    if not with_boundary:
        return normals
    off = centroid - pts
    off -= np.einsum("ij,ij->i", off, normals)[:, None] * normals
    spread = dist[:, 1:].mean(axis=1)
    score = np.linalg.norm(off, axis=1) / np.where(spread > 0, spread, 1.0)
    return normals, score


def smallest_eigenvectors(cov):
    """Unit eigenvector of the smallest eigenvalue of many symmetric 3 x 3 matrices.

    Closed form (trigonometric eigenvalues, then the cross product of two rows of
    ``C - lambda_min I``), several times faster than a batched ``eigh``; the few
    near-degenerate matrices (two equal small eigenvalues) fall back to ``eigh``.

    Parameters
    ----------
    cov : ndarray, shape (m, 3, 3)

    Returns
    -------
    ndarray, shape (m, 3)
    """
    c = np.asarray(cov, dtype=np.float64)
    a, b_, cc = c[:, 0, 0], c[:, 1, 1], c[:, 2, 2]
    d, e, f = c[:, 0, 1], c[:, 0, 2], c[:, 1, 2]
    q = (a + b_ + cc) / 3.0
    a0, b0, c0 = a - q, b_ - q, cc - q
    p = np.sqrt((a0**2 + b0**2 + c0**2 + 2.0 * (d**2 + e**2 + f**2)) / 6.0)
    safe = np.where(p > 0, p, 1.0)
    det = a0 * (b0 * c0 - f * f) - d * (d * c0 - f * e) + e * (d * f - b0 * e)
    r = np.clip(det / (2.0 * safe**3), -1.0, 1.0)
    lam = q + 2.0 * p * np.cos(np.arccos(r) / 3.0 + 2.0 * np.pi / 3.0)
    # Rows of C - lambda I; the null vector is the largest cross product of two rows.
    r0 = np.stack([a - lam, d, e], axis=1)
    r1 = np.stack([d, b_ - lam, f], axis=1)
    r2 = np.stack([e, f, cc - lam], axis=1)
    crosses = np.stack([np.cross(r0, r1), np.cross(r0, r2), np.cross(r1, r2)], axis=1)
    size = np.einsum("mij,mij->mi", crosses, crosses)
    best = np.argmax(size, axis=1)
    rows = np.arange(len(c))
    out = crosses[rows, best]
    norm = np.sqrt(size[rows, best])
    bad = norm <= 1e-6 * np.maximum(a + b_ + cc, 1e-300) ** 2
    out[~bad] /= norm[~bad, None]
    if bad.any():
        out[bad] = np.linalg.eigh(c[bad])[1][:, :, 0]
    return out


def register(model, cloud, *, scale=None, rotation=None, translation=None, coeffs=None,
             max_distance=np.inf, reject_factor=3.0, keep_distance=0.01, boundary_ratio=0.5,
             symmetric=False, normals=None, point_to_plane=True, tangential=0.1,
             similarity_iterations=20, similarity_tolerance=1e-2, similarity_vertices=2000,
             anneal=(1e-3, 5e-4, 2.5e-4, 1.2e-4), anneal_iterations=2, coarse_iterations=10,
             coarse_vertices=2500, shape_iterations=20, tolerance=1e-3, lambda1=0.0,
             lambda2=0.0, prior="eigen", n_coeffs=None, weights=None, tree=None, workers=1):
    """Register a linear model to a point cloud: similarity first, then similarity + shape.

    Parameters
    ----------
    model : LinearModel
        E.g. ``head.identity.take(head.skin)`` or ``head.regional(10).take(head.skin)``.
    cloud : array_like, shape (m, 3), metres
        Target points (a scan or a sampled head); it may cover only part of the model.
    scale, rotation, translation : optional
        Start similarity (model -> cloud). When all are None: identity rotation, centroids
        matched and scale from the RMS radii (:func:`initial_similarity`); tested from
        10 degrees of rotation and +-10 % scale.
    coeffs : ndarray, shape (K,), optional
        Start coefficients (default zero).
    max_distance : float
        Correspondences farther than this (metres) are rejected (thesis' threshold).
    reject_factor : float or None
        Also reject correspondences farther than this many times the median distance...
    keep_distance : float
        ... unless closer than this (metres; default 1 cm, about one standard deviation of
        a region's shape, so true shape differences are not taken for outliers).
    boundary_ratio : float or None
        Cloud points whose boundary score (see :func:`estimate_normals`) exceeds this are
        not used as targets, so a partial scan's edge does not drag the vertices beyond it;
        None keeps every point.
    anneal : sequence of float
        Stiffness schedule (metres) of the shape stage: before the final iterations, run
        ``anneal_iterations`` steps with an extra prior ``sum(weights) * stiffness^2 |c|^2``
        for each value (a unit coefficient vector costs as much as a residual of
        ``stiffness`` at every vertex). Starting stiff and relaxing keeps the shape from
        bending into the first, still wrong, correspondences (e.g. under the chin). Empty:
        no annealing.
    anneal_iterations : int
        Gauss-Newton steps per stiffness value.
    coarse_iterations : int
        After annealing, most steps without stiffness on the subsample, to convergence.
    coarse_vertices : int
        Vertices used in the annealing and coarse steps (an even subsample; all if
        fewer): they bring the shape near for a fraction of the cost; the final
        ``shape_iterations`` on all vertices then only polish.
    symmetric : bool
        Also use cloud -> nearest vertex pairs (see ``ClosestPointRows``).
    normals : array_like, shape (m, 3), optional
        Cloud normals; estimated from the cloud (:func:`estimate_normals`) when
        ``point_to_plane`` and not given.
    point_to_plane : bool
        Use the point-to-plane cost plus ``tangential`` times point-to-point (converges in
        far fewer iterations than the thesis' point-to-point, which ``False`` selects).
    tangential : float
        Weight of the point-to-point term with ``point_to_plane``.
    similarity_iterations, shape_iterations : int
        Most Gauss-Newton steps of the similarity stage and of the final stage on all
        vertices (0 skips a stage; ``shape_iterations=0`` fits the similarity only).
    tolerance : float
        The shape stage stops when its error (eq. 46) changes by less than this fraction.
    similarity_tolerance : float
        The same for the similarity stage (looser: it only has to bring the pose near).
    similarity_vertices : int
        Vertices used in the similarity stage (an even subsample; all if fewer).
    lambda1, lambda2, prior, n_coeffs
        Passed to the shape stage (see ``ShapeProblem``).
    weights : array_like, shape (V,), optional
        Per-vertex weights (default 1).
    tree : scipy.spatial.cKDTree, optional
        A tree built on ``cloud``, to reuse it across calls.
    workers : int
        Threads for the KD-tree queries (-1: all cores).

    Returns
    -------
    ShapeFit
        Of the final stage on all vertices (``iterations`` counts its steps); ``info`` adds
        "similarity_stage" (its error history, iterations, converged), "coarse_iterations"
        (annealing and coarse steps), "inlier_fraction", "rms_distance" (metres, inliers to
        their nearest cloud point) and "seconds".

    Raises
    ------
    ValueError
        Bad cloud (shape, NaN, fewer than 4 points), bad start values, or a system the
        correspondences cannot determine.
    """
    t0 = time.perf_counter()
    pts = as_points(cloud, "cloud", min_count=4)
    if tree is None:
        tree = cKDTree(pts)
    elif tree.n != len(pts):
        raise ValueError(f"tree: built on {tree.n} points but the cloud has {len(pts)}")
    n = model.mean.shape[0]
    k = model.basis.shape[0]
    c0 = np.zeros(k) if coeffs is None else np.asarray(coeffs, dtype=np.float64)
    if c0.shape != (k,) or not np.isfinite(c0).all():
        raise ValueError(f"coeffs: expected {k} finite numbers, got shape {c0.shape}")
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=np.float64)
    if w.shape != (n,) or not np.isfinite(w).all() or (w < 0).any():
        raise ValueError(f"weights: expected {n} finite non-negative numbers, got {w.shape}")

    start = model.mean + np.tensordot(c0, model.basis, axes=1) if c0.any() else model.mean
    if scale is None and rotation is None and translation is None:
        s, rot, t = initial_similarity(start, pts)
    else:
        s = 1.0 if scale is None else float(scale)
        rot = np.eye(3) if rotation is None else check_rotation(rotation)
        t = np.zeros(3) if translation is None else np.asarray(translation, dtype=np.float64)
    exclude = None
    if (point_to_plane and normals is None) or boundary_ratio is not None:
        nrm, score = estimate_normals(pts, tree=tree, workers=workers, with_boundary=True)
        normals = nrm if normals is None else normals
        if boundary_ratio is not None:
            exclude = score > boundary_ratio
    common = dict(max_distance=max_distance, reject_factor=reject_factor,
                  keep_distance=keep_distance, symmetric=symmetric,
                  normals=normals if point_to_plane else None, tangential=tangential,
                  exclude=exclude,
                  tree=tree, workers=workers, name="cloud")

    sim_info = {"error_history": [], "iterations": 0, "converged": True}
    sim_tol = max(tolerance, similarity_tolerance)
    if similarity_iterations > 0:
        step = max(1, n // max(int(similarity_vertices), 1))
        sub = np.arange(0, n, step)
        # No symmetric pulls here: 11k cloud points folded onto a 2000-vertex subsample
        # would cost more than the whole stage and the pose does not need them.
        rows = ClosestPointRows(sub, pts, weights=w[sub], **{**common, "symmetric": False})
        fit = ShapeProblem(model, rows, freeze=("shape",)).solve(
            scale=s, rotation=rot, translation=t, coeffs=c0,
            max_iterations=similarity_iterations, tolerance=sim_tol)
        s, rot, t = fit.scale, fit.rotation, fit.translation
        sim_info = {"error_history": fit.error_history, "iterations": fit.iterations,
                    "converged": fit.converged}

    state = dict(scale=s, rotation=rot, translation=t, coeffs=c0)
    priors = dict(lambda1=lambda1, lambda2=lambda2, prior=prior, n_coeffs=n_coeffs)
    coarse_steps = 0
    if shape_iterations > 0:
        # The stiff stages only need to bring the shape near: a subsample does it for a
        # fraction of the cost of all vertices.
        step = max(1, n // max(int(coarse_vertices), 1))
        sub = np.arange(0, n, step)
        problem = ShapeProblem(model, ClosestPointRows(sub, pts, weights=w[sub], **common),
                               **priors)
        wtot = float(w[sub].sum())
        stages = [(st, anneal_iterations) for st in anneal] + [(0.0, coarse_iterations)]
        for stiff, iters in stages:
            if iters <= 0:
                continue
            problem.set_priors(anneal=np.sqrt(wtot) * float(stiff))
            f = problem.solve(**state, max_iterations=iters, tolerance=tolerance)
            state = dict(scale=f.scale, rotation=f.rotation, translation=f.translation,
                         coeffs=f.coeffs)
            coarse_steps += f.iterations

    rows = ClosestPointRows(np.arange(n), pts, weights=w, **common)
    problem = ShapeProblem(model, rows, freeze=("shape",) if shape_iterations == 0 else (),
                           **priors)
    fit = problem.solve(**state, max_iterations=shape_iterations, tolerance=tolerance)
    inl = rows.inliers
    fit.info.update({
        "similarity_stage": sim_info,
        "coarse_iterations": coarse_steps,
        "inlier_fraction": float(inl.mean()),
        "rms_distance": float(np.sqrt(np.mean(rows.distances[inl] ** 2))) if inl.any()
        else float("nan"),
        "seconds": time.perf_counter() - t0,
    })
    return fit
