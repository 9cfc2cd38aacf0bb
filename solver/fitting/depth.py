"""The detector's depth of mirror pairs of landmarks: how the head is turned in a photo.

A face mesh detector estimates each point's depth toward the camera as well as its place
in the photo (``View.depth``, pixels). On the rendered sample its depth follows the true
head's to a correlation of 0.993, and the depth difference of a mirror pair (the two outer
eye corners) is the head's turn about the photo's vertical axis seen across the pair's
width, which the points' pixels hardly show: a fit of detected points alone turns a front
photo's head several degrees off. Held as rows, one per mirror pair of points with a depth
(neither an outline point), these keep the turn (and the face's left-right depth) the
detector saw. In orthographic photos, and in perspective ones whose camera's turn the
joint step moves as the rigid motion it is (``Camera.moves_rigidly``: a pinhole camera;
a DLT's modes move its points across the image only, so rows on depth there would not
see its turn).
"""

import numpy as np

from ..cameras.mirror import mirror_name
from .rows import CameraRows, ScalarRows

#: A point's depth standard deviation as a share of its placement uncertainty (both px):
#: the mirror pairs' depth differences are 3.9 px RMS off the real scan's surface for
#: points uncertain by 3.8-8.5 px (0.6; 0.2 on the rendered sample; docs/DECISIONS.md).
DEPTH_SHARE = 0.7


def mirror_pairs(names, usable):
    """Index pairs (i, j), (m, 2), of landmarks ``names`` that are a subject's right one
    and its left counterpart (``mirror_name``), both ``usable`` (n,) bool."""
    at = {n: i for i, n in enumerate(names)}
    pairs = [(i, at[mirror_name(n)]) for i, n in enumerate(names)
             if "right" in n.split("_") and mirror_name(n) in at]
    return np.array([(i, j) for i, j in pairs if usable[i] and usable[j]],
                    dtype=np.intp).reshape(-1, 2)


class DepthPairRows(CameraRows):
    """One row per mirror pair (a, b): the depth of b less that of a toward the camera,
    pixels, against the detector's. The prediction is ``k n . (x_b - x_a)`` with ``n`` the
    camera's depth axis (``Camera.depth_axis``) and ``k`` its pixels per metre, both the
    pair's mean (exact for an orthographic camera).

    Parameters
    ----------
    vertices : array_like of int, shape (n,)
        The copies of the view's landmarks (those of its landmark rows).
    pairs : ndarray of int, shape (m, 2)
        Positions in ``vertices`` of each pair's right and left point.
    observed : ndarray, shape (m,)
        The detector's depth differences, left less right, px.
    camera : Camera
    weights : ndarray, shape (m,)
        1 / variance of each difference, px^-2.
    name : str
    """

    def __init__(self, vertices, pairs, observed, camera, weights, name="depth"):
        self.vertices = np.asarray(vertices, dtype=np.intp)
        self.pairs = np.asarray(pairs, dtype=np.intp).reshape(-1, 2)
        self.observed = np.asarray(observed, dtype=np.float64).reshape(-1)
        self.weights = np.asarray(weights, dtype=np.float64).reshape(-1)
        if not len(self.pairs) == len(self.observed) == len(self.weights):
            raise ValueError(f"{name}: pairs, observed and weights must have one entry a pair")
        self.camera = camera
        self.name = name

    def _terms(self, world):
        """(d(depth px)/d(position) of each pair (m, 3), observed less predicted depth
        differences (m,) px)."""
        a, b = self.pairs[:, 0], self.pairs[:, 1]
        ends = world[np.concatenate([a, b])]
        toward = np.asarray(self.camera.depth_axis(ends), dtype=np.float64)
        g = self.camera.pixels_per_metre(ends)[:, None] * toward
        g = 0.5 * (g[:len(a)] + g[len(a):])
        return g, self.observed - np.einsum("ij,ij->i", g, world[b] - world[a])

    def residuals(self, world):
        """Observed less predicted depth differences, (m,) px."""
        return self._terms(world)[1]

    def block(self, world, jacobian=True):
        g, r = self._terms(world)
        w = self.weights
        sq = float(w @ r ** 2)
        if not jacobian:
            return ScalarRows(None, None, None, None, sq, float(w.sum()), len(r))
        return ScalarRows(self.pairs, np.stack([-g, g], axis=1), r, w, sq, float(w.sum()),
                          len(r))


def depth_rows(view, start, views=()):
    """The depth rows of ``view`` (``ViewData``) on its landmark copies from ``start``, or
    None: a mirror view or a view whose camera mirror views among ``views`` share (their
    copies are reflected, so the joint step lifts that camera's modes across the image
    only), a camera whose turn the joint step does not move rigidly (a DLT), or no mirror
    pair with depths (outline points left out: their vertices are not where an outline
    point lies)."""
    cam = view.camera
    if cam is None or view.depth is None or view.mirror_of is not None \
            or (cam.perspective and not cam.moves_rigidly) \
            or any(u.mirror_of == view.name for u in views):
        return None
    usable = np.isfinite(view.depth) & np.isfinite(view.depth_sigma) & ~view.outline_point
    pairs = mirror_pairs(view.names, usable)
    if not len(pairs):
        return None
    a, b = pairs[:, 0], pairs[:, 1]
    var = view.depth_sigma[a] ** 2 + view.depth_sigma[b] ** 2
    return DepthPairRows(np.arange(start, start + len(view.names)), pairs,
                         view.depth[b] - view.depth[a], cam, 1.0 / var,
                         name=f"depth {view.name}")
