"""The landmarks file: the interface every caller (add-on, command line, tests) uses to hand
landmarks placed on photos to the fit.

A file is JSON (UTF-8) with pixel coordinates, origin at the image's top-left corner, u to
the right, v down. Version 1 holds orthographic photos (a front and a profile)::

    {"format": "headrecon-landmarks", "version": 1,
     "views": {"front": {"image": "front.jpg", "size": [768, 1024],
                         "camera": "orthographic-front",
                         "points": {"nose_tip": [384.5, 540.0]}},
               "side": {"image": "side.jpg", "size": [768, 1024],
                        "camera": "orthographic-right",
                        "points": {"nose_tip": [150.0, 541.0]},
                        "contour": [[140.0, 120.0], [138.5, 131.0]]}}}

Version 2 (photos from any camera, at any angle) keeps that structure and adds:

- ``camera`` may be a camera object whose parameters are unknown (``{"kind": "dlt"}``,
  ``{"kind": "pinhole", "lens_mm": 50}``): computed from passpoints or by self-calibration;
  camera objects are checked field by field against the schema of their kind;
- ``"calibrated": true|false`` per view: keep the camera fixed, or refine it (absent: false);
- ``"mirror_of": "front"``: the view is the mirror image inside that view's photo (one
  camera and a flat mirror, seed 001). Its landmarks carry the subject's true names (the
  point that looks like a left eye in the mirror is stored as the right eye);
- ``"passpoints"``: top level ``{"name": [x, y, z]}`` metres of a calibration object, and
  per view ``{"name": [u, v]}`` pixels (seed 004): a DLT camera computed from them.

This module reads and writes the file. Checking happens in two layers: the JSON Schema
``assets/landmarks.schema.json`` (structure and types, both versions, validated with our
own ``jsonschema_lite`` because Blender lacks ``jsonschema``), then the checks a schema
cannot express (``case_check``): landmark names against ``assets/landmarks.json``
(``landmark_set``), points inside the image, finite numbers, one landmark given twice,
enough landmarks for a fit, camera parameters (``camera_json``), mirror and passpoint
references. Every problem is a ``ValueError`` naming the file, the view and the key. What
reading gives is a ``LandmarkCase`` of ``View`` objects (``case``).

The version of the format is dispatched in one place (``_VERSIONS``: its schema and
reader). ``landmarks_to_dict`` / ``save_landmarks`` write the lowest version that holds the
case (``case_version``), so a version-1 file is written back as version 1, unchanged.
"""

import functools
import json
import os
from pathlib import Path

import numpy as np

from ..cameras import OrthographicCamera
from ..paths import ASSETS_DIR
from .atomic import write_file_atomic
from .camera_json import camera_from_json, camera_object_problems, has_parameters
from .case import LandmarkCase, View, case_version
from .case_check import case_problems, check_case
from .contour import contour_array, size_problem
from .json_file import read_json
from .jsonschema_lite import Validator, format_path
from .landmark_set import as_landmark_set

FORMAT = "headrecon-landmarks"
#: Newest version read and written. Writing picks the lowest version that holds the case.
CURRENT_VERSION = 2
SCHEMA_PATH = ASSETS_DIR / "landmarks.schema.json"

#: Keys only version 2 has (for the hint when a version-1 file uses one).
_V2_VIEW_KEYS = ("calibrated", "mirror_of", "passpoints")


# --------------------------------------------------------------------------------------
# Errors


class LandmarksError(ValueError):
    """Every problem found in one landmarks document.

    ``str()`` is one line (the first problem, plus how many more), so a command line can
    print it as is; ``messages()`` lists them all (``python -m solver validate`` does).

    Attributes
    ----------
    source : str
        File path or "<dict>".
    problems : list of (str, str)
        (JSON path such as ``views.front.points.nose_tip``, message) pairs.
    """

    def __init__(self, source, problems):
        self.source = str(source)
        self.problems = list(problems)
        first = self.messages()[0]
        more = len(self.problems) - 1
        super().__init__(first + (f" (and {more} more problem{'s' * (more > 1)})"
                                  if more else ""))

    def messages(self):
        """Every problem as a line ``source: path: message``."""
        return [f"{self.source}: {p}: {m}" if p else f"{self.source}: {m}"
                for p, m in self.problems]


# --------------------------------------------------------------------------------------
# Reading


@functools.lru_cache(maxsize=4)
def _validator(schema_path):
    return Validator(read_json(schema_path))


def _strip_camera_prefix(message):
    return message[len("camera: "):] if message.startswith("camera: ") else message


def _read_view(vname, vd, camera, **fields):
    contour = vd.get("contour")
    view = View(
        name=vname, image=vd.get("image"), size=tuple(vd["size"]), camera=camera,
        points=vd["points"],
        contour=None if contour is None else np.array(contour, dtype=np.float64).reshape(-1, 2),
        extra={k: v for k, v in vd.items() if k.startswith("x-")},
        uncertainty=vd.get("uncertainty", {}), depth=vd.get("depth", {}), **fields)
    if camera is not None and isinstance(vd["camera"], dict):
        view.keep_camera_as_read(vd["camera"])
    return view


def _read_v1(data, problems, bad_cameras):
    """Views of a schema-valid version-1 document (problems appended, not raised)."""
    views = {}
    for vname, vd in data["views"].items():
        where = ("views", vname)
        size = tuple(vd["size"])
        value = vd["camera"]
        try:
            if isinstance(value, dict) and not has_parameters(value):
                raise ValueError(f"a {value['kind']} camera without its parameters needs "
                                 "version 2 of the file (set \"version\": 2)")
            camera = camera_from_json(value, size)
        except ValueError as e:
            problems.append((format_path(where + ("camera",)), _strip_camera_prefix(str(e))))
            camera = OrthographicCamera.nominal("orthographic-front", size)
            bad_cameras.add(vname)
        views[vname] = _read_view(vname, vd, camera)
    return views, {}


def _read_v2(data, problems, bad_cameras):
    """Views and passpoints of a schema-valid version-2 document."""
    views = {}
    for vname, vd in data["views"].items():
        where = ("views", vname, "camera")
        size = tuple(vd["size"])
        value = vd["camera"]
        camera, hints = None, {}
        found = [] if isinstance(value, str) else camera_object_problems(value, size, where)
        if found:
            problems += found
            bad_cameras.add(vname)
            hints = {"kind": value.get("kind")}
        elif isinstance(value, dict) and not has_parameters(value):
            hints = dict(value)
        else:
            try:
                camera = camera_from_json(value, size)
            except ValueError as e:
                problems.append((format_path(where), _strip_camera_prefix(str(e))))
                bad_cameras.add(vname)
                hints = {"kind": value.get("kind")}
        views[vname] = _read_view(vname, vd, camera, calibrated=vd.get("calibrated"),
                                  mirror_of=vd.get("mirror_of"),
                                  passpoints=vd.get("passpoints", {}), camera_hints=hints)
    return views, data.get("passpoints", {})


# version -> (schema file, reader). A new version adds its entry here. A reader takes the
# schema-valid document, a list to append (path, message) problems to and a set to add the
# names of views whose camera could not be built to, and returns (views, passpoints).
# One schema file describes every version (its "if version is N" branches).
_VERSIONS = {1: (SCHEMA_PATH, _read_v1), 2: (SCHEMA_PATH, _read_v2)}


def parse_landmarks(data, source="<dict>", known_names=None, for_fit=True):
    """Validate a landmarks document (version 1 or 2) and build the case.

    Parameters
    ----------
    data : dict
        The parsed JSON.
    source : str
        File name used in messages (and to resolve image paths).
    known_names : LandmarkSet, HeadModel-like, iterable of str, or None
        Accepted landmark names (None: ``assets/landmarks.json``).
    for_fit : bool
        Also require enough landmarks (and passpoints) for a fit (False for work in
        progress).

    Returns
    -------
    LandmarkCase

    Raises
    ------
    LandmarksError (a ValueError)
        Naming the source, the view and the key of every problem.
    """
    source = str(source)
    if not isinstance(data, dict):
        raise LandmarksError(source, [("", "expected a JSON object at the top level, got "
                                           f"{type(data).__name__}")])
    if data.get("format") != FORMAT:
        got = data.get("format")
        raise LandmarksError(source, [("format", f"expected {FORMAT!r}, got {got!r}"
                                                 + ("" if got is not None else
                                                    " (not a HeadRecon landmarks file?)"))])
    version = data.get("version")
    if isinstance(version, bool) or not isinstance(version, int | float) \
            or version not in _VERSIONS:
        known = sorted(_VERSIONS)
        known = (f"version {known[0]}" if len(known) == 1 else
                 "versions " + ", ".join(str(v) for v in known[:-1]) + f" and {known[-1]}")
        raise LandmarksError(source, [("version", f"unsupported version {version!r}; this "
                                                  f"HeadRecon reads {known} (a newer "
                                                  "HeadRecon may read it)")])
    version = int(version)
    schema_path, reader = _VERSIONS[version]
    checked, too_big = _contours_aside(data)
    if too_big:
        raise LandmarksError(source, too_big)
    errors = _validator(str(schema_path)).errors(checked)
    if errors:
        raise LandmarksError(source, [_version_hint(e, version) for e in errors])
    lms = as_landmark_set(known_names)
    problems = []
    bad_cameras = set()
    views, passpoints = reader(data, problems, bad_cameras)
    case = LandmarkCase(views, source, {k: v for k, v in data.items() if k.startswith("x-")},
                        passpoints)
    problems += case_problems(case, lms, for_fit, bad_cameras)
    if problems:
        raise LandmarksError(source, problems)
    return case


def _contours_aside(data):
    """The document for the schema with each well-formed contour as ``[]`` (checked with
    numpy in ``case_check`` instead: the schema's per-item walk took 9 s over 100,000
    points), and the (path, message) of every contour over ``MAX_CONTOUR_POINTS``."""
    views = data.get("views")
    if not isinstance(views, dict):
        return data, []
    out, too_big = {}, []
    for name, vd in views.items():
        contour = vd.get("contour") if isinstance(vd, dict) else None
        if isinstance(contour, list) and size_problem(len(contour)):
            too_big.append((format_path(("views", name, "contour")),
                            size_problem(len(contour))))
        elif contour_array(contour) is not None:
            vd = {**vd, "contour": []}
        out[name] = vd
    return {**data, "views": out}, too_big


def _version_hint(error, version):
    """(path, message) of a schema error; a version-2 key in a version-1 file says so."""
    path = error.path
    v2_key = (len(path) == 3 and path[0] == "views" and path[2] in _V2_VIEW_KEYS) \
        or path == ("passpoints",)
    if version == 1 and v2_key and error.keyword in ("additionalProperties", "false"):
        return error.where, "a version-2 key in a version-1 file; set \"version\": 2"
    return error.where, error.message


def load_landmarks(path, known_names=None, for_fit=True):
    """Read and validate a landmarks file (see ``parse_landmarks``).

    Raises
    ------
    FileNotFoundError
        No such file (message names it).
    ValueError
        Not UTF-8, not JSON, or any problem ``parse_landmarks`` finds.
    """
    return parse_landmarks(read_json(path), str(path), known_names, for_fit)


# --------------------------------------------------------------------------------------
# Writing


def landmarks_to_dict(case, base_dir=None, version=None):
    """The case as a JSON-ready dict.

    Parameters
    ----------
    case : LandmarkCase
    base_dir : path-like, optional
        Folder the document will be saved in: relative image paths are rewritten to stay
        pointing at the same photos (default: the case's own folder, paths unchanged).
    version : int, optional
        File version to write (default ``case_version(case)``: 1 unless the case uses a
        version-2 feature, so version-1 files are written back unchanged).

    Raises
    ------
    ValueError
        ``version`` unknown, or too old for what the case uses (names the view and key).
    """
    version = _write_version(case, version)
    out = {"format": FORMAT, "version": version, "views": {}}
    old = case.base_dir
    new = Path(base_dir).resolve() if base_dir is not None else None
    for name, view in case.views.items():
        image = None
        if view.image is not None and new is not None and old is not None and old != new \
                and not Path(view.image).is_absolute():
            try:
                image = Path(os.path.relpath(old / view.image, new)).as_posix()
            except ValueError:  # different drives on Windows: keep it absolute
                image = str(old / view.image)
        out["views"][name] = view.to_dict(image)
    if case.passpoints:
        out["passpoints"] = {k: v.tolist() for k, v in case.passpoints.items()}
    out.update(case.extra)
    return out


def _write_version(case, version):
    if version is None:
        return case_version(case)
    if isinstance(version, bool) or version not in _VERSIONS:
        raise ValueError(f"version: expected one of {sorted(_VERSIONS)}, got {version!r}")
    version = int(version)
    if version < 2:
        used = [format_path(("views", n, k)) for n, v in case.views.items()
                for k in v.version2_features()]
        used += ["passpoints"] if case.passpoints else []
        if used:
            raise ValueError(f"{case.source}: {used[0]}: needs version 2 of the file; version "
                             f"{version} cannot store it")
    return version


def _dumps(obj, indent=0):
    """JSON with one landmark per line: arrays of numbers stay on one line."""
    pad = "  " * (indent + 1)
    if isinstance(obj, dict):
        if not obj:
            return "{}"
        items = [f"{pad}{json.dumps(k, ensure_ascii=False)}: {_dumps(v, indent + 1)}"
                 for k, v in obj.items()]
        return "{\n" + ",\n".join(items) + "\n" + "  " * indent + "}"
    if isinstance(obj, list) and obj and any(isinstance(x, dict | list) for x in obj):
        items = [pad + _dumps(x, indent + 1) for x in obj]
        return "[\n" + ",\n".join(items) + "\n" + "  " * indent + "]"
    return json.dumps(obj, ensure_ascii=False, allow_nan=False)


def save_landmarks(case, path, known_names=None, version=None):
    """Write ``case`` to ``path`` atomically (temp file in the same folder, then rename).

    The document is validated first (as work in progress: without the landmark count
    floor), so a file this writes always loads again. Relative image paths are rewritten
    if the file moves to another folder. ``version`` as in ``landmarks_to_dict`` (default:
    the lowest that holds the case).

    Raises
    ------
    ValueError
        The case has problems (nothing is written).
    """
    path = Path(path)
    data = landmarks_to_dict(case, path.parent, version)
    schema_path = _VERSIONS[data["version"]][0]
    problems = [(e.where, e.message) for e in _validator(str(schema_path)).errors(data)]
    if not problems:
        problems = check_case(case, known_names, for_fit=False)
    if problems:
        raise LandmarksError(str(path), problems)
    write_file_atomic(path, _dumps(data) + "\n")
