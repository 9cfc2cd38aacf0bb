"""How to fit: the options of ``fit_head`` and their checks."""

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

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
    noise : {"estimate", "fixed"}
        "estimate": the placement noise of each view's landmarks and outline is estimated
        from the fit's own residuals, with a Student-t weight per landmark, and the fit
        repeated with them (``noise.py``); ``noise_px`` is then the least noise assumed.
        "fixed": every landmark and outline point is placed with ``noise_px``.
    noise_px : float
        Standard deviation of landmark placement the weights assume (the floor of the
        estimate), pixels.
    outline_landmarks : {"vertex", "slide"}
        How the outline points of a front photo (``assets/landmarks.json`` "outline": the
        jaw, the chin, the head's and neck's sides) are fitted. "vertex" (default): each to
        its model vertex, as any landmark. "slide": across the posed model's silhouette,
        loosely along it (``OutlinePointRows``, ``OutlineAlongRows``). In a profile photo
        those without a meaning there are left out either way.
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
    noise: str = "estimate"
    noise_px: float = 1.0
    outline_landmarks: str = "vertex"
    contour_weight: float = 1.0
    contour_threshold_px: float = 20.0
    landmark_weights: dict | None = None
    fixed_cameras: tuple = ()
    flag_sigmas: float = 3.0
    flag_min_px: float = 5.0
    tps_iterations: int = 6
    camera_distance_m: float | None = None
    calibration_rounds: int = 8


def check_options(options, model):
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
    if o.noise not in ("estimate", "fixed"):
        raise ValueError(f"options.noise: {o.noise!r}; use 'estimate' or 'fixed'")
    if o.outline_landmarks not in ("vertex", "slide"):
        raise ValueError(f"options.outline_landmarks: {o.outline_landmarks!r}; use 'vertex' "
                         "or 'slide'")
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

