"""Principal component analysis with the small-matrix trick (thesis §2.1, Turk & Pentland).

With M samples of dimension D >> M, the eigenvectors of the D x D covariance come from
the M x M Gram matrix: if (X^T X) v = l v then X v is an eigenvector of X X^T with the
same eigenvalue. That keeps a PCA of a 30k-coordinate head at the cost of an M x M
eigendecomposition.
"""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PCA:
    """A PCA model.

    Attributes
    ----------
    mean : ndarray, shape (D,)
    components : ndarray, shape (K, D)
        Orthonormal principal directions, largest variance first.
    variances : ndarray, shape (K,)
        Eigenvalues of the sample covariance (unit of the data, squared).
    """

    mean: np.ndarray
    components: np.ndarray
    variances: np.ndarray

    @property
    def stddevs(self):
        """Standard deviation along each component, shape (K,)."""
        return np.sqrt(self.variances)

    def project(self, x, n_components=None, standardized=False):
        """Coefficients of samples ``x`` (shape (D,) or (N, D)) on the first components.

        With ``standardized`` the coefficients are in standard deviations (N(0, 1) units).
        """
        comps, sd = self._first(n_components)
        x = np.asarray(x, dtype=np.float64)
        if x.shape[-1] != self.mean.shape[0]:
            raise ValueError(f"x: last axis must have length {self.mean.shape[0]}, got {x.shape}")
        c = (x - self.mean) @ comps.T
        return c / sd if standardized else c

    def reconstruct(self, coeffs, standardized=False):
        """Samples from coefficients (shape (K',) or (N, K'), K' <= K)."""
        c = np.asarray(coeffs, dtype=np.float64)
        comps, sd = self._first(c.shape[-1])
        if standardized:
            c = c * sd
        return self.mean + c @ comps

    def _first(self, k):
        k = self.components.shape[0] if k is None else int(k)
        if not 0 < k <= self.components.shape[0]:
            raise ValueError(f"n_components must be in 1..{self.components.shape[0]}, got {k}")
        return self.components[:k], self.stddevs[:k]


def fit_pca(samples, n_components=None, rel_tol=1e-10):
    """Build a PCA from samples with the small-matrix trick (thesis §2.1).

    Parameters
    ----------
    samples : array_like, shape (M, D)
        One sample per row; D may be far larger than M.
    n_components : int, optional
        Keep at most this many components (default: all with non-negligible variance).
    rel_tol : float
        Components whose eigenvalue is below ``rel_tol`` times the largest are dropped.

    Returns
    -------
    PCA
    """
    x = np.asarray(samples, dtype=np.float64)
    if x.ndim != 2 or x.shape[0] < 2:
        raise ValueError(f"samples: expected shape (M >= 2, D), got {x.shape}")
    if not np.isfinite(x).all():
        raise ValueError("samples: contains NaN or inf")
    m = x.shape[0]
    mean = x.mean(axis=0)
    a = x - mean
    if a.shape[1] < m:
        # More samples than dimensions: the ordinary covariance is the small matrix.
        evals, evecs = np.linalg.eigh(a.T @ a)
        comps = evecs.T
    else:
        gram = a @ a.T  # (M, M)
        evals, v = np.linalg.eigh(gram)
        comps = (a.T @ v).T  # rows are eigenvectors of a.T @ a, not yet unit length
    order = np.argsort(evals)[::-1]
    evals, comps = evals[order], comps[order]
    keep = evals > rel_tol * max(evals[0], np.finfo(float).tiny)
    if n_components is not None:
        keep &= np.arange(len(evals)) < n_components
    evals, comps = evals[keep], comps[keep]
    comps /= np.linalg.norm(comps, axis=1, keepdims=True)
    return PCA(mean=mean, components=comps, variances=evals / (m - 1))
