"""Fit the head model to landmarks on a front and a profile photo (thesis §4.4, §9).

Every approach starts with the profile-line fit (§4.4.1): first the side camera's 2-D
similarity alone (the similarity-only ICP: in a profile photo that is the head's scale,
rotation in the sagittal plane and position), then with the shape, against the traced
outline (the model's midsagittal ``profile_chain``, closest points in the image, a
distance threshold) and the side landmarks. Then:

- approach 1 (§4.4.2): all landmarks as image rows through their cameras, so a front
  landmark contributes its two known coordinates only, the front rows weighted;
- approach 2 (§4.4.3): TPS-ICP: warp the fitted head with a thin-plate spline so its
  landmark vertices reach 3-D targets (each landmark moved within the image plane of every
  photo that shows it: the profile gives depth, the front x and z), fit the model to the
  warped head (all skin vertices, landmarks weighted), repeat while the error falls;
- combined (the thesis' outlook, §9): both, keeping the one whose landmarks and contour
  reproject better, the smaller shape prior breaking near ties.

Cameras: each photo keeps its own camera, refitted to the head between shape-ICP solves
(``Camera.refit``); see ``solver/fit_engine.py`` for the alternation and the gauge (head
scale 1 and translation 0 when every camera is refitted).
"""

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from .cameras import Camera
from .fit_engine import (MIN_VIEW_LANDMARKS, Engine, State, ViewData, densify,
                         is_side_camera)
from .landmarks_file import LandmarkCase, LandmarkSet
from .linear_model import concat
from .result import FitResult, ViewResidual
from .shape_icp import PointRows
from .tps import ThinPlateSpline

METHODS = ("combined", "approach1", "approach2")


@dataclass
class FitOptions:
    """How to fit. The defaults are what the benchmark (``bench/bench_fit.py``) measured.

    Attributes
    ----------
    method : {"combined", "approach1", "approach2"}
    n_identity : int
        Global identity components fitted (the first ones; at most the model's 100).
    n_regional : int
        Components per region of the regional model (0: global model only).
    lambda1 : float
        Weight of the region-border smoothness rows Gamma, per millimetre of disagreement
        (used with ``n_regional > 0``).
    lambda2 : float
        Weight of the shape prior Lambda; 1 is the Bayesian prior for landmarks with
        ``noise_px`` noise.
    prior : {"eigen", "identity"}
        "eigen": penalise coefficients in standard deviations (Mahalanobis); "identity":
        the thesis' ``w I`` on raw eigenvector weights (metres of displacement).
    landmark_weight : float
        Weight of every landmark row relative to the prior.
    front_weight : float
        Extra weight of landmarks in front(-like) photos (thesis §4.4.2: the profile has
        more rows).
    exact_landmarks : bool
        Add the thin-plate-spline remainder that makes every landmark hit exactly
        (``FitResult.detail``).
    max_iterations : int
        Most rounds of each alternation (shape-ICP steps + camera refits).
    tolerance : float
        Stop an alternation when its cost falls by less than this fraction per round.
    progress : callable(fraction, message) or None
    noise_px : float
        Standard deviation of landmark placement the weights assume, pixels.
    contour_weight : float
        Weight of one profile-chain correspondence relative to one landmark.
    contour_threshold_px : float
        Contour correspondences farther than this are dropped (thesis §4.4.1).
    landmark_weights : dict of str -> float, optional
        Per-landmark weight factors (canonical names or ibugNN), e.g. 0 to ignore one.
    fixed_cameras : tuple of str
        Views whose camera is kept as given (calibrated); the others are refitted.
    flag_sigmas : float
        A landmark is flagged when its residual exceeds the mean plus this many standard
        deviations of all the others' residuals ...
    flag_min_px : float
        ... and this many pixels (so noise alone rarely flags).
    tps_iterations : int
        Most TPS-ICP rounds of approach 2.
    """

    method: str = "combined"
    n_identity: int = 100
    n_regional: int = 0
    lambda1: float = 1.0
    lambda2: float = 1.0
    prior: str = "eigen"
    landmark_weight: float = 1.0
    front_weight: float = 1.0
    exact_landmarks: bool = False
    max_iterations: int = 40
    tolerance: float = 1e-4
    progress: Callable | None = None
    noise_px: float = 1.0
    contour_weight: float = 0.5
    contour_threshold_px: float = 20.0
    landmark_weights: dict | None = None
    fixed_cameras: tuple = ()
    flag_sigmas: float = 3.0
    flag_min_px: float = 5.0
    tps_iterations: int = 8


# ----------------------------------------------------------------------------- input


def _check_options(options, model):
    o = FitOptions() if options is None else options
    if not isinstance(o, FitOptions):
        raise ValueError(f"options: expected FitOptions, got {type(o).__name__}")
    if o.method not in METHODS:
        raise ValueError(f"options.method: {o.method!r}; use one of {', '.join(METHODS)}")
    k = model.identity.n_coeffs
    if isinstance(o.n_identity, bool) or not isinstance(o.n_identity, int | np.integer) \
            or not 0 <= o.n_identity <= k:
        raise ValueError(f"options.n_identity: must be an integer in 0..{k}, "
                         f"got {o.n_identity!r}")
    if isinstance(o.n_regional, bool) or not isinstance(o.n_regional, int | np.integer) \
            or o.n_regional < 0:
        raise ValueError(f"options.n_regional: must be an integer >= 0, got {o.n_regional!r}")
    if o.n_identity == 0 and o.n_regional == 0:
        raise ValueError("options.n_identity, options.n_regional: both 0 leave no shape to "
                         "fit")
    for name in ("lambda1", "lambda2", "landmark_weight", "front_weight", "contour_weight",
                 "flag_sigmas", "flag_min_px"):
        val = getattr(o, name)
        if not isinstance(val, int | float) or not np.isfinite(val) or val < 0:
            raise ValueError(f"options.{name}: must be a finite number >= 0, got {val!r}")
    for name in ("noise_px", "contour_threshold_px", "tolerance"):
        val = getattr(o, name)
        if not isinstance(val, int | float) or not np.isfinite(val) or val <= 0:
            raise ValueError(f"options.{name}: must be a finite number > 0, got {val!r}")
    if o.prior not in ("eigen", "identity"):
        raise ValueError(f"options.prior: {o.prior!r}; use 'eigen' or 'identity'")
    for name in ("max_iterations", "tps_iterations"):
        val = getattr(o, name)
        if isinstance(val, bool) or not isinstance(val, int | np.integer) or val < 1:
            raise ValueError(f"options.{name}: must be an integer >= 1, got {val!r}")
    if o.progress is not None and not callable(o.progress):
        raise ValueError("options.progress: must be callable(fraction, message) or None")
    return o


def _linear_model(model, opts):
    parts = []
    if opts.n_identity > 0:
        parts.append(model.identity.first(int(opts.n_identity)))
    if opts.n_regional > 0:
        parts.append(model.regional(int(opts.n_regional)))
    lin = parts[0] if len(parts) == 1 else concat(parts[0], parts[1])
    return lin


def _prepare_views(model, case, opts):
    """The case's views as ``ViewData``; every problem is a ValueError naming the view or
    landmark."""
    if not isinstance(case, LandmarkCase):
        raise ValueError(f"case: expected a LandmarkCase, got {type(case).__name__}")
    if not case.views:
        raise ValueError(f"{case.source}: the case has no views")
    lms = LandmarkSet.from_dict({"format": "headrecon-landmark-set",
                                 "landmarks": list(model.landmark_info)}, "<model>")
    weights = dict(opts.landmark_weights or {})
    for key, val in weights.items():
        if lms.canonical(key) is None:
            raise ValueError(f"options.landmark_weights: unknown landmark {key!r}"
                             f"{lms.suggestion(key)}")
        if not isinstance(val, int | float) or not np.isfinite(val) or val < 0:
            raise ValueError(f"options.landmark_weights[{key!r}]: must be a finite number "
                             f">= 0, got {val!r}")
    weights = {lms.canonical(k): float(v) for k, v in weights.items()}
    fixed = set(opts.fixed_cameras)
    unknown = fixed - set(case.views)
    if unknown:
        raise ValueError(f"options.fixed_cameras: no view named {sorted(unknown)[0]!r} "
                         f"(views: {', '.join(case.views)})")
    n_vertices = model.n_vertices
    views = []
    for name, view in case.views.items():
        where = f"{case.source}: view {name!r}"
        cam = view.camera
        if not isinstance(cam, Camera):
            raise ValueError(f"{where}: camera of unknown kind ({type(cam).__name__}); "
                             "expected a solver.cameras.Camera")
        names, verts, px = [], [], []
        for key, uv in view.points.items():
            canon = lms.canonical(key)
            if canon is None:
                raise ValueError(f"{where}: unknown landmark {key!r}{lms.suggestion(key)}")
            uv = np.asarray(uv, dtype=np.float64).reshape(-1)
            if uv.shape != (2,) or not np.isfinite(uv).all():
                raise ValueError(f"{where}: landmark {key!r}: expected two finite pixel "
                                 f"coordinates, got {uv.tolist()}")
            vtx = lms.vertices[canon]
            if not 0 <= vtx < n_vertices:
                raise ValueError(f"{where}: landmark {key!r}: vertex {vtx} is not in the "
                                 "model")
            names.append(canon)
            verts.append(vtx)
            px.append(uv)
        w = opts.landmark_weight * np.array([weights.get(n, 1.0) for n in names])
        used = int(np.count_nonzero(w))
        refit = name not in fixed
        need = max(MIN_VIEW_LANDMARKS, cam.min_refit_points if refit else 1)
        if used < need:
            raise ValueError(f"{where}: {used} usable landmark{'s' * (used != 1)}; the fit "
                             f"needs at least {need} in this view ({need - used} more)")
        contour = None
        side = is_side_camera(cam)
        if view.contour is not None and len(view.contour) >= 2 and side:
            c = np.asarray(view.contour, dtype=np.float64)
            if not np.isfinite(c).all():
                raise ValueError(f"{where}: contour has a point that is not finite")
            contour = densify(c, 1.0)
        views.append(ViewData(name, cam, names, np.array(verts, dtype=np.int64),
                              np.array(px, dtype=np.float64).reshape(-1, 2), w, side,
                              contour, refit))
    return views


# ----------------------------------------------------------------------------- stages


class _Progress:
    def __init__(self, callback):
        self.callback = callback

    def __call__(self, fraction, message):
        if self.callback is not None:
            self.callback(float(min(max(fraction, 0.0), 1.0)), message)


def _profile_fit(eng, state, opts):
    """Thesis §4.4.1 on the side views: the cameras alone (similarity-only ICP: a profile
    camera's 2-D similarity is the head's scale, sagittal rotation and position), then the
    shape with them (the head's rotation frozen: the profile cannot see the other two)."""
    side = [v for v in eng.views if v.side]
    info = {}
    if not side:
        return state, info
    joint = eng.joint(side)
    hist = [joint.cost(state)]
    for _ in range(opts.max_iterations):
        joint.refit(state)
        hist.append(joint.cost(state))
        if hist[-2] - hist[-1] <= opts.tolerance * hist[-2]:
            break
    info["similarity_history"] = hist
    state, hist = joint.run(state, freeze=("rotation",), max_outer=opts.max_iterations,
                            tolerance=opts.tolerance)
    info["shape_history"] = hist
    return state, info


def _approach1(eng, state, opts):
    """Thesis §4.4.2: every landmark as image rows (front ones weighted), plus contour."""
    joint = eng.joint(eng.views, front_weight=opts.front_weight)
    state, hist = joint.run(state, max_outer=opts.max_iterations, tolerance=opts.tolerance)
    return state, {"history": hist}


def landmark_targets(eng, state, extra_views=None):
    """3-D targets of the landmark vertices: each vertex moved, within the image plane of
    every photo that shows it, onto its placed pixels (least squares over the photos
    through their cameras' Jacobians; a direction no photo sees keeps the model's value:
    the depth of a front-only landmark).

    Returns
    -------
    vertices : ndarray, shape (n,)
        Unique landmark vertices.
    current : ndarray, shape (n, 3)
        Their world positions now.
    targets : ndarray, shape (n, 3)
    """
    views = eng.views if extra_views is None else extra_views
    allv = np.concatenate([v.vertices[v.weights > 0] for v in views])
    uniq, inv = np.unique(allv, return_inverse=True)
    x = eng.world(state, uniq)
    a = np.zeros((len(uniq), 3, 3))
    b = np.zeros((len(uniq), 3))
    start = 0
    for v in views:
        use = v.weights > 0
        n = int(use.sum())
        idx = inv[start:start + n]
        start += n
        cam = state.cameras[v.name]
        xi = x[idx]
        jac = np.asarray(cam.jacobian(xi), dtype=np.float64).reshape(n, 2, 3)
        r = v.pixels[use] - cam.project(xi)
        w = v.weights[use]
        np.add.at(a, idx, w[:, None, None] * np.einsum("nki,nkj->nij", jac, jac))
        np.add.at(b, idx, w[:, None] * np.einsum("nki,nk->ni", jac, r))
    eps = 1e-9 * np.trace(a, axis1=1, axis2=2)[:, None, None] * np.eye(3) + 1e-12 * np.eye(3)
    delta = np.linalg.solve(a + eps, b[..., None])[..., 0]
    return uniq, x, x + delta


def _dense_vertices(model, step=4):
    """Every ``step``-th skin vertex: the dense 3-D rows of approach 2 (the skin is
    regularly meshed, so a stride is an even subsample)."""
    return np.asarray(model.skin, dtype=np.int64)[::step]


def _approach2(eng, model, state, opts):
    """Thesis §4.4.3: TPS-ICP, repeated while the reprojection error falls."""
    dense = _dense_vertices(model)
    lin = eng.linear_model()
    # Metres to the image rows' weighted pixels: a landmark's 3-D row weighs as its pixel
    # rows would (camera scale squared); the dense rows together weigh as all landmarks.
    s2 = _pixels_per_metre_sq(eng, state)
    n_lm = sum(int((v.weights > 0).sum()) for v in eng.views)
    w_lm = s2 * eng.inv_var * opts.landmark_weight
    joint = eng.joint(eng.views)
    best = (reprojection_rms(eng, joint, state), state.copy())
    history = [best[0]]
    for _ in range(opts.tps_iterations):
        verts, cur, tgt = landmark_targets(eng, state)
        tps = ThinPlateSpline.fit(cur, tgt, regularization=0.0)
        warped = tps.apply(eng.world(state, dense))
        rows = [PointRows(dense, warped, weights=w_lm * n_lm / len(dense), name="tps mesh"),
                PointRows(verts, tgt, weights=w_lm, name="tps landmarks")]
        problem = eng.problem(lin, rows)
        fit = problem.solve(scale=state.scale, rotation=state.rotation,
                            translation=state.translation, coeffs=state.coeffs,
                            max_iterations=3, tolerance=opts.tolerance, sigma=1.0)
        state = state.copy()
        state.rotation, state.coeffs = fit.rotation, fit.coeffs
        state.scale, state.translation = fit.scale, fit.translation
        joint.cost(state)  # contour correspondences at the new head
        joint.refit(state)
        err = reprojection_rms(eng, joint, state)
        history.append(err)
        if err < best[0]:
            improved = best[0] - err > 1e-3 * best[0]
            best = (err, state.copy())
            if not improved:
                break
        else:
            break
    eng.use(best[1])
    return best[1], {"history": history}


def reprojection_rms(eng, joint, state):
    """RMS of every landmark and contour-correspondence pixel residual at ``state``."""
    parts = list(eng.reprojection(state).values())
    parts += list(joint.contour_residuals(state).values())
    allr = np.concatenate(parts)
    return float(np.sqrt((allr**2).mean())) if allr.size else 0.0


def _pixels_per_metre_sq(eng, state):
    """Mean squared image scale of the cameras at the head (pixels per metre, squared)."""
    vals = []
    centre = eng.world(state, np.asarray([eng.chain[len(eng.chain) // 2]]))
    for v in eng.views:
        jac = np.asarray(state.cameras[v.name].jacobian(centre)).reshape(2, 3)
        vals.append(0.5 * float((jac * jac).sum()))
    return float(np.mean(vals))
