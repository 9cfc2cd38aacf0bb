"""Approach 1 of the thesis (§4.4.2) and the profile-line fit that starts every approach
(§4.4.1): landmarks and traced outlines as image rows through their cameras."""

from .outline import own_outline_views, view_outlines

# Smallest relative gain of a re-calibration for another joint run (Joint.settle).
SETTLE_TOLERANCE = 1e-3


# The first outline stage of approach 1 keeps every contour row within this fraction of
# the contour threshold (8 px at the default 20), for this many rounds: see approach1.
RELEASE_KEEP = 0.4
RELEASE_ROUNDS = 2


def profile_fit(eng, state, opts):
    """Thesis §4.4.1 on the orthographic side views: the cameras alone (similarity-only
    ICP: a profile camera's 2-D similarity is the head's scale, sagittal rotation and
    position), then the shape with them (the head's rotation frozen: the profile cannot
    see the other two). A perspective profile photo is left to the joint stages: alone it
    cannot tell its camera's distance from the head's depth."""
    side = [v for v in eng.views
            if v.side and not eng.real_view(v).camera.perspective]
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


def approach1(model, eng, state, opts, staged=True):
    """Thesis §4.4.2: every landmark as image rows (front ones weighted), plus contour.

    Photos whose traced outline is matched to the head's own outline (every outline but
    an orthographic profile's, see :func:`view_outline`) are fitted in stages: the
    landmarks alone, then, with the outline candidates found on that head, landmarks
    and outlines together, first for RELEASE_ROUNDS rounds (cameras not re-calibrated)
    keeping every outline row within RELEASE_KEEP of the contour threshold (8 px), then,
    with candidates found anew, with the usual cut-off (3 sigmas of the noise,
    ``ContourRows``). From the mean head the outline rows latch onto the wrong rim (a
    cheek for a jaw, an ear for the skull) and the fit settles in a worse minimum. And
    where the landmarks leave the head some 10 px off the tracing (the neck, which no
    landmark holds), the noise's cut-off trims those rows from the start, so they never
    pull it there: the wide stage does. (Measured: docs/DECISIONS.md.)

    With free perspective cameras or mirror planes (self-calibration) the joint rounds
    alternate with full re-calibrations of those cameras until both settle
    (``Joint.settle``): joint rounds run until a round changes the cost by less than
    0.1 % (or ``tolerance`` if larger; the choice of outline vertices alone moves the cost
    by about that much), and a re-calibration that lowers the cost by less than that
    ends the alternation, after at most ``calibration_rounds``.

    Without ``staged`` (a fit that starts from a head already fitted to these outlines:
    the noise rounds after the first, ``fit_head(initial=...)``) only the last stage runs:
    begun again from the landmarks alone, such a fit left its head and latched the
    outlines anew, so the rounds made the result hinge on a thousandth of a pixel.

    Returns (state, info): ``info["joint"]`` is the last stage's problem and
    ``info["outlines"]`` its outline candidates (view name -> (vertices, faces, edges)),
    besides "history" (and "calibration_rounds")."""
    selfcal = self_calibrating(eng)
    tol = max(opts.tolerance, SETTLE_TOLERANCE) if selfcal else opts.tolerance
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

    if staged and own_outline_views(eng, state) and any(len(v.vertices) for v in eng.views):
        state = stage(eng.joint(eng.views, front_weight=opts.front_weight, contour=False),
                      state)
        state = stage(eng.joint(eng.views, front_weight=opts.front_weight,
                                outlines=view_outlines(model, eng, state),
                                keep_distance=RELEASE_KEEP * eng.contour_threshold), state,
                      settle=False, max_outer=RELEASE_ROUNDS)
    out["outlines"] = view_outlines(model, eng, state)
    joint = eng.joint(eng.views, front_weight=opts.front_weight, outlines=out["outlines"])
    out["joint"] = joint
    return stage(joint, state), out


def self_calibrating(eng):
    """Whether a free camera has parameters the joint rounds linearise (perspective) or a
    mirror plane is estimated: then camera calibration and shape are alternated until
    both settle."""
    return any(v.mirror_of is not None or (eng.camera_moves(v) and v.camera.perspective)
               for v in eng.views)

