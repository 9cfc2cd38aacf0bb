"""A linear shape model x(c) = mean + sum_k c_k * basis_k, the one form every fit works on.

The global identity model and the regional model of thesis §3.4 (region bases blended at
their borders, eq. 19) are both a LinearModel, so the shape-ICP
(§4.3) needs to know nothing about regions beyond the optional smoothness rows Gamma.
"""

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class LinearModel:
    """Linear shape model over V vertices with K coefficients.

    Attributes
    ----------
    mean : ndarray, shape (V, 3), metres
    basis : ndarray, shape (K, V, 3), metres per unit coefficient
        Coefficients are in standard-normal units: c ~ N(0, I) under the model.
    stddev : ndarray, shape (K,), metres
        Norm of each raw (unit-length) principal direction's standard deviation, i.e. the
        square root of its eigenvalue; lets a prior be scaled by eigenvalues (thesis eq. 42).
    names : tuple of str, length K
        Name of each coefficient (becomes a shape key name).
    gamma : ndarray, shape (G, K), optional
        Smoothness rows Gamma (thesis eq. 40-41): Gamma @ c is the disagreement, in metres,
        of regions at vertices two regions share; a fit adds lambda1 * Gamma as rows.
    """

    mean: np.ndarray
    basis: np.ndarray
    stddev: np.ndarray
    names: tuple = ()
    gamma: np.ndarray | None = field(default=None)

    @property
    def n_vertices(self):
        return self.mean.shape[0]

    @property
    def n_coeffs(self):
        return self.basis.shape[0]

    def instance(self, coeffs):
        """Vertex positions for coefficients ``coeffs`` (shape (K,)), shape (V, 3)."""
        c = np.asarray(coeffs, dtype=np.float64)
        if c.shape != (self.n_coeffs,):
            raise ValueError(f"coeffs: expected shape ({self.n_coeffs},), got {c.shape}")
        return self.mean + np.tensordot(c, self.basis, axes=1)

    def take(self, vertices):
        """The same model restricted to the given vertex indices (Gamma is kept: it acts
        on coefficients only)."""
        idx = np.asarray(vertices, dtype=np.intp)
        return LinearModel(self.mean[idx], self.basis[:, idx], self.stddev, self.names,
                           self.gamma)

    def first(self, k):
        """The model with only its first ``k`` coefficients (Gamma columns cut to match)."""
        g = None if self.gamma is None else self.gamma[:, :k]
        return LinearModel(self.mean, self.basis[:k], self.stddev[:k], self.names[:k], g)

