"""Triangulation: 3-D points from their pixels in two or more calibrated views.

Seed 000 eq. 16: with the DLT parameters b^j of camera j known, each observed (corrected)
pixel (x_j, y_j) of a point p = (X, Y, Z) gives two linear equations::

    (b1 - x b9) X + (b2 - x b10) Y + (b3 - x b11) Z = x - b4
    (b5 - y b9) X + (b6 - y b10) Y + (b7 - y b11) Z = y - b8

(eq. 9 read as equations in p). m >= 2 views give an overdetermined 2m x 3 system, solved
here for many points at once (batched QR, no normal equations). Each equation is the pixel
error times the denominator b9 X + b10 Y + b11 Z + 1, so views at different distances are
weighed differently; ``iterations`` re-solves with every row divided by that denominator at
the current estimate (the a_i of eq. 12b), after which the least squares weighs pixel
errors alike in every view. ``iterations=0`` is eq. 16 as printed.

Lens distortion is removed first (eq. 15, ``DLTCamera.undistort``; a pinhole camera's k1
by ``PinholeCamera.undistort``, its matrix K R [I | -C] is then exact). Orthographic
cameras (solver/cameras.py) are affine and fit the same equations with denominator 1.

Two residuals are reported per point: the reprojection residual in each view (pixels) and
the gap between the viewing rays (metres): the length of the common perpendicular of two
rays (seed 001 eq. 3.5-3.7), the largest over pairs of views.
"""

from dataclasses import dataclass

import numpy as np

from .dlt import DLTCamera
from .orthographic import OrthographicCamera
from .pinhole import PinholeCamera


@dataclass
class Triangulation:
    """Result of ``triangulate``.

    Attributes
    ----------
    points : ndarray, shape (n, 3), metres
        NaN for points seen in fewer than 2 views or whose rays are parallel.
    residuals : ndarray, shape (m, n, 2), pixels
        Observed minus reprojected pixel per view (NaN where not observed); observations
        with weight 0 get theirs too, so they can be judged against the others.
    rms : ndarray, shape (n,), pixels
        RMS of the reprojection residual lengths over the observations used (weight > 0).
    ray_distance : ndarray, shape (m, n), metres
        Distance from the triangulated point to each view's viewing ray (NaN where not
        observed).
    ray_gap : ndarray, shape (n,), metres
        Largest distance between two of the point's viewing rays used (length of their common
        perpendicular, seed 001 eq. 3.5-3.7); 0 when the rays meet.
    n_views : ndarray, shape (n,), int
        Views used for each point (observed, weight > 0).
    """

    points: np.ndarray
    residuals: np.ndarray
    rms: np.ndarray
    ray_distance: np.ndarray
    ray_gap: np.ndarray
    n_views: np.ndarray


def projection_matrix(camera):
    """The 3x4 matrix of a camera for eq. 16, in b-form (bottom-right entry 1) when the
    camera is a DLT camera whose world origin is off its principal plane.

    Parameters
    ----------
    camera : DLTCamera, PinholeCamera or OrthographicCamera
        A pinhole camera's matrix is K R [I | -C] without k1 (``triangulate`` removes k1
        from the pixels first).

    Returns
    -------
    ndarray, shape (3, 4)
    """
    if isinstance(camera, DLTCamera | PinholeCamera):
        p = camera.matrix
        if abs(p[2, 3]) > 1e-9:
            return p / p[2, 3]
        return p.copy()
    if isinstance(camera, OrthographicCamera):
        p = np.zeros((3, 4))
        p[:2, :3] = camera.scale * camera.rotation[:2]
        p[:2, 3] = camera.offset
        p[2, 3] = 1.0
        return p
    raise ValueError(f"cameras: triangulation needs DLT, pinhole or orthographic cameras, "
                     f"got {type(camera).__name__}")


def viewing_rays(camera, pixels):
    """Viewing rays of observed pixels: origins (n, 3) metres, unit directions (n, 3).

    Parameters
    ----------
    camera : DLTCamera, PinholeCamera or OrthographicCamera
    pixels : ndarray, shape (n, 2), pixels
    """
    q = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    if isinstance(camera, DLTCamera | PinholeCamera):
        return camera.back_project(q)
    if isinstance(camera, OrthographicCamera):
        r = camera.rotation
        origins = ((q - camera.offset) / camera.scale) @ r[:2]
        return origins, np.broadcast_to(r[2], origins.shape).copy()
    raise ValueError(f"cameras: need DLT, pinhole or orthographic cameras, got "
                     f"{type(camera).__name__}")


def ray_midpoint(origin1, direction1, origin2, direction2):
    """Closest points of two families of lines and the midpoint between them.

    Seed 001 eq. 3.1-3.7: with V1 = F1 + a1 u1, V2 = F2 + a2 u2 (u unit vectors; eq. 3.1
    prints V1 = F1 - a1 u1, but eq. 3.2-3.6 follow from the + sign), the squared distance H
    (eq. 3.2) is least for a1, a2 of eq. 3.5-3.6, and the point is the midpoint (eq. 3.7).

    Parameters
    ----------
    origin1, direction1, origin2, direction2 : array_like, shape (n, 3) or (3,)
        Ray origins (metres) and directions (need not be unit length).

    Returns
    -------
    midpoint : ndarray, shape (n, 3), metres
        (V1 + V2) / 2; NaN where the lines are parallel.
    gap : ndarray, shape (n,), metres
        |V1 - V2|, the length of the common perpendicular.
    a1, a2 : ndarray, shape (n,), metres
        Distances along the (normalised) directions from each origin to V1 and V2.
    """
    f1, u1, f2, u2 = np.broadcast_arrays(*(np.atleast_2d(np.asarray(a, dtype=np.float64))
                                           for a in (origin1, direction1, origin2, direction2)))
    u1 = u1 / np.linalg.norm(u1, axis=1, keepdims=True)
    u2 = u2 / np.linalg.norm(u2, axis=1, keepdims=True)
    d = f2 - f1
    c = (u1 * u2).sum(axis=1)
    e1 = (u1 * d).sum(axis=1)
    e2 = (u2 * d).sum(axis=1)
    den = 1.0 - c * c
    ok = den > 1e-14
    den = np.where(ok, den, np.nan)
    a1 = (e1 - e2 * c) / den  # eq. 3.5
    a2 = (e1 * c - e2) / den  # eq. 3.6
    v1 = f1 + a1[:, None] * u1
    v2 = f2 + a2[:, None] * u2
    gap = np.linalg.norm(v1 - v2, axis=1)
    # parallel lines: their distance is still defined
    par = np.linalg.norm(np.cross(d, u1), axis=1)
    gap = np.where(ok, gap, par)
    return 0.5 * (v1 + v2), gap, a1, a2  # eq. 3.7


def _line_distance(o1, u1, o2, u2):
    """Distance between lines (n, 3) given unit directions (parallel lines handled)."""
    return ray_midpoint(o1, u1, o2, u2)[1]


def triangulate(cameras, pixels, weights=None, iterations=2):
    """Triangulate points seen in two or more calibrated views (seed 000 eq. 16).

    Parameters
    ----------
    cameras : sequence of DLTCamera, PinholeCamera or OrthographicCamera, length m
    pixels : array_like, shape (m, n, 2), pixels
        Observed pixel of point i in view j; NaN rows where a view does not see a point.
    weights : array_like, shape (m,) or (m, n), optional
        Non-negative weight per view or per observation (each pair of equations is
        multiplied by its square root).
    iterations : int
        Re-solves with rows divided by their denominators (see the module docstring);
        0 gives eq. 16 exactly.

    Returns
    -------
    Triangulation

    Raises
    ------
    ValueError
        Fewer than two cameras or a pixel array that does not match them.
    """
    cams = list(cameras)
    m = len(cams)
    if m < 2:
        raise ValueError(f"cameras: triangulation needs at least 2 views, got {m}")
    q = np.asarray(pixels, dtype=np.float64)
    if q.ndim != 3 or q.shape[0] != m or q.shape[2] != 2:
        raise ValueError(f"pixels: expected shape ({m}, n, 2), got {q.shape}")
    n = q.shape[1]
    seen = np.isfinite(q).all(axis=2)  # (m, n)
    if weights is None:
        w = np.ones((m, n))
    else:
        w = np.asarray(weights, dtype=np.float64)
        if w.shape == (m,):
            w = np.repeat(w[:, None], n, axis=1)
        elif w.shape != (m, n):
            raise ValueError(f"weights: expected shape ({m},) or ({m}, {n}), got {w.shape}")
        if not np.isfinite(w).all() or (w < 0).any():
            raise ValueError("weights: must be finite and non-negative")
    w = np.where(seen, w, 0.0)
    used = seen & (w > 0)

    mats = np.stack([projection_matrix(c) for c in cams])  # (m, 3, 4)
    # corrected pixels (eq. 15), zeros where missing (their rows get weight 0)
    qc = np.where(seen[:, :, None], q, 0.0)
    for j, c in enumerate(cams):
        if (isinstance(c, DLTCamera) and c.has_distortion) or \
                (isinstance(c, PinholeCamera) and c.k1 != 0.0):
            qc[j] = c.undistort(qc[j])
    # rows: (P0[:3] - x P2[:3]) X = x P2[3] - P0[3], and the same with P1, y
    a = mats[:, None, :2, :3] - qc[:, :, :, None] * mats[:, None, 2:3, :3]  # (m, n, 2, 3)
    b = qc * mats[:, None, 2, 3, None] - mats[:, None, :2, 3]  # (m, n, 2)
    a = np.moveaxis(a, 1, 0).reshape(n, 2 * m, 3)
    b = np.moveaxis(b, 1, 0).reshape(n, 2 * m)
    sw = np.repeat(np.sqrt(w).T, 2, axis=1)  # (n, 2m)
    n_views = used.sum(axis=0)

    x = _solve_batched(a, b, sw)
    for _ in range(max(0, int(iterations))):
        den = np.einsum("mk,nk->nm", mats[:, 2, :3], np.nan_to_num(x)) + mats[:, 2, 3]
        den = np.where(np.abs(den) > 1e-12, den, 1.0)
        x = _solve_batched(a, b, sw / np.repeat(np.abs(den), 2, axis=1))
    x[n_views < 2] = np.nan
    good = np.isfinite(x).all(axis=1)

    # residuals
    res = np.full((m, n, 2), np.nan)
    dist = np.full((m, n), np.nan)
    rays = []
    for j, c in enumerate(cams):
        sel = seen[j] & good
        o = np.full((n, 3), np.nan)
        u = np.full((n, 3), np.nan)
        if sel.any():
            res[j, sel] = q[j, sel] - c.project(x[sel])
            o[sel], u[sel] = viewing_rays(c, q[j, sel])
            rel = x[sel] - o[sel]
            dist[j, sel] = np.linalg.norm(rel - (rel * u[sel]).sum(axis=1)[:, None] * u[sel],
                                          axis=1)
        rays.append((o, u))
    gap = np.zeros(n)
    for j in range(m):
        for k in range(j + 1, m):
            both = used[j] & used[k] & good
            if both.any():
                g = _line_distance(rays[j][0][both], rays[j][1][both],
                                   rays[k][0][both], rays[k][1][both])
                gap[both] = np.maximum(gap[both], g)
    gap[~good] = np.nan
    sq = np.where(used, np.nan_to_num((res**2).sum(axis=2)), 0.0).sum(axis=0)
    cnt = np.where(good, used.sum(axis=0), 0)
    rms = np.full(n, np.nan)
    rms[cnt > 0] = np.sqrt(sq[cnt > 0] / cnt[cnt > 0])
    return Triangulation(x, res, rms, dist, gap, n_views)


def _solve_batched(a, b, sw):
    """Least squares of n small systems (n, r, 3) x = (n, r) by batched QR; NaN where the
    system is rank deficient."""
    aw = a * sw[:, :, None]
    bw = b * sw
    qm, rm = np.linalg.qr(aw)  # (n, r, 3), (n, 3, 3)
    y = np.einsum("nri,nr->ni", qm, bw)
    diag = np.abs(np.diagonal(rm, axis1=1, axis2=2))
    scale = diag.max(axis=1) if len(diag) else np.zeros(0)
    ok = diag.min(axis=1, initial=np.inf) > 1e-12 * np.where(scale > 0, scale, 1.0)
    out = np.full((len(a), 3), np.nan)
    if ok.any():
        out[ok] = np.linalg.solve(rm[ok], y[ok][:, :, None])[:, :, 0]
    return out
