"""Fit the head model to landmarks on photos (thesis §4.4, §9), composed from the stages
of this package: a front and a profile
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
  camera (no profile stage) it does worse than approach 1 (docs/DECISIONS.md), so there
  combined is approach 1 alone; and the fits after the first (with the estimated noise)
  refine the first one's head with approach 1 alone, which won every such fit measured.
  A head those fits leave in a wrong minimum (tilted and bent so that a stretch of a
  traced outline finds no outline row) is fitted once more with the settled noise, from
  the first fit's other approach's head, and where the head kept still misses the
  outline, from the mean head; the clearly lowest posterior cost wins. A head that
  comes out implausible under the model is fitted again with a stronger prior, and kept
  where its landmarks fit about as well (``PRIOR_STEPS``); the head a stronger prior gives
  is also one more start where the head still misses the outline or lies beyond
  ``UNUSUAL_PERCENTILE`` of the model's heads.

Cameras: no photo is assumed to share scale, tilt or framing with another. Nominal
orthographic cameras whose landmarks show a side photo short of a profile are first placed
by the yaws the landmarks show (``view_guess.placed_by_landmarks``). Each keeps its
own camera, solved together with the head in every Gauss-Newton step (its parameters as
extra modes of the shape-ICP) and re-calibrated through ``Camera.refit`` (see
``joint.py``, and ``engine.py`` for the gauge: head scale 1 and translation 0 when every
camera is free, and the head's rotation too when they are all perspective; the identity
modes carry the head's size). Self-calibrated perspective cameras alternate full
re-calibrations with joint rounds until both settle (:func:`approach1`). A mirror view's
camera is its photo's camera reflected in a mirror plane the fit estimates
(``Engine.initial_plane``, seed 001 ch. 3); ``info["mirror"]`` reports the plane and each
landmark's gap between its direct and its mirrored ray. ``info["projection"]`` reports
each photo's parallel-projection error (seed 001 ch. 2) and ``info["warnings"]`` what the
user should know.

Everything is least squares in pixels weighted by 1 / sigma^2 against the prior
``lambda2^2 |c|^2`` (c in standard deviations), sigma the placement noise the fit
estimates from its own residuals (``noise.py``; ``noise_px`` its floor), so with
``lambda2 = 1`` the fit is the posterior mode for landmarks placed with that noise, and the
inverse normal matrix is the posterior covariance behind ``FitResult.uncertainty``.
"""


import dataclasses
import time

import numpy as np

from ..cameras import ORTHO_VIEWS, OrthographicCamera
from ..detect.view_guess import placed_by_landmarks
from ..errors import rms
from ..geometry import rotation_from_vector
from .approach1 import approach1, profile_fit
from .approach2 import approach2
from .checks import post_fit_warnings
from .engine import Engine, fitted_model, skin_basis32
from .expression import (
    estimate_expressions,
    expression_report,
    expressions_moved,
    neutral_case,
)
from .noise import MAX_ROUNDS, estimate_noise
from .options import FitOptions, check_options, in_photo_pixels
from .outcome import (
    PLAUSIBLE_PERCENTILE,
    choose,
    lens_warnings,
    make_result,
    mirror_info,
    plausibility,
    prior_raised_warning,
    projection_info,
    skin_maps,
    vertex_uncertainty,
)
from .outline import body_weights, outline_candidates
from .pose import init_pose
from .rows import ImageRows
from .views import (
    State,
    drop_warnings,
    photo_scale,
    prepare_views,
    previous_cameras,
    saved_state,
    skip_warnings,
    unused_views,
)


class Progress:
    """The options' progress callback, given fractions of the part ``lo`` .. ``hi`` of
    the whole fit."""

    def __init__(self, callback, lo=0.0, hi=1.0):
        self.callback, self.lo, self.hi = callback, lo, hi

    def __call__(self, fraction, message):
        if self.callback is not None:
            f = self.lo + (self.hi - self.lo) * float(min(max(fraction, 0.0), 1.0))
            self.callback(f, message)

    def part(self, lo, hi):
        """The progress of a part: ``lo`` .. ``hi`` of this one."""
        span = self.hi - self.lo
        return Progress(self.callback, self.lo + span * lo, self.lo + span * hi)


def prepare_fit(model, options=None):
    """Make what every fit of ``model`` with ``options`` (default ``FitOptions()``) makes
    once and keeps with the model: the fitted modes, the skin's float32 basis and maps for
    the uncertainty, the profile's outline candidates, the expressions; so the first fit
    does not wait for them (the add-on's warm-up runs this while the artist places
    photos)."""
    opts = options or FitOptions()
    check_options(opts, model)
    skin_basis32(fitted_model(model, opts), np.asarray(model.skin, dtype=np.int64))
    skin_maps(model)
    outline_candidates(model)
    _ = model.expressions


#: A fit whose head misses more than this share of a photo's traced outline is run again
#: from other starts (a head bent into the wrong minimum leaves a stretch of the outline
#: unmatched; docs/DECISIONS.md).
MISSED_OUTLINE = 0.08
#: ... and such a fit's head is kept only if its posterior cost is lower by more than this
#: share: between two heads near a tie the cost does not tell the better one.
SECOND_START_GAIN = 0.1
#: Where a view's outline below the neck's base is more than this many times as uncertain
#: as the rest of it (``noise.Noise.body_ratio``: bare shoulders, a top coloured as skin),
#: the first noise round starts again from the mean head, not from the first fit's head,
#: which was bent to the body (docs/DECISIONS.md, "The outline below the neck's base").
BODY_RESTART = 2.0
#: An implausible head (``outcome.PLAUSIBLE_PERCENTILE``) is fitted again with the prior's
#: weight raised by these factors in turn, until its head is plausible ...
PRIOR_STEPS = (1.5, 2.0, 3.0)
#: ... each kept only while its landmarks' RMS reprojection error stays within this factor
#: of the first fit's: the landmarks then do not tell the implausible head from a nearer
#: one, as where a lens or a turn is unknown; a truly unusual head's landmarks do.
PRIOR_RMS_SLACK = 1.05
#: A plausible head beyond this percentile of the model's heads is fitted once more from
#: the head a stronger prior gives: a fitted head is drawn toward the mean head, so one
#: this far out is more often a head bent into a wrong minimum than an unusual person
#: (docs/DECISIONS.md, "A head far out under the model: the stronger prior's start").
UNUSUAL_PERCENTILE = 90.0
#: A fit with an orthographic photo turned in its own plane by more than this many degrees
#: is fitted once more from the head that carries the turn, the photos level
#: (:func:`level_photos_start`), kept where its posterior cost is clearly lower.
LEVEL_START_DEG = 6.0


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
        model sizes) instead of the mean head, with the placement noise and the photos'
        expressions it estimated (its ``refit_state``); the profile stage is then
        skipped.

    Returns
    -------
    FitResult
        ``info`` holds: "approach" (the one the first fit chose), "candidates" (each
        approach's RMS reprojection error in pixels and prior in that fit), "iterations"
        and "errors" per stage ("calibration_rounds": re-calibrations of self-calibrated
        cameras in approach 1),
        "timings" (seconds), "rms_px" per view and "contour_rms_px", "projection" (per
        photo the parallel-projection error epsilon, see :func:`projection_info`),
        "mirror" (per mirror view the plane and the landmarks' ray gaps),
        "noise" (the estimated placement noise per view, every landmark's weight and the
        number of fits, ``noise.Noise.report``; not with ``noise="fixed"``),
        "plausibility" (the identity's Mahalanobis norm and its percentile under the
        model, ``outcome.plausibility``), "unused" (the views skipped and the
        landmarks left out per view, ``views.unused_views``), "warnings"
        (messages for the user), "refit_state" (what :func:`refit_landmarks`
        continues from) and, when the head was fitted again from other starts (it
        missed more than ``MISSED_OUTLINE`` of a traced outline), "starts": "costs", the
        posterior cost each start ended at ("continued", "other approach" and, where the
        head kept still missed it, "mean head", then "stronger prior's head"; the last
        also where an implausible head's raised fits were not kept or the head lies beyond
        ``UNUSUAL_PERCENTILE``; "photos level" where a photo ended turned in its plane by
        more than ``LEVEL_START_DEG``, :func:`level_photos_start`), and "kept", the
        start whose head was kept (another's only when lower by more than
        ``SECOND_START_GAIN``); and, when
        the first head was implausible, "prior": "first" (its plausibility and landmark
        RMS in pixels), "tried" (each fit with the prior's weight raised: "factor",
        "mahalanobis", "percentile", "rms_px") and "factor", the one kept (1: the first
        head; see ``PRIOR_STEPS``). With ``options.expressions`` "fit": "expressions"
        (per view, each expression its photo showed and taken out: its weight) and
        "expression_sd" (the same names: each weight's standard deviation, how surely the
        landmarks tell it from neutral).

    Raises
    ------
    ValueError
        Bad options, a view with an unknown camera kind or too few landmarks (naming the
        view and how many more it needs), unknown landmark names, a mirror view that
        cannot be placed, an unusable ``initial``.
    """
    t0 = time.perf_counter()
    opts = _in_photo_pixels(model, case, check_options(options, model))
    progress = Progress(opts.progress)
    state0 = (getattr(initial, "info", None) or {}).get("refit_state") or {}
    factor = float(state0.get("prior_factor", 1.0))
    turned = []
    if initial is None:  # a side photo short of a profile, its landmarks placed by hand
        case, turned = placed_by_landmarks(model, case)
    result, checked, another = _noise_rounds(model, case, _prior_raised(opts, factor),
                                             initial, state0, progress, t0)
    if initial is None:
        def refit(f, part):
            return _noise_rounds(model, case, _prior_raised(opts, f), None, {},
                                 progress.part(*part), t0)[0]

        result, factor, raised = _more_plausible(result, refit)
        if factor == 1.0 and another is not None:
            result = _from_stronger_prior(case, result, raised, refit, another)
            level = level_photos_start(result)
            if level is not None:
                result = another("photos level", level)
    result.info["refit_state"]["prior_factor"] = factor
    result.info["warnings"][:0] = turned
    return _checked(model, checked, _prior_raised(opts, factor), result)


def _prior_raised(opts, factor):
    """``opts`` with the prior's weight ``lambda2`` raised ``factor`` times."""
    return opts if factor == 1.0 else dataclasses.replace(opts, lambda2=opts.lambda2 * factor)


def _more_plausible(result, refit):
    """``result``, or where its head is implausible (``outcome.plausibility``) the fit again
    with the prior's weight raised by each of ``PRIOR_STEPS`` in turn (``refit(factor,
    (lo, hi))``, the part of the progress it reports in), until a head is plausible; a
    raised fit is kept while its landmarks' RMS reprojection error stays within
    ``PRIOR_RMS_SLACK`` of the first's (docs/DECISIONS.md, "An implausible head is fitted
    again with a stronger prior"). Returns (result, the factor kept); ``info["prior"]``
    says what was tried."""
    first = result.info["plausibility"]
    if first["percentile"] <= PLAUSIBLE_PERCENTILE:
        return result, 1.0, []
    rms0, t = result.rms_px(), time.perf_counter()
    kept, factor, tried, heads = result, 1.0, [], []
    for i, f in enumerate(PRIOR_STEPS):
        lo = 0.9 + 0.1 * i / len(PRIOR_STEPS)
        again = refit(f, (lo, lo + 0.1 / len(PRIOR_STEPS)))
        heads.append(again)
        p, r = again.info["plausibility"], again.rms_px()
        tried.append({"factor": f, "mahalanobis": p["mahalanobis"],
                      "percentile": p["percentile"], "rms_px": r})
        if r > PRIOR_RMS_SLACK * rms0:
            break
        kept, factor = again, f
        if p["percentile"] <= PLAUSIBLE_PERCENTILE:
            break
    timings = dict(result.info["timings"])
    timings["stronger_prior"] = time.perf_counter() - t
    timings["total"] += timings["stronger_prior"]
    kept.info["timings"] = timings
    kept.info["prior"] = {"factor": factor, "first": {**first, "rms_px": rms0},
                          "tried": tried}
    if factor != 1.0:
        lens = [w for w in lens_warnings(kept.cameras) if w not in kept.info["warnings"]]
        kept.info["warnings"][:0] = [prior_raised_warning(first, rms0, kept, factor), *lens]
    return kept, factor, heads


def _from_stronger_prior(case, result, raised, refit, another):
    """``result``, or the fit of its own problem from the head a stronger prior gives,
    where that ends at a posterior cost clearly lower (``another``, as the other starts
    are kept): a fit with the prior's weight raised has fewer minima, so its head lies in
    another basin of the problem. The head is ``raised[0]`` (the first raised fit of an
    implausible head, not kept for its landmarks' error), else, where the head still
    misses more than ``MISSED_OUTLINE`` of a traced outline or lies beyond
    ``UNUSUAL_PERCENTILE`` of the model's heads, a fit with the weight raised by
    ``PRIOR_STEPS[0]`` (``refit``) (docs/DECISIONS.md, "A stronger prior's head as a
    start")."""
    suspect = result.info["plausibility"]["percentile"] > UNUSUAL_PERCENTILE \
        or outline_missed(case, result) > MISSED_OUTLINE
    if not raised and (not suspect or not PRIOR_STEPS):
        return result
    t = time.perf_counter()
    before = result.info["timings"].get("stronger_prior", 0.0)
    prior = result.info.get("prior")
    out = another("stronger prior's head",
                  raised[0] if raised else refit(PRIOR_STEPS[0], (0.9, 0.99)))
    if prior is not None:
        out.info["prior"] = prior
    out.info["timings"]["stronger_prior"] = before + time.perf_counter() - t
    return out


def level_photos_start(result):
    """``result`` with each orthographic photo turned back level in its own plane and the
    head turned instead, so that photo sees it as before; None where no photo of two or
    more orthographic ones is turned by more than ``LEVEL_START_DEG``. A photo's turn in
    its plane and the head's tilt trade in that photo, and only the other photos tell them
    apart, so a fit can end with a photo turned to match a head tilted wrongly; from
    this start the tilt lies with the head (docs/DECISIONS.md, "A photo turned in its
    plane to meet a head tilted wrongly"). A photo stored a quarter or half turn round
    (a camera held on its side) is level at that turn: its angle is taken off the nearest
    quarter turn."""
    ortho = {n: c for n, c in result.cameras.items()
             if isinstance(c, OrthographicCamera) and c.view in ORTHO_VIEWS}
    quarter = np.pi / 2
    angles = {n: c.in_plane_angle - quarter * np.round(c.in_plane_angle / quarter)
              for n, c in ortho.items()}
    if len(ortho) < 2 or max(abs(a) for a in angles.values()) <= np.radians(LEVEL_START_DEG):
        return None
    turn, cameras = np.eye(3), dict(result.cameras)
    for name, cam in ortho.items():
        in_plane = rotation_from_vector((0.0, 0.0, angles[name]))  # about the view axis
        cameras[name] = OrthographicCamera(in_plane.T @ cam.rotation, cam.scale, cam.offset,
                                           cam.size, cam.view)
        turn = (cam.rotation.T @ in_plane @ cam.rotation) @ turn
    return dataclasses.replace(result, rotation=turn @ result.rotation,
                               translation=turn @ result.translation, cameras=cameras)


def _noise_rounds(model, case, opts, initial, state0, progress, t0):
    """The fit of :func:`fit_head` with ``opts`` as they are: the noise rounds (or one fit
    with fixed noise) and, where the head misses the outline, its other starts. Returns
    (result, the case its checks read, a function ``(key, head) -> result``: the fit from
    another ``head`` with the noise and expressions the rounds settled on where its
    posterior cost is lower by more than ``SECOND_START_GAIN``, else the result, either
    recording it in ``info["starts"]`` under ``key``; None without noise rounds).
    ``state0``: ``initial``'s ``refit_state`` (or {})."""
    # A given head goes on with the photos' expressions (taken out of the landmarks) and
    # the noise it was fitted with, so its own fit is where it stays (from the landmarks as
    # given and the default noise, its first round would move it first).
    start_noise, start_shown = state0.get("noise"), state0.get("expressions") or {}
    start_sd = state0.get("expression_sd") or {}
    given = case
    if start_shown and opts.expressions == "fit":
        given = neutral_case(model, case, initial, start_shown)
    if opts.noise == "fixed":
        return _fit(model, given, opts, initial, None, progress, t0)[0], given, None
    # The noise from the fit's residuals (and each photo's expression, expression.py), the
    # fit again with them, until the estimates settle (noise.py); each fit after the first
    # starts where the last one ended.
    first = _fit(model, given, opts, initial, start_noise, progress.part(0.0, 0.55), t0,
                 uncertainty=False)
    result, contour, along, effective, measured, roles, finish, other_start = first
    later = opts if opts.method != "combined" else dataclasses.replace(opts,
                                                                       method="approach1")
    noise, rounds, expressions, expression_sd = start_noise, 1, start_shown, start_sd
    restarted = False
    timings = dict(result.info["timings"])
    while rounds < MAX_ROUNDS:
        estimate = estimate_noise(measured[0], contour, effective, opts.noise_px, along,
                                  definition=measured[2], rim=roles[0], relative=roles[1])
        shown, shown_sd = expressions, expression_sd
        if opts.expressions == "fit":
            shown, shown_sd = estimate_expressions(model, case, result, estimate.landmark_px,
                                                   estimate.weights, opts.lambda2)
        if noise is not None and noise.settled(estimate) \
                and not expressions_moved(expressions, shown):
            break
        noise, expressions, expression_sd = estimate, shown, shown_sd
        part = 0.55 + 0.12 * (rounds - 1)
        # a first fit that bent the head to a body the model does not follow is no start
        start = None if rounds == 1 and initial is None \
            and noise.body_ratio() > BODY_RESTART else result
        restarted |= start is None
        result, contour, along, effective, measured, roles, finish, _ = _fit(
            model, neutral_case(model, case, result, expressions), later, start, noise,
            progress.part(part, part + 0.12), t0, uncertainty=False)
        rounds += 1
        _add_timings(timings, result.info["timings"])

    def from_head(start, part, kept):
        """The fit from ``start`` (a FitResult, or None: the mean head) with the noise and
        expressions settled on (taken out of the photos as ``kept`` sees them): (its
        ``_fit`` answer, its posterior cost)."""
        again = _fit(model, neutral_case(model, case, kept, expressions), later, start,
                     noise, part, t0, uncertainty=False)
        _add_timings(timings, again[0].info["timings"])
        return again, _cost(again[0])

    def finished(fitted, starts):
        """The rounds' result from ``fitted`` (a ``_fit`` answer): its uncertainty, and
        what the rounds found in its info."""
        result, finish = fitted[0], fitted[6]
        result.uncertainty, result.method = finish(), opts.method
        # the choice between the approaches was made in the first fit, the only one
        # running both
        result.info.update({k: first[0].info[k] for k in ("approach", "candidates")})
        result.info["noise"] = {**noise.report(), "fits": rounds, "restarted": restarted}
        if starts is not None:
            result.info["starts"] = starts
        result.info["refit_state"]["noise"] = noise
        if opts.expressions == "fit":
            result.info["expressions"] = expression_report(model, expressions)
            result.info["expression_sd"] = expression_report(model, expressions,
                                                             expression_sd)
            result.info["refit_state"]["expressions"] = expressions
            result.info["refit_state"]["expression_sd"] = expression_sd
        result.info["timings"] = dict(timings)
        return result

    fitted = (result, contour, along, effective, measured, roles, finish, other_start)
    costs = {"continued": _cost(result)}
    starts = {"costs": costs, "kept": "continued"}
    if initial is None and outline_missed(case, result) > MISSED_OUTLINE:
        # More starts (approach 1, as the rounds): from the head of the first fit's other
        # approach where it ran two (a round's cost), then, while the head kept still
        # misses the outline, from the mean head (a whole first fit); the clearly lowest
        # posterior cost is kept.
        other = other_start()
        tries = ([("other approach", other)] if other is not None else []) \
            + [("mean head", None)]
        for i, (key, start) in enumerate(tries):
            if i and outline_missed(case, fitted[0]) <= MISSED_OUTLINE:
                break
            part = progress.part(0.91 + 0.04 * i, 0.95 + 0.04 * i)
            again, costs[key] = from_head(start, part, fitted[0])
            if costs[key] < (1.0 - SECOND_START_GAIN) * costs[starts["kept"]]:
                fitted, starts["kept"] = again, key
    result = finished(fitted, starts if len(costs) > 1 else None)
    progress(1.0, f"done ({result.info['approach']}, {rounds} fits)")

    best = result

    def another(key, start):
        """The result kept so far (the rounds', or an earlier start's), or the fit from
        ``start`` (``from_head``) where its posterior cost is clearly lower;
        ``info["starts"]`` records it under ``key``."""
        nonlocal best
        again, costs[key] = from_head(start, progress.part(0.99, 1.0), result)
        if costs[key] < (1.0 - SECOND_START_GAIN) * costs[starts["kept"]]:
            starts["kept"] = key
            best = finished(again, starts)
        else:
            best.info["starts"], best.info["timings"] = starts, dict(timings)
        return best

    return result, case, another


def _in_photo_pixels(model, case, opts):
    """``opts`` in the case's photo pixels (``options.in_photo_pixels``): scaled by its own
    ``pixel_scale``, else by the head's size in the photos (``views.photo_scale``), so a
    large or small photo fits as the same photo at the size the settings were made for
    (docs/DECISIONS.md, "Large photos")."""
    scale = opts.pixel_scale if opts.pixel_scale is not None else photo_scale(model, case)
    return in_photo_pixels(opts, scale)


def _add_timings(timings, more):
    """Add a later fit's stage seconds to ``timings``; its "total" (since the start) is
    the new total."""
    for stage, seconds in more.items():
        timings[stage] = seconds if stage == "total" else timings.get(stage, 0.0) + seconds


def outline_missed(case, result):
    """The largest share, over the photos with a traced outline, of its points that the
    fitted head's outline left unmatched (no outline row within the cut-off)."""
    pairs = result.info["refit_state"]["contour"]
    shares = [1.0 - len(pairs[n]["pixels"]) / len(v.contour) if n in pairs else 1.0
              for n, v in case.views.items()
              if v.contour is not None and len(v.contour) >= 2 and n in result.cameras]
    return max(shares, default=0.0)


def _cost(result):
    """The posterior cost a fit with estimated noise ended at (its chosen candidate's)."""
    return result.info["candidates"][result.info["approach"]]["rms_px"]


def _checked(model, case, opts, result):
    """``result`` with the warnings of the checks after a fit (checks.py)."""
    def quick_fit(c, o):  # the checks read its landmark residuals only
        return _fit(model, c, o, None, None, Progress(None), time.perf_counter(),
                    uncertainty=False)[0]

    result.info["warnings"] += post_fit_warnings(model, case, result, opts, quick_fit)
    return result


def _fit(model, case, opts, initial, noise, progress, t0, uncertainty=True):
    """One fit of the case with landmark and outline weights from ``noise`` (None: all
    placed with ``noise_px``), from ``initial``'s state when given. Returns (result,
    contour residuals per view, the sliding landmarks' residuals along the outline per
    view, effective number of fitted parameters,
    ``Engine.without_definition_offsets``: the landmark residuals the noise is measured on
    and the definition offsets' size per view, per view the outline landmarks tied to
    their vertices and each landmark's weight factor from its given uncertainty, a
    function giving the result's per-vertex uncertainty, and one giving the head of the
    approach not chosen as a FitResult to start from, or None). Without ``uncertainty``
    the result has none yet (the noise rounds need only the last fit's)."""
    cams = None if initial is None else previous_cameras(initial, "initial")
    views, skipped = prepare_views(model, case, opts, cameras=cams, noise=noise)
    eng = Engine.for_fit(model, views, opts)
    timings = {}
    info_p = {}
    if initial is None:
        state = State(np.eye(3), np.zeros(eng.lin.n_coeffs), {v.name: v.camera for v in views})
        progress(0.0, "placing the cameras")
        init_pose(eng, state)
        eng.init_cameras(state)
        eng.finish_views(state)
        progress(0.05, "fitting the profile")
        t = time.perf_counter()
        state_p, info_p = profile_fit(eng, state, opts)
        timings["profile"] = time.perf_counter() - t
    else:
        state_p, _ = saved_state(initial, eng, views, "initial")
        eng.finish_views(state_p)
    candidates = {}
    if opts.method in ("approach1", "combined"):
        progress(0.35, "approach 1: landmark ICP")
        t = time.perf_counter()
        eng.use(state_p)
        candidates["approach1"] = approach1(model, eng, state_p.copy(), opts,
                                            staged=initial is None)
        timings["approach1"] = time.perf_counter() - t
    if opts.method == "approach2" or (opts.method == "combined" and not any(
            eng.real_view(v).camera.perspective for v in eng.views)):
        progress(0.6, "approach 2: TPS-ICP")
        t = time.perf_counter()
        eng.use(state_p)
        candidates["approach2"] = approach2(eng, model, state_p.copy(), opts)
        timings["approach2"] = time.perf_counter() - t
    # the result's problem over all views (approach 1's, already linearised, when it has
    # the same weights), with the outline candidates of approach 1 (else approach 2)
    source = candidates.get("approach1", candidates.get("approach2"))[1]
    joint = source.pop("joint", None)
    if joint is None or opts.front_weight != 1.0:
        joint = eng.joint(eng.views, outlines=source["outlines"])
    chosen, scores = choose(eng, joint, candidates, by_cost=noise is not None)
    state = candidates[chosen][0]
    eng.use(state)
    progress(0.85, "uncertainty and result")
    t = time.perf_counter()
    joint.cost(state)
    cov = joint.covariance(state)

    def finish():
        return vertex_uncertainty(model, eng, cov)

    unc = finish() if uncertainty else None
    contour = joint.contour_residuals(state)
    pairs = joint.contour_pairs(state, kinds=("contour",))
    matches = joint.outline_matches(state)
    along = joint.along_residuals(state)
    info = {
        "approach": chosen,
        "candidates": {n: {"rms_px": r, "prior": p} for n, (r, p) in scores.items()},
        "iterations": {"profile_similarity": len(info_p.get("similarity_history", [0])) - 1,
                       "profile_shape": len(info_p.get("shape_history", [0])) - 1,
                       **{n: len(c[1]["history"]) - 1 for n, c in candidates.items()}},
        "errors": {"profile_similarity": info_p.get("similarity_history", []),
                   "profile_shape": info_p.get("shape_history", []),
                   **{n: c[1]["history"] for n, c in candidates.items()}},
        "contour_rms_px": {n: rms(d) for n, (d, _) in contour.items()},
        "refit_state": {
            "coeffs": state.coeffs.copy(), "n_identity": int(opts.n_identity),
            "n_regional": int(opts.n_regional), "pixel_scale": opts.pixel_scale,
            "planes": _saved_planes(state.planes),
            "contour": {n: {"vertices": np.concatenate([p[0] for p in lst]),
                            "pixels": np.vstack([p[1] for p in lst])}
                        for n, lst in pairs.items()},
            # the sliding landmarks: the vertex each met the outline at, and the offset
            # along the outline from it (refit_landmarks holds them there)
            "outline": {n: {"names": [eng.view(n).names[i] for i in idx],
                            "vertices": verts.copy(), "offsets": along.copy()}
                        for n, (idx, _, verts, along) in matches.items()}},
    }
    if "approach1" in candidates and "calibration_rounds" in candidates["approach1"][1]:
        info["iterations"]["calibration_rounds"] = \
            candidates["approach1"][1]["calibration_rounds"]
    result = make_result(model, eng, state, opts, opts.method, info, uncertainty=unc,
                          skipped=skipped,
                          outline={n: m[:2] for n, m in matches.items()})
    info["rms_px"] = {n: result.rms_px(n) for n in result.residuals}
    info["projection"], fitted = projection_info(model, result, eng, opts)
    if state.planes:
        info["mirror"], more = mirror_info(eng, state, opts)
        fitted += more
    # The refit keeps what the full fit found about cameras and mirrors, but says anew
    # which views it skipped: a dragged landmark can make a skipped view usable.
    info["refit_state"]["warnings"] = list(fitted)
    info["plausibility"], implausible = plausibility(result.identity_coeffs, result.cameras)
    info["unused"] = unused_views(skipped, eng.views)
    info["warnings"] = skip_warnings(skipped) + drop_warnings(eng.views) + fitted \
        + implausible
    timings["result"] = time.perf_counter() - t
    timings["total"] = time.perf_counter() - t0
    info["timings"] = timings
    progress(1.0, f"done ({chosen})")
    measured = eng.without_definition_offsets(state, result.local_vertices,
                                              result.residuals, opts.front_weight)
    roles = ({v.name: {n for n, o in zip(v.names, v.outline_point & ~v.slide, strict=True)
                       if o} for v in eng.views},
             {v.name: dict(zip(v.names, v.relative.tolist(), strict=True)) for v in eng.views})
    others = [c[0] for n, c in candidates.items() if n != chosen]

    def other_start():
        """The other approach's head as a FitResult to start from, or None."""
        if not others:
            return None
        other = others[0]
        eng.use(other)
        saved = {"coeffs": other.coeffs.copy(), "planes": _saved_planes(other.planes)}
        start = make_result(model, eng, other, opts, opts.method, {"refit_state": saved},
                            skipped=skipped)
        eng.use(state)
        return start

    return (result, contour, along, eng.effective_parameters(cov) + measured[1], measured,
            roles, finish, other_start)


def _saved_planes(planes):
    """Mirror planes (view name -> MirrorPlane) as a fit's ``refit_state`` keeps them."""
    return {n: {"normal": p.normal.copy(), "offset": p.offset} for n, p in planes.items()}


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
    opts = check_options(options, model)
    if opts.pixel_scale is None and saved.get("pixel_scale") is not None:
        # the fit's own: a moved landmark does not change what a pixel is
        opts = dataclasses.replace(opts, pixel_scale=saved["pixel_scale"])
    opts = _prior_raised(_in_photo_pixels(model, case, opts),
                         float(saved.get("prior_factor", 1.0)))
    opts = FitOptions(**{**opts.__dict__, "n_identity": int(saved["n_identity"]),
                         "n_regional": int(saved["n_regional"]), "method": previous.method})
    if saved.get("expressions"):
        case = neutral_case(model, case, previous, saved["expressions"])
    views, skipped = prepare_views(model, case, opts,
                                    cameras=previous_cameras(previous, "previous"),
                                    noise=saved.get("noise"))
    eng = Engine.for_fit(model, views, opts)
    state, saved = saved_state(previous, eng, views, "previous")
    eng.finish_views(state)
    rows, verts = [], []
    held = {}  # view name -> (landmark indices, rows) of the sliding landmarks
    off = 0
    for v in views:
        if len(v.vertices):
            rows.append(eng.landmark_rows(v, off, opts.front_weight, slide=True))
            verts.append(v.vertices)
            off += len(v.vertices)
        # a sliding landmark stays where the full fit met the outline with it: on that
        # vertex, offset along the outline as it was there
        where = saved.get("outline", {}).get(v.name)
        slid = {n: i for i, n in enumerate(v.names) if v.slide[i]}
        pick = [(slid[n], j) for j, n in enumerate(where["names"]) if n in slid] \
            if where is not None else []
        if pick:
            idx = np.array([i for i, _ in pick])
            sel = np.array([j for _, j in pick])
            w = eng.landmark_scale(v, opts.front_weight) * v.weights[idx]
            held_rows = ImageRows(np.arange(off, off + len(idx)),
                                  v.pixels[idx] - np.asarray(where["offsets"])[sel],
                                  v.camera, weights=w, name=f"outline points {v.name}")
            rows.append(held_rows)
            held[v.name] = (idx, held_rows)
            verts.append(np.asarray(where["vertices"], dtype=np.int64)[sel])
            off += len(idx)
        pairs = saved.get("contour", {}).get(v.name)
        if pairs is not None and len(pairs["vertices"]):
            cv = np.asarray(pairs["vertices"], dtype=np.int64)
            rows.append(ImageRows(np.arange(off, off + len(cv)), pairs["pixels"], v.camera,
                                  weights=opts.contour_weight * eng.inv_var * v.contour_scale
                                  * body_weights(eng.body[cv], v.body_scale),
                                  name=f"contour {v.name}"))
            verts.append(cv)
            off += len(cv)
    problem = eng.problem(eng.copies_model(np.concatenate(verts)), rows,
                          freeze=("rotation",))
    fit = problem.solve(scale=state.scale, rotation=state.rotation,
                        translation=state.translation, coeffs=state.coeffs,
                        max_iterations=1, tolerance=0.0, sigma=1.0, final_system=False)
    state.coeffs = fit.coeffs.copy()
    world = eng.world(state, np.concatenate(verts))
    outline = {n: (idx, np.linalg.norm(r.pixels - r.camera.project(world[r.vertices]), axis=1))
               for n, (idx, r) in held.items()}
    info = {"approach": previous.info.get("approach", previous.method), "refit": True,
            "refit_state": {**saved, "coeffs": state.coeffs.copy()},
            "unused": unused_views(skipped, views),
            "warnings": skip_warnings(skipped) + drop_warnings(views)
            + list(saved.get("warnings", []))}
    info["plausibility"], implausible = plausibility(state.coeffs[:int(opts.n_identity)],
                                                     state.cameras)
    info["warnings"] += implausible
    result = make_result(model, eng, state, opts, previous.method, info,
                          uncertainty=np.asarray(previous.uncertainty).copy(),
                          detail=np.asarray(previous.detail).copy(), skipped=skipped,
                          outline=outline)
    info["rms_px"] = {n: result.rms_px(n) for n in result.residuals}
    info["timings"] = {"total": time.perf_counter() - t0}
    return result

