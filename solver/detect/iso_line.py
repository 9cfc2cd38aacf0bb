"""Closed iso-lines of a 2-D map (marching squares), as ordered polygons: how a
segmentation's probability becomes an outline with sub-pixel positions between the map's
samples, without tracing pixels one by one."""

import numpy as np

# Marching-squares segments per cell case (bit 1 top-left, 2 top-right, 4 bottom-right,
# 8 bottom-left at or above the level), as pairs of cell edges (0 top, 1 right, 2 bottom,
# 3 left). The saddles 5 and 10 are resolved by the cell's mean (``_SADDLE``).
_SEGMENTS = {1: [(3, 0)], 2: [(0, 1)], 3: [(3, 1)], 4: [(1, 2)], 6: [(0, 2)], 7: [(3, 2)],
             8: [(3, 2)], 9: [(0, 2)], 11: [(1, 2)], 12: [(3, 1)], 13: [(0, 1)],
             14: [(3, 0)]}
# saddle case -> (segments when the cell's mean is at or above the level, else)
_SADDLE = {5: ([(0, 1), (3, 2)], [(3, 0), (1, 2)]),
           10: ([(3, 0), (1, 2)], [(0, 1), (3, 2)])}


def iso_lines(values, level=0.5):
    """The closed lines where ``values`` crosses ``level``.

    Parameters
    ----------
    values : ndarray (H, W)
        Samples on a grid; sample (row r, column c) is at (x, y) = (c, r). Outside the
        grid counts as below the level, so every line closes (half a sample outside).
    level : float

    Returns
    -------
    list of ndarray (n, 2)
        Each line's points (x, y) in order, not repeating the first; linear
        interpolation between samples. Each runs clockwise on screen (x right, y down:
        positive ``polygon_area``), so around a region at or above the level its outward
        normal is (t_y, -t_x) for the direction of travel t. Longest first.
    """
    v = np.asarray(values, np.float64)
    # outside: the edge sample mirrored about the level, so a line leaving the grid
    # crosses half a sample outside, as between two samples of a step
    f = 2 * level - np.pad(v, 1, mode="edge")
    f[1:-1, 1:-1] = v
    above = np.pad(v >= level, 1)
    h, w = f.shape
    a, b, c, d = above[:-1, :-1], above[:-1, 1:], above[1:, 1:], above[1:, :-1]
    case = a * 1 + b * 2 + c * 4 + d * 8
    rows, cols = np.nonzero((case > 0) & (case < 15))
    if rows.size == 0:
        return []
    finite = f

    def edge_point(r, c_, edge):
        """Edge id and the crossing's (x, y) on edge ``edge`` of cell (r, c_)."""
        if edge == 0:
            r0, c0, r1, c1 = r, c_, r, c_ + 1
        elif edge == 1:
            r0, c0, r1, c1 = r, c_ + 1, r + 1, c_ + 1
        elif edge == 2:
            r0, c0, r1, c1 = r + 1, c_, r + 1, c_ + 1
        else:
            r0, c0, r1, c1 = r, c_, r + 1, c_
        f0, f1 = finite[r0, c0], finite[r1, c1]
        t = (level - f0) / (f1 - f0)
        key = (r0 * w + c0) * 2 + (r0 != r1)
        # back to the unpadded grid: subtract the pad
        return key, (c0 + t * (c1 - c0) - 1.0, r0 + t * (r1 - r0) - 1.0)

    mean = (finite[:-1, :-1] + finite[:-1, 1:] + finite[1:, 1:] + finite[1:, :-1]) / 4
    neighbours, where = {}, {}
    for r, c_ in zip(rows.tolist(), cols.tolist(), strict=True):
        k = int(case[r, c_])
        segs = (_SADDLE[k][0 if mean[r, c_] >= level else 1] if k in _SADDLE
                else _SEGMENTS[k])
        for e0, e1 in segs:
            k0, p0 = edge_point(r, c_, e0)
            k1, p1 = edge_point(r, c_, e1)
            where[k0], where[k1] = p0, p1
            neighbours.setdefault(k0, []).append(k1)
            neighbours.setdefault(k1, []).append(k0)
    lines, seen = [], set()
    for start in neighbours:
        if start in seen:
            continue
        line, prev, cur = [start], None, start
        seen.add(start)
        while True:
            nxt = [k for k in neighbours[cur] if k != prev]
            if not nxt or nxt[0] == start or nxt[0] in seen:
                break
            prev, cur = cur, nxt[0]
            seen.add(cur)
            line.append(cur)
        pts = np.array([where[k] for k in line])
        if polygon_area(pts) < 0:
            pts = pts[::-1]
        lines.append(pts)
    return sorted(lines, key=len, reverse=True)


def polygon_area(points):
    """Signed area (shoelace) of a closed polygon (n, 2), positive when it runs clockwise
    on screen (x right, y down)."""
    x, y = np.asarray(points, float).T
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
