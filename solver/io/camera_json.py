"""Cameras as the landmarks file stores them: a nominal view's string or a camera object
(``{"kind": ...}`` with its parameters, or without them in version 2: to be computed), and
the checks a schema cannot make on such an object."""

import math

import numpy as np

from ..cameras import ORTHO_VIEWS, OrthographicCamera, camera_from_dict
from .jsonschema_lite import format_path

#: Plausible lenses, mm equivalent on a 36 mm sensor (a fisheye to the longest tele): a
#: pinhole's focal length (``lens_mm``, ``focal_px``, ``focal_range_mm``, ``focal_prior``)
#: outside it ends the fit in non-finite numbers or a least-squares solver that fails.
LENS_MM_RANGE = (2.0, 5000.0)
#: Plausible radial distortion k1 of a pinhole camera (normalised coordinates).
K1_RANGE = (-1.0, 1.0)

# Per kind: the fields that make its parameters known (any one present: the object must be
# a complete camera), and the fields that only make sense with them.
_PARAMETER_KEYS = {"dlt": ("parameters", "matrix"), "pinhole": ("rotation", "centre")}
_WITH_PARAMETERS = {"dlt": ("depth_sign", "distortion", "distortion_centre")}


def _camera_equal(a, b):
    return (type(a) is type(b) and np.allclose(a.rotation, b.rotation, rtol=0, atol=1e-12)
            and math.isclose(a.scale, b.scale, rel_tol=1e-12)
            and np.allclose(a.offset, b.offset, rtol=0, atol=1e-9) and a.size == b.size)


def camera_to_json(camera, size):
    """A camera as the file stores it: the nominal view's string when the camera is exactly
    ``OrthographicCamera.nominal(view, size)``, else its parameters (``to_dict``)."""
    if isinstance(camera, OrthographicCamera) and camera.view in ORTHO_VIEWS:
        if _camera_equal(camera, OrthographicCamera.nominal(camera.view, size)):
            return camera.view
    return camera.to_dict()


def is_nominal(camera, size):
    """Whether the file stores ``camera`` as a nominal view's string."""
    return isinstance(camera_to_json(camera, size), str)


def camera_from_json(value, size):
    """Inverse of ``camera_to_json``: a nominal view string or a ``{"kind": ...}`` object
    with the camera's parameters (``size`` defaults to the view's).

    Raises
    ------
    ValueError
        Unknown string or kind, missing or bad parameters, or a camera whose size disagrees.
    """
    if isinstance(value, str):
        return OrthographicCamera.nominal(value, size)
    if not isinstance(value, dict):
        raise ValueError(f"expected a view name or a camera object, got {value!r}")
    if "size" not in value:
        value = {**value, "size": list(size)}
    try:
        cam = camera_from_dict(value)
    except (KeyError, TypeError, IndexError) as e:
        raise ValueError(f"bad camera parameters ({type(e).__name__}: {e})") from None
    cam_size = getattr(cam, "size", None)
    if cam_size is not None and tuple(cam_size) != tuple(size):
        raise ValueError(f"camera size {list(cam_size)} differs from the view size "
                         f"{list(size)}")
    return cam


def has_parameters(value):
    """Whether a camera object of the file gives its parameters (else: to be computed)."""
    keys = _PARAMETER_KEYS.get(value.get("kind"))
    return keys is None or any(k in value for k in keys)


def non_finite_paths(value, path):
    """Paths (tuples, starting with ``path``) of the NaN / infinite numbers inside a JSON
    value."""
    if isinstance(value, float):
        return [] if math.isfinite(value) else [path]
    if isinstance(value, dict):
        return [p for k, v in value.items() for p in non_finite_paths(v, path + (k,))]
    if isinstance(value, list):
        return [p for i, v in enumerate(value) for p in non_finite_paths(v, path + (i,))]
    return []


def _px_per_mm(size):
    return max(float(size[0]), float(size[1])) / 36.0


def camera_range_problems(value, size, where):
    """The fields of a camera object (as the file stores it, or ``Camera.to_dict()``)
    outside their plausible range: a pinhole's focal length (``LENS_MM_RANGE``), its
    principal point (inside the photo) and k1 (``K1_RANGE``); a DLT's focal lengths and
    principal point, read from its parameters, against the same. Returns (path, message)
    pairs naming the range."""
    kind = value.get("kind")
    if kind == "dlt":
        return _dlt_range_problems(value, size, where)
    w, h = (float(v) for v in size)
    lo, hi = LENS_MM_RANGE
    problems = []

    def bad(key, message):
        problems.append((format_path(where + (key,)), message))

    if kind == "pinhole":
        ppm = _px_per_mm(size)
        if "focal_px" in value:
            f = float(value["focal_px"])
            if not lo * ppm <= f <= hi * ppm:
                bad("focal_px", f"{f:g} px is outside {lo * ppm:.4g}..{hi * ppm:.4g} px, the "
                                f"lenses of {lo:g}..{hi:g} mm (36 mm equivalent) on this "
                                f"{size[0]}x{size[1]} photo")
        elif "lens_mm" in value and not lo <= float(value["lens_mm"]) <= hi:
            bad("lens_mm", f"{float(value['lens_mm']):g} mm is outside {lo:g}..{hi:g} mm "
                           "(36 mm equivalent)")
        for key, n_lenses in (("focal_range_mm", 2), ("focal_prior", 1)):
            pair = value.get(key)
            lenses = () if pair is None else pair[:n_lenses]
            if any(not lo <= float(x) <= hi for x in lenses):
                bad(key, f"{list(pair)}: the lens (mm, 36 mm equivalent) must be in "
                         f"{lo:g}..{hi:g}")
        pp = value.get("principal_point")
        if pp is not None and not (0.0 <= float(pp[0]) <= w and 0.0 <= float(pp[1]) <= h):
            bad("principal_point", f"({float(pp[0]):g}, {float(pp[1]):g}) lies outside the "
                                   f"{size[0]}x{size[1]} photo")
        k1 = value.get("k1")
        if k1 is not None and not K1_RANGE[0] <= float(k1) <= K1_RANGE[1]:
            bad("k1", f"{float(k1):g} is outside {K1_RANGE[0]:g}..{K1_RANGE[1]:g}")
    return problems


def camera_object_problems(value, size, where):
    """What a schema cannot say about a camera object of the file (version 2): numbers that
    are not finite, fields that contradict each other, options the camera would refuse.
    ``where`` is the path of the camera; returns (path, message) pairs."""
    problems = [(format_path(p), "not a finite number; NaN and infinity are not allowed")
                for p in non_finite_paths(value, where)]
    if problems:
        return problems
    kind = value.get("kind")
    at = format_path(where)
    if kind == "dlt":
        params, matrix = "parameters" in value, "matrix" in value

        def bad(key, message):
            problems.append((format_path(where + (key,)), message))

        if params and matrix:
            problems.append((at, "give 'parameters' (b1..b11 or b1..b16) or 'matrix', not "
                                 "both"))
        if not (params or matrix):
            for key in _WITH_PARAMETERS["dlt"]:
                if key in value:
                    bad(key, "given without the camera's 'parameters' (or 'matrix')")
        else:
            if "depth_sign" in value and not params:
                bad("depth_sign", "only goes with 'parameters'")
            if "distortion" in value and params:
                bad("distortion", "with 'parameters' the lens terms are b12..b16 (16 "
                                  "parameters); 'distortion' goes with 'matrix'")
            lens = len(value.get("parameters", ())) == 16 or "distortion" in value
            if "distortion_centre" in value and not lens:
                bad("distortion_centre", "given without lens distortion terms (16 "
                                         "parameters, or 'distortion' with 'matrix')")
    elif kind == "pinhole" and not has_parameters(value):
        # Unknown pose: check the options the self-calibration will use by building the
        # camera they describe with a stand-in pose.
        trial = {**value, "rotation": np.eye(3).tolist(), "centre": [0.0, 0.0, -1.0],
                 "size": value.get("size", list(size))}
        if "focal_px" not in trial and "lens_mm" not in trial:
            trial["focal_px"] = 1.0
        try:
            camera_from_dict(trial)
        except (ValueError, TypeError, KeyError) as e:
            problems.append((at, str(e)))
        if not problems:
            problems += camera_range_problems(value, value.get("size", size), where)
    if not has_parameters(value) and "size" in value and list(value["size"]) != list(size):
        problems.append((format_path(where + ("size",)),
                         f"camera size {list(value['size'])} differs from the view size "
                         f"{list(size)}"))
    return problems


def _dlt_range_problems(value, size, where):
    """``camera_range_problems`` of a DLT with parameters: its intrinsics (``decompose``)
    as a pinhole's. A kept DLT with a focal length of 1e12 px ended the fit in a singular
    system naming no view, one with its principal point far outside the photo in a head
    hundreds of pixels off without a warning."""
    if not has_parameters(value):
        return []
    try:
        k = camera_from_dict({**value, "size": value.get("size", list(size))}).decompose()[0]
    except (ValueError, TypeError, KeyError, np.linalg.LinAlgError):
        return []  # not a camera: reported where it is built
    lo, hi = LENS_MM_RANGE
    ppm = _px_per_mm(size)
    w, h = (float(v) for v in size)
    at = format_path(where)
    problems = []
    focal = np.array([k[0, 0], k[1, 1]])
    if not (np.isfinite(k).all() and (lo * ppm <= focal).all() and (focal <= hi * ppm).all()):
        problems.append((at, f"its parameters give a focal length of "
                             f"{' x '.join(f'{f:.4g}' for f in focal)} px, outside "
                             f"{lo * ppm:.4g}..{hi * ppm:.4g} px, the lenses of {lo:g}..{hi:g} "
                             f"mm (36 mm equivalent) on this {size[0]}x{size[1]} photo"))
    elif not (0.0 <= k[0, 2] <= w and 0.0 <= k[1, 2] <= h):
        problems.append((at, f"its parameters put the principal point at ({k[0, 2]:.4g}, "
                             f"{k[1, 2]:.4g}), outside the {size[0]}x{size[1]} photo"))
    return problems
