"""Mesh and rotation math in one place, for the fit, the cameras, the synthetic cases and
the texture bake: vertex normals of a triangle mesh, cross-product matrices, rotations from
rotation vectors and between two directions, and the checks that a matrix is a rotation."""

import numpy as np


def vertex_normals(vertices, triangles):
    """Unit vertex normals of a triangle mesh: the sum of the normals of the triangles
    around each vertex, weighted by their areas (zero where no triangle touches it). The
    winding decides the side: counter-clockwise seen from outside, as ICT's, points out.

    Parameters
    ----------
    vertices : array_like, shape (V, 3)
    triangles : array_like of int, shape (T, 3)

    Returns
    -------
    ndarray, shape (V, 3)
    """
    v = np.asarray(vertices, dtype=np.float64)
    tri = np.asarray(triangles, dtype=np.intp).reshape(-1, 3)
    face = np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])
    # Every first corner in triangle order, then every second, then every third: the
    # same sums as adding the faces corner by corner, in one pass per coordinate.
    corner = tri.T.ravel()
    normal = np.stack([np.bincount(corner, np.tile(face[:, d], 3), minlength=len(v))
                       for d in range(3)], axis=1)
    return normal / np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)


def skew(v):
    """Cross-product matrices: (..., 3) -> (..., 3, 3) with ``skew(a) @ b == a x b``."""
    v = np.asarray(v, dtype=np.float64)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def rotation_from_vector(theta):
    """Rotation matrix of the rotation vector ``theta`` (axis * angle, radians), (3, 3):
    Rodrigues' formula, the exact form of the thesis' ``I + [theta]_x`` (eq. 14/25); below
    1e-8 radians its second-order series, exact to rounding at that size."""
    th = np.asarray(theta, dtype=np.float64).reshape(3)
    a = float(np.linalg.norm(th))
    k = skew(th)
    if a < 1e-8:
        return np.eye(3) + k + 0.5 * k @ k
    # Left to right, ((1 - cos a) / a^2 * k) @ k: another order changes the last bit.
    return np.eye(3) + np.sin(a) / a * k + (1.0 - np.cos(a)) / a**2 * k @ k


def rotation_between(a, b):
    """The smallest rotation taking unit vector ``a`` to unit vector ``b``, (3, 3); a half
    turn about an axis perpendicular to ``a`` when they are opposite."""
    axis = np.cross(a, b)
    s = np.linalg.norm(axis)
    c = float(np.clip(a @ b, -1.0, 1.0))
    if s < 1e-15:
        if c > 0:
            return np.eye(3)
        perp = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        return rotation_from_vector(np.pi * perp / np.linalg.norm(perp))
    return rotation_from_vector(axis / s * np.arctan2(s, c))


def orthonormalize(r):
    """Nearest proper rotation to a 3 x 3 matrix (polar decomposition by SVD)."""
    u, _, vt = np.linalg.svd(r)
    if np.linalg.det(u @ vt) < 0:
        u[:, -1] *= -1
    return u @ vt


def check_rotation(r, name="rotation"):
    """``r`` as the nearest proper rotation (float64 (3, 3)), or a ValueError naming
    ``name`` when it is not finite, not orthonormal to 1e-6 or a reflection (det < 0)."""
    r = np.asarray(r, dtype=np.float64)
    if r.shape != (3, 3) or not np.isfinite(r).all():
        raise ValueError(f"{name}: expected a finite (3, 3) matrix, got shape {r.shape}")
    if np.abs(r @ r.T - np.eye(3)).max() > 1e-6 or np.linalg.det(r) < 0:
        raise ValueError(f"{name}: not a proper rotation (R R^T != I or det < 0)")
    return orthonormalize(r)


def check_orthonormal(rot, name):
    """``rot`` as an exactly orthonormal float64 (3, 3), or a ValueError naming ``name``
    when it is not orthonormal to 1e-6. Unlike :func:`check_rotation` it keeps a matrix
    already orthonormal to 1e-13 bit for bit (a camera read back from JSON stays the one
    written) and snaps others by SVD keeping their determinant."""
    r = np.asarray(rot, dtype=np.float64)
    if r.shape != (3, 3) or not np.isfinite(r).all():
        raise ValueError(f"{name}: must be a finite 3x3 matrix, got shape {r.shape}")
    if not np.allclose(r @ r.T, np.eye(3), atol=1e-6):
        raise ValueError(f"{name}: not orthonormal (R R^T differs from I by "
                         f"{np.abs(r @ r.T - np.eye(3)).max():.3g})")
    if np.abs(r @ r.T - np.eye(3)).max() <= 1e-13:
        return r.copy()
    u, _, vt = np.linalg.svd(r)
    return u @ vt


def inside_polygon(points, polygon):
    """Which ``points`` (P, 2) lie inside the closed ``polygon`` (n, 2) (even-odd rule),
    (P,) bool."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)[:, None, :]
    a = np.asarray(polygon, dtype=np.float64)
    b = np.roll(a, -1, axis=0)
    crosses = (a[:, 1] > p[..., 1]) != (b[:, 1] > p[..., 1])
    dy = np.where(b[:, 1] != a[:, 1], b[:, 1] - a[:, 1], 1.0)
    xs = a[:, 0] + (p[..., 1] - a[:, 1]) * (b[:, 0] - a[:, 0]) / dy
    return (np.sum(crosses & (xs > p[..., 0]), axis=1) % 2).astype(bool)


def distance_to_segments(points, a, b):
    """Distance of each point (n, 2) to the nearest of the segments ``a``-``b`` (m, 2)
    each, (n,); infinite without segments."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(a) == 0:
        return np.full(len(p), np.inf)
    ab = b - a
    ll = np.maximum((ab * ab).sum(1), 1e-12)
    t = np.clip(((p[:, None, :] - a[None]) * ab[None]).sum(2) / ll[None], 0.0, 1.0)
    d = p[:, None, :] - (a[None] + t[..., None] * ab[None])
    return np.sqrt((d * d).sum(2)).min(axis=1)
