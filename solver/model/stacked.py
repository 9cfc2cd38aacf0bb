"""Linear models over the same vertices stacked one after the other (global modes, then
regional ones) without copying their bases into one array."""

import numpy as np


class StackedModel:
    """Linear models over the same vertices, one after the other (the global modes, then
    the regional ones), without copying their bases into one (K, V, 3) array: the fit
    only ever needs a few hundred vertices at once, or the displacement of all.

    Attributes
    ----------
    parts : list of LinearModel
    mean : ndarray, shape (V, 3)
    stddev : ndarray, shape (K,)
    names : tuple of str
    gamma : ndarray, shape (G, K) or None
        The parts' Gamma rows side by side (zeros under the other parts' coefficients).
    """

    def __init__(self, parts):
        if not parts:
            raise ValueError("parts: at least one linear model is needed")
        self.parts = list(parts)
        self.mean = self.parts[0].mean
        self.stddev = np.concatenate([p.stddev for p in self.parts])
        self.names = tuple(n for p in self.parts for n in p.names)
        self.sizes = [p.n_coeffs for p in self.parts]
        k = sum(self.sizes)
        rows = []
        start = 0
        for p in self.parts:
            if p.gamma is not None:
                g = np.zeros((p.gamma.shape[0], k))
                g[:, start:start + p.n_coeffs] = p.gamma
                rows.append(g)
            start += p.n_coeffs
        self.gamma = np.vstack(rows) if rows else None

    @property
    def n_coeffs(self):
        return int(self.stddev.shape[0])

    def split(self, coeffs):
        """The coefficients of each part."""
        out, start = [], 0
        for k in self.sizes:
            out.append(coeffs[start:start + k])
            start += k
        return out

    def displacements(self, coeffs):
        """Displacement of every vertex by each part, list of (V, 3)."""
        return [np.tensordot(c, p.basis, axes=1) for c, p in zip(self.split(coeffs),
                                                                  self.parts, strict=True)]

    def slice(self, vertices):
        """(mean (n, 3), basis (K, n, 3)) of a vertex subset."""
        v = np.asarray(vertices, dtype=np.int64)
        # take, not basis[:, v]: fancy indexing along axis 1 leaves another layout, which
        # every product with the slice would pay for (or a second copy to mend it).
        return self.mean[v], np.concatenate([np.take(p.basis, v, axis=1) for p in self.parts])

