"""Fit the head model to landmarks on photos (thesis §4.4, §9): a front and a profile
photo as in the thesis, or any number of photos at any angle, orthographic or perspective
(calibrated, from passpoints, or self-calibrated on the head), and mirror images.

Every approach starts with the profile-line fit (§4.4.1) on the orthographic profile
photos: first the side camera's 2-D similarity alone (the similarity-only ICP: in a
profile photo that is the head's scale, rotation in the sagittal plane and position), then
with the shape, against the traced outline (the model's outline in the photo, found among
vertices near its midsagittal ``profile_chain``; closest points in the image, a distance
threshold) and the side landmarks. Then:

- approach 1 (§4.4.2): all landmarks as image rows through their cameras, so a front
  landmark contributes its two known coordinates only, the front rows weighted; the
  outline traced in any photo pulls the model's outline there (other photos than
  orthographic profiles find it among the skin vertices near the traced line,
  ``view_outline``);
- approach 2 (§4.4.3): TPS-ICP: warp the fitted head with a thin-plate spline so its
  landmark vertices reach 3-D targets (each landmark moved within the image plane of every
  photo that shows it: the profile gives depth, the front x and z), fit the model to the
  warped skin and the targets (landmarks weighted), repeat while the error falls;
- combined (the thesis' outlook, §9): both, keeping the one whose landmarks and contour
  reproject better, the smaller shape prior breaking near ties. Approach 2 is the
  thesis' method for orthographic photos: its 3-D targets come from the photos' image
  planes, and it refines a head the profile stage has already shaped. With a perspective
  camera (no profile stage) it measured 2.0-2.8 mm against 1.0-1.3 mm for approach 1 (8
  synthetic cases of 2 and 3 photos, calibrated or not), so there combined is approach 1
  alone.

Cameras: no photo is assumed to share scale, tilt or framing with another. Each keeps its
own camera, solved together with the head in every Gauss-Newton step (its parameters as
extra modes of the shape-ICP) and re-calibrated through ``Camera.refit`` (see
``solver/fit_engine.py``, also for the gauge: head scale 1 and translation 0 when every
camera is free, and the head's rotation too when they are all perspective; the identity
modes carry the head's size). Self-calibrated perspective cameras alternate full
re-calibrations with joint rounds until both settle (:func:`_approach1`). A mirror view's
camera is its photo's camera reflected in a mirror plane the fit estimates
(``Engine.initial_plane``, seed 001 ch. 3); ``info["mirror"]`` reports the plane and each
landmark's gap between its direct and its mirrored ray. ``info["projection"]`` reports
each photo's parallel-projection error (seed 001 ch. 2) and ``info["warnings"]`` what the
user should know.

Everything is least squares in pixels weighted by 1 / ``noise_px``^2 against the prior
``lambda2^2 |c|^2`` (c in standard deviations), so with ``lambda2 = 1`` the fit is the
posterior mode for landmarks placed with that noise, and the inverse normal matrix is the
posterior covariance behind ``FitResult.uncertainty``.
"""

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..cameras.base import Camera, OrthographicCamera
from ..cameras.mirror import MirrorPlane
from ..io.landmarks_file import (
    MIN_LANDMARKS_PER_VIEW,
    MIN_LANDMARKS_TOTAL,
    LandmarkCase,
    LandmarkSet,
)
from .engine import (
    ContourRows,
    Engine,
    StackedModel,
    State,
    ViewData,
    as_dlt,
    is_perspective,
    is_side_camera,
)
from .result import FitResult, ViewResidual
from .shape_icp import ImageRows, PointRows
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
        Most rounds of each stage (a round: Gauss-Newton steps of head and cameras).
    tolerance : float
        Stop a stage when its cost changes by less than this fraction in a round.
    progress : callable(fraction, message) or None
    noise_px : float
        Standard deviation of landmark placement the weights assume, pixels.
    contour_weight : float
        Weight of one traced outline point relative to one landmark (a point that
        stands for less than 6 pixels of outline weighs that much less; see
        ``ContourRows``). 1: a point is placed as well as a landmark.
    contour_threshold_px : float
        Contour correspondences farther than this are dropped (thesis §4.4.1).
    landmark_weights : dict of str -> float, optional
        Per-landmark weight factors (canonical names or ibugNN), e.g. 0 to ignore one.
    fixed_cameras : tuple of str
        Views whose camera is kept as given, besides those the case marks ``calibrated``;
        every other camera is refitted (a photo's scale, tilt and framing are unknown).
    flag_sigmas : float
        A landmark is flagged when its residual exceeds the mean plus this many standard
        deviations of all the others' residuals ...
    flag_min_px : float
        ... and this many pixels (so noise alone rarely flags).
    tps_iterations : int
        Most TPS-ICP rounds of approach 2.
    camera_distance_m : float or None
        How far the photographer stood from the middle of the head, metres (optional). The
        fit cannot know it for orthographic photos; given, it checks each orthographic
        photo's parallel-projection error against the landmarks' reading error (seed 001
        ch. 2, ``solver/projection_check.py``) and warns in ``info["warnings"]`` when a
        perspective camera is needed. Perspective cameras are always checked (reported
        only: their projection is central anyway).
    calibration_rounds : int
        Most re-calibrations of free perspective cameras and mirror planes between joint
        rounds (see ``Joint.settle``).
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
    contour_weight: float = 1.0
    contour_threshold_px: float = 20.0
    landmark_weights: dict | None = None
    fixed_cameras: tuple = ()
    flag_sigmas: float = 3.0
    flag_min_px: float = 5.0
    tps_iterations: int = 6
    camera_distance_m: float | None = None
    calibration_rounds: int = 8


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
    val = o.calibration_rounds
    if isinstance(val, bool) or not isinstance(val, int | np.integer) or val < 0:
        raise ValueError(f"options.calibration_rounds: must be an integer >= 0, got {val!r}")
    d = o.camera_distance_m
    if d is not None and (isinstance(d, bool) or not isinstance(d, int | float)
                          or not np.isfinite(d) or d <= 0):
        raise ValueError(f"options.camera_distance_m: must be None or a finite number > 0 "
                         f"(metres), got {d!r}")
    if o.progress is not None and not callable(o.progress):
        raise ValueError("options.progress: must be callable(fraction, message) or None")
    return o


_LIN_CACHE = {}


def _linear_model(model, opts):
    """The fitted model: the first ``n_identity`` global modes, then the regional ones.
    Cached per model and sizes, so repeated fits reuse it and the vertex slices their
    engines cache on it."""
    key = (id(model), int(opts.n_identity), int(opts.n_regional))
    hit = _LIN_CACHE.get(key)
    if hit is not None and hit[0] is model:
        return hit[1]
    parts = []
    if opts.n_identity > 0:
        parts.append(model.identity.first(int(opts.n_identity)))
    if opts.n_regional > 0:
        parts.append(model.regional(int(opts.n_regional)))
    lin = StackedModel(parts)
    if len(_LIN_CACHE) >= 4:
        _LIN_CACHE.clear()
    _LIN_CACHE[key] = (model, lin)
    return lin


def _prepare_views(model, case, opts, cameras=None):
    """The case's views as ``ViewData``; every problem is a ValueError naming the view or
    landmark. ``cameras`` (view name -> Camera, e.g. a previous fit's) replaces the file's
    cameras and nothing is computed.

    A mirror view (``View.mirror_of``) whose camera is not kept is linked to the view it
    mirrors: its camera is that view's camera reflected in a mirror plane the fit
    estimates, so the file's camera for it (often just ``{"kind": "dlt"}``) is not used.

    Landmarks per view follow the file's rule (``landmarks_file.check_case``): a view whose
    camera is refitted on the head needs ``MIN_LANDMARKS_PER_VIEW`` and what its camera's
    refit needs; a kept camera, or one the view's passpoints give, needs none. A
    passpoint camera with too few landmarks to refine it is kept as computed. A view with
    no usable landmark adds nothing to the head fit: it is returned in ``skipped`` (its
    camera still goes into the result).

    Returns
    -------
    views : list of ViewData
        The views the head is fitted to.
    skipped : list of ViewData
        Views with a camera but no usable landmark.
    """
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
    views, skipped = [], []
    exempt, total = False, 0
    for name, view in case.views.items():
        where = f"{case.source}: view {name!r}"
        kept = bool(getattr(view, "camera_fixed", False)) or name in fixed
        link = _mirror_link(case, view, kept, where)
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
        refit = not kept and link is None
        if cameras is not None:
            if name not in cameras:
                raise ValueError(f"{where}: was not in that fit (views: "
                                 f"{', '.join(cameras)})")
            cam = cameras[name]
        elif link is not None:
            cam = None  # the real camera reflected, once that camera is placed
        else:
            cam = view.camera
            if cam is None:
                if refit and not view.passpoints:  # self-calibrated: the count first
                    _check_count(where, used, MIN_LANDMARKS_PER_VIEW)
                cam = _compute_camera(model, case, view, lms, where)
        if cam is not None and not isinstance(cam, Camera):
            raise ValueError(f"{where}: camera of unknown kind ({type(cam).__name__}); "
                             "expected a solver.cameras.Camera")
        need = MIN_LANDMARKS_PER_VIEW
        if refit:
            need = max(need, cam.min_refit_points)
            if used < need and view.passpoints:
                refit = False  # the passpoints give the camera; too few landmarks to refine it
        if kept or (not refit and link is None):
            need = 0
        _check_count(where, used, need)
        exempt = exempt or used < MIN_LANDMARKS_PER_VIEW
        total += used
        contour = None
        if view.contour is not None and len(view.contour) >= 2:
            c = np.asarray(view.contour, dtype=np.float64)
            if not np.isfinite(c).all():
                raise ValueError(f"{where}: contour has a point that is not finite")
            if len(np.unique(c.reshape(-1, 2), axis=0)) < 2:
                raise ValueError(f"{where}: contour needs at least 2 distinct points")
            contour = c.reshape(-1, 2)
        side = cam is not None and is_side_camera(cam)
        data = ViewData(name, cam, names, np.array(verts, dtype=np.int64),
                        np.array(px, dtype=np.float64).reshape(-1, 2), w, side, contour,
                        refit, link)
        (views if used else skipped).append(data)
    for v in views:
        if v.mirror_of is not None and any(u.name == v.mirror_of for u in skipped):
            raise ValueError(f"{case.source}: view {v.name!r} mirrors view {v.mirror_of!r}, "
                             "which has no usable landmark; the mirror is found from "
                             "landmarks placed in both")
    # Views below the per-view floor (passpoint or kept cameras) rely on the others: then
    # hold the case to the file's total as well.
    if exempt and total < MIN_LANDMARKS_TOTAL:
        raise ValueError(f"{case.source}: {total} usable landmark{'s' * (total != 1)} in "
                         f"all; the fit needs at least {MIN_LANDMARKS_TOTAL}")
    return views, skipped


def _check_count(where, used, need):
    if used < need:
        raise ValueError(f"{where}: {used} usable landmark{'s' * (used != 1)}; the fit "
                         f"needs at least {need} in this view ({need - used} more)")


def _skip_warnings(skipped):
    return [f"view {v.name!r}: no usable landmark, so it adds nothing to the head fit"
            f"{' (its outline is not used)' if v.contour is not None else ''}; its camera is "
            "kept as given or computed from its passpoints" for v in skipped]


def _mirror_link(case, view, kept, where):
    """The view a mirror view's camera is derived from (None: not a mirror view, or one
    whose camera is kept as given)."""
    target = getattr(view, "mirror_of", None)
    if target is None:
        return None
    if target not in case.views or target == view.name:
        raise ValueError(f"{where}: mirror_of names {target!r}, not another view of the case "
                         f"(views: {', '.join(case.views)})")
    if getattr(case.views[target], "mirror_of", None) is not None:
        raise ValueError(f"{where}: mirror_of names {target!r}, itself a mirror view; name "
                         "the view seen directly")
    if kept:
        if view.camera is None:
            raise ValueError(f"{where}: a mirror view whose camera is kept needs the camera's "
                             "parameters (or leave it free: it is then the real camera "
                             "reflected in the mirror)")
        return None
    return target


#: Lenses (mm, 35 mm equivalent) a pinhole camera without a stated focal length is tried
#: with; the one whose pose fits the mean head's landmarks best starts the fit.
TRIAL_LENSES_MM = (24.0, 35.0, 50.0, 85.0, 135.0)
#: Relative standard deviation of the focal prior a stated ``lens_mm`` gives (EXIF data of
#: uncertain crop factor).
LENS_PRIOR_SIGMA = 0.05


def _compute_camera(model, case, view, lms, where):
    """A camera for a view whose file gives only its kind (``View.camera`` None): a DLT
    from the view's passpoints when it has them (a "pinhole" kind: the nearest pinhole
    camera). Else self-calibrated on the mean head's landmarks, a start the fit refines: a
    DLT fitted to them; a pinhole camera posed on them with the file's focal length
    (``lens_mm``, then also a prior of LENS_PRIOR_SIGMA on it) or, without one, with the
    best of TRIAL_LENSES_MM. (A DLT or a free focal length fitted to the mean head would
    bend the camera to the mean head's shape: a head is shallow, so focal length and
    distance trade off.)"""
    from ..cameras.dlt import fit_dlt
    from ..cameras.pinhole import PinholeCamera

    hints = dict(getattr(view, "camera_hints", {}) or {})
    kind = hints.get("kind")
    if kind not in ("dlt", "pinhole"):
        raise ValueError(f"{where}: no camera parameters and no way to compute a camera of "
                         f"kind {kind!r} (give the parameters, or a 'dlt'/'pinhole' kind)")
    keys = [k for k in view.points if lms.canonical(k) is not None]
    verts = [lms.vertices[lms.canonical(k)] for k in keys]
    uv = np.array([view.points[k] for k in keys], dtype=np.float64).reshape(-1, 2)
    options = {}
    if "lens_mm" in hints:
        options["focal_prior"] = (float(hints["lens_mm"]), LENS_PRIOR_SIGMA)
    if hints.get("focal_prior") is not None:
        options["focal_prior"] = tuple(float(x) for x in hints["focal_prior"])
    if "free_focal" in hints:
        options["free_focal"] = bool(hints["free_focal"])
    try:
        if view.passpoints:
            _, xyz, pts = case.passpoint_arrays(view.name)
            dlt = fit_dlt(xyz, pts, view.size).camera
            return dlt if kind == "dlt" else PinholeCamera.from_dlt(dlt, **options)
        if kind == "dlt":
            return fit_dlt(model.vertices[verts], uv, view.size).camera
        ppm = PinholeCamera.px_per_mm(view.size)
        if "focal_px" in hints:
            lenses = [float(hints["focal_px"]) / ppm]
        elif "lens_mm" in hints:
            lenses = [float(hints["lens_mm"])]
        else:
            lenses = list(TRIAL_LENSES_MM)
        best = None
        for lens in lenses:
            probe = PinholeCamera(lens * ppm, np.eye(3), np.zeros(3), view.size,
                                  free_focal=False, focal_range_mm=None)
            cam = probe.refit(model.vertices[verts], uv)
            err = float((cam.reprojection_error(model.vertices[verts], uv) ** 2).sum())
            if best is None or err < best[0]:
                best = (err, cam)
        cam = best[1]
        return PinholeCamera(cam.focal_px, cam.rotation, cam.centre, view.size, **options)
    except ValueError as e:
        raise ValueError(f"{where}: cannot compute the {kind} camera: {e}") from None


# ----------------------------------------------------------------------------- stages


class _Progress:
    def __init__(self, callback):
        self.callback = callback

    def __call__(self, fraction, message):
        if self.callback is not None:
            self.callback(float(min(max(fraction, 0.0), 1.0)), message)


def _init_pose(eng, state):
    """Place the head in the world of the calibrated (kept) cameras. With two or more, the
    landmarks seen in two of them are triangulated and the mean head's landmark vertices
    fitted to those points by a similarity (Procrustes). With one perspective camera, the
    mean head is posed so its landmarks project onto the placed ones (a pose-only pinhole
    refit, scale 1: one photo cannot tell size from distance). Otherwise the head starts
    at the origin, upright, at scale 1 (the free cameras come to it)."""
    fixed = [v for v in eng.views if not v.refit and v.mirror_of is None]
    if len(fixed) >= 2 and _pose_by_triangulation(eng, state, fixed):
        return
    persp = [v for v in fixed if is_perspective(v.camera)]
    if len(persp) >= 1:
        _pose_by_resection(eng, state, max(persp, key=lambda v: len(v.vertices)))


def _pose_by_triangulation(eng, state, fixed):
    from ..cameras.triangulate import triangulate
    from ..procrustes import similarity_procrustes

    verts = np.unique(np.concatenate([v.vertices for v in fixed]))
    pix = np.full((len(fixed), len(verts), 2), np.nan)
    for j, v in enumerate(fixed):
        pix[j, np.searchsorted(verts, v.vertices)] = v.pixels
    try:
        tri = triangulate([v.camera for v in fixed], pix)
    except (ValueError, TypeError):  # a kind triangulation does not know
        return False
    ok = np.isfinite(tri.points).all(axis=1)
    if ok.sum() < 4:
        return False
    try:
        sim = similarity_procrustes(eng.local(state, verts[ok]), tri.points[ok])
    except ValueError:
        return False
    state.scale, state.rotation, state.translation = sim.scale, sim.rotation, sim.translation
    return True


def _pose_by_resection(eng, state, view):
    """Pose the head (scale kept) from one calibrated perspective camera: the camera's pose
    relative to the mean head (a pinhole refit with its intrinsics kept) composed with
    its pose in the world."""
    from ..cameras.pinhole import PinholeCamera

    cam = view.camera
    try:
        if isinstance(cam, PinholeCamera):
            probe = PinholeCamera(cam.focal_px, cam.rotation, cam.centre, cam.size,
                                  cam.principal_point, cam.k1, free_focal=False,
                                  focal_range_mm=None)
        else:
            k, r, c = cam.decompose()
            if np.linalg.det(r) < 0:
                return
            probe = PinholeCamera.from_krc(k, r, c, cam.size, principal_point="keep",
                                           free_focal=False, focal_range_mm=None)
        local = eng.local(state, view.vertices)
        rel = probe.refit(local, view.pixels, view.weights)
    except ValueError:
        return
    rot = probe.rotation.T @ rel.rotation
    state.rotation = rot
    state.translation = probe.centre - rot @ rel.centre
    state.scale = 1.0


def _profile_fit(eng, state, opts):
    """Thesis §4.4.1 on the orthographic side views: the cameras alone (similarity-only
    ICP: a profile camera's 2-D similarity is the head's scale, sagittal rotation and
    position), then the shape with them (the head's rotation frozen: the profile cannot
    see the other two). A perspective profile photo is left to the joint stages: alone it
    cannot tell its camera's distance from the head's depth."""
    side = [v for v in eng.views
            if v.side and not is_perspective(eng.real_view(v).camera)]
    info = {}
    if not side:
        return state, info
    joint = eng.joint(side)
    # The head's scale and position stay too: one profile photo cannot tell its depth
    # (and with a calibrated camera the front photo is needed to place the head).
    joint.gauge = tuple(sorted(set(joint.gauge) | {"scale", "translation"}))
    if joint.blocks:
        state, hist = joint.run(state, max_outer=opts.max_iterations,
                                tolerance=opts.tolerance, cameras_only=True)
        info["similarity_history"] = hist
    state, hist = joint.run(state, freeze=("rotation",), max_outer=opts.max_iterations,
                            tolerance=opts.tolerance)
    info["shape_history"] = hist
    return state, info


def _approach1(model, eng, state, opts):
    """Thesis §4.4.2: every landmark as image rows (front ones weighted), plus contour.

    Photos whose traced outline is matched to the head's own outline (every outline but
    an orthographic profile's, see :func:`view_outline`) are fitted in stages: the
    landmarks alone, then, with the outline candidates found on that head, landmarks
    and outlines together, first for _RELEASE_ROUNDS rounds (cameras not re-calibrated)
    keeping every outline row within _RELEASE_KEEP of the contour threshold (8 px), then,
    with candidates found anew, with the usual cut-off (3 sigmas of the noise,
    ``ContourRows``). From the mean head the outline rows latch onto the wrong rim (a
    cheek for a jaw, an ear for the skull) and the fit settles in a worse minimum: on two
    perspective photos the landmarks-first stage more than halves the gap to a fit
    started from the true head. And where the landmarks leave the head
    some 10 px off the tracing (the neck, which no landmark holds), the noise's cut-off
    trims those rows from the start, so they never pull it there: the wide stage does
    (2 photos, 40 heads of ``bench/bench_perspective.py``: 1.3 % less error on average,
    up to 0.17 mm on a head; the lost rows' points then all have rows).

    With free perspective cameras or mirror planes (self-calibration) the joint rounds
    alternate with full re-calibrations of those cameras until both settle
    (``Joint.settle``): joint rounds run until a round changes the cost by less than
    0.1 % (or ``tolerance`` if larger; the choice of outline vertices alone moves the cost
    by about that much), and a re-calibration that lowers the cost by less than that
    ends the alternation, after at most ``calibration_rounds``.

    Returns (state, info): ``info["joint"]`` is the last stage's problem and
    ``info["outlines"]`` its outline candidates (view name -> (vertices, faces, edges)),
    besides "history" (and "calibration_rounds")."""
    selfcal = _self_calibrating(eng)
    tol = max(opts.tolerance, _SETTLE_TOLERANCE) if selfcal else opts.tolerance
    out = {"history": []}
    if selfcal:
        out["calibration_rounds"] = 0

    def stage(joint, state, settle=True, max_outer=None):
        state, hist = joint.run(state, max_outer=max_outer or opts.max_iterations,
                                tolerance=tol)
        out["history"] += hist
        if selfcal and settle:
            state, more, rounds = joint.settle(state, opts.calibration_rounds, tol,
                                               max_outer=opts.max_iterations)
            out["history"] += more
            out["calibration_rounds"] += rounds
        return state

    if _own_outline_views(eng, state) and any(len(v.vertices) for v in eng.views):
        state = stage(eng.joint(eng.views, front_weight=opts.front_weight, contour=False),
                      state)
        state = stage(eng.joint(eng.views, front_weight=opts.front_weight,
                                outlines=_view_outlines(model, eng, state),
                                keep_distance=_RELEASE_KEEP * eng.contour_threshold), state,
                      settle=False, max_outer=_RELEASE_ROUNDS)
    out["outlines"] = _view_outlines(model, eng, state)
    joint = eng.joint(eng.views, front_weight=opts.front_weight, outlines=out["outlines"])
    out["joint"] = joint
    return stage(joint, state), out


# Smallest relative gain of a re-calibration for another joint run (Joint.settle).
_SETTLE_TOLERANCE = 1e-3
# The first outline stage of approach 1 keeps every contour row within this fraction of
# the contour threshold (8 px at the default 20), for this many rounds: see _approach1.
# (On 40 heads of two photos, 2 rounds do what a run to convergence does; 1 does not.)
_RELEASE_KEEP = 0.4
_RELEASE_ROUNDS = 2


def _self_calibrating(eng):
    """Whether a free camera has parameters the joint rounds linearise (perspective) or a
    mirror plane is estimated: then camera calibration and shape are alternated until
    both settle."""
    return any(v.mirror_of is not None or (eng.camera_moves(v) and is_perspective(v.camera))
               for v in eng.views)


def landmark_targets(eng, state):
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
    views = eng.views
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


# Share of the TPS-warped skin in approach 2's cost, relative to all landmarks.
_DENSE_SHARE = 0.3
# Approach 2 stops once a round improves the reprojection error by less than this fraction.
_A2_PROGRESS = 0.01


def _dense_vertices(model, step=8):
    """Every ``step``-th skin vertex (about 1400): the dense 3-D rows of approach 2 (the
    skin is regularly meshed, so a stride is an even subsample; the benchmark's accuracy
    is the same with every 4th)."""
    return np.asarray(model.skin, dtype=np.int64)[::step]


def _approach2(eng, model, state, opts):
    """Thesis §4.4.3: TPS-ICP, repeated while the reprojection error falls.

    Each round warps the head with a thin-plate spline that takes its landmark vertices
    to their 3-D targets (:func:`landmark_targets`), then fits the model to the warped
    skin (every 8th skin vertex) and to the targets themselves (weighted like the
    landmarks' pixels), with the profile contour as in approach 1; the cameras follow.
    Outlines other than an orthographic profile's are matched to candidates found on the
    head approach 2 starts from (``info["outlines"]``, as in :func:`_approach1`).
    """
    dense = _dense_vertices(model)
    # Metres to the image rows' weighted pixels: a landmark's 3-D row weighs what its
    # pixel rows would (camera scale squared / noise^2); all dense rows together weigh
    # DENSE_SHARE times all landmarks (the warp between landmarks is a guess: it should
    # steer, not dominate).
    s2 = _pixels_per_metre_sq(eng, state)
    n_lm = sum(int((v.weights > 0).sum()) for v in eng.views)
    w_lm = s2 * eng.inv_var * opts.landmark_weight
    own = _view_outlines(model, eng, state)
    joint = eng.joint(eng.views, outlines=own)
    verts, _, tgt = landmark_targets(eng, state)
    side = [v for v in eng.views if v.contour is not None]
    # The shape-ICP works on copies of the vertices used: dense skin, landmarks, then the
    # outline candidates once per photo with a traced outline.
    nd, nl = len(dense), len(verts)
    mesh_rows = PointRows(np.arange(nd), eng.world(state, dense),
                          weights=_DENSE_SHARE * w_lm * n_lm / nd, name="tps mesh")
    lm_rows = PointRows(np.arange(nd, nd + nl), tgt, weights=w_lm, name="tps landmarks")
    contour, parts, off = [], [], nd + nl
    for v in side:
        cand, faces, edges = eng.outline_candidates(v, own)
        contour.append(ContourRows(np.arange(off, off + len(cand)), v.contour, v.camera,
                                   weights=eng.contour_weight * eng.inv_var, faces=faces,
                                   edges=edges, max_distance=eng.contour_threshold,
                                   keep_distance=eng.contour_keep, name=v.name))
        parts.append(cand)
        off += len(cand)
    # One problem for all rounds: only targets change, so the dense rows' Gram matrix
    # is computed once.
    copies = np.concatenate([dense, verts] + parts)
    problem = eng.problem(eng.copies_model(copies), [mesh_rows, lm_rows] + contour)
    best = (reprojection_rms(eng, joint, state), state.copy())
    history = [best[0]]
    for _ in range(opts.tps_iterations):
        _, cur, tgt = landmark_targets(eng, state)  # same vertices every round
        tps = ThinPlateSpline.fit(cur, tgt, regularization=0.0)
        mesh_rows.set_targets(tps.apply(eng.world(state, dense)))
        lm_rows.set_targets(tgt)
        for rows in contour:
            rows.set_camera(state.cameras[rows.name])
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
            improved = best[0] - err > _A2_PROGRESS * best[0]
            best = (err, state.copy())
            if not improved:
                break
        else:
            break
    eng.use(best[1])
    return best[1], {"history": history, "outlines": own}


def reprojection_rms(eng, joint, state):
    """RMS of every landmark and contour-correspondence pixel residual at ``state``."""
    parts = list(eng.reprojection(state).values())
    parts += list(joint.contour_residuals(state).values())
    allr = np.concatenate(parts)
    return float(np.sqrt((allr**2).mean())) if allr.size else 0.0


def _pixels_per_metre_sq(eng, state):
    """Mean squared image scale of the cameras at the head (pixels per metre, squared)."""
    vals = []
    verts = np.concatenate([v.vertices for v in eng.views])
    centre = eng.world(state, verts).mean(axis=0, keepdims=True)
    for v in eng.views:
        jac = np.asarray(state.cameras[v.name].jacobian(centre)).reshape(2, 3)
        vals.append(0.5 * float((jac * jac).sum()))
    return float(np.mean(vals))


# ----------------------------------------------------------------------------- choosing


def _choose(eng, joint, candidates, tie=0.05):
    """The candidate whose landmarks and contour reproject best; within ``tie`` (relative)
    of the best, the one with the smallest shape prior (the more typical head)."""
    scores = {}
    for name, (state, _) in candidates.items():
        scores[name] = (reprojection_rms(eng, joint, state), eng.prior_cost(state.coeffs))
    best_rms = min(r for r, _ in scores.values())
    close = [n for n, (r, _) in scores.items() if r <= best_rms * (1.0 + tie) + 1e-9]
    chosen = min(close, key=lambda n: scores[n][1])
    return chosen, scores


# ----------------------------------------------------------------------------- result


def flag_residuals(residuals, sigmas=3.0, min_px=5.0):
    """Landmarks whose residual stands out (seed 000 §5: a residual far above the others
    means a data error).

    Each residual is compared with the mean and standard deviation of all the *other*
    residuals (leave-one-out, so an outlier does not hide itself by inflating the spread):
    flagged when above ``mean + sigmas * std`` and above ``min_px``.

    Parameters
    ----------
    residuals : dict of str -> ndarray (n,)
        Pixel residuals per view.
    sigmas, min_px : float

    Returns
    -------
    dict of str -> ndarray of bool
    """
    names = list(residuals)
    allr = np.concatenate([np.asarray(residuals[n], dtype=np.float64) for n in names]) \
        if names else np.zeros(0)
    m = len(allr)
    if m < 3:
        return {n: np.zeros(len(residuals[n]), bool) for n in names}
    s1, s2 = allr.sum(), (allr**2).sum()
    mean_o = (s1 - allr) / (m - 1)
    var_o = np.maximum((s2 - allr**2) / (m - 1) - mean_o**2, 0.0)
    flag = (allr > mean_o + sigmas * np.sqrt(var_o)) & (allr > min_px)
    out, i = {}, 0
    for n in names:
        k = len(residuals[n])
        out[n] = flag[i:i + k]
        i += k
    return out


def _view_errors(camera, world, view):
    if not len(view.vertices):
        return np.zeros(0)
    return np.linalg.norm(camera.project(world[view.vertices]) - view.pixels, axis=1)


def _residuals(eng, state, opts, local, skipped=()):
    """Landmark residuals of the final head (``local`` includes any detail), flagged; a
    skipped view's (landmarks of weight 0 only, or none) unflagged."""
    world = state.scale * local @ state.rotation.T + state.translation
    res = {v.name: _view_errors(state.cameras[v.name], world, v) for v in eng.views}
    flags = flag_residuals(res, opts.flag_sigmas, opts.flag_min_px)
    out = {}
    for v in eng.views:
        r = res[v.name]
        out[v.name] = ViewResidual(list(v.names), r.copy(),
                                   [n for n, f in zip(v.names, flags[v.name], strict=True)
                                    if f])
    for v in skipped:
        out[v.name] = ViewResidual(list(v.names), _view_errors(v.camera, world, v), [])
    return out


_SKIN_CACHE = {}


def _skin_maps(model):
    """Per model (cached): non-skin vertices, the nearest skin vertex of each (to give
    them the skin's uncertainty) and the skin vertices that steer them (TPS controls)."""
    key = id(model)
    hit = _SKIN_CACHE.get(key)
    if hit is not None and hit[0] is model:
        return hit[1]
    n = model.n_vertices
    skin = np.asarray(model.skin, dtype=np.int64)
    is_skin = np.zeros(n, bool)
    is_skin[skin] = True
    other = np.flatnonzero(~is_skin)
    rest = model.vertices
    tree = cKDTree(rest[skin])
    nearest = skin[tree.query(rest[other])[1]] if len(other) else other
    # TPS controls: skin within 2 cm of a non-skin vertex (the eyelids, lips, mouth
    # corners that hold the eyes and teeth), thinned to about 300 by a stride.
    ctrl = np.zeros(0, np.int64)
    if len(other):
        d, _ = cKDTree(rest[other]).query(rest[skin], distance_upper_bound=0.02)
        near = skin[np.isfinite(d)]
        ctrl = near[::max(1, len(near) // 300)]
    maps = {"other": other, "nearest": nearest, "controls": ctrl}
    _SKIN_CACHE.clear()
    _SKIN_CACHE[key] = (model, maps)
    return maps


def _follow_skin(model, skin_disp):
    """Displacement of the non-skin parts (eyes, teeth, ...) that carries a skin-only
    displacement (regional modes are zero off the skin) smoothly onto them: a thin-plate
    spline through the skin around them, (V, 3), zero on the skin."""
    maps = _skin_maps(model)
    out = np.zeros_like(skin_disp)
    ctrl, other = maps["controls"], maps["other"]
    if len(other) == 0 or len(ctrl) < 4 or not skin_disp[ctrl].any():
        return out
    rest = model.vertices
    tps = ThinPlateSpline.fit(rest[ctrl], rest[ctrl] + skin_disp[ctrl], regularization=1e-4)
    out[other] = tps.apply(rest[other]) - rest[other]
    return out


def _uncertainty(model, eng, cov):
    """Posterior standard deviation of each vertex, millimetres: sqrt of the trace of
    B_v Sigma B_v^T over the skin (float32: display precision), the nearest skin vertex's
    value elsewhere."""
    maps = _skin_maps(model)
    skin = np.asarray(model.skin, dtype=np.int64)
    b32 = eng.skin_basis32(skin)
    evals, evecs = np.linalg.eigh(0.5 * (cov + cov.T))
    f = (np.sqrt(np.clip(evals, 0.0, None))[:, None] * evecs.T).astype(np.float32)
    y = f @ b32
    # squares summed in float32 too: 100 terms lose ~1e-6 relative, and converting the
    # (K, 3 S) product to float64 first cost as much as the product itself
    var = np.einsum("ij,ij->j", y, y).reshape(-1, 3).sum(axis=1, dtype=np.float64)
    out = np.zeros(model.n_vertices)
    out[skin] = 1000.0 * np.sqrt(var)
    out[maps["other"]] = out[maps["nearest"]]
    return out


def _local_terms(model, eng, state, opts):
    """(identity coeffs, regional coeffs, identity+regional displacement (V, 3), the
    regional part (V, 3))."""
    k_id = int(opts.n_identity)
    c = state.coeffs
    parts = eng.lin.displacements(c)
    disp = parts[0].copy()
    for extra in parts[1:]:
        disp += extra
    reg = parts[-1] if opts.n_regional > 0 else np.zeros_like(disp)
    return c[:k_id].copy(), c[k_id:].copy(), disp, reg


def _exact_detail(eng, state, local):
    """TPS in the model frame that moves every landmark vertex onto its target (the pixels
    it was placed at, in every photo that shows it), applied to all vertices: (V, 3)."""
    verts, _, tgt = landmark_targets(eng, state)
    if len(verts) < 4:
        return np.zeros_like(local)
    tgt_local = ((tgt - state.translation) @ state.rotation) / state.scale
    try:
        tps = ThinPlateSpline.fit(local[verts], tgt_local, regularization=0.0)
    except ValueError:
        return np.zeros_like(local)
    return tps.apply(local) - local


def _make_result(model, eng, state, opts, method, info, uncertainty=None, detail=None,
                 skipped=()):
    ident, regc, disp, reg = _local_terms(model, eng, state, opts)
    if detail is None:
        detail = np.zeros_like(disp)
        if opts.n_regional > 0:
            detail += _follow_skin(model, reg)
        if opts.exact_landmarks:
            detail += _exact_detail(eng, state, model.vertices + disp + detail)
    local = model.vertices + disp + detail
    names = tuple(eng.lin.names[int(opts.n_identity):]) if opts.n_regional > 0 else ()
    return FitResult(
        method=method, scale=float(state.scale), rotation=state.rotation.copy(),
        translation=state.translation.copy(), identity_coeffs=ident,
        regional_coeffs=regc, regional_names=names, detail=detail, local_vertices=local,
        cameras={**state.cameras, **{v.name: v.camera for v in skipped}},
        residuals=_residuals(eng, state, opts, local, skipped),
        uncertainty=uncertainty, info=info)


# ----------------------------------------------------------------------------- API


_OUTLINE_CACHE = {}
_NORMAL_CACHE = {}


def _mean_normals(model):
    """Unit vertex normals of the mean head (area-weighted face normals), (V, 3), cached
    per model."""
    hit = _NORMAL_CACHE.get(id(model))
    if hit is not None and hit[0] is model:
        return hit[1]
    v = model.vertices
    tri, _, _ = model.triangles()
    face = np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])
    normal = np.zeros_like(v)
    for k in range(3):
        np.add.at(normal, tri[:, k], face)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
    _NORMAL_CACHE.clear()
    _NORMAL_CACHE[id(model)] = (model, normal)
    return normal


def _candidate_mesh(model, verts):
    """Triangles among candidate vertices and the edges two of them share.

    Returns
    -------
    faces : ndarray, shape (F, 3)
        Triangles whose corners are all candidates, as indices into ``verts``.
    edges : ndarray, shape (E, 4)
        Edges shared by exactly two of those triangles: (a, b, face 1, face 2).
    """
    tri, _, _ = model.triangles()
    local = np.full(model.n_vertices, -1, dtype=np.int64)
    local[verts] = np.arange(len(verts))
    faces = local[tri]
    faces = faces[(faces >= 0).all(axis=1)]
    return faces, shared_edges(faces, len(verts))


def shared_edges(faces, n_vertices):
    """Edges shared by exactly two of the triangles ``faces`` (F, 3) over ``n_vertices``
    vertices: (E, 4) as (a, b, face 1, face 2), a < b."""
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    # edges with their two faces: sort the 3F half-edges by their vertex pair
    half = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    owner = np.tile(np.arange(len(faces)), 3)
    half = np.sort(half, axis=1)
    key = half[:, 0] * n_vertices + half[:, 1]
    order = np.argsort(key, kind="stable")
    key, half, owner = key[order], half[order], owner[order]
    # exactly two faces per edge (an edge on three would be a defect; it is skipped)
    same = np.flatnonzero(key[1:] == key[:-1])
    two = same[(same + 2 >= len(key)) | (key[np.minimum(same + 2, len(key) - 1)] != key[same])]
    two = two[(two == 0) | (key[np.maximum(two - 1, 0)] != key[two])]
    return np.column_stack([half[two, 0], half[two, 1], owner[two], owner[two + 1]])


def outline_candidates(model, max_x=0.05, max_normal_x=0.4):
    """Vertices that can form the head's outline in a profile photo, with their mesh
    (cached per model): skin within ``max_x`` metres of the midsagittal plane whose
    normals (of the mean head) face across the left-right axis (|n_x| < ``max_normal_x``:
    about 24 degrees of margin for a turned head or another identity).

    Returns
    -------
    vertices : ndarray, shape (n,)
    faces : ndarray, shape (F, 3)
        Triangles whose corners are all candidates, as indices into ``vertices``.
    edges : ndarray, shape (E, 4)
        Edges shared by exactly two of those triangles: (a, b, face 1, face 2).
    """
    hit = _OUTLINE_CACHE.get(id(model))
    if hit is not None and hit[0] is model:
        return hit[1]
    v = model.vertices
    normal = _mean_normals(model)
    skin = np.asarray(model.skin, dtype=np.int64)
    keep = (np.abs(v[skin, 0]) < max_x) & (np.abs(normal[skin, 0]) < max_normal_x)
    verts = np.union1d(skin[keep], np.asarray(model.profile_chain, dtype=np.int64))
    out = (verts, *_candidate_mesh(model, verts))
    _OUTLINE_CACHE.clear()
    _OUTLINE_CACHE[id(model)] = (model, out)
    return out


def view_outline(model, eng, state, view, margin=1.5):
    """Outline candidates of a photo that is not an orthographic profile (a front or
    three-quarter view, a perspective photo at any angle): the skin vertices of the head at
    ``state`` that the view's camera in ``state`` projects within ``margin`` times the
    contour threshold of the traced outline, with their mesh; ``ContourRows`` finds the
    outline among them each round (the outermost rim, so the inner folds near the outline,
    the far side of the nose or an ear's inner rim, do no harm).

    Every vertex near the outline, whatever way it faces: an ear is thin, and its outline
    runs along edges between faces that turn from the camera to across it within a
    millimetre or two, so a band of normals that face across the line of sight (on the
    mean head) misses some of their corners, and a traced point there meets no rim even on
    the true head. The margin (30 px by default) leaves room for the head to move during
    a stage; rows form only within the contour threshold anyway.

    Returns
    -------
    (vertices (n,), faces (F, 3), edges (E, 4))
    """
    skin = np.asarray(model.skin, dtype=np.int64)
    world = eng.world(state, skin)
    camera = state.cameras[view.name]
    dist, _ = cKDTree(view.contour).query(camera.project(world))
    verts = skin[dist <= margin * eng.contour_threshold]
    return (verts, *_candidate_mesh(model, verts))


def _own_outline_views(eng, state):
    """The views whose traced outline is matched to candidates of their own
    (:func:`view_outline`): every outline but an orthographic profile's (a perspective
    photo from the side sees more than the midline: the rays to the outline fan out over
    the head)."""
    return [v for v in eng.views if v.contour is not None
            and not (v.side and not is_perspective(state.cameras[v.name]))]


def _view_outlines(model, eng, state):
    """Outline candidates found on the head of ``state`` for every view that does not use
    the profile's (:func:`_own_outline_views`): view name -> (vertices, faces, edges),
    for ``Engine.joint(..., outlines=)``. A value, not kept on the views: each approach
    finds them on its own head, where it uses them."""
    return {v.name: view_outline(model, eng, state, v) for v in _own_outline_views(eng, state)}


def _engine(model, views, opts):
    lin = _linear_model(model, opts)
    return Engine(lin, views, *outline_candidates(model), opts.noise_px, opts.lambda1,
                  opts.lambda2, opts.prior, opts.contour_weight, opts.contour_threshold_px)


def _rms(values):
    v = np.asarray(values, dtype=np.float64)
    return float(np.sqrt((v**2).mean())) if v.size else 0.0


def _saved_state(previous, eng, views, where):
    """The State a previous FitResult ended in (cameras of the views it had, mirror
    planes)."""
    saved = getattr(previous, "info", {}).get("refit_state") if previous is not None else None
    if saved is None:
        raise ValueError(f"{where}: expected a FitResult from fit_head (its info has no "
                         "'refit_state')")
    coeffs = np.asarray(saved["coeffs"], dtype=np.float64)
    if coeffs.shape != (eng.lin.n_coeffs,):
        raise ValueError(f"{where}: {coeffs.size} coefficients, but the model with these "
                         f"options has {eng.lin.n_coeffs} (n_identity and n_regional must "
                         "match)")
    missing = [v.name for v in views if v.name not in previous.cameras]
    if missing:
        raise ValueError(f"{where}: view {missing[0]!r} was not in that fit (views: "
                         f"{', '.join(previous.cameras)})")
    planes = {}
    for v in views:
        if v.mirror_of is None:
            continue
        p = saved.get("planes", {}).get(v.name)
        if p is None:
            raise ValueError(f"{where}: view {v.name!r} was not a mirror view in that fit")
        planes[v.name] = MirrorPlane(np.asarray(p["normal"], dtype=np.float64),
                                     float(p["offset"]))
    return State(np.asarray(previous.rotation, dtype=np.float64).copy(), coeffs.copy(),
                 {v.name: previous.cameras[v.name] for v in views}, float(previous.scale),
                 np.asarray(previous.translation, dtype=np.float64).copy(), planes), saved


def _previous_cameras(previous, where):
    cams = getattr(previous, "cameras", None)
    if not isinstance(cams, dict) or "refit_state" not in getattr(previous, "info", {}):
        raise ValueError(f"{where}: expected a FitResult from fit_head (its info has no "
                         "'refit_state')")
    return cams


def _mirror_info(eng, state, opts):
    """Per mirror view: the plane, and each landmark seen directly and in the mirror
    triangulated from both rays (seed 001 eq. 3.5-3.7) with the gap between them: in
    metres and in pixels at the landmark's depth (gap * f / depth). A gap that stands out
    (``flag_residuals`` with the options' sigmas and pixel floor) means a landmark placed
    on different points in the two images. Returns (info, warnings)."""
    from ..cameras.mirror import triangulate_mirror

    out, warnings = {}, []
    for m in eng.views:
        if m.mirror_of is None:
            continue
        r = eng.view(m.mirror_of)
        plane = state.planes[m.name]
        real = as_dlt(state.cameras[r.name])
        direct = {n: i for i, n in enumerate(r.names)}
        pairs = [(n, direct[n], j) for j, n in enumerate(m.names) if n in direct]
        names = [p[0] for p in pairs]
        d_px = r.pixels[[p[1] for p in pairs]]
        m_px = m.pixels[[p[2] for p in pairs]]
        mid, gaps = triangulate_mirror(real, plane, d_px, m_px)
        k = real.decompose()[0]
        depth = np.maximum(np.abs(real.depth(mid)), 1e-9)
        gap_px = gaps * float(np.sqrt(k[0, 0] * k[1, 1])) / depth
        flags = flag_residuals({"gaps": gap_px}, opts.flag_sigmas, opts.flag_min_px)["gaps"]
        flagged = [n for n, f in zip(names, flags, strict=True) if f]
        out[m.name] = {
            "mirror_of": r.name, "normal": plane.normal.copy(), "offset_m": plane.offset,
            "point_m": plane.point,
            "ray_gap_mm": {n: 1000.0 * float(g) for n, g in zip(names, gaps, strict=True)},
            "ray_gap_px": {n: float(g) for n, g in zip(names, gap_px, strict=True)},
            "flagged": flagged}
        if flagged:
            worst = ", ".join(f"{n} ({out[m.name]['ray_gap_px'][n]:.1f} px)" for n in flagged)
            warnings.append(f"view {m.name!r} (mirror of {r.name!r}): the direct and the "
                            f"mirrored ray of {worst} miss each other; check where these "
                            "landmarks are placed in both images")
    return out, warnings


def _projection_info(model, result, eng, opts):
    """Seed 001 ch. 2: the parallel-projection error epsilon of every photo for the fitted
    head (its skin). Perspective cameras are always reported; an orthographic photo only
    when ``camera_distance_m`` is given, with a warning when its epsilon exceeds what the
    landmarks can tell (reading error 2 noise_px over the head's image size). Returns
    (info, warnings)."""
    from ..cameras.projection_check import check_orthographic, check_projection

    pts = result.world_vertices[np.asarray(model.skin, dtype=np.int64)]
    out, warnings = {}, []
    reading = 2.0 * opts.noise_px
    for v in eng.views:
        cam = result.cameras[v.name]
        try:
            if is_perspective(cam):
                chk = check_projection(cam, pts, reading_error_px=reading, view=v.name)
            elif isinstance(cam, OrthographicCamera) and opts.camera_distance_m is not None:
                chk = check_orthographic(cam, pts, opts.camera_distance_m,
                                         reading_error_px=reading, view=v.name)
                if chk.exceeds:
                    warnings.append(chk.message)
            else:
                continue
        except ValueError as e:  # e.g. a head point behind the camera: say so, go on
            warnings.append(str(e))
            continue
        out[v.name] = {"epsilon": chk.epsilon, "epsilon_max": chk.epsilon_max,
                       "distance_m": chk.distance, "depth_extent_m": chk.depth_extent,
                       "min_distance_m": chk.min_distance, "exceeds": chk.exceeds,
                       "perspective": is_perspective(cam)}
    return out, warnings


def fit_head(model, case, options=None, initial=None):
    """Fit the head model to the landmarks (and contours) of a case.

    Parameters
    ----------
    model : HeadModel
    case : LandmarkCase
        Views with landmarks in pixels (any number, any angle; orthographic, DLT or
        pinhole cameras, given, calibrated or to be computed; mirror views); any view may
        carry a traced contour.
    options : FitOptions, optional
    initial : FitResult, optional
        Start from this fit's cameras, pose, mirror planes and coefficients (same views and
        model sizes) instead of the mean head; the profile stage is then skipped.

    Returns
    -------
    FitResult
        ``info`` holds: "approach" (the one used), "candidates" (each approach's RMS
        reprojection error in pixels and prior), "iterations" and "errors" per stage
        ("calibration_rounds": re-calibrations of self-calibrated cameras in approach 1),
        "timings" (seconds), "rms_px" per view and "contour_rms_px", "projection" (per
        photo the parallel-projection error epsilon, see :func:`_projection_info`),
        "mirror" (per mirror view the plane and the landmarks' ray gaps), "warnings"
        (messages for the user) and "refit_state" (what :func:`refit_landmarks`
        continues from).

    Raises
    ------
    ValueError
        Bad options, a view with an unknown camera kind or too few landmarks (naming the
        view and how many more it needs), unknown landmark names, a mirror view that
        cannot be placed, an unusable ``initial``.
    """
    t0 = time.perf_counter()
    opts = _check_options(options, model)
    progress = _Progress(opts.progress)
    cams = None if initial is None else _previous_cameras(initial, "initial")
    views, skipped = _prepare_views(model, case, opts, cameras=cams)
    eng = _engine(model, views, opts)
    timings = {}
    info_p = {}
    if initial is None:
        state = State(np.eye(3), np.zeros(eng.lin.n_coeffs), {v.name: v.camera for v in views})
        progress(0.0, "placing the cameras")
        _init_pose(eng, state)
        eng.init_cameras(state)
        eng.finish_views(state)
        progress(0.05, "fitting the profile")
        t = time.perf_counter()
        state_p, info_p = _profile_fit(eng, state, opts)
        timings["profile"] = time.perf_counter() - t
    else:
        state_p, _ = _saved_state(initial, eng, views, "initial")
        eng.finish_views(state_p)
    candidates = {}
    if opts.method in ("approach1", "combined"):
        progress(0.35, "approach 1: landmark ICP")
        t = time.perf_counter()
        eng.use(state_p)
        candidates["approach1"] = _approach1(model, eng, state_p.copy(), opts)
        timings["approach1"] = time.perf_counter() - t
    if opts.method == "approach2" or (opts.method == "combined" and not any(
            is_perspective(eng.real_view(v).camera) for v in eng.views)):
        progress(0.6, "approach 2: TPS-ICP")
        t = time.perf_counter()
        eng.use(state_p)
        candidates["approach2"] = _approach2(eng, model, state_p.copy(), opts)
        timings["approach2"] = time.perf_counter() - t
    # the result's problem over all views (approach 1's, already linearised, when it has
    # the same weights), with the outline candidates of approach 1 (else approach 2)
    source = candidates.get("approach1", candidates.get("approach2"))[1]
    joint = source.pop("joint", None)
    if joint is None or opts.front_weight != 1.0:
        joint = eng.joint(eng.views, outlines=source["outlines"])
    chosen, scores = _choose(eng, joint, candidates)
    state = candidates[chosen][0]
    eng.use(state)
    progress(0.85, "uncertainty and result")
    t = time.perf_counter()
    joint.cost(state)
    cov = joint.covariance(state)
    unc = _uncertainty(model, eng, cov)
    contour = joint.contour_residuals(state)
    pairs = joint.contour_pairs(state)
    info = {
        "approach": chosen,
        "candidates": {n: {"rms_px": r, "prior": p} for n, (r, p) in scores.items()},
        "iterations": {"profile_similarity": len(info_p.get("similarity_history", [0])) - 1,
                       "profile_shape": len(info_p.get("shape_history", [0])) - 1,
                       **{n: len(c[1]["history"]) - 1 for n, c in candidates.items()}},
        "errors": {"profile_similarity": info_p.get("similarity_history", []),
                   "profile_shape": info_p.get("shape_history", []),
                   **{n: c[1]["history"] for n, c in candidates.items()}},
        "contour_rms_px": {n: _rms(d) for n, d in contour.items()},
        "refit_state": {
            "coeffs": state.coeffs.copy(), "n_identity": int(opts.n_identity),
            "n_regional": int(opts.n_regional),
            "planes": {n: {"normal": p.normal.copy(), "offset": p.offset}
                       for n, p in state.planes.items()},
            "contour": {n: {"vertices": np.concatenate([p[0] for p in lst]),
                            "pixels": np.vstack([p[1] for p in lst])}
                        for n, lst in pairs.items()}},
    }
    if "approach1" in candidates and "calibration_rounds" in candidates["approach1"][1]:
        info["iterations"]["calibration_rounds"] = \
            candidates["approach1"][1]["calibration_rounds"]
    result = _make_result(model, eng, state, opts, opts.method, info, uncertainty=unc,
                          skipped=skipped)
    info["rms_px"] = {n: _rms(r.pixels) for n, r in result.residuals.items()}
    info["projection"], fitted = _projection_info(model, result, eng, opts)
    if state.planes:
        info["mirror"], more = _mirror_info(eng, state, opts)
        fitted += more
    # The refit keeps what the full fit found about cameras and mirrors, but says anew
    # which views it skipped: a dragged landmark can make a skipped view usable.
    info["refit_state"]["warnings"] = list(fitted)
    info["warnings"] = _skip_warnings(skipped) + fitted
    timings["result"] = time.perf_counter() - t
    timings["total"] = time.perf_counter() - t0
    info["timings"] = timings
    progress(1.0, f"done ({chosen})")
    return result


def refit_landmarks(model, case, previous, options=None):
    """The fast path while a landmark is dragged: one linear solve of the shape on the
    landmark rows, keeping ``previous``'s cameras, head pose and contour correspondences.

    Parameters
    ----------
    model : HeadModel
    case : LandmarkCase
        The same views as the fit that produced ``previous`` (landmarks moved, added or
        removed).
    previous : FitResult
        From :func:`fit_head` (or this function) on this model.
    options : FitOptions, optional
        Weights, priors and flagging (``n_identity``/``n_regional`` are taken from
        ``previous``).

    Returns
    -------
    FitResult
        Uncertainty and ``detail`` are carried over from ``previous`` (no TPS here); the
        residuals are recomputed.

    Raises
    ------
    ValueError
        ``previous`` is not a fit of this kind, a view is missing from it, or the case is
        invalid (as in :func:`fit_head`).
    """
    t0 = time.perf_counter()
    saved = getattr(previous, "info", {}).get("refit_state") if previous is not None else None
    if saved is None:
        raise ValueError("previous: expected a FitResult from fit_head (its info has no "
                         "'refit_state')")
    opts = _check_options(options, model)
    opts = FitOptions(**{**opts.__dict__, "n_identity": int(saved["n_identity"]),
                         "n_regional": int(saved["n_regional"]), "method": previous.method})
    views, skipped = _prepare_views(model, case, opts,
                                    cameras=_previous_cameras(previous, "previous"))
    eng = _engine(model, views, opts)
    state, saved = _saved_state(previous, eng, views, "previous")
    eng.use(state)
    rows, verts = [], []
    off = 0
    for v in views:
        n = len(v.vertices)
        if n:
            w = (1.0 if v.side else opts.front_weight) * eng.inv_var * v.weights
            rows.append(ImageRows(np.arange(off, off + n), v.pixels, v.camera, weights=w,
                                  name=f"landmarks {v.name}"))
            verts.append(v.vertices)
            off += n
        pairs = saved.get("contour", {}).get(v.name)
        if pairs is not None and len(pairs["vertices"]):
            cv = np.asarray(pairs["vertices"], dtype=np.int64)
            rows.append(ImageRows(np.arange(off, off + len(cv)), pairs["pixels"], v.camera,
                                  weights=opts.contour_weight * eng.inv_var,
                                  name=f"contour {v.name}"))
            verts.append(cv)
            off += len(cv)
    problem = eng.problem(eng.copies_model(np.concatenate(verts)), rows,
                          freeze=("rotation",))
    fit = problem.solve(scale=state.scale, rotation=state.rotation,
                        translation=state.translation, coeffs=state.coeffs,
                        max_iterations=1, tolerance=0.0, sigma=1.0)
    state.coeffs = fit.coeffs.copy()
    info = {"approach": previous.info.get("approach", previous.method), "refit": True,
            "refit_state": {**saved, "coeffs": state.coeffs.copy()},
            "warnings": _skip_warnings(skipped) + list(saved.get("warnings", []))}
    result = _make_result(model, eng, state, opts, previous.method, info,
                          uncertainty=np.asarray(previous.uncertainty).copy(),
                          detail=np.asarray(previous.detail).copy(), skipped=skipped)
    info["rms_px"] = {n: _rms(r.pixels) for n, r in result.residuals.items()}
    info["timings"] = {"total": time.perf_counter() - t0}
    return result
