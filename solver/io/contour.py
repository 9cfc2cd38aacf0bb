"""Traced outlines as the fit can use them: a size limit a file must keep, a fast check of
a well-formed contour, and thinning a dense one.

The fit weighs a traced point by the outline it stands for, up to ``SPACING_PX`` of it
(``ContourRows``): points closer together share one point's weight, so a contour traced
every pixel tells the fit no more than one every few pixels and costs a row per point.
"""

import numpy as np

#: Most points one contour may have. A head's outline is at most a few thousand pixels
#: long even on a large photo; a contour of more points is not a traced outline.
MAX_CONTOUR_POINTS = 20_000
#: Outline length per point at which the fit gives a point its full weight (pixels).
SPACING_PX = 6.0
#: Thinning keeps a point per this much outline (pixels): three per full weight.
THIN_SPACING_PX = 2.0


def contour_array(value):
    """A contour as the file gives it, as (n, 2) float64, or None when it is not a list of
    [u, v] pairs of JSON numbers (left to the schema, which names the bad item)."""
    if not isinstance(value, list) or not all(
            isinstance(p, list) and len(p) == 2
            and all(isinstance(c, int | float) and not isinstance(c, bool) for c in p)
            for p in value):
        return None
    return np.array(value, dtype=np.float64).reshape(-1, 2)


def size_problem(n):
    """The message for a contour of ``n`` points over ``MAX_CONTOUR_POINTS``, or None."""
    if n <= MAX_CONTOUR_POINTS:
        return None
    return (f"{n} points; at most {MAX_CONTOUR_POINTS} are read (the fit uses one per "
            f"{THIN_SPACING_PX:g} px of outline)")


def thin_contour(points, spacing_px=THIN_SPACING_PX):
    """The points of a contour at least ``spacing_px`` from the point kept before them
    (the first and the last point always kept), in drawing order. Thinning again keeps
    them all. One pass over at most ``MAX_CONTOUR_POINTS`` points, once per fit.

    Parameters
    ----------
    points : ndarray, shape (n, 2), pixels
    spacing_px : float

    Returns
    -------
    ndarray, shape (m, 2), m <= n
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(p) < 3:
        return p
    keep, last = [0], p[0]
    for i, q in enumerate(p[1:-1].tolist(), start=1):
        if (q[0] - last[0]) ** 2 + (q[1] - last[1]) ** 2 >= spacing_px * spacing_px:
            keep.append(i)
            last = q
    keep.append(len(p) - 1)
    return p[keep]


def thin_case_contours(case, spacing_px=THIN_SPACING_PX):
    """Thin every contour of ``case`` in place (``thin_contour``) and say so.

    Returns
    -------
    list of str
        One notice per thinned contour, naming the file and view.
    """
    notes = []
    for name, view in case.views.items():
        if view.contour is None:
            continue
        thin = thin_contour(view.contour, spacing_px)
        if len(thin) < len(view.contour):
            notes.append(f"{case.source}: views.{name}.contour: {len(view.contour)} points "
                         f"thinned to {len(thin)} for the fit (one per {spacing_px:g} px of "
                         f"outline; the fit weighs points closer than {SPACING_PX:g} px as "
                         "one)")
            view.contour = thin
    return notes
