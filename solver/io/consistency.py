"""Consistency of a case before any fit: cameras that contradict themselves or each other,
and landmark layouts a fit cannot use. Each was a fit that ended with exit 0 and a head
tens of millimetres off (a v1 rotation with determinant -1: 370 mm; two front photos:
44 mm; all landmarks on a line: 75 mm), so they are refused with the reason.
"""

import numpy as np

from ..cameras import OrthographicCamera, is_side_camera
from .jsonschema_lite import format_path
from .landmark_counts import MIN_LANDMARKS_PER_VIEW

#: Two orthographic views whose viewing directions are within this angle look the same way.
SAME_DIRECTION_DEG = 5.0
#: A view's landmarks whose RMS distance from their mean is below this are in one place.
MIN_SPREAD_PX = 2.0
#: ... and on one line when their RMS distance from it is below this, or below
#: ``LINE_RATIO`` of their spread (a face's landmarks spread in two directions).
LINE_PX = 1.0
LINE_RATIO = 0.01


def is_mirrored(camera):
    """True / False for a camera seen in a mirror (rotation determinant -1), None if the
    camera does not say."""
    flag = getattr(camera, "is_mirrored", None)
    if isinstance(flag, bool):
        return flag
    rot = getattr(camera, "rotation", None)
    if rot is None:
        return None
    return bool(np.linalg.det(np.asarray(rot, dtype=np.float64).reshape(3, 3)) < 0)


def consistency_problems(case, for_fit, bad_cameras=frozenset()):
    """(path, message) of what makes a case contradict itself: a mirrored camera outside a
    mirror view, two orthographic views looking the same way, and (``for_fit``) a view's
    landmarks all in one place or on one line. Views in ``bad_cameras`` (already reported)
    skip the camera checks."""
    problems = []
    directions = []  # (view, unit viewing direction, label) of the orthographic views
    for name, view in case.views.items():
        at = format_path(("views", name, "camera"))
        cam = view.camera
        if cam is not None and name not in bad_cameras and view.mirror_of is None:
            if is_mirrored(cam):
                problems.append((format_path(("views", name, "camera", "rotation")),
                                 "determinant -1, a mirrored camera: only a mirror view "
                                 "(version 2, 'mirror_of') has one; give a rotation with "
                                 "determinant +1"))
            elif isinstance(cam, OrthographicCamera):
                d = np.asarray(cam.rotation, dtype=np.float64)[2]
                label = cam.view if np.allclose(cam.rotation, _nominal_rotation(cam.view),
                                                atol=1e-9) else "a given rotation"
                for other, e, other_label in directions:
                    angle = np.degrees(np.arccos(np.clip(d @ e, -1.0, 1.0)))
                    if angle < SAME_DIRECTION_DEG:
                        both = f"both {label}" if label == other_label else \
                            f"{angle:.1f} degrees apart"
                        problems.append((at, f"looks the same way as view {other!r} "
                                             f"({both}): two photos from one direction "
                                             "tell nothing of the head's depth; is one a "
                                             "profile ('orthographic-right' or '-left')?"))
                        break
                directions.append((name, d / np.linalg.norm(d), label))
        if for_fit:
            problems += _layout_problems(view, ("views", name, "points"))
            if _placed_by_outline(view, name in bad_cameras):
                problems += _outline_problems(view.contour, ("views", name, "contour"))
    return problems


def _placed_by_outline(view, bad_camera):
    """Whether the fit places ``view``'s camera by its traced outline alone
    (``fitting/contour_start.py``): an orthographic profile photo with a contour and fewer
    than ``MIN_LANDMARKS_PER_VIEW`` landmarks."""
    cam = view.camera
    return (view.contour is not None and not bad_camera and cam is not None
            and not cam.perspective and is_side_camera(cam)
            and len(view.points) < MIN_LANDMARKS_PER_VIEW)


def _outline_problems(contour, where):
    """An outline that places a camera but is one place or one line: it has no profile to
    lay the head's onto (a horizontal one ended the fit naming no view, one within a pixel
    gave that photo a camera 8 px per metre and no warning)."""
    c = np.asarray(contour, dtype=np.float64).reshape(-1, 2)
    if len(c) < 2 or not np.isfinite(c).all():
        return []  # reported as not finite, or by the fit's own count
    why = (f"with fewer than {MIN_LANDMARKS_PER_VIEW} landmarks this photo's camera is "
           "placed by its outline alone, which must trace the head's profile")
    found = _spread_problem(c, "points", f"; {why}", f"; {why}")
    return [(format_path(where), found)] if found else []


def _nominal_rotation(view):
    from ..cameras import ORTHO_VIEWS

    return ORTHO_VIEWS.get(view, np.full((3, 3), np.nan))


def _layout_problems(view, where):
    """A view's landmarks all in one place, or all on one line."""
    if len(view.points) < 3:
        return []
    px = np.array(list(view.points.values()), dtype=np.float64).reshape(-1, 2)
    if not np.isfinite(px).all():
        return []  # reported as not finite
    found = _spread_problem(px, "landmarks", "; a fit needs them spread over the face (were "
                            "they placed on one pixel?)",
                            "; a face's landmarks spread in two directions")
    return [(format_path(where), found)] if found else []


def _spread_problem(px, what, one_place, one_line):
    """The message for points ``px`` (n >= 2, 2) all within ``MIN_SPREAD_PX`` of one point
    or all on one line, ending with ``one_place`` or ``one_line`` (the reason), or None."""
    n = len(px)
    mean = px.mean(axis=0)
    s = np.linalg.svd(px - mean, compute_uv=False) / np.sqrt(n)
    if s[0] < MIN_SPREAD_PX:
        return (f"all {n} {what} lie within {MIN_SPREAD_PX:g} px of ({mean[0]:.1f}, "
                f"{mean[1]:.1f})" + one_place)
    if s[1] < max(LINE_PX, LINE_RATIO * s[0]):
        return f"all {n} {what} lie on one line (RMS {s[1]:.2g} px off it)" + one_line
    return None
