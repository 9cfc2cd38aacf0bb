"""Seam feathering: a photo's blend weight fades out over a band of the surface before the
edge of what that photo sees (an occlusion edge: under the chin in a front photo, behind
the ear in a profile), so where two photos meet the texture crosses from one to the other
gradually instead of in a step. Distances are measured over the mesh (along its edges), so
the band is the same on both sides of a UV seam and across UDIM tiles.

The outline against the photo's background has its own fade in the photo itself
(``BakeOptions.feather``); this one works on the surface for every edge of a view's
coverage.
"""

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra


def edge_graph(points, triangles):
    """Symmetric sparse graph (V, V) of a triangle mesh's edges, weighted by their length.

    Parameters
    ----------
    points : ndarray, shape (V, 3), metres
    triangles : ndarray, shape (T, 3), int

    Returns
    -------
    scipy.sparse.csr_matrix, shape (V, V)
    """
    pts = np.asarray(points, dtype=np.float64)
    tri = np.asarray(triangles, dtype=np.int64)
    a = np.concatenate([tri[:, 0], tri[:, 1], tri[:, 2]])
    b = np.concatenate([tri[:, 1], tri[:, 2], tri[:, 0]])
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    key = np.unique(lo * len(pts) + hi)
    lo, hi = key // len(pts), key % len(pts)
    length = np.maximum(np.linalg.norm(pts[lo] - pts[hi], axis=1), 1e-9)
    g = sp.coo_matrix((length, (lo, hi)), shape=(len(pts), len(pts)))
    return (g + g.T).tocsr()


def seam_fade(unseen, graph, width):
    """Weight factor per vertex rising from 0 at the vertices a view does not see to 1 at
    ``width`` metres from them over the surface (smoothstep).

    Parameters
    ----------
    unseen : ndarray, shape (V,), bool
        Vertices the view does not see (occluded, facing away, outside the photo).
    graph : scipy.sparse matrix, shape (V, V)
        :func:`edge_graph` of the mesh.
    width : float
        Width of the fade in metres (0: no fade, all ones).

    Returns
    -------
    ndarray, shape (V,), float64
        0 on ``unseen``, 1 from ``width`` away, smooth in between.
    """
    unseen = np.asarray(unseen, dtype=bool)
    if unseen.shape != (graph.shape[0],):
        raise ValueError(f"unseen: expected shape ({graph.shape[0]},), got {unseen.shape}")
    if width < 0:
        raise ValueError(f"width: expected >= 0 metres, got {width}")
    out = np.ones(len(unseen))
    sources = np.flatnonzero(unseen)
    if width == 0 or not len(sources):
        return out
    d = dijkstra(graph, directed=False, indices=sources, min_only=True, limit=width)
    t = np.clip(d / width, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def tile_seam_difference(rasters, textures):
    """How far apart the textures of UV tiles meet: at each vertex two tiles share, the
    distance between the colours they give it (each tile's texels averaged onto its
    vertices by their interpolation weights), the largest over the pairs of tiles.

    Parameters
    ----------
    rasters : dict of int -> UVRaster
        Each tile's raster (``uvs.uv_raster``).
    textures : dict of int -> ndarray, shape (size, size, 3)
        Each tile's texture, the rasters' tiles.

    Returns
    -------
    ndarray, shape (M,)
        One distance per shared vertex, in the textures' units (empty for one tile).
    """
    colours, covered = [], []
    for tile, r in rasters.items():
        w = np.zeros(r.n_vertices)
        w[r.vertices] = r.cover  # the interpolation weights' sums, kept with the raster
        c = r.gather @ np.asarray(textures[tile], dtype=np.float64).reshape(-1, 3)[r.texel]
        colours.append(c / np.maximum(w, 1e-30)[:, None])
        covered.append(w > 0)
    colours, covered = np.array(colours), np.array(covered)  # (T, V, 3), (T, V)
    shared = covered.sum(axis=0) >= 2
    out = np.zeros(shared.sum())
    for a in range(len(colours)):
        for b in range(a + 1, len(colours)):
            both = (covered[a] & covered[b])[shared]
            d = np.linalg.norm(colours[a, shared] - colours[b, shared], axis=1)
            out = np.where(both, np.maximum(out, d), out)
    return out
