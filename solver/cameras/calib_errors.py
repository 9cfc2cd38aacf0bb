"""Finding bad passpoints from residuals (seed 000 §5-6, Mössner 1992).

Seed 000 §5 lists three places where data errors show: (1) the passpoints' reprojection
residuals after calibrating each camera, (2) large residuals of the triangulation (eq. 16),
(3) reconstructing surveyed points seen in several views. §6 condenses the residuals into
three numbers: res1 (1-norm / count), res2 (2-norm / sqrt(count)) and resm (largest); "if
resm is clearly larger than res1 there is a data error".

Those norms say *that* something is wrong; to say *which* passpoint, each view is checked
point by point with leave-one-out predictions (the rule):

- calibrate the view without passpoint i (a DLT from the others) and predict where i
  should be; e_i = distance between that prediction and where i was placed (pixels);
- s_i = RMS scatter of the other points around that calibration, sqrt(SSR / dof) with
  dof = 2 (n - 1) - p, floored at ``floor_px`` (pixel reading is never better than that,
  and exact synthetic data would otherwise make every point stand out);
- score_i = e_i / s_i. The worst point is flagged when its score exceeds ``k`` (default 5:
  a correct point scores above 5 with probability about exp(-12.5) under Gaussian reading
  errors), then it is left out and the check repeats, so several bad points are found one
  by one and one bad point cannot hide behind the scatter it causes in the others.

Leaving the point out matters: fitted with the point, the calibration bends toward it, so
its own residual understates the error and its neighbours' overstate it.
"""

from dataclasses import dataclass, field

import numpy as np

from ..errors import as_points
from .dlt import MIN_POINTS, fit_dlt
from .triangulate import triangulate

#: leave-one-out needs this many degrees of freedom left (2 (n - 1) - p) to be meaningful
_MIN_DOF = 4


@dataclass
class ErrorNorms:
    """Seed 000 §6: res1 = sum|r| / N, res2 = sqrt(sum r^2) / sqrt(N), resm = max |r|.

    Attributes
    ----------
    res1, res2, resm : float
        In the residuals' unit (pixels or metres).
    count : int
        N, the residuals used (NaN ignored).
    """

    res1: float
    res2: float
    resm: float
    count: int

    def data_error_suspected(self, ratio=4.0):
        """True when resm > ratio * res1 (seed 000 §6: resm clearly above res1)."""
        return self.count > 0 and self.resm > ratio * self.res1


def error_norms(residuals):
    """res1, res2 and resm of residual lengths (seed 000 §6).

    Parameters
    ----------
    residuals : array_like, shape (...,) or (..., 2|3)
        Residual lengths, or residual vectors whose last axis holds the components (2 for
        pixels, 3 for points); NaN entries are ignored.

    Returns
    -------
    ErrorNorms
    """
    r = np.asarray(residuals, dtype=np.float64)
    if r.ndim >= 2 and r.shape[-1] in (2, 3):
        r = np.linalg.norm(r, axis=-1)
    r = np.abs(r[np.isfinite(r)])
    if r.size == 0:
        return ErrorNorms(0.0, 0.0, 0.0, 0)
    return ErrorNorms(float(r.sum() / r.size), float(np.sqrt((r * r).sum() / r.size)),
                      float(r.max()), int(r.size))


@dataclass
class Suspect:
    """A passpoint that stands out in one view (see the module docstring's rule).

    Attributes
    ----------
    view : str
    name : str
    index : int
        Row of the passpoint in the input arrays.
    residual : float, pixels
        Its reprojection residual in the calibration that includes it.
    predicted : float, pixels
        e_i: distance from where the other passpoints predict it.
    scatter : float, pixels
        s_i: the other passpoints' scatter (floored).
    score : float
        e_i / s_i.
    """

    view: str
    name: str
    index: int
    residual: float
    predicted: float
    scatter: float
    score: float

    @property
    def message(self):
        return (f"passpoint {self.name!r} in view {self.view!r} is {self.predicted:.1f} px "
                f"from where the other passpoints put it ({self.score:.1f} x their scatter "
                f"of {self.scatter:.2f} px): misplaced or mislabelled?")


@dataclass
class PasspointCheck:
    """Result of ``check_passpoints``.

    Attributes
    ----------
    fits : dict of str -> DLTFit
        Each view calibrated with all its passpoints.
    residuals : dict of str -> ndarray, shape (n,), pixels
        Residual length of every passpoint in that calibration (NaN where not seen).
    norms : ErrorNorms
        res1, res2, resm over all views (pixels).
    suspects : list of Suspect
        Flagged passpoints, in the order found (worst first within a view).
    cleaned : dict of str -> DLTFit
        Each view recalibrated without its suspects.
    cleaned_norms : ErrorNorms
    notes : list of str
        Views too small to check point by point, and the like.
    """

    fits: dict
    residuals: dict
    norms: ErrorNorms
    suspects: list
    cleaned: dict
    cleaned_norms: ErrorNorms
    notes: list = field(default_factory=list)

    @property
    def messages(self):
        """One line per suspect, then the notes."""
        return [s.message for s in self.suspects] + list(self.notes)


def check_passpoints(points, pixels, names=None, n_params=11, k=5.0, floor_px=0.25,
                     sizes=None):
    """Calibrate every view and name the passpoints that do not fit (seed 000 §5 (1), §6).

    Parameters
    ----------
    points : array_like, shape (n, 3), metres
        Surveyed passpoints.
    pixels : dict of str -> array_like, shape (n, 2), pixels
        Per view, where each passpoint is seen; NaN rows where a view does not see it.
    names : sequence of str, length n, optional
        Passpoint names for the messages (default "#0", "#1", ...).
    n_params : {11, 16}
    k : float
        Flag threshold on the leave-one-out score (module docstring).
    floor_px : float, pixels
        Lower bound on the scatter s_i.
    sizes : dict of str -> (int, int), optional
        Image sizes stored with the fitted cameras (default: the pixel extent).

    Returns
    -------
    PasspointCheck

    Raises
    ------
    ValueError
        Bad shapes, or a view the DLT cannot calibrate (message names the view).
    """
    x = as_points(points, "points")
    n = len(x)
    names = [f"#{i}" for i in range(n)] if names is None else [str(s) for s in names]
    if len(names) != n:
        raise ValueError(f"names: {len(names)} names for {n} points")
    if not isinstance(pixels, dict) or not pixels:
        raise ValueError("pixels: expected a dict view -> (n, 2) array")
    fits, resid, cleaned, suspects, notes = {}, {}, {}, [], []
    for view, px in pixels.items():
        q = np.asarray(px, dtype=np.float64)
        if q.shape != (n, 2):
            raise ValueError(f"pixels[{view!r}]: expected shape ({n}, 2), got {q.shape}")
        seen = np.isfinite(q).all(axis=1)
        qz = np.where(seen[:, None], q, 0.0)
        size = (sizes or {}).get(view)
        if size is None:
            size = (int(np.ceil(qz[:, 0].max())) + 1, int(np.ceil(qz[:, 1].max())) + 1)
        try:
            fit = fit_dlt(x, qz, size, n_params=n_params, weights=seen.astype(float))
        except ValueError as e:
            raise ValueError(f"view {view!r}: {e}") from None
        fits[view] = fit
        r = np.linalg.norm(fit.residuals, axis=1)
        resid[view] = np.where(seen, r, np.nan)
        found, note = _leave_one_out(view, x, qz, seen, names, fit, size, n_params, k,
                                     floor_px)
        suspects.extend(found)
        if note:
            notes.append(note)
        keep = seen.copy()
        keep[[s.index for s in found]] = False
        cleaned[view] = fit if not found else fit_dlt(x, qz, size, n_params=n_params,
                                                      weights=keep.astype(float))
    norms = error_norms(np.concatenate(list(resid.values())))
    clean_r = [np.where(_kept(v, suspects, pixels[v]), np.linalg.norm(f.residuals, axis=1),
                        np.nan) for v, f in cleaned.items()]
    clean_norms = error_norms(np.concatenate(clean_r))
    if norms.data_error_suspected() and not suspects:
        notes.append(f"resm {norms.resm:.2f} px is more than 4 x res1 {norms.res1:.2f} px "
                     "(seed 000 §6): a data error is likely, but no single passpoint "
                     "stands out")
    return PasspointCheck(fits, resid, norms, suspects, cleaned, clean_norms, notes)


def _kept(view, suspects, px):
    q = np.asarray(px, dtype=np.float64)
    keep = np.isfinite(q).all(axis=1)
    keep[[s.index for s in suspects if s.view == view]] = False
    return keep


def _leave_one_out(view, x, q, seen, names, fit, size, n_params, k, floor_px):
    """Flag passpoints of one view one at a time (module docstring)."""
    p = fit.n_params
    active = seen.copy()
    found = []
    full_res = np.linalg.norm(fit.residuals, axis=1)
    while True:
        idx = np.flatnonzero(active)
        dof = 2 * (len(idx) - 1) - p
        if dof < _MIN_DOF or len(idx) - 1 < MIN_POINTS[p]:
            note = ""
            if not found:
                need = -(-(p + _MIN_DOF) // 2) + 1
                note = (f"view {view!r}: {len(idx)} passpoints are too few to single out a "
                        f"bad one (need {need} for the {p}-parameter DLT)")
            return found, note
        best = None
        for i in idx:
            w = active.astype(float)
            w[i] = 0.0
            try:
                f = fit_dlt(x, q, size, n_params=n_params, weights=w)
            except ValueError:
                continue  # without i the rest is degenerate: i cannot be judged alone
            r = np.linalg.norm(f.residuals, axis=1)
            others = active.copy()
            others[i] = False
            s = max(np.sqrt((r[others] ** 2).sum() / (2 * others.sum() - f.n_params)),
                    floor_px)
            score = r[i] / s
            if best is None or score > best.score:
                best = Suspect(view, names[i], int(i), float(full_res[i]), float(r[i]),
                               float(s), float(score))
        if best is None or best.score <= k:
            return found, ""
        found.append(best)
        active[best.index] = False


@dataclass
class ReconstructionCheck:
    """Result of ``check_reconstruction`` (seed 000 §5 (3)).

    Attributes
    ----------
    errors : ndarray, shape (n, 3), metres
        Triangulated minus surveyed position (NaN where fewer than 2 views see a point).
    norms : ErrorNorms
        res1, res2, resm of the error lengths (metres).
    worst : list of (str, float)
        Passpoint names with their error length, largest first.
    """

    errors: np.ndarray
    norms: ErrorNorms
    worst: list


def check_reconstruction(cameras, points, pixels, names=None):
    """Triangulate surveyed points seen in several views and compare (seed 000 §5 (3)).

    Parameters
    ----------
    cameras : sequence of DLTCamera, length m
    points : array_like, shape (n, 3), metres
        Surveyed positions.
    pixels : array_like, shape (m, n, 2), pixels
        NaN rows where a view does not see a point.
    names : sequence of str, length n, optional

    Returns
    -------
    ReconstructionCheck
    """
    x = as_points(points, "points")
    names = [f"#{i}" for i in range(len(x))] if names is None else [str(s) for s in names]
    t = triangulate(cameras, pixels)
    err = t.points - x
    length = np.linalg.norm(err, axis=1)
    order = [int(i) for i in np.argsort(-np.nan_to_num(length, nan=-1.0))
             if np.isfinite(length[i])]
    return ReconstructionCheck(err, error_norms(length),
                               [(names[i], float(length[i])) for i in order])
