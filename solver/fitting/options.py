"""How to fit: the options of ``fit_head`` and their checks."""

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: ``FitOptions.method``: both thesis approaches keeping the better fit, or one of them.
FIT_METHODS = ("combined", "approach1", "approach2")
#: The head's sizes in the photos the fit's pixel settings are made for, (smallest,
#: largest): its landmarks spread over this many pixels per metre of the same landmarks on
#: the mean head (the benchmarks' photos, 1024 px high with the head filling them:
#: 1870-2650). A head larger or smaller in its photo gets its settings scaled with it from
#: the nearer end (``pixel_scale``).
REFERENCE_PX_PER_M = (1800.0, 2700.0)
#: The least placement noise (px) a scaled-down noise floor reaches: no landmark is placed
#: finer than half a pixel of its photo (a pixel's own quantisation is 0.29 px a coordinate).
LEAST_NOISE_PX = 0.5


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
        estimate), pixels (of a head the size it is in the benchmarks' 1024-px photos:
        see ``pixel_scale``).
    expressions : {"fit", "neutral"}
        "fit" (default): with ``noise="estimate"`` each photo's expression (eyes closed, a
        smile) is estimated from its landmarks and taken out of them before the identity
        is fitted again (``expression.py``; ``info["expressions"]`` reports it); with
        ``noise="fixed"`` the expressions of ``initial``, if any, are taken out.
        "neutral": the faces in the photos are assumed neutral.
    outline_landmarks : {"vertex", "slide"}
        How the outline points of a front photo (``assets/landmarks.json`` "outline": the
        jaw, the chin, the head's and neck's sides) are fitted. "vertex" (default): each to
        its model vertex, as any landmark. "slide": across the posed model's silhouette,
        loosely along it (``OutlinePointRows``, ``OutlineAlongRows``). In a profile photo
        those without a meaning there are left out either way.
    definition_mm : float
        Standard deviation of the offset a landmark group (an eye, a brow, one side of the
        jaw; ``assets/landmarks.json`` "group") shares in a photo, millimetres on the
        face: where "the brow" lies is a convention that differs between people,
        detectors and the model, so a group's common shift is mostly not shape
        (``definition.GroupedImageRows``). 0: every landmark's error independent.
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
    pixel_scale : float or None
        Photo pixels per pixel of the settings above (``noise_px``,
        ``contour_threshold_px``, ``flag_min_px``) and of the fit's own outline spacing
        and normals: None (default) from the head's size in the photos
        (``views.photo_scale``: 1 within ``REFERENCE_PX_PER_M``, else over its nearer
        end), so a 12-megapixel photo fits as the same photo 1024 px high does, and a
        512-px one closer to it than with the settings as given.
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
    definition_mm: float = 2.0
    expressions: str = "fit"
    contour_weight: float = 1.0
    contour_threshold_px: float = 20.0
    landmark_weights: dict | None = None
    fixed_cameras: tuple = ()
    flag_sigmas: float = 3.0
    flag_min_px: float = 5.0
    tps_iterations: int = 6
    camera_distance_m: float | None = None
    calibration_rounds: int = 8
    pixel_scale: float | None = None


#: (least, most) of each numeric option: beyond them a fit means nothing or overflows
#: (``lambda2=1e300`` overflowed the prior's cost; ``noise_px=1e-300`` the weights).
RANGES = {
    "lambda1": (0.0, 1e6), "lambda2": (0.0, 1e6), "landmark_weight": (0.0, 1e6),
    "front_weight": (0.0, 1e6), "contour_weight": (0.0, 1e6), "flag_sigmas": (0.0, 1e3),
    "flag_min_px": (0.0, 1e6), "noise_px": (1e-3, 1e4), "contour_threshold_px": (1e-2, 1e6),
    "tolerance": (1e-12, 1.0), "camera_distance_m": (1e-2, 1e4),
    "definition_mm": (0.0, 1e3), "pixel_scale": (1e-3, 1e3),
}
#: (least, most) of each whole-number option.
INT_RANGES = {"max_iterations": (1, 10000), "tps_iterations": (1, 1000),
              "calibration_rounds": (0, 1000), "n_regional": (0, 1000)}


def _number_problem(name, value):
    """The message for a numeric option outside ``RANGES``, or None."""
    lo, hi = RANGES[name]
    ok = not isinstance(value, bool) and isinstance(value, int | float | np.floating) \
        and np.isfinite(value) and lo <= value <= hi
    return None if ok else (f"options.{name}: must be a number in [{lo:g}, {hi:g}], got "
                            f"{value!r}")


def _integer_problem(name, value, hi=None):
    """The message for a whole-number option outside ``INT_RANGES`` (or ``hi``), or None."""
    lo, top = INT_RANGES.get(name, (0, hi))
    top = top if hi is None else hi
    ok = not isinstance(value, bool) and isinstance(value, int | np.integer) \
        and lo <= value <= top
    return None if ok else (f"options.{name}: must be an integer in {lo}..{top}, got "
                            f"{value!r}")


def check_options(options, model):
    """``options`` (None: the defaults) checked against ``RANGES`` and the model.

    Raises
    ------
    ValueError
        Naming the option (``options.<name>``) with its allowed values or range.
    """
    o = FitOptions() if options is None else options
    if not isinstance(o, FitOptions):
        raise ValueError(f"options: expected FitOptions, got {type(o).__name__}")
    if o.method not in FIT_METHODS:
        raise ValueError(f"options.method: {o.method!r}; use one of {', '.join(FIT_METHODS)}")
    problems = [_integer_problem("n_identity", o.n_identity, model.identity.n_coeffs)]
    problems += [_integer_problem(name, getattr(o, name)) for name in INT_RANGES]
    problems += [_number_problem(name, getattr(o, name)) for name in RANGES
                 if name not in ("camera_distance_m", "pixel_scale")
                 or getattr(o, name) is not None]
    problems = [p for p in problems if p is not None]
    if problems:
        raise ValueError(problems[0])
    if o.n_identity == 0 and o.n_regional == 0:
        raise ValueError("options.n_identity, options.n_regional: both 0 leave no shape to "
                         "fit")
    if o.n_regional > 0 and hasattr(model, "regional"):
        try:
            model.regional(o.n_regional)  # kept with the model: the fit uses it next
        except ValueError as e:
            raise ValueError(f"options.n_regional: {e}") from None
    if o.noise not in ("estimate", "fixed"):
        raise ValueError(f"options.noise: {o.noise!r}; use 'estimate' or 'fixed'")
    if o.expressions not in ("fit", "neutral"):
        raise ValueError(f"options.expressions: {o.expressions!r}; use 'fit' or 'neutral'")
    if o.outline_landmarks not in ("vertex", "slide"):
        raise ValueError(f"options.outline_landmarks: {o.outline_landmarks!r}; use 'vertex' "
                         "or 'slide'")
    if o.prior not in ("eigen", "identity"):
        raise ValueError(f"options.prior: {o.prior!r}; use 'eigen' or 'identity'")
    if o.progress is not None and not callable(o.progress):
        raise ValueError("options.progress: must be callable(fraction, message) or None")
    return o


def in_photo_pixels(opts, scale):
    """``opts`` with its pixel settings (``noise_px``, ``contour_threshold_px``,
    ``flag_min_px``) in photo pixels: times ``scale``, the photos' pixels per pixel of the
    settings (kept as ``pixel_scale``); scaled down, the noise stops at ``LEAST_NOISE_PX``
    (or at its own value, where that is smaller)."""
    noise = opts.noise_px * scale
    if scale < 1.0:
        noise = max(noise, min(opts.noise_px, LEAST_NOISE_PX))
    return dataclasses.replace(opts, noise_px=noise,
                               contour_threshold_px=opts.contour_threshold_px * scale,
                               flag_min_px=opts.flag_min_px * scale,
                               pixel_scale=float(scale))
