"""Cameras as the landmarks file stores them: a nominal view's string or a camera object
(``{"kind": ...}`` with its parameters, or without them in version 2: to be computed), and
the checks a schema cannot make on such an object."""

import math

import numpy as np

from ..cameras import ORTHO_VIEWS, OrthographicCamera, camera_from_dict
from .jsonschema_lite import format_path

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
    if not has_parameters(value) and "size" in value and list(value["size"]) != list(size):
        problems.append((format_path(where + ("size",)),
                         f"camera size {list(value['size'])} differs from the view size "
                         f"{list(size)}"))
    return problems
