"""Checks after a fit that tell the user what the photos could not: a fit from one photo
(its depth or width is the model's prior), and photos whose left and right disagree (left
and right landmark names swapped, or a left profile labelled right), which a fit explains
only by a head turned away from its photos or tens of millimetres off.

Sides are tested cheaply first, on every fit (:func:`mirror_suspects`: the handedness the
landmarks imply against the face and the cameras, under a millisecond). A view whose
landmarks put its camera behind the head is warned about from that alone; views that only
disagree with the others are fitted again, mirrored, and warned about when that explains
the photos at least ``MIRROR_RATIO`` times better (docs/DECISIONS.md, "Swapped sides").
"""

import dataclasses

import numpy as np

from ..cameras import OrthographicCamera
from ..cameras.base import is_side_camera

#: Views that disagree are warned about when the case with them mirrored reproduces the
#: landmarks this many times better (pixel RMS).
MIRROR_RATIO = 2.0
#: A view whose implied viewing direction has this cosine or less with the face's (toward
#: the back of the head) is behind the head.
BEHIND_COS = -0.5
#: Spread of a view's landmark points (singular value, relative to the largest) below
#: which a direction is left out of the implied camera.
RCOND = 0.05
#: Iterations of the quick fits of the mirrored case and of the case as labelled.
QUICK_ITERATIONS = 15
_LEFT, _RIGHT = "_left", "_right"
_OTHER_SIDE = {"orthographic-right": "orthographic-left", "orthographic-left": "orthographic-right"}


def post_fit_warnings(model, case, result, opts, quick_fit):
    """Warnings of a finished fit: a single photo, and views whose sides look exchanged.

    Parameters
    ----------
    model : HeadModel
    case : LandmarkCase
        What was fitted.
    result : FitResult
        Its fit.
    opts : FitOptions
        Its (checked) options.
    quick_fit : callable
        ``quick_fit(case, options) -> FitResult``: a fit without these checks, for the
        mirrored case.

    Returns
    -------
    list of str
    """
    return single_view_warnings(model, result, used_views(result, opts)) \
        + mirror_warnings(model, case, result, opts, quick_fit)


def used_views(result, opts):
    """Names of the views the fit used: with a landmark of weight > 0 or a traced outline
    it fitted (the others are skipped, ``views.prepare_views``)."""
    weights = opts.landmark_weights or {}
    traced = result.info.get("contour_rms_px", {})
    return [n for n, r in result.residuals.items()
            if n in traced
            or any(x not in r.unused and weights.get(x, 1.0) > 0 for x in r.names)]


def single_view_warnings(model, result, used):
    """One warning when the fit rests on a single photo: what it cannot tell (depth for a
    photo facing the head, width for a profile) is the model's prior, and what to add.

    Parameters
    ----------
    model : HeadModel
    result : FitResult
    used : list of str
        Names of the views the fit used. A mirror view counts as a photo of its own (it
        sees the head from another side).
    """
    if len(used) != 1:
        return []
    name = used[0]
    cam = result.cameras[name]
    centre = result.world_vertices[np.asarray(model.skin)].mean(axis=0)
    if is_side_camera(cam, centre):
        return [f"view {name!r} is the only photo: the head's width comes from the model's "
                "prior only (a profile shows none of it); add a front photo "
                "('orthographic-front' or a photo toward the face) for a measured width"]
    return [f"view {name!r} is the only photo: the head's depth (the profile: nose, chin, "
            "forehead, back of the head) comes from the model's prior only; add a profile "
            "photo ('orthographic-right' or '-left', or a photo from the side) for a "
            "measured depth"]


def swap_name(name):
    """The landmark on the other side: ``_left`` and ``_right`` suffixes exchanged
    (assets/landmarks.json); a midline name unchanged."""
    if name.endswith(_LEFT):
        return name[:-len(_LEFT)] + _RIGHT
    if name.endswith(_RIGHT):
        return name[:-len(_RIGHT)] + _LEFT
    return name


def implied_frame(local_points, pixels):
    """The camera frame a view's landmarks imply in the head's own frame: rows (u axis,
    v axis, viewing direction) of the affine camera that best maps the head's landmark
    points to the pixels, the direction from u x v, so a mirrored image gives a frame that
    no rotation of the head explains. Returns (3, 3), or None when the layout is too
    degenerate to tell.

    Parameters
    ----------
    local_points : ndarray, shape (n, 3), metres
    pixels : ndarray, shape (n, 2)
    """
    if len(local_points) < 4:
        return None
    x = local_points - local_points.mean(axis=0)
    p = pixels - pixels.mean(axis=0)
    # a direction the points hardly spread along (a profile's midline landmarks in depth)
    # is left out rather than guessed: u x v then rests on the two the photo shows
    a, _, rank, _ = np.linalg.lstsq(x, p, rcond=RCOND)
    if rank < 2:
        return None
    u, v = a[:, 0], a[:, 1]
    d = np.cross(u, v)
    nu, nv, nd = np.linalg.norm(u), np.linalg.norm(v), np.linalg.norm(d)
    if min(nu, nv) == 0 or nd < 0.5 * nu * nv:  # axes far from perpendicular
        return None
    return np.array([u / nu, v / nv, d / nd])


def claimed_rotation(camera):
    """Rotation (rows u, v, viewing direction) a view's given camera claims, world frame;
    None for a camera without one."""
    rot = getattr(camera, "rotation", None)
    if rot is None and hasattr(camera, "as_dlt"):
        try:
            rot = camera.as_dlt().decompose()[1]
        except ValueError:  # numpy's LinAlgError too
            return None
    return None if rot is None else np.asarray(rot, dtype=np.float64).reshape(3, 3)


def mirror_suspects(model, case, result):
    """Views whose landmarks look mirrored, as (behind, disagreeing): views whose implied
    camera looks at the back of the head (:func:`implied_frame`; the face's landmarks
    cannot be seen from there), and views with a given camera whose implied head rotation
    differs from the other views' by more than 90 degrees (with two such views and
    neither behind the head, the profile: a front photo's side is told by the first
    test). Disagreement is only looked for when no view is behind the head."""
    local = result.local_vertices
    frames, behind = {}, []
    for name, view in case.views.items():
        if view.mirror_of is not None or not view.points:
            continue
        canon = [model.landmark_set.canonical(n) for n in view.points]
        verts = np.array([model.landmarks[n] for n in canon], dtype=np.int64)
        frame = implied_frame(local[verts], np.array(list(view.points.values()), dtype=float))
        if frame is None:
            continue
        # the face looks toward -Y: a camera seeing its landmarks looks toward +Y or sideways
        if frame[2, 1] < BEHIND_COS:
            behind.append(name)
            continue
        rot = claimed_rotation(view.camera) if view.camera is not None else None
        if rot is not None:
            frames[name] = rot.T @ frame  # the head's rotation as this view sees it
    names = list(frames)
    agree = {n: sum(_angle_cos(frames[n], frames[m]) > 0.0 for m in names if m != n)
             for n in names}
    if behind or len(names) < 2 or min(agree.values()) == len(names) - 1:
        return behind, []
    if len(names) == 2:
        sides = [n for n in names if is_side_camera(case.views[n].camera)]
        return [], sides[:1] or names[1:]
    return [], [n for n in names if agree[n] < (len(names) - 1) / 2]


def _angle_cos(r1, r2):
    """Cosine of the angle of the rotation between two rotations."""
    return 0.5 * (np.trace(r1.T @ r2) - 1.0)


def mirrored_case(case, views):
    """The case with ``views`` mirrored: their landmark names' sides exchanged and an
    orthographic profile's camera turned to the other side (the photo the user took)."""
    out = {}
    for name, view in case.views.items():
        if name in views:
            cam, other = view.camera, _other_side(view)
            if other is not None:
                cam = OrthographicCamera.nominal(other, view.size)
            view = dataclasses.replace(view, camera=cam, points={
                swap_name(n): p for n, p in view.points.items()})
        out[name] = view
    return dataclasses.replace(case, views=out)


def landmark_rms(result):
    """Pixel RMS of the landmarks a fit used, over all views."""
    r = [np.asarray(v.pixels)[[n not in v.unused for n in v.names]]
         for v in result.residuals.values()]
    r = np.concatenate(r) if r else np.zeros(0)
    return float(np.sqrt(np.mean(r**2))) if len(r) else 0.0


def mirror_warnings(model, case, result, opts, quick_fit):
    """A warning per view whose left and right look exchanged (:func:`mirror_suspects`).

    A view whose landmarks put its camera behind the head is warned about at once: the fit
    as labelled can reproduce them about as well by turning the head away from the photo,
    so no fit tells it better. Views that only disagree with the others are warned about
    when the case with them mirrored (:func:`mirrored_case`) reproduces the landmarks at
    least ``MIRROR_RATIO`` times better than the case as labelled, both by the same quick
    fit (fixed noise, approach 1, ``QUICK_ITERATIONS``)."""
    behind, disagree = mirror_suspects(model, case, result)
    evidence = {}
    if disagree:
        quick = dataclasses.replace(opts, noise="fixed", method="approach1", progress=None,
                                    max_iterations=QUICK_ITERATIONS)
        try:
            mirrored = landmark_rms(quick_fit(mirrored_case(case, disagree), quick))
            labelled = landmark_rms(quick_fit(case, quick))
        except (ValueError, ArithmeticError):  # a case that cannot be fitted: no evidence
            mirrored, labelled = np.inf, 0.0
        if labelled >= MIRROR_RATIO * mirrored:
            evidence = {n: f"the landmarks are reproduced to {mirrored:.1f} px RMS against "
                           f"{labelled:.1f} px as labelled" for n in disagree}
    for name in behind:
        evidence[name] = ("its landmarks are the mirror image of a face: as labelled "
                          "they put the camera behind the head")
    sides = [n for n in case.views if n not in evidence and _other_side(case.views[n])]
    out = []
    for name, why in evidence.items():
        other = _other_side(case.views[name])
        what = f"the _left/_right names of view {name!r} exchanged" if other is None else \
            f"view {name!r} a {other[len('orthographic-'):]} profile"
        also = f" (or view {sides[0]!r} a profile of the other side)" if sides else ""
        out.append(f"view {name!r}: its left and right look exchanged ({why}; with {what}"
                   f"{also} they are consistent), so the head fitted as labelled is likely "
                   "wrong (turned or mirrored); check that the _left/_right names are the "
                   "subject's own sides (the image's right in a front photo) and which side "
                   "each profile photo shows")
    return out


def _other_side(view):
    """The other profile's camera name of an orthographic profile view, else None."""
    cam = view.camera
    return _OTHER_SIDE.get(cam.view) if isinstance(cam, OrthographicCamera) else None
