"""Seam levelling: what a global gain and offset per photo (``equalise.py``) leave of the
colour step between two photos, because the light differs from place to place (a profile
photo used mirrored carries the other cheek's light), taken out by a smooth additive
correction of each photo over the surface (after Lempitsky and Ivanov, "Seamless mosaicing
of image-based texture maps", 2007).

The correction of a view is the difference to the reference view where both see the
surface, smoothed over the mesh, and continued smoothly where only the view itself sees
it, fading out over a few centimetres (``decay``), so the view's own region moves
with its border near the seam, keeps its detail, and far from it keeps its colours. Vertex
values in, vertex values out; the mesh is points (V, 3) in metres and triangles (T, 3).
"""

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .shading import mesh_operators


def level_field(difference, overlap, points, triangles, length, decay=None,
                operators=None):
    """A smooth correction per vertex that matches ``difference`` where ``overlap`` is
    high and, where it is 0, continues it smoothly and fades out over about ``decay``.

    Solves ``(A W + length^2 L + (length / decay)^2 A) f = A W d`` with ``A`` the
    vertices' areas, ``W`` the overlap, ``L`` the cotangent Laplacian.

    Parameters
    ----------
    difference : ndarray, shape (V,) or (V, K)
        Reference colour minus the view's colour, where they overlap (anything elsewhere).
    overlap : ndarray, shape (V,)
        How much each vertex is seen by both, in [0, 1] (0: only one of them sees it).
    points : ndarray, shape (V, 3), metres
    triangles : ndarray, shape (T, 3), int
        Vertices of no triangle get 0.
    length : float
        Smoothing length in metres (> 0): detail of the difference finer than this is not
        followed (it is the photos' detail, not their light).
    decay : float, optional
        Metres over which the correction fades away from the overlap (> ``length``), so a
        photo keeps its own colours far from its seams; default: no fading (a harmonic
        continuation, only parts that touch no overlap go to 0).
    operators : tuple, optional
        ``shading.mesh_operators(points, triangles)``, when the caller has them already
        (several views levelled on one surface).

    Returns
    -------
    ndarray, shape like ``difference``, float64
    """
    d = np.asarray(difference, dtype=np.float64)
    wv = np.clip(np.asarray(overlap, dtype=np.float64), 0.0, 1.0)
    if wv.shape != d.shape[:1]:
        raise ValueError(f"overlap: expected shape ({d.shape[0]},), got {wv.shape}")
    if length <= 0:
        raise ValueError(f"length: expected > 0 metres, got {length}")
    used, _, area, lap = operators or mesh_operators(points, triangles)
    data = area * wv[used]
    if decay is not None and not decay > length:
        raise ValueError(f"decay: expected more than length ({length} m), got {decay}")
    screen = 1e-6 if decay is None else (length / decay) ** 2
    a = (sp.diags(data + screen * area) + length * length * lap).tocsc()
    rhs = data[:, None] * np.nan_to_num(d[used]).reshape(len(used), -1)
    out = np.zeros(d.shape)
    out[used] = spla.spsolve(a, rhs).reshape(d[used].shape)
    return out
