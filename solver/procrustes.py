"""Similarity Procrustes (Umeyama 1991), weighted, in 2-D or 3-D.

Closed-form least squares for ``min sum_i w_i |s R x_i + t - y_i|^2`` over a scale s, a
proper rotation R (det +1) and a translation t. The fit uses it in 3-D to start a
registration (the thesis' classic ICP, §2.3, eq. 16, solved by SVD) and in 2-D to align
photos' landmark sets per view.
"""

from dataclasses import dataclass

import numpy as np

from .errors import as_points, as_weights


@dataclass(frozen=True)
class Similarity:
    """The map ``x -> scale * rotation @ x + translation`` in ``dim`` dimensions.

    Attributes
    ----------
    scale : float
        Dimensionless.
    rotation : ndarray, shape (d, d)
        Proper rotation (det +1).
    translation : ndarray, shape (d,)
        Same unit as the points.
    rms : float
        Weighted root-mean-square residual of the fit that produced it (0 when not fitted).
    """

    scale: float
    rotation: np.ndarray
    translation: np.ndarray
    rms: float = 0.0

    @property
    def dim(self):
        return self.rotation.shape[0]

    def apply(self, points):
        """Map points: (n, d) -> (n, d)."""
        x = as_points(points, "points", dim=self.dim)
        return self.scale * x @ self.rotation.T + self.translation

    def inverse(self):
        """The inverse similarity."""
        rt = self.rotation.T
        return Similarity(1.0 / self.scale, rt, -(rt @ self.translation) / self.scale, self.rms)

    def matrix(self):
        """Homogeneous matrix, shape (d+1, d+1)."""
        d = self.dim
        m = np.eye(d + 1)
        m[:d, :d] = self.scale * self.rotation
        m[:d, d] = self.translation
        return m


def similarity_procrustes(source, target, weights=None, with_scale=True):
    """Weighted similarity that maps ``source`` onto ``target`` in the least-squares sense.

    Parameters
    ----------
    source, target : array_like, shape (n, d), d in {2, 3}
        Corresponding points (same unit, e.g. metres or pixels).
    weights : array_like, shape (n,), optional
        Non-negative weight of each pair (default 1). Pairs with weight 0 are ignored.
    with_scale : bool
        Fit the scale (default); with False the scale is 1 (a rigid fit).

    Returns
    -------
    Similarity
        With ``target ~= scale * source @ rotation.T + translation`` and ``rms`` the
        weighted RMS residual.

    Raises
    ------
    ValueError
        Mismatched shapes, NaN, negative or all-zero weights, or a degenerate source
        (all points equal, or collinear in 3-D) that leaves the rotation undetermined.
    """
    src = np.asarray(source, dtype=np.float64)
    if src.ndim != 2 or src.shape[1] not in (2, 3):
        raise ValueError(f"source: expected shape (n, 2) or (n, 3), got {src.shape}")
    d = src.shape[1]
    src = as_points(src, "source", dim=d, min_count=2)
    dst = as_points(target, "target", dim=d)
    if dst.shape != src.shape:
        raise ValueError(f"target: shape {dst.shape} does not match source {src.shape}")
    w = as_weights(weights, len(src))
    wsum = w.sum()
    if wsum <= 0:
        raise ValueError("weights: all zero")
    wn = w / wsum
    mu_x = wn @ src
    mu_y = wn @ dst
    xc = src - mu_x
    yc = dst - mu_y
    var_x = wn @ np.einsum("ij,ij->i", xc, xc)
    if var_x <= 1e-30 * max(1.0, float(np.abs(src).max()) ** 2):
        raise ValueError("source: all (weighted) points coincide; the similarity is undetermined")
    cov = (yc * wn[:, None]).T @ xc  # (d, d): sum w y x^T
    u, sv, vt = np.linalg.svd(cov)
    # Rotation undetermined when the cross-covariance has rank < d-1 (e.g. collinear 3-D).
    if sv[d - 2] <= 1e-12 * max(sv[0], 1e-300):
        what = "collinear" if d == 3 else "degenerate"
        raise ValueError(f"source/target: points are {what}; the rotation is undetermined")
    sign = np.ones(d)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        sign[-1] = -1.0  # nearest proper rotation instead of a reflection
    rot = (u * sign) @ vt
    scale = float((sv * sign).sum() / var_x) if with_scale else 1.0
    if scale <= 0:
        raise ValueError("source/target: the best similarity has a non-positive scale "
                         "(the point sets do not correspond)")
    trans = mu_y - scale * rot @ mu_x
    res = scale * src @ rot.T + trans - dst
    rms = float(np.sqrt(wn @ np.einsum("ij,ij->i", res, res)))
    return Similarity(scale, rot, trans, rms)
