"""Thin-plate splines in 3-D (thesis §2.2, Bookstein 1989) with the kernel U(r) = |r|.

A spline maps every point x to ``f(x) = A^T [1, x] + sum_i w_i U(|x - c_i|)`` and is fitted
so that the control points c_i land on their targets while bending as little as possible.
The fit uses it for approach 2 (§4.4.3: pull the profile-fitted head onto the front
landmarks) and to add the detail that makes landmarks hit exactly.

In 3-D, ``-|r|`` (not ``|r|``) is the conditionally positive definite kernel, so smoothing
subtracts the regulariser: ``(K - lambda I) W + P A = Y``. With ``K + lambda I`` the system
would turn singular at some lambda; with the minus it stays regular for every lambda >= 0.
"""

import numpy as np
from scipy.spatial.distance import cdist

from ..errors import as_points

# apply() evaluates at most this many point-centre distances at once (8 bytes each).
_CHUNK_ELEMENTS = 2_000_000


class ThinPlateSpline:
    """A fitted 3-D thin-plate spline. Build with :meth:`fit`.

    Attributes
    ----------
    centers : ndarray, shape (n, 3)
        Control points, in the normalised frame (see ``origin``/``unit``).
    weights : ndarray, shape (n, 3)
        Kernel weights W.
    affine : ndarray, shape (4, 3)
        Affine part A acting on ``[1, x, y, z]`` (normalised frame).
    origin : ndarray, shape (3,), and unit : float
        Inputs are normalised as ``(x - origin) / unit`` (centroid and RMS radius of the
        control points) so the linear system is well scaled whatever the units.
    regularization : float
        The lambda the spline was fitted with, in the unit of the points.
    """

    def __init__(self, centers, weights, affine, origin, unit, regularization=0.0):
        self.centers = centers
        self.weights = weights
        self.affine = affine
        self.origin = origin
        self.unit = float(unit)
        self.regularization = float(regularization)

    @classmethod
    def fit(cls, source, target, regularization=0.0):
        """Fit the spline that maps ``source`` onto ``target``.

        Parameters
        ----------
        source : array_like, shape (n, 3), n >= 4
            Control points (e.g. model vertices), metres. Must not all lie in one plane.
        target : array_like, shape (n, 3)
            Where each control point goes, metres.
        regularization : float
            Smoothing lambda >= 0, in the points' unit (metres): 0 interpolates exactly;
            larger values trade hitting the targets for less bending, and a very large value
            gives the least-squares affine map.

        Returns
        -------
        ThinPlateSpline

        Raises
        ------
        ValueError
            Shape mismatch, NaN/inf, fewer than 4 points, coplanar control points, repeated
            control points (without regularization), or a negative/NaN lambda.
        """
        src = as_points(source, "source", min_count=4)
        dst = as_points(target, "target")
        if dst.shape != src.shape:
            raise ValueError(f"target: shape {dst.shape} does not match source {src.shape}")
        lam = float(regularization)
        if not np.isfinite(lam) or lam < 0:
            raise ValueError(f"regularization: must be finite and >= 0, got {regularization!r}")
        n = len(src)
        origin = src.mean(axis=0)
        centred = src - origin
        unit = float(np.sqrt((centred**2).sum(axis=1).mean()))
        if unit == 0.0:
            raise ValueError("source: all control points coincide")
        x = centred / unit
        sv = np.linalg.svd(x, compute_uv=False)
        if sv[2] < 1e-9 * sv[0]:
            raise ValueError("source: control points are coplanar (or collinear); a 3-D "
                             "thin-plate spline needs points spanning 3-D")
        k = cdist(x, x)
        if lam == 0.0:
            off = k + np.diag(np.full(n, np.inf))
            i, j = np.unravel_index(np.argmin(off), off.shape)
            if off[i, j] < 1e-12:
                raise ValueError(f"source: control points {min(i, j)} and {max(i, j)} coincide "
                                 "(use regularization > 0 to average them)")
        p = np.hstack([np.ones((n, 1)), x])
        a = np.zeros((n + 4, n + 4))
        a[:n, :n] = k - (lam / unit) * np.eye(n)
        a[:n, n:] = p
        a[n:, :n] = p.T
        rhs = np.zeros((n + 4, 3))
        rhs[:n] = dst
        try:
            sol = np.linalg.solve(a, rhs)
        except np.linalg.LinAlgError:
            raise ValueError("source: the spline system is singular (degenerate control "
                             "points)") from None
        if not np.isfinite(sol).all():
            raise ValueError("source: the spline system is singular (degenerate control points)")
        return cls(x, sol[:n], sol[n:], origin, unit, lam)

    def apply(self, points, chunk=None):
        """Evaluate the spline at points.

        Parameters
        ----------
        points : array_like, shape (m, 3), metres
        chunk : int, optional
            Points per block (default: keeps each distance block near 16 MB), so 26k
            vertices against hundreds of centres never allocate an m x n matrix at once.

        Returns
        -------
        ndarray, shape (m, 3), metres
        """
        x = (as_points(points, "points", min_count=0) - self.origin) / self.unit
        m, n = len(x), len(self.centers)
        if chunk is None:
            chunk = max(1, _CHUNK_ELEMENTS // max(n, 1))
        out = x @ self.affine[1:] + self.affine[0]
        for a in range(0, m, chunk):
            b = min(m, a + chunk)
            out[a:b] += cdist(x[a:b], self.centers) @ self.weights
        return out

    def bending_energy(self):
        """Bending energy ``-trace(W^T K W)`` (>= 0; 0 for an affine map), normalised frame."""
        k = cdist(self.centers, self.centers)
        return float(-np.einsum("ij,ik,kj->", self.weights, k, self.weights))

