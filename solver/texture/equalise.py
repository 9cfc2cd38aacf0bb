"""Colour equalisation between photos before they are blended: every view but one gets a
gain and an offset per channel, fitted by least squares on the texels two views both see,
so a front photo and a profile taken under other light (or exposure, or white balance)
meet without a step in colour or brightness. :func:`seam_difference` measures what is
left of such a step across the band where two views blend.

Colours are in whatever encoding the bake blends (the photos' sRGB values); arrays are
dense over the texels of a bake, one row per view, a weight of 0 where a view does not see
a texel.
"""

from dataclasses import dataclass

import numpy as np

#: Relative weight of the pull toward gain 1 and offset 0, per unit of a view's overlap:
#: far too weak to bend a well-determined fit, enough to keep a view that overlaps no
#: other one unchanged.
PRIOR = 1e-2

#: Gains are kept within this factor of 1 (a photo more than twice as bright as another
#: is no exposure difference the blend should hide).
MAX_GAIN = 2.0


def _check(colours, weights):
    c = np.asarray(colours, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    if c.ndim != 3 or w.shape != c.shape[:2]:
        raise ValueError(f"colours (P, N, C) and weights (P, N) expected, got {c.shape} "
                         f"and {w.shape}")
    if not (np.isfinite(c).all() and np.isfinite(w).all()) or (w < 0).any():
        raise ValueError("colours and weights must be finite, weights >= 0")
    return c, w


def default_reference(weights):
    """The view fixed as the reference: the one that overlaps the others most (the sum
    over the other views and the texels of the smaller of the two weights; the front photo
    between two profiles), the largest total weight breaking ties.

    Parameters
    ----------
    weights : ndarray, shape (P, N)
    """
    w = np.asarray(weights, dtype=np.float64)
    shared = np.array([sum(float(np.minimum(w[a], w[b]).sum()) for b in range(len(w))
                           if b != a) for a in range(len(w))])
    total = w.sum(axis=1)
    return int(np.lexsort((total, shared))[-1])


def fit_gains(colours, weights, reference=None, iterations=6, groups=None):
    """Per-view, per-channel gain and offset that make the views agree where they overlap.

    Minimises, per channel, ``sum over view pairs (a, b) and texels t of
    min(w_a, w_b) * r^2`` with ``r = (g_a c_a + o_a) - (g_b c_b + o_b)``, the reference
    view held at gain 1 and offset 0, plus a weak pull of every other view toward 1 and 0
    (``PRIOR``). A few reweighted rounds (Cauchy weights at twice the residuals' robust
    spread) keep texels where the views disagree for other reasons (a highlight, the
    fit's small misregistration at an edge) from setting the gains.

    Parameters
    ----------
    colours : ndarray, shape (P, N, C)
        Each view's colour at each texel (anything where the view does not see it).
    weights : ndarray, shape (P, N)
        Each view's blend weight, 0 where it does not see the texel.
    reference : int, optional
        The view held fixed; default :func:`default_reference`.
    iterations : int
        Least-squares rounds (1: plain least squares).
    groups : sequence of int, shape (P,), optional
        Rows that are one photo (a photo used directly and mirrored) share one gain and
        offset and are not fitted against each other; default one group per row.
        ``reference`` is then a row of the reference group.

    Returns
    -------
    gain, offset : ndarray, shape (P, C)
        Equalised colour is ``gain[p] * colour + offset[p]``; the reference row is
        (1, 0). Gains are clipped to [1 / MAX_GAIN, MAX_GAIN].
    """
    c, w = _check(colours, weights)
    rows, _, nc = c.shape
    ref_row = default_reference(w) if reference is None else int(reference)
    if not 0 <= ref_row < rows:
        raise ValueError(f"reference: view {ref_row} of {rows}")
    _, group = np.unique(np.arange(rows) if groups is None else np.asarray(groups),
                         return_inverse=True)
    if group.shape != (rows,):
        raise ValueError(f"groups: expected {rows} entries, got {np.shape(groups)}")
    p, ref = int(group.max()) + 1, int(group[ref_row])
    g_gain, g_offset = np.ones((p, nc)), np.zeros((p, nc))
    masks = {}  # (row a, row b) -> (texels, min weight), rows of different groups
    for a in range(rows):
        for b in range(a + 1, rows):
            both = np.flatnonzero((w[a] > 0) & (w[b] > 0))
            if group[a] != group[b] and len(both):
                masks[a, b] = (both, np.minimum(w[a, both], w[b, both]))
    if p < 2 or not masks:
        return g_gain[group], g_offset[group]
    gain, offset = g_gain, g_offset
    free = [v for v in range(p) if v != ref]
    for ch in range(nc):
        robust = {k: np.ones(len(m[0])) for k, m in masks.items()}
        for _ in range(max(1, int(iterations))):
            h = np.zeros((2 * p, 2 * p))
            overlap, square = np.zeros(p), np.zeros(p)
            for (a, b), (idx, om) in masks.items():
                om = om * robust[a, b]
                ca, cb = c[a, idx, ch], c[b, idx, ch]
                s, sa, sb = om.sum(), om @ ca, om @ cb
                saa, sbb, sab = om @ (ca * ca), om @ (cb * cb), om @ (ca * cb)
                block = np.array([[saa, sa, -sab, -sa], [sa, s, -sb, -s],
                                  [-sab, -sb, sbb, sb], [-sa, -s, sb, s]])
                ga, gb = group[a], group[b]
                ix = [2 * ga, 2 * ga + 1, 2 * gb, 2 * gb + 1]
                h[np.ix_(ix, ix)] += block
                overlap[[ga, gb]] += s
                square[ga] += saa
                square[gb] += sbb
            # the prior: PRIOR * overlap * ((g - 1)^2 * mean(c^2) + o^2) per view (a gain
            # step costs as much as the offset that brightens as much), a floor for views
            # that overlap nothing
            prior = PRIOR * (overlap + 1e-6 * overlap.sum() + 1e-12)
            level = np.maximum(square / np.maximum(overlap, 1e-30), 1e-4)
            rhs = np.zeros(2 * p)
            h[np.arange(0, 2 * p, 2), np.arange(0, 2 * p, 2)] += prior * level
            h[np.arange(1, 2 * p, 2), np.arange(1, 2 * p, 2)] += prior
            rhs[0::2] += prior * level
            keep = np.array([2 * v + k for v in free for k in (0, 1)])
            fixed = np.array([2 * ref, 2 * ref + 1])
            x = np.zeros(2 * p)
            x[fixed] = (1.0, 0.0)
            x[keep] = np.linalg.solve(h[np.ix_(keep, keep)],
                                      rhs[keep] - h[np.ix_(keep, fixed)] @ x[fixed])
            gain[:, ch], offset[:, ch] = x[0::2], x[1::2]
            ga, oa = gain[group, ch], offset[group, ch]
            res = {k: (ga[k[0]] * c[k[0], m[0], ch] + oa[k[0]])
                   - (ga[k[1]] * c[k[1], m[0], ch] + oa[k[1]])
                   for k, m in masks.items()}
            allr = np.concatenate(list(res.values()))
            scale = 1.4826 * np.median(np.abs(allr - np.median(allr)))
            k_cauchy = max(2.0 * scale, 1e-6)
            robust = {k: 1.0 / (1.0 + (r / k_cauchy) ** 2) for k, r in res.items()}
    np.clip(gain, 1.0 / MAX_GAIN, MAX_GAIN, out=gain)
    gain[ref], offset[ref] = 1.0, 0.0
    return gain[group], offset[group]


def apply_gains(colours, gain, offset, in_place=False):
    """``gain[p] * colours[p] + offset[p]`` for colours (P, N, C), gain and offset (P, C)
    (float32 kept; not clipped, the blend and the texture's clip follow); ``in_place``
    writes it into ``colours`` (an ndarray), the same values without a second copy."""
    c = np.asarray(colours)
    g, o = np.asarray(gain, c.dtype), np.asarray(offset, c.dtype)
    if not in_place:
        c = c.copy()
    # one channel of one pass at a time: a long strided loop, where broadcasting the
    # (P, 1, C) factors runs a loop of C per texel (2.6 x slower)
    for p in range(c.shape[0]):
        for ch in range(c.shape[2]):
            v = c[p, :, ch]
            v *= g[p, ch]
            v += o[p, ch]
    return c


@dataclass(frozen=True)
class SeamDifference:
    """What is left of a colour step between views where they blend.

    Attributes
    ----------
    absolute : float
        Mean over the band's cells of the mean-over-channels absolute difference between
        two views' average colours in the cell, in colour units (1 = full scale).
    relative : float
        ``absolute`` over the band's mean colour level (0.03 = 3 %).
    texels : int
        Texels in the band (each pair of views counted on its own).
    """

    absolute: float
    relative: float
    texels: int


def seam_difference(colours, weights, cells, band=0.2):
    """The colour difference between views across the seam band.

    The band is where two views both carry at least ``band`` of a texel's blend weight
    (their colours visibly mix). The band's texels are grouped into ``cells`` (small
    patches of the texture), each view's colour averaged per cell, so the measure is the
    low-frequency step between views (what equalisation can fix and a seam shows), not
    detail the two photos place a texel apart.

    Parameters
    ----------
    colours : ndarray, shape (P, N, C)
    weights : ndarray, shape (P, N)
    cells : ndarray, shape (N,), int
        Patch number of each texel (e.g. 16 x 16 texel squares, per tile).
    band : float
        Smallest share of the blend weight of each of the two views, in (0, 0.5].

    Returns
    -------
    SeamDifference
        Cells weighted by their texels; zeros when no two views blend anywhere.
    """
    c, w = _check(colours, weights)
    cells = np.asarray(cells)
    if cells.shape != c.shape[1:2]:
        raise ValueError(f"cells: expected shape ({c.shape[1]},), got {cells.shape}")
    if not 0 < band <= 0.5:
        raise ValueError(f"band: expected a share in (0, 0.5], got {band}")
    total = w.sum(axis=0)
    share = w / np.maximum(total, 1e-30)
    diff_sum = level_sum = 0.0
    count = 0
    p = c.shape[0]
    for a in range(p):
        for b in range(a + 1, p):
            idx = np.flatnonzero((share[a] >= band) & (share[b] >= band))
            if not len(idx):
                continue
            _, cell, n = np.unique(cells[idx], return_inverse=True, return_counts=True)
            mean_a = np.stack([np.bincount(cell, c[a, idx, k]) for k in range(c.shape[2])],
                              1) / n[:, None]
            mean_b = np.stack([np.bincount(cell, c[b, idx, k]) for k in range(c.shape[2])],
                              1) / n[:, None]
            diff_sum += float(n @ np.abs(mean_a - mean_b).mean(axis=1))
            level_sum += float(n @ (0.5 * (mean_a + mean_b)).mean(axis=1))
            count += len(idx)
    if count == 0:
        return SeamDifference(0.0, 0.0, 0)
    return SeamDifference(diff_sum / count, diff_sum / max(level_sum, 1e-30), count)
