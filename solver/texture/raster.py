"""Vectorised triangle rasterisation on a pixel grid: which pixel centres each triangle
covers, with barycentric coordinates. The texture bake uses it twice: once in UV space
(texel -> triangle, cached per model and size) and once per photo for a depth buffer.

Grid convention: pixel (column i, row j) has its centre at (i + 0.5, j + 0.5), so a grid
of width W spans x in [0, W]; flat index ``j * W + i``. Whether rows run down (photos) or
the caller flipped v (textures) is the caller's business.

Triangles are processed in batches grouped by bounding-box size: each batch tests one
rectangle of candidate centres per triangle, so there is no Python loop per triangle or
per pixel, and the wasted candidates stay below ~2.3x the boxes' area.
"""

import numpy as np

# Box sizes a batch is rounded up to (about x1.5 steps): little waste, few batches.
_LADDER = np.array([1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512,
                    768, 1024, 1536, 2048, 3072, 4096, 6144, 8192, 12288, 16384])
_CHUNK = 1 << 21  # candidate centres per batch: bounds memory (~100 MB of temporaries)
_EPS = 1e-9  # barycentric slack so centres on a shared edge are not lost to rounding


def rasterize(tri_xy, width, height):
    """Pixel centres covered by each triangle.

    Parameters
    ----------
    tri_xy : ndarray, shape (T, 3, 2)
        Triangle corners in pixel units (x along a row, y along a column).
    width, height : int
        Grid size in pixels; centres outside it are dropped.

    Returns
    -------
    pixel : ndarray, shape (N,), int64
        Flat index ``row * width + column`` of each covered centre.
    tri : ndarray, shape (N,), int64
        Triangle covering it (index into ``tri_xy``).
    bary : ndarray, shape (N, 3), float64
        Barycentric coordinates of the centre in that triangle (sum to 1, each >= ~0).

    Notes
    -----
    A centre on an edge shared by two triangles is reported for both; callers that need
    one triangle per pixel use :func:`first_per_pixel`. Degenerate (zero-area) triangles
    cover nothing.
    """
    out_p, out_t, out_b = [], [], []
    for pixel, tri, bary in _fragments(tri_xy, width, height):
        out_p.append(pixel)
        out_t.append(tri)
        out_b.append(bary)
    if not out_p:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3))
    return np.concatenate(out_p), np.concatenate(out_t), np.concatenate(out_b)


def _fragments(tri_xy, width, height):
    """The covered centres of :func:`rasterize`, a batch at a time: (pixel (n,), triangle
    (n,), barycentrics (n, 3)) per batch, so a caller that reduces them (a depth buffer)
    never holds them all."""
    t = np.asarray(tri_xy, dtype=np.float64)
    if t.ndim != 3 or t.shape[1:] != (3, 2):
        raise ValueError(f"tri_xy: expected shape (T, 3, 2), got {t.shape}")
    width, height = int(width), int(height)
    if len(t) == 0 or width <= 0 or height <= 0:
        return
    finite = np.isfinite(t).all(axis=(1, 2))
    x, y = t[..., 0], t[..., 1]
    with np.errstate(invalid="ignore"):
        x0 = np.ceil(x.min(1) - 0.5)
        x1 = np.floor(x.max(1) - 0.5)
        y0 = np.ceil(y.min(1) - 0.5)
        y1 = np.floor(y.max(1) - 0.5)
    x0 = np.clip(np.nan_to_num(x0), 0, width - 1).astype(np.int64)
    y0 = np.clip(np.nan_to_num(y0), 0, height - 1).astype(np.int64)
    bw = np.clip(np.nan_to_num(x1), -1, width - 1).astype(np.int64) - x0 + 1
    bh = np.clip(np.nan_to_num(y1), -1, height - 1).astype(np.int64) - y0 + 1

    # Barycentrics are an affine function of the centre: l1 = a1 (cx - xa) + b1 (cy - ya),
    # l2 likewise, l0 = 1 - l1 - l2 (inverse of the 2x2 edge matrix).
    ex1, ey1 = x[:, 1] - x[:, 0], y[:, 1] - y[:, 0]
    ex2, ey2 = x[:, 2] - x[:, 0], y[:, 2] - y[:, 0]
    det = ex1 * ey2 - ex2 * ey1
    scale = np.maximum(np.abs(ex1 * ey1) + np.abs(ex2 * ey2) + np.abs(ex1 * ex2)
                       + np.abs(ey1 * ey2), 1e-300)
    ok = finite & (bw > 0) & (bh > 0) & (np.abs(det) > 1e-12 * scale)
    idx = np.flatnonzero(ok)
    if len(idx) == 0:
        return
    inv = 1.0 / det[idx]
    coef = np.stack([ey2[idx] * inv, -ex2[idx] * inv, -ey1[idx] * inv, ex1[idx] * inv,
                     x[idx, 0], y[idx, 0]], axis=1)

    ladder = _LADDER
    biggest = max(int(bw[idx].max()), int(bh[idx].max()))
    if biggest > ladder[-1]:  # grids wider than the ladder: one more rung
        ladder = np.append(ladder, biggest)
    gi = np.searchsorted(ladder, bw[idx])
    gj = np.searchsorted(ladder, bh[idx])
    key = gi * len(ladder) + gj
    order = np.argsort(key, kind="stable")
    keys, starts = np.unique(key[order], return_index=True)
    ends = np.append(starts[1:], len(order))

    for k, s, e in zip(keys, starts, ends, strict=True):
        gw, gh = int(ladder[k // len(ladder)]), int(ladder[k % len(ladder)])
        members = idx[order[s:e]]
        mc = coef[order[s:e]]
        band = min(gh, max(1, _CHUNK // gw))  # rows per pass: huge boxes go in bands
        step = max(1, _CHUNK // (gw * band))
        ox = np.arange(gw)
        for c in range(0, len(members), step):
            m = members[c:c + step]
            cf = mc[c:c + step]
            for r0 in range(0, gh, band):
                oy = np.arange(r0, min(gh, r0 + band))
                hit = _cover(m, cf, ox, oy, x0, y0, bw, bh, width)
                if hit is not None:
                    yield hit


def _cover(m, cf, ox, oy, x0, y0, bw, bh, width):
    """Test the candidate centres (column offsets ox, row offsets oy in each box) of
    triangles ``m`` with barycentric coefficients ``cf``; the hits as (pixel, triangle,
    barycentrics clipped to [0, 1] and summing to 1), or None."""
    px = x0[m, None, None] + ox[None, None, :]  # (n, 1, gw)
    py = y0[m, None, None] + oy[None, :, None]  # (n, rows, 1)
    inbox = (ox[None, None, :] < bw[m, None, None]) & (oy[None, :, None] < bh[m, None, None])
    dx = px + 0.5 - cf[:, 4, None, None]
    dy = py + 0.5 - cf[:, 5, None, None]
    l1 = cf[:, 0, None, None] * dx + cf[:, 1, None, None] * dy
    l2 = cf[:, 2, None, None] * dx + cf[:, 3, None, None] * dy
    l0 = 1.0 - l1 - l2
    hit = inbox & (l0 >= -_EPS) & (l1 >= -_EPS) & (l2 >= -_EPS)
    n_i, r_i, c_i = np.nonzero(hit)
    if not len(n_i):
        return None
    bary = np.clip(np.stack([l0[hit], l1[hit], l2[hit]], axis=1), 0.0, 1.0)
    bary /= bary.sum(axis=1, keepdims=True)
    return py[n_i, r_i, 0] * width + px[n_i, 0, c_i], m[n_i], bary


def first_per_pixel(pixel, *arrays):
    """Keep one fragment per pixel (the first in input order), sorted by pixel.

    Parameters
    ----------
    pixel : ndarray, shape (N,)
    *arrays : ndarrays with first dimension N

    Returns
    -------
    tuple of ndarrays: the unique pixels, then each array restricted to the kept fragments.
    """
    uniq, first = np.unique(pixel, return_index=True)
    return (uniq, *(a[first] for a in arrays))


def depth_buffer(tri_xy, tri_depth, width, height):
    """Nearest depth per pixel centre of a set of triangles (a z-buffer).

    Parameters
    ----------
    tri_xy : ndarray, shape (T, 3, 2)
        Projected corners, pixel units of this grid.
    tri_depth : ndarray, shape (T, 3)
        Depth of each corner (larger is farther); interpolated linearly in the image,
        exact for parallel projection and within a hair of it for small triangles seen
        in perspective.
    width, height : int

    Returns
    -------
    ndarray, shape (height, width), float64
        Smallest depth covering each pixel centre; ``inf`` where nothing does.
    """
    d = np.asarray(tri_depth, dtype=np.float64)
    buf = np.full(int(width) * int(height), np.inf)
    for pixel, tri, bary in _fragments(tri_xy, width, height):
        np.minimum.at(buf, pixel, np.einsum("nk,nk->n", bary, d[tri]))
    return buf.reshape(int(height), int(width))
