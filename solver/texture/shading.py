"""Shading removal: the photos' light baked into the texture (a darker side, the brighter
forehead) estimated as a heavily smoothed luminance over the surface and divided out, for
a flat, albedo-like texture that the artist lights again in Blender. It also flattens the
skin's own slow colour changes (a darker neck) and leaves shading finer than the smoothing
(a nostril's shadow), so it is an option (``BakeOptions.shading="remove"``), off by default.

The division is done in linear light (shading multiplies radiance), on sRGB values in and
out; the smoothing is on the mesh (screened Poisson, ``(M + l^2 L) s = M f`` with the
cotangent Laplacian ``L`` and lumped areas ``M``), so it is the same across UV seams.
"""

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .uvs import cotan_laplacian

#: Rec. 709 luminance of linear RGB.
LUMA = np.array([0.2126, 0.7152, 0.0722])


def srgb_to_linear(x):
    """sRGB-encoded values in [0, 1] (any shape) to linear light."""
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(x):
    """Linear light in [0, 1] (any shape) to sRGB-encoded values."""
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def vertex_areas(points, triangles):
    """Lumped (one third of the adjacent triangles') area per vertex (V,), square metres."""
    pts = np.asarray(points, dtype=np.float64)
    tri = np.asarray(triangles, dtype=np.int64)
    p = pts[tri]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    return np.bincount(tri.ravel(), np.repeat(area / 3.0, 3), minlength=len(pts))


def mesh_operators(points, triangles):
    """The surface operators of the vertices ``triangles`` use: (those vertices (U,), the
    triangles in their numbering (T, 3), lumped areas (U,) m^2, cotangent Laplacian (U, U)
    sparse), for smoothing and levelling on the mesh."""
    tri = np.asarray(triangles, dtype=np.int64)
    used = np.unique(tri)
    local = np.searchsorted(used, tri)
    pts = np.asarray(points, dtype=np.float64)[used]
    return used, local, vertex_areas(pts, local), cotan_laplacian(pts, local)


def smooth_on_mesh(values, points, triangles, length):
    """Values per vertex smoothed over the surface with length scale ``length``.

    Solves ``(M + length^2 L) s = M f`` (screened Poisson; a kernel of about ``length``
    metres), per column.

    Parameters
    ----------
    values : ndarray, shape (V,) or (V, K)
    points : ndarray, shape (V, 3), metres
    triangles : ndarray, shape (T, 3), int
        Vertices of no triangle keep their value.
    length : float
        Smoothing length in metres (> 0).

    Returns
    -------
    ndarray, shape like ``values``, float64
    """
    f = np.asarray(values, dtype=np.float64)
    if length <= 0:
        raise ValueError(f"length: expected > 0 metres, got {length}")
    used, _, mass, lap = mesh_operators(points, triangles)
    a = (sp.diags(mass) + length * length * lap).tocsc()
    out = f.copy()
    out[used] = spla.spsolve(a, mass[:, None] * f[used].reshape(len(used), -1)).reshape(
        f[used].shape)
    return out


def shading_factor(rgb, points, triangles, length):
    """The light to divide out per vertex: smoothed luminance over its mean.

    Parameters
    ----------
    rgb : ndarray, shape (V, 3)
        Vertex colours, sRGB-encoded in [0, 1].
    points, triangles, length
        As in :func:`smooth_on_mesh`.

    Returns
    -------
    ndarray, shape (V,)
        Around 1 (area-weighted mean 1 over the triangles' vertices); dividing linear
        colour by it flattens the low-frequency light.
    """
    lum = srgb_to_linear(rgb) @ LUMA
    s = smooth_on_mesh(lum, points, triangles, length)
    tri = np.asarray(triangles, dtype=np.int64)
    area = vertex_areas(points, tri)
    mean = float(area @ s / max(area.sum(), 1e-30))
    return np.maximum(s, 1e-3 * max(mean, 1e-6)) / max(mean, 1e-6)


def remove_shading(rgb, factor):
    """Colours (..., 3) sRGB with the light ``factor`` (...) divided out in linear light;
    sRGB out, clipped to [0, 1]."""
    lin = srgb_to_linear(rgb) / np.asarray(factor, dtype=np.float64)[..., None]
    return linear_to_srgb(lin)
