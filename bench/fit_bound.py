"""The least RMS skin error any fit can reach from a case (a Bayes bound).

    from bench.fit_bound import fit_bound_mm
    bound = fit_bound_mm(model, case, truth, noise_px=1.0)  # as fit_head sees the case

The synthetic heads are drawn from the model's prior (identity coefficients c ~ N(0, I))
and their landmarks and outlines are observed with Gaussian noise sigma. Linearised at the
true head, every observation is ``A_c c + A_n n + noise``: ``n`` the nuisances a fit must
estimate with the head (the head's pose and size; each camera's parameters unless the
view is calibrated, with the priors the fit puts on them). The posterior covariance of c,
the nuisances integrated out, is ``S = (I + A_c^T A_c / s^2 - H_cn H_nn^+ H_nc)^-1``
(``H`` the information matrix; the pseudo-inverse because some nuisances are a gauge, e.g.
the head's pose when every camera is free), and no estimator has a smaller expected
squared error than the posterior mean, whose error has covariance S. Spread over the skin
with the similarity the benchmarks align away removed, ``sqrt(trace(P B S B^T P) / N)``
is the RMS error to expect from the best possible use of the case (P: the projection that
removes a small similarity of the skin; B: the skin's basis, metres per coefficient).

Outline rows: each traced point (noise-free, as many as the case has) pulls the true head's
rim vertex nearest to it across the outline (``n . dP(x)``, n the outline's normal): to
first order a silhouette moves with the surface's normal motion at its rim; the rim's
sliding along the surface is second order.

A bound tells an estimator that wastes information (far above its bound) from a setup that
has too little (the bound itself above a target), and the ratio of two setups' bounds is
the ratio of their errors under equally efficient fits.
"""

import numpy as np
from scipy.spatial import cKDTree

from solver import OrthographicCamera, PinholeCamera
from solver.fitting.views import LENS_PRIOR_SIGMA
from solver.geometry import rotation_from_vector
from solver.synthetic import resample_polyline, vertex_normals

#: Step of the finite differences of the camera parameters (log-focal, radians, metres).
_EPS = 1e-6
#: A rim vertex stands for a traced point when it faces across the line of sight there
#: (|cos| below this) and projects within these pixels of the point across the outline.
_RIM_COS = 0.3
_RIM_ACROSS_PX = 1.5
_RIM_NEAR_PX = 8.0


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


def _landmark_vertices(model, view):
    return np.array([model.landmarks[n] for n in view.points], dtype=np.int64)


def _coefficient_rows(model, truth, camera, world, verts):
    """d pixel / d coefficient of ``verts`` seen by ``camera``: (n, 2, K)."""
    jac = np.asarray(camera.jacobian(world[verts]))  # (n, 2, 3)
    moved = truth.scale * model.identity.basis[:, verts, :] @ truth.rotation.T  # (K, n, 3)
    return np.einsum("nij,knj->nik", jac, moved)


def outline_rows(model, case, truth, name, normals=None):
    """The rim vertex each traced outline point of view ``name`` lies on, and the
    outline's unit normal there.

    Parameters
    ----------
    model : HeadModel
    case : LandmarkCase
        ``case.views[name].contour`` says how many points were traced.
    truth : SyntheticTruth
        ``truth.contour[name]``: the noise-free outline.
    name : str
    normals : ndarray, shape (V, 3), optional
        Vertex normals of the true posed head (computed when not given).

    Returns
    -------
    vertices : ndarray, shape (m,)
    image_normals : ndarray, shape (m, 2)
    points : ndarray, shape (m, 2), pixels
        The traced points they stand for: m <= the traced points, those with no rim vertex
        near them are left out (where the outline crosses the neck's cut, say).
    """
    view, cam = case.views[name], truth.cameras[name]
    world = truth.world_vertices
    if normals is None:
        normals = vertex_normals(model, world)
    pts = resample_polyline(truth.contour[name], len(view.contour))
    tangent = np.gradient(pts, axis=0)
    across = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)
    across /= np.maximum(np.linalg.norm(across, axis=1, keepdims=True), 1e-12)
    skin = np.asarray(model.skin, dtype=np.int64)
    toward = np.asarray(cam.toward_camera(world[skin]), dtype=np.float64)
    rim = skin[np.abs(np.einsum("ij,ij->i", normals[skin], toward)) < _RIM_COS]
    proj = cam.project(world[rim])
    near, j = cKDTree(proj).query(pts)
    off = np.abs(np.einsum("ij,ij->i", proj[j] - pts, across))
    ok = (near <= _RIM_NEAR_PX) & (off <= _RIM_ACROSS_PX)
    return rim[j[ok]], across[ok], pts[ok]


def _camera_variants(camera):
    """Copies of ``camera`` with each free parameter moved by _EPS: pinhole log-focal,
    rotation (3) and centre (3); orthographic log-scale, in-plane angle and offset (2; the
    fit keeps its viewing direction)."""
    if isinstance(camera, PinholeCamera):
        out = [camera.replaced(focal_px=camera.focal_px * np.exp(_EPS))]
        for k in range(3):
            out.append(camera.replaced(rotation=camera.rotation
                                       @ rotation_from_vector(_EPS * np.eye(3)[k]).T))
        for k in range(3):
            out.append(camera.replaced(centre=camera.centre + _EPS * np.eye(3)[k]))
        return out
    if isinstance(camera, OrthographicCamera):
        def moved(rotation=camera.rotation, scale=camera.scale, offset=camera.offset):
            return OrthographicCamera(rotation, scale, offset, camera.size, camera.view)
        spin = rotation_from_vector(_EPS * np.eye(3)[2]) @ camera.rotation
        return [moved(scale=camera.scale * np.exp(_EPS)), moved(rotation=spin),
                moved(offset=camera.offset + [_EPS, 0.0]),
                moved(offset=camera.offset + [0.0, _EPS])]
    raise ValueError(f"fit_bound: no bound for a {type(camera).__name__}")


def information(model, case, truth, noise_px=1.0, *, outlines=True, pose=True,
                cameras=True):
    """The case's information matrix about coefficients and nuisances, at the true head.

    Parameters
    ----------
    model, case, truth : see :func:`fit_bound_mm`
    noise_px : float
        Noise of every landmark coordinate and every traced point across the outline.
    outlines : bool
        Use the traced outlines (views whose ``contour`` is set).
    pose : bool
        The head's pose and size are unknown (7 flat nuisances).
    cameras : bool
        Uncalibrated cameras are unknown: their free parameters are nuisances, a pinhole's
        focal length with the fit's prior (LENS_PRIOR_SIGMA) when the view states its lens.

    Returns
    -------
    ndarray, shape (K + M, K + M)
        The first K rows and columns the identity coefficients (their prior included); then
        M nuisances.
    """
    if not noise_px > 0:
        raise ValueError(f"noise_px: must be > 0, got {noise_px!r}")
    k = model.identity.basis.shape[0]
    world = truth.world_vertices
    centre = world[model.skin].mean(axis=0)
    normals = vertex_normals(model, world)
    columns = k + (7 if pose else 0)
    layout, prior = {}, [np.ones(k), np.zeros(columns - k)]
    for name, view in case.views.items():
        variants = [] if (view.calibrated or not cameras) else \
            _camera_variants(truth.cameras[name])
        layout[name] = (columns, variants)
        columns += len(variants)
        p = np.zeros(len(variants))
        if variants and isinstance(truth.cameras[name], PinholeCamera) \
                and "lens_mm" in (view.camera_hints or {}):
            p[0] = 1.0 / LENS_PRIOR_SIGMA**2
        prior.append(p)
    rows = [np.zeros((0, columns))]
    for name, view in case.views.items():
        cam = truth.cameras[name]
        groups = [(_landmark_vertices(model, view), None)]
        if outlines and view.contour is not None:
            groups.append(outline_rows(model, case, truth, name, normals)[:2])
        start, variants = layout[name]
        for verts, across in groups:
            if len(verts) == 0:
                continue
            x = world[verts]
            a = np.zeros((len(verts), 2, columns))
            a[:, :, :k] = _coefficient_rows(model, truth, cam, world, verts)
            if pose:  # translation, rotation about the skin's centre, size
                jac = np.asarray(cam.jacobian(x))
                for i, e in enumerate(np.eye(3)):
                    a[:, :, k + i] = jac @ e
                    a[:, :, k + 3 + i] = np.einsum("nij,nj->ni", jac, np.cross(e, x - centre))
                a[:, :, k + 6] = np.einsum("nij,nj->ni", jac, x - centre)
            base = cam.project(x)
            for i, moved in enumerate(variants):
                a[:, :, start + i] = (moved.project(x) - base) / _EPS
            a = a.reshape(-1, columns) if across is None else \
                np.einsum("ni,nip->np", across, a)
            rows.append(a)
    rows = np.vstack(rows)
    return rows.T @ rows / noise_px**2 + np.diag(np.concatenate(prior))


def posterior_covariance(info, k):
    """Covariance of the first ``k`` parameters with the rest integrated out (flat or
    Gaussian priors already in ``info``; gauge directions of the rest have no effect)."""
    h_cc, h_cn, h_nn = info[:k, :k], info[:k, k:], info[k:, k:]
    if h_nn.size:
        d = 1.0 / np.sqrt(np.maximum(np.diag(h_nn), 1e-300))
        inv = d[:, None] * np.linalg.pinv(h_nn * d[:, None] * d[None, :], rcond=1e-10,
                                          hermitian=True) * d[None, :]
        h_cc = h_cc - h_cn @ inv @ h_cn.T
    return np.linalg.inv(h_cc)


def skin_error_mm(model, truth, cov):
    """Expected RMS skin error (mm), similarity removed, of coefficients whose error has
    covariance ``cov`` (K, K)."""
    basis = model.identity.basis
    k = basis.shape[0]
    skin = basis[:, model.skin, :].reshape(k, -1)  # (K, 3N) metres
    q = similarity_projector(truth.local_vertices[model.skin])
    skin = skin - (skin @ q) @ q.T
    mse = np.einsum("kj,kl,lj->", skin, cov, skin) / len(model.skin)
    return 1000.0 * float(np.sqrt(max(mse, 0.0)))


def fit_bound_mm(model, case, truth, noise_px=1.0, *, outlines=True, pose=True,
                 cameras=True):
    """Expected RMS skin error (mm) of the posterior mean given what the fit is given.

    Parameters
    ----------
    model : HeadModel
    case : LandmarkCase
        Its views' landmark names (``view.points``) say which landmarks each photo shows;
        ``view.contour`` whether (and with how many points) its outline was traced;
        ``view.calibrated`` whether its camera is known.
    truth : SyntheticTruth
        The true head (pose, coefficients), cameras (``truth.cameras[view name]``, pinhole
        or orthographic) and noise-free outlines (``truth.contour``).
    noise_px : float
        Landmark and outline noise, pixels (standard deviation per coordinate), > 0.
    outlines, pose, cameras : bool
        See :func:`information`; all True: as ``fit_head`` sees the case.

    Returns
    -------
    float, millimetres
    """
    k = model.identity.basis.shape[0]
    info = information(model, case, truth, noise_px, outlines=outlines, pose=pose,
                       cameras=cameras)
    return skin_error_mm(model, truth, posterior_covariance(info, k))

