"""Errors, both kinds the solver deals in: bad input turned into a ValueError whose message
names the argument at fault, and the size of a residual (``rms``)."""

import numpy as np


def as_points(a, name, dim=3, min_count=1):
    """Return ``a`` as a float64 array of shape (n, dim), or raise ValueError naming ``name``.

    Parameters
    ----------
    a : array_like, shape (n, dim)
    name : str
        What the caller calls this argument; used in the message.
    dim : int
        Number of coordinates per point.
    min_count : int
        Fewest points accepted.
    """
    arr = np.asarray(a, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != dim:
        raise ValueError(f"{name}: expected an array of shape (n, {dim}), got {arr.shape}")
    if arr.shape[0] < min_count:
        raise ValueError(f"{name}: needs at least {min_count} points, got {arr.shape[0]}")
    # two quick passes when all is well (a NaN or an infinity reaches the min or the max)
    if arr.size and not (np.isfinite(arr.min()) and np.isfinite(arr.max())):
        bad = ~np.isfinite(arr).all(axis=1)
        if bad.any():
            raise ValueError(f"{name}: row {int(np.flatnonzero(bad)[0])} is not finite "
                             "(NaN or inf)")
    return arr


def as_weights(weights, n, name="weights"):
    """Per-point weights as float64 of shape (n,): ones when ``weights`` is None, else
    checked to be finite and non-negative; ValueError naming ``name`` otherwise."""
    if weights is None:
        return np.ones(n)
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (n,):
        raise ValueError(f"{name}: expected shape ({n},), got {w.shape}")
    if not np.isfinite(w).all() or (w < 0).any():
        raise ValueError(f"{name}: must be finite and non-negative")
    return w


def rms(values):
    """Root mean square of ``values`` (any shape; each entry one number, e.g. pixel
    residuals); 0.0 when empty."""
    v = np.asarray(values, dtype=np.float64)
    return float(np.sqrt((v * v).mean())) if v.size else 0.0
