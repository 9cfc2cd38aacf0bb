"""Landmark definition offsets: the landmarks of one group (an eye, a brow, one side of the
jaw) as a person or a detector places them sit off the model's landmark vertices together,
because where "the brow" or "the jaw line" lies is a convention that differs between people,
detectors and the model. Independent noise per point would make such a shared shift look
like ten consistent measurements of the head's shape; ``GroupedImageRows`` gives each group
a shared offset per photo with its own prior instead (marginalised in closed form), so the
shape follows what the points say relative to each other and only partly their common shift.
"""

import numpy as np

from ..cameras import OrthographicCamera
from .noise import STUDENT_NU
from .rows import ImageRows, ScalarRows, _projected


def group_terms(labels, weights, jac, sigma_m):
    """What a point's group shares: ``t`` (n,), the offset's variance over the noise's for
    the group's mean (``sigma_G^2 * sum_G w``, ``sigma_G`` in pixels through the
    Jacobians ``jac`` (n, 2, 3), pixels per metre), and each point's share ``u`` (n,) of
    its group's weight (``w / sum_G w``; 0 in a group of weight 0): the group's weighted
    mean of a per-point value is ``group_means(labels, u, value)``.

    ``labels`` (n,) are 0 .. G-1 (``np.unique(..., return_inverse=True)``): sums per group
    are bincounts, no (n, n) membership matrix."""
    w = np.asarray(weights, dtype=np.float64)
    wsum = np.bincount(labels, weights=w)[labels]
    safe = np.where(wsum > 0, wsum, 1.0)
    px_per_m2 = 0.5 * (np.asarray(jac) ** 2).sum(axis=(1, 2))
    sig2 = np.broadcast_to(np.asarray(sigma_m, dtype=np.float64) ** 2, w.shape)
    scale2 = np.bincount(labels, weights=w * px_per_m2 * sig2)[labels] / safe
    return np.where(wsum > 0, scale2 * wsum, 0.0), w / safe


def group_means(labels, u, values):
    """Each point's group mean of ``values`` (n, d) weighted by the shares ``u`` (n,)
    (:func:`group_terms`), shape (n, d)."""
    v = np.asarray(values, dtype=np.float64)
    sums = np.stack([np.bincount(labels, weights=u * v[:, a]) for a in range(v.shape[1])],
                    axis=1)
    return sums[labels]


#: How much larger the offset of a group of outline points (the jaw, the chin: a front
#: photo's outline, ``ViewData.outline_point``) is than an inner group's: where along
#: the silhouette and how high on the jaw such a point goes is less agreed on than where an
#: eye's corner is (measured: docs/DECISIONS.md).
OUTLINE_DEFINITION = 3.0

#: Reweighting steps of a group's offset against a misplaced point of it (Student-t, with
#: the placement noise's degrees of freedom).
ROBUST_STEPS = 5

#: Groups with fewer used points than this do not count in the estimate of the offsets'
#: size: one point cannot tell its group's offset from its own noise.
MIN_GROUP = 3

#: The ratios of the offsets' size to the size assumed that ``group_offsets`` looks among:
#: at least 2 %, so a view keeps its groups for the next round to measure again, at most 4
#: times (``FitOptions.definition_mm`` caps the size).
RATIO_GRID = np.geomspace(0.02, 4.0, 240)


def definition_sigmas(view):
    """Each landmark's group offset standard deviation in a view (``ViewData``), metres:
    the view's ``definition_m``, ``OUTLINE_DEFINITION`` times that for outline points."""
    return view.definition_m * np.where(view.outline_point, OUTLINE_DEFINITION, 1.0)


def group_offsets(residuals, groups, weights, jac, sigma_m, detected=False):
    """The offsets the landmark groups of one photo most likely share, given the fit's
    residuals, and what they say about the offsets' size.

    Parameters
    ----------
    residuals : ndarray, shape (n, 2), pixels (placed - projected)
    groups : sequence, shape (n,)
    weights : ndarray, shape (n,)
        1 / noise^2 of each point (0: not used).
    jac : ndarray, shape (n, 2, 3)
        The camera's Jacobians at the points, pixels per metre.
    sigma_m : float or ndarray, shape (n,)
        The offsets' standard deviation the fit assumed, metres (per point: its group's).
    detected : bool
        The points came with uncertainties of their own (a detector's): the head takes up
        much of their groups' offsets before the residuals can show them, so ``ratio`` is
        one EM step of the variance component (the squared posterior offset plus its
        posterior variance, over the variance assumed), which falls from the start by
        15-35 % a round; else the residuals' maximum likelihood (docs/DECISIONS.md).

    Returns
    -------
    offsets : ndarray, shape (n, 2), pixels
        Posterior mean of each point's group offset: the noise is measured on the
        residuals less these.
    taken : float
        The parameters they take up (trace of their hat matrix, about two per group).
    ratio : float or None
        How many times ``sigma_m`` the residuals say the offsets are, over the groups of at
        least ``MIN_GROUP`` points: by type-II maximum likelihood (each group's weighted
        mean residual ~ N(0, ratio^2 sigma_G^2 + 1 / sum_G w) per axis; on ``RATIO_GRID``),
        or for ``detected`` points the EM step; None without such a group.
    """
    _, labels = np.unique(np.asarray(groups), return_inverse=True)
    w = np.asarray(weights, dtype=np.float64)
    r = np.asarray(residuals, dtype=np.float64)
    # A misplaced point must not drag its group's offset (its neighbours would then look
    # misplaced too): the offset is a Student-t mean of the group, its points reweighted
    # by how far each sits from it against the photo's typical distance.
    robust = np.ones_like(w)
    for step in range(ROBUST_STEPS):
        t, u = group_terms(labels, w * robust, jac, sigma_m)
        gain = t / (1.0 + t)
        mean = group_means(labels, u, r)  # (n, 2) each point's group's mean residual
        e = gain[:, None] * mean
        if step == ROBUST_STEPS - 1:
            break  # the offsets, their terms and weights from one and the same step
        sq = ((r - e) ** 2).sum(axis=1)
        typical = float(np.median(sq[w > 0])) if np.any(w > 0) else 0.0
        if not typical > 0:
            break
        robust = (STUDENT_NU + 2.0) / (STUDENT_NU + sq / typical)
    first = np.unique(labels, return_index=True)[1]
    used = np.bincount(labels, weights=(w > 0).astype(float))[labels[first]]
    big = first[used >= MIN_GROUP]
    ratio = None
    if len(big) and np.any(sigma_m):
        # per group: sigma_G^2 (px^2) = t / sum w; posterior variance sigma_G^2 / (1 + t)
        wsum = np.bincount(labels, weights=w * robust)[labels[big]]
        s2_px = t[big] / wsum
        ok = s2_px > 0
        if ok.any() and detected:
            rho = ((e[big] ** 2).sum(axis=1) / 2.0 + s2_px / (1.0 + t[big]))[ok] / s2_px[ok]
            ratio = float(np.sqrt(rho.mean()))
        elif ok.any():
            m2 = (mean[big] ** 2).sum(axis=1)[ok]
            var = RATIO_GRID[:, None] ** 2 * s2_px[ok] + 1.0 / wsum[ok]  # (grid, groups)
            loglik = -(np.log(var) + m2 / (2.0 * var)).sum(axis=1)
            ratio = float(RATIO_GRID[int(np.argmax(loglik))])
    return e, float(2.0 * gain[first].sum()), ratio


class GroupedImageRows(ImageRows):
    """Image rows of landmarks whose errors share one offset per group and image axis.

    The error of landmark i of group G is ``e_G + n_i``: ``n_i`` independent with the rows'
    weight ``w_i`` (1 / noise^2), ``e_G`` a shared 2-D offset ~ N(0, sigma_G^2) per axis,
    ``sigma_G`` the definition offset ``sigma_m`` seen through the camera (pixels per metre
    at the group's points). Marginalising ``e_G`` whitens the group's residuals per axis:
    ``r_i - beta_G * mean_w(r)`` with the weights kept, ``beta_G = 1 - 1 / sqrt(1 +
    sigma_G^2 * sum_G w)`` (Sherman-Morrison).

    The block gives the same normal equations in a cheaper form: each point's plain row,
    and one row per group and axis on the group's weighted mean ``mean_w(r)`` with the
    negative weight ``-(2 beta_G - beta_G^2) sum_G w`` (``ScalarRows.mix``), since
    ``sum_G w_i (r_i - beta mean)^2 = sum_G w_i r_i^2 - (2 beta - beta^2) sum_G w mean^2``.
    Whitened, every row would depend on all vertices of its group (docs/DECISIONS.md).

    Parameters
    ----------
    vertices, pixels, camera, weights, name
        As :class:`ImageRows`.
    groups : array_like of int, shape (n,)
        Group label of each point (points of one label share the offset).
    sigma_m : float or array_like, shape (n,)
        The shared offset's standard deviation, metres (0: plain ``ImageRows``); per
        point, the group's (its points' mean square, weighted).
    """

    def __init__(self, vertices, pixels, camera, groups, sigma_m, weights=1.0,
                 name="image"):
        super().__init__(vertices, pixels, camera, weights=weights, name=name)
        g = np.asarray(groups)
        if g.shape != (len(self.vertices),):
            raise ValueError(f"{name}: groups must have shape ({len(self.vertices)},), "
                             f"got {g.shape}")
        _, self.labels = np.unique(g, return_inverse=True)
        self.sigma_m = np.asarray(sigma_m, dtype=np.float64) if np.ndim(sigma_m) \
            else float(sigma_m)
        if not np.all(np.asarray(self.sigma_m) >= 0.0):
            raise ValueError(f"{name}: sigma_m must be >= 0, got {sigma_m!r}")
        # The mean rows' pattern (fixed with the groups and weights): a (2G, 2n) matrix
        # whose row 2g + a takes the weighted mean of group g's rows of axis a.
        n_groups = int(self.labels.max()) + 1 if len(self.labels) else 0
        _, self._share = group_terms(self.labels, self.weights, np.zeros((len(g), 2, 3)),
                                     0.0)
        mix = np.zeros((n_groups, 2, len(g), 2))
        for a in range(2):
            mix[self.labels, a, np.arange(len(g)), a] = self._share
        self._mix = mix.reshape(2 * n_groups, 2 * len(g))
        self._wsum = np.bincount(self.labels, weights=self.weights, minlength=n_groups)
        self._first = np.unique(self.labels, return_index=True)[1]  # a point of each group
        self._shrunk = None  # (orthographic camera, its shrink())

    def shrink(self, jac):
        """(beta per point (n,), each point's share of its group's weight (n,)) at the
        camera's Jacobians ``jac`` (n, 2, 3): see :func:`group_terms`."""
        t, u = group_terms(self.labels, self.weights, jac, self.sigma_m)
        return 1.0 - 1.0 / np.sqrt(1.0 + t), u

    def block(self, world, jacobian=True):
        if not np.any(self.sigma_m):
            return super().block(world, jacobian)
        w = self.weights
        n = len(w)
        r = self.pixels - _projected(self.camera, world, self.name, self.vertices)
        ortho = isinstance(self.camera, OrthographicCamera)
        # an orthographic camera's Jacobians do not depend on the head: its shrink once per
        # camera, and a cost (no Jacobian asked for) then needs none
        known = ortho and self._shrunk is not None and self._shrunk[0] is self.camera
        if jacobian or not known:
            jac = np.asarray(self.camera.jacobian(world), dtype=np.float64).reshape(n, 2, 3)
        if not ortho:
            beta, u = self.shrink(jac)
        else:
            if not known:
                self._shrunk = (self.camera, self.shrink(jac))
            beta, u = self._shrunk[1]
        mean = group_means(self.labels, u, r)  # (n, 2) each point's group mean
        rw = r - beta[:, None] * mean  # (n, 2) whitened residuals
        sq = float(w @ np.einsum("ij,ij->i", rw, rw))
        nrows = 2 * int((w > 0).sum())
        if not jacobian:
            return ScalarRows(None, None, None, None, sq, float(w.sum()), nrows)
        first = self._first
        b = beta[first]
        mix_w = np.repeat(-(2.0 * b - b * b) * self._wsum, 2)
        return ScalarRows(np.repeat(np.arange(n), 2), jac.reshape(2 * n, 3), r.reshape(-1),
                          np.repeat(w, 2), sq, float(w.sum()), nrows, mix=self._mix,
                          mix_r=mean[first].reshape(-1), mix_w=mix_w)
