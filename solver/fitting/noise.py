"""How well the landmarks and outlines were placed, estimated from the fit itself.

Real landmarks (an artist's clicks, a detector's points) sit several pixels from the model's
landmark vertices even on a perfect head, because a landmark's definition differs between
people, detectors and the model. A fit that assumed 1-px placement chases them and bends
the head. So the fit estimates the placement noise from its own residuals: one standard
deviation per view for each group of rows: the inner landmarks tied to their vertices, the
outline landmarks tied to theirs (a front photo's jaw and chin: where along the silhouette
they go is far less certain than an eye's corner), the landmarks on the head's outline
(their distance across it) and the traced outline
(variance components: the weighted squared residuals over the rows that the data, not
the fitted parameters, account for), with ``noise_px`` as the floor; and a Student-t weight per
landmark, so a misplaced one loses its weight on its own. The fit is repeated with these
weights until they settle. Everything else follows: the shape prior (lambda2 = 1 against
rows weighted 1 / sigma^2) then keeps a head that few or noisy landmarks describe near the
mean head.
"""

import functools
from dataclasses import dataclass, field

import numpy as np

#: Degrees of freedom of the Student-t placement error: heavy enough tails that a landmark
#: ten sigmas off keeps about 1 % of its weight.
STUDENT_NU = 5.0
#: The estimate is repeated until no sigma moves by more than this fraction.
SETTLED = 0.05
#: Most fits of one case (the first with the floor, then with the estimates).
MAX_ROUNDS = 4
#: Fewest outline rows below the neck's base that have a noise of their own (else they
#: count with the rest of the outline).
BODY_MIN_ROWS = 20
#: A landmark whose weight falls below this is reported as down-weighted (for Gaussian
#: placement about one in 10^5 landmarks falls this far by chance).
DOWN_WEIGHTED = 0.2


@dataclass
class Noise:
    """Placement noise of a case as estimated from a fit.

    Attributes
    ----------
    landmark_px : dict of str -> float
        Per view: standard deviation of a landmark coordinate, pixels.
    outline_px : dict of str -> float
        Per view with at least 3 landmarks on the head's outline (``outline_names``):
        standard deviation across the outline, pixels.
    outline_names : dict of str -> frozenset
        Per view: the landmarks whose residual was their distance across the outline.
    along_px : dict of str -> float
        Per view with at least 3 of them: standard deviation of where along the outline
        they were placed (from their vertices), pixels.
    contour_px : dict of str -> float
        Per view with a traced outline: standard deviation across the outline, pixels.
    body_px : dict of str -> float
        Per view with at least ``BODY_MIN_ROWS`` outline rows below the neck's base
        (``outline.body_vertices``): their standard deviation across the outline, pixels;
        at least ``contour_px``, and as many times it as their residuals are larger than
        the rest of the outline's (the floor, ``noise_px``, bounds the outline's, not this
        ratio: a photo's outline follows the head to a fraction of a pixel, and the body
        under clothes or a top coloured as skin is what departs from it).
    weights : dict of str -> dict of str -> float
        Per view and landmark: the Student-t weight (about 1 for a typical residual, up to
        (nu + 2) / nu for none, toward 0 for an outlier).
    floor_px : float
        The least noise assumed (``FitOptions.noise_px``).
    definition_m : dict of str -> float
        Per view with a landmark group of at least ``definition.MIN_GROUP`` points: the
        standard deviation of the offset a group shares there, metres
        (``definition.group_offsets``; the next fit's ``ViewData.definition_m``).
    rim_px : dict of str -> float
        Per view with at least 3 outline landmarks tied to their vertices (``rim_names``):
        standard deviation of their coordinates, pixels.
    rim_names : dict of str -> frozenset
        Per view: the outline landmarks tied to their vertices (``ViewData.outline_point``
        and not sliding) whose noise was estimated apart from the inner landmarks'.
    """

    landmark_px: dict = field(default_factory=dict)
    contour_px: dict = field(default_factory=dict)
    body_px: dict = field(default_factory=dict)
    weights: dict = field(default_factory=dict)
    floor_px: float = 1.0
    outline_px: dict = field(default_factory=dict)
    outline_names: dict = field(default_factory=dict)
    along_px: dict = field(default_factory=dict)
    definition_m: dict = field(default_factory=dict)
    rim_px: dict = field(default_factory=dict)
    rim_names: dict = field(default_factory=dict)

    def landmark_factor(self, view, name):
        """Multiplier of a landmark's weight (relative to 1 / floor^2): its Student-t
        precision, weight / scale^2 (1 for a landmark of a group without an estimate)."""
        if name in self.outline_names.get(view, ()):
            # too few on the outline for an estimate of their own: the view's landmarks'
            sigma = self.outline_px.get(view, self.landmark_px.get(view))
            return self._factor(sigma, 1) * self.weights.get(view, {}).get(name, 1.0)
        sigma = self.landmark_px.get(view)
        if name in self.rim_names.get(view, ()):
            sigma = self.rim_px.get(view, sigma)
        return self._factor(sigma, 2) * self.weights.get(view, {}).get(name, 1.0)

    def along_factor(self, view, name):
        """Multiplier of a sliding landmark's weight along the outline (relative to
        1 / floor^2; as :meth:`landmark_factor` for any other landmark)."""
        if name in self.outline_names.get(view, ()):
            return self._factor(self.along_px.get(view, self.landmark_px.get(view)), 1)
        return self.landmark_factor(view, name)

    def contour_factor(self, view):
        """Multiplier of a view's outline rows' weight (relative to 1 / floor^2)."""
        return self._factor(self.contour_px.get(view), 1)

    def body_factor(self, view):
        """Multiplier of the weight of a view's outline rows below the neck's base,
        relative to its other outline rows' (1 with too few of them for an estimate)."""
        body = self.body_px.get(view)
        return 1.0 if body is None else (self.contour_px[view] / body) ** 2

    def body_ratio(self):
        """How many times as uncertain as the rest of its outline a view's outline below
        the neck's base is, the largest over the views (1 without such an estimate)."""
        return max((b / self.contour_px[v] for v, b in self.body_px.items()), default=1.0)

    def _factor(self, sigma, dim):
        """(floor / Student-t scale)^2 of a group with Gaussian-equivalent ``sigma``."""
        if sigma is None:
            return 1.0
        return self.floor_px ** 2 / (sigma ** 2 * consistency(dim))

    def settled(self, other):
        """Whether every sigma of ``other`` is within SETTLED of this one's (the landmark
        groups' definition offsets too)."""
        for mine, theirs in ((self.landmark_px, other.landmark_px),
                             (self.outline_px, other.outline_px),
                             (self.along_px, other.along_px),
                             (self.contour_px, other.contour_px),
                             (self.body_px, other.body_px),
                             (self.rim_px, other.rim_px),
                             (self.definition_m, other.definition_m)):
            if set(mine) != set(theirs):
                return False
            for k, s in mine.items():
                if abs(np.log(theirs[k] / s)) > SETTLED:
                    return False
        return True

    def report(self):
        """JSON-ready summary: sigmas per view, every landmark's weight, and the landmarks
        that lost most of theirs."""
        return {"landmark_px": dict(self.landmark_px), "outline_px": dict(self.outline_px),
                "along_px": dict(self.along_px),
                "contour_px": dict(self.contour_px), "body_px": dict(self.body_px),
                "rim_px": dict(self.rim_px),
                "floor_px": self.floor_px,
                "definition_mm": {v: 1e3 * m for v, m in self.definition_m.items()},
                "weights": {v: dict(ws) for v, ws in self.weights.items()},
                "down_weighted": {v: {n: w for n, w in ws.items() if w < DOWN_WEIGHTED}
                                  for v, ws in self.weights.items()
                                  if any(w < DOWN_WEIGHTED for w in ws.values())}}


def estimate_noise(residuals, contour, effective, floor_px, along=None, definition=None,
                   rim=None, relative=None):
    """The placement noise a fit's residuals say.

    Parameters
    ----------
    residuals : dict of str -> ViewResidual
        Per view: the landmarks' residuals (pixel distances; across the head's outline for
        the names in ``outline``; those in ``unused`` are not counted).
    contour : dict of str -> (ndarray (m,), ndarray (m,) bool)
        Per view: the outline rows' residuals across the outline, pixels, and which rows
        meet the silhouette below the neck's base (``Joint.contour_residuals``).
    along : dict of str -> (list of str, ndarray (k,)), optional
        Per view: the sliding landmarks that met the outline and their residuals along
        it, pixels.
    effective : float
        Effective number of fitted parameters (the trace of the fit's hat matrix): the
        rows they account for are not counted as measurements of the noise.
    floor_px : float
    definition : dict of str -> float, optional
        Per view: the landmark groups' definition offset the residuals say, metres (kept
        as ``Noise.definition_m``).
    rim : dict of str -> set of str, optional
        Per view: the outline landmarks tied to their vertices; with at least 3 of them
        used their noise is a group of its own (``Noise.rim_px``).
    relative : dict of str -> dict of str -> float, optional
        Per view and landmark: its weight factor from its given uncertainty against the
        view's others (``views.uncertainty_factors``; 1 when missing). A landmark given
        twice as uncertain counts its residual at half its length: a group's noise is that
        of its typical landmark, and a landmark is an outlier against its own uncertainty.

    Returns
    -------
    Noise
    """
    out = Noise(floor_px=float(floor_px), definition_m=dict(definition or {}))
    # (view, names, residuals, dimension (2: at a vertex, 1: across), the Noise dict)
    groups = []
    for view, res in residuals.items():
        scale = (relative or {}).get(view, {})
        r = np.asarray(res.pixels, dtype=np.float64) \
            * np.sqrt([scale.get(n, 1.0) for n in res.names])
        skip, across = set(res.unused), set(res.outline)
        at_rim = set((rim or {}).get(view, ())) - across
        used = [i for i, n in enumerate(res.names) if n not in skip]
        rims = [i for i in used if res.names[i] in at_rim]
        if len(rims) < 3:
            rims = []  # too few for an estimate: with the inner landmarks
        else:
            out.rim_names[view] = frozenset(res.names[i] for i in rims)
        inner = [i for i in used if res.names[i] not in across and i not in rims]
        on = [i for i in used if res.names[i] in across]
        if on:
            out.outline_names[view] = frozenset(res.names[i] for i in on)
        for keep, dim, where, least in ((inner, 2, out.landmark_px, 1),
                                        (rims, 2, out.rim_px, 3),
                                        (on, 1, out.outline_px, 3)):
            if len(keep) >= least:
                groups.append((view, [res.names[i] for i in keep], r[keep], dim, where))
    along = {v: np.asarray(a[1], dtype=np.float64) for v, a in (along or {}).items()}
    n_rows = sum(g[3] * len(g[2]) for g in groups) \
        + sum(len(c) for c, _ in contour.values()) + sum(len(a) for a in along.values())
    # each group's variance from its own rows, inflated as all rows share the parameters
    inflate = n_rows / max(n_rows - effective, 0.5 * n_rows) if n_rows else 1.0
    for view, names, r, dim, where in groups:
        sigma, w = _student_t(r ** 2, dim, inflate, floor_px)
        where[view] = sigma
        out.weights.setdefault(view, {}).update(zip(names, w.tolist(), strict=True))
    for view, (c, body) in contour.items():
        c, body = np.asarray(c, dtype=np.float64), np.asarray(body, dtype=bool)
        apart = body.sum() >= BODY_MIN_ROWS and (~body).sum() >= 3
        head = c[~body] if apart else c
        if len(head) >= 3:
            out.contour_px[view] = _student_t(head ** 2, 1, inflate, floor_px)[0]
        if apart:
            # the body's departure from the head model, as a ratio of the two unfloored
            ratio = _student_t(c[body] ** 2, 1, inflate, 1e-6)[0] \
                / _student_t(head ** 2, 1, inflate, 1e-6)[0]
            out.body_px[view] = out.contour_px[view] * max(ratio, 1.0)
    for view, a in along.items():
        if len(a) >= 3:
            out.along_px[view] = _student_t(a ** 2, 1, inflate, floor_px)[0]
    return out


def _student_t(sq, dim, inflate, floor_px, iterations=20):
    """(sigma, weights) of residuals with squared lengths ``sq`` (n,) in ``dim`` dimensions
    under a Student-t error: the EM of its scale s (weights (nu + dim) / (nu + sq / s^2),
    s^2 the weighted mean square per coordinate), reported as the standard deviation a
    Gaussian error of that scale has (s / sqrt(consistency)), at least ``floor_px``."""
    c = consistency(dim)
    s2 = max(float(sq.mean()) / dim * inflate, c * floor_px ** 2)
    for _ in range(iterations):
        w = (STUDENT_NU + dim) / (STUDENT_NU + sq / s2)
        new = max(float((w * sq).sum() / (dim * len(sq))) * inflate, c * floor_px ** 2)
        done = abs(new - s2) <= 1e-6 * s2
        s2 = new
        if done:
            break
    return float(np.sqrt(s2 / c)), (STUDENT_NU + dim) / (STUDENT_NU + sq / s2)


@functools.cache
def consistency(dim):
    """s^2 / sigma^2 that the Student-t scale's EM reaches on Gaussian residuals of standard
    deviation sigma in ``dim`` dimensions (about 0.76 for 2-D, 0.73 for 1-D at nu = 5): what
    turns the scale into the noise's standard deviation."""
    # squared lengths q of standard-normal residuals and their probabilities, by Gauss
    # quadrature: for 1-D q = z^2 (Hermite), for 2-D q = 2 u with u exponential (Laguerre)
    if dim == 1:
        z, w = np.polynomial.hermite_e.hermegauss(80)
        q, w = z * z, w / np.sqrt(2.0 * np.pi)
    elif dim == 2:
        u, w = np.polynomial.laguerre.laggauss(80)
        q = 2.0 * u
    else:
        raise ValueError(f"dim: 1 or 2, got {dim!r}")
    nu = STUDENT_NU
    s2 = 1.0
    for _ in range(100):
        new = float(w @ ((nu + dim) * q / (nu + q / s2))) / dim
        if abs(new - s2) < 1e-12:
            break
        s2 = new
    return float(s2)
