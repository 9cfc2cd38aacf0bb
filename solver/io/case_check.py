"""The checks of a landmark case that a schema cannot express: landmark names, points
inside the image, finite numbers, cameras, mirror views, passpoints, and enough landmarks
for a fit (the rule of ``landmark_counts``). Every problem is a (JSON path, message) pair.
"""

import difflib
import math

import numpy as np

from ..cameras import (
    ORTHO_VIEWS,
    Camera,
    OrthographicCamera,
    camera_class,
    camera_kinds,
    is_side_camera,
)
from .camera_json import (
    camera_object_problems,
    camera_range_problems,
    camera_to_json,
    is_nominal,
    non_finite_paths,
)
from .consistency import consistency_problems, is_mirrored
from .jsonschema_lite import format_path
from .landmark_counts import count_problems, landmarks_needed, too_few_distinct
from .landmark_set import as_landmark_set

#: Fewest passpoints from which a view's DLT camera is computed (11 unknowns, seed 000 §2).
MIN_PASSPOINTS = 6


def check_case(case, known_names=None, for_fit=True):
    """The checks a schema cannot express, on a built case.

    Returns
    -------
    list of (str, str)
        (JSON path, message) per problem: unknown landmark names (with the closest known
        name), one landmark given twice (a name and its ibug alias), non-finite numbers,
        points outside the image, cameras (kind, finite parameters, size, a rotation that
        is one, ``calibrated`` without parameters), ``mirror_of`` (a missing view, itself,
        another mirror view, a different photo, a camera that is not mirrored), passpoints
        (undefined names, not finite, outside the image, on an orthographic view), and
        (``for_fit``) fewer landmarks than the fit needs (``landmark_counts``: none for a
        kept camera or one from passpoints, except in a mirror view) or passpoints that
        cannot give a camera, or fewer than ``MIN_DISTINCT_LANDMARKS`` different landmarks
        in all.
    """
    return case_problems(case, as_landmark_set(known_names), for_fit)


def case_problems(case, landmark_set, for_fit, bad_cameras=frozenset()):
    """``check_case`` with the landmark set resolved; the views named in ``bad_cameras``
    (whose camera the reader could not build, and has reported) skip the camera checks."""
    per_view = {}
    used, needed = {}, {}
    distinct = {}  # ("v", model vertex) or ("n", name) -> canonical name, over all views
    for vname, view in case.views.items():
        where = ("views", vname)
        w, h = view.size
        found = _points_problems(view, where, landmark_set)
        if view.contour is not None:
            found += _contour_problems(view.contour, where, w, h)
        if vname not in bad_cameras:
            found += _camera_problems(view, where)
        found += _mirror_problems(case, view, where)
        found += _passpoint_problems(case, view, where, for_fit and vname not in bad_cameras)
        per_view[vname] = found
        for key in view.points:
            canon = landmark_set.canonical(key)
            if canon is not None:
                vertex = landmark_set.vertices.get(canon, -1)
                distinct[("v", vertex) if vertex >= 0 else ("n", canon)] = canon
        used[vname] = len(view.points)
        needed[vname] = _landmarks_needed(view, vname in bad_cameras)
    top = []
    for name, xyz in case.passpoints.items():
        at = format_path(("passpoints", name))
        if not name:
            top.append(("passpoints", "a passpoint without a name"))
        elif xyz.shape != (3,):
            top.append((at, f"expected [x, y, z], got {xyz.size} numbers"))
        elif not np.isfinite(xyz).all():
            top.append((at, "not a finite number; NaN and infinity are not allowed"))
    top += consistency_problems(case, for_fit, bad_cameras)
    total = []
    for name, message in count_problems(used, needed) if for_fit else ():
        if name is None:
            total.append(("views", message))
        else:  # after the view's other problems
            per_view[name].append((format_path(("views", name, "points")), message))
    few = too_few_distinct(list(distinct.values())) if for_fit and not total else None
    if few is not None:
        total.append(("views", few))
    return [p for found in per_view.values() for p in found] + top + total


def _landmarks_needed(view, bad_camera):
    """``landmarks_needed`` of a view; a camera the reader could not build is of no known
    kind."""
    if bad_camera:
        min_refit = 0
    elif view.camera is not None:
        min_refit = getattr(view.camera, "min_refit_points", 0)
    else:
        cls = camera_class(view.camera_hints.get("kind"))
        min_refit = cls.min_refit_points if cls is not None else 0
    outline = view.contour is not None and not bad_camera and view.camera is not None \
        and not view.camera.perspective and is_side_camera(view.camera)
    return landmarks_needed(min_refit, kept=view.camera_fixed, passpoints=bool(view.passpoints),
                            mirror=view.mirror_of is not None, outline=outline)


def _points_problems(view, where, lms):
    problems = []
    w, h = view.size
    seen = {}  # canonical name (or vertex) -> key as written
    for key, uv in view.points.items():
        at = format_path(where + ("points", key))
        canon = lms.canonical(key)
        if canon is None:
            problems.append((at, "unknown landmark" + lms.suggestion(key)))
        else:
            vertex = lms.vertices.get(canon, -1)
            ident = ("v", vertex) if vertex >= 0 else ("n", canon)
            if ident in seen:
                same = f"{seen[ident]!r}" + (f" (both are {canon!r})"
                                             if seen[ident] != canon else "")
                problems.append((at, f"the same landmark as {same}; give it once"))
            else:
                seen[ident] = key
        problems += _point_problems(at, uv, w, h)
    for key, sigma in view.uncertainty.items():
        at = format_path(where + ("uncertainty", key))
        if key not in view.points:
            problems.append((at, "no such landmark in this view's 'points'"))
        elif not (np.isfinite(sigma) and sigma > 0):
            problems.append((at, f"expected a finite number of pixels > 0, got {sigma!r}"))
    for key, depth in view.depth.items():
        at = format_path(where + ("depth", key))
        if key not in view.uncertainty:
            problems.append((at, "a depth needs the landmark's 'uncertainty' in this view"))
        elif not np.isfinite(depth):
            problems.append((at, f"expected a finite number of pixels, got {depth!r}"))
    return problems


def _camera_problems(view, where):
    """Problems of a built view's camera (see ``check_case``)."""
    at = format_path(where + ("camera",))
    cam = view.camera
    problems = []
    if view.calibrated is not None and not isinstance(view.calibrated, bool):
        problems.append((format_path(where + ("calibrated",)),
                         f"expected true or false, got {view.calibrated!r}"))
    if cam is None:
        kind = view.camera_hints.get("kind")
        if kind is None:
            return problems + [(at, "no camera: give a Camera, or camera_hints with the "
                                    "kind of camera to compute")]
        if kind == "orthographic":
            return problems + [(at, "an orthographic camera without parameters: use one of "
                                    + ", ".join(repr(v) for v in ORTHO_VIEWS))]
        if camera_class(kind) is None:
            return problems + [(format_path(where + ("camera", "kind")),
                                f"unknown kind {kind!r}; known: {', '.join(camera_kinds())}")]
        problems += camera_object_problems(view.camera_hints, view.size, where + ("camera",))
        if view.calibrated is True and not view.passpoints:
            problems.append((format_path(where + ("calibrated",)),
                             "true, but the camera's parameters are not given (and no "
                             "passpoints to compute them from): give them, or set false to "
                             "self-calibrate"))
        return problems
    if not isinstance(cam, Camera):
        return problems + [(at, f"expected a Camera, got {type(cam).__name__}")]
    try:
        value = cam.to_dict()
    except ValueError as e:
        return problems + [(at, str(e))]
    problems += [(format_path(p), "not a finite number; NaN and infinity are not allowed")
                 for p in non_finite_paths(value, where + ("camera",))]
    if problems:
        return problems
    cam_size = getattr(cam, "size", None)
    if cam_size is not None and tuple(cam_size) != tuple(view.size):
        problems.append((at, f"camera size {list(cam_size)} differs from the view size "
                             f"{list(view.size)}"))
    problems += camera_range_problems(value, view.size, where + ("camera",))
    if isinstance(cam, OrthographicCamera):
        r = np.asarray(cam.rotation, dtype=np.float64)
        if not np.allclose(r @ r.T, np.eye(3), rtol=0, atol=1e-6):
            problems.append((format_path(where + ("camera", "rotation")),
                             "not a rotation (its rows must be orthonormal)"))
    if view.calibrated is True and is_nominal(cam, view.size):
        problems.append((format_path(where + ("calibrated",)),
                         f"true, but {camera_to_json(cam, view.size)!r} is a nominal camera "
                         "(its scale and offset a guess): give the camera's parameters to "
                         "keep it fixed"))
    return problems


def _mirror_problems(case, view, where):
    """Problems of a view's ``mirror_of`` (see ``check_case``)."""
    target = view.mirror_of
    if target is None:
        return []
    at = format_path(where + ("mirror_of",))
    if not isinstance(target, str) or not target:
        return [(at, f"expected the name of another view, got {target!r}")]
    if target == view.name:
        return [(at, "names this view itself; a mirror view names the view whose photo it is "
                     "seen in")]
    if target not in case.views:
        close = difflib.get_close_matches(target, list(case.views), n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        return [(at, f"no view named {target!r} (views: {', '.join(case.views)}){hint}")]
    other = case.views[target]
    problems = []
    if other.mirror_of is not None:
        problems.append((at, f"{target!r} is itself a mirror view; name the view seen "
                             "directly"))
    if tuple(other.size) != tuple(view.size):
        problems.append((format_path(where + ("size",)),
                         f"{list(view.size)} differs from the size {list(other.size)} of "
                         f"{target!r}, whose photo the mirror image is in"))
    if view.image is not None and other.image is not None and view.image != other.image:
        problems.append((format_path(where + ("image",)),
                         f"{view.image!r} is not the photo of {target!r} ({other.image!r}); a "
                         "mirror view is inside the same photo"))
    cam = view.camera
    if cam is not None and is_nominal(cam, view.size):
        problems.append((format_path(where + ("camera",)),
                         f"{camera_to_json(cam, view.size)!r} cannot see a mirror image (its "
                         "landmarks carry the subject's true names, so the camera is "
                         "mirrored): give {\"kind\": \"dlt\"} to compute it, or a mirrored "
                         "camera's parameters"))
    elif cam is not None and is_mirrored(cam) is False:
        problems.append((format_path(where + ("camera",)),
                         "not mirrored (rotation determinant +1); a view seen in a mirror "
                         "has a mirrored camera (determinant -1), e.g. "
                         "solver.mirror.reflected_camera"))
    return problems


def _passpoint_problems(case, view, where, for_fit):
    """Problems of a view's passpoints (see ``check_case``)."""
    if not view.passpoints:
        return []
    problems = []
    w, h = view.size
    usable = []
    if not case.passpoints:  # one message, not one per passpoint
        n = len(view.passpoints)
        return [(format_path(where + ("passpoints",)),
                 f"{n} passpoint{'s' * (n != 1)}, but the file defines none: the top-level "
                 "'passpoints' gives each one's [x, y, z] metres")]
    for key, uv in view.passpoints.items():
        at = format_path(where + ("passpoints", key))
        found = _point_problems(at, uv, w, h)
        if key not in case.passpoints:
            close = difflib.get_close_matches(key, list(case.passpoints), n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            found.insert(0, (at, "not defined in the top-level 'passpoints' ([x, y, z] "
                                 f"metres){hint}"))
        elif not found and case.passpoints[key].shape == (3,) \
                and np.isfinite(case.passpoints[key]).all():
            usable.append(key)
        problems += found
    if view.camera_kind == "orthographic":
        problems.append((format_path(where + ("passpoints",)),
                         "passpoints compute a perspective (DLT) camera, and this view's "
                         "camera is orthographic: give \"camera\": {\"kind\": \"dlt\"}"))
    elif for_fit and view.camera is None and len(usable) == len(view.passpoints):
        # The camera is to be computed from them: make sure it can be (when every passpoint
        # is fine; a bad one is reported at the top level or above).
        from ..cameras.dlt import fit_dlt

        n = len(usable)
        at = format_path(where + ("passpoints",))
        if n < MIN_PASSPOINTS:
            problems.append((at, f"{n} passpoint{'s' * (n != 1)}; computing the camera needs "
                                 f"at least {MIN_PASSPOINTS}, not all in one plane"))
        else:
            _, xyz, uv = case.passpoint_arrays(view.name)
            try:
                cam = fit_dlt(xyz, uv, view.size).camera
            except ValueError as e:
                msg = str(e)
                msg = msg[len("points: "):] if msg.startswith("points: ") else msg
                problems.append((at, f"cannot compute the camera: {msg}"))
            else:
                problems += [(at, f"cannot compute the camera: the camera they give: {msg}")
                             for _, msg in camera_range_problems(cam.to_dict(), view.size,
                                                                 where + ("camera",))]
    return problems


def _contour_problems(contour, where, w, h):
    """The first contour point that is not finite or outside the image (vectorised: a
    contour may have thousands of points), with how many more there are."""
    c = np.asarray(contour, dtype=np.float64).reshape(-1, 2)
    with np.errstate(invalid="ignore"):
        bad = ~(np.isfinite(c).all(axis=1) & (c >= 0).all(axis=1) & (c[:, 0] <= w)
                & (c[:, 1] <= h))
    if not bad.any():
        return []
    i = int(np.flatnonzero(bad)[0])
    at, message = _point_problems(format_path(where + ("contour", i)), c[i], w, h)[0]
    more = int(bad.sum()) - 1
    return [(at, message + (f" (and {more} more point{'s' * (more > 1)})" if more else ""))]


def _point_problems(at, uv, w, h):
    if len(uv) != 2:
        return [(at, f"expected [u, v], got {len(uv)} numbers")]
    u, v = uv
    if not (math.isfinite(u) and math.isfinite(v)):
        return [(at, f"not a finite number ({u}, {v}); NaN and infinity are not allowed")]
    if not (0.0 <= u <= w and 0.0 <= v <= h):
        return [(at, f"({u:g}, {v:g}) lies outside the {w}x{h} image")]
    return []
