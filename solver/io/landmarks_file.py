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

Checking happens in two layers: the JSON Schema ``assets/landmarks.schema.json`` (structure
and types, both versions, validated with our own ``jsonschema_lite`` because Blender lacks
``jsonschema``), then the checks a schema cannot express: landmark names against
``assets/landmarks.json``, points inside the image, finite numbers, one landmark given
twice, enough landmarks for a fit, camera parameters, mirror and passpoint references.
Every problem is a ``ValueError`` naming the file, the view and the key.

The version of the format is dispatched in one place (``_VERSIONS``: its schema and
reader). ``landmarks_to_dict`` / ``save_landmarks`` write the lowest version that holds the
case (``case_version``), so a version-1 file is written back as version 1, unchanged.
"""

import copy
import difflib
import functools
import json
import math
import os
import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..cameras import ORTHO_VIEWS, Camera, OrthographicCamera, camera_from_dict, camera_kinds
from ..cameras import base as _cameras
from ..paths import ASSETS_DIR
from .jsonschema_lite import Validator, format_path

FORMAT = "headrecon-landmarks"
#: Newest version read and written. Writing picks the lowest version that holds the case.
CURRENT_VERSION = 2
SCHEMA_PATH = ASSETS_DIR / "landmarks.schema.json"
LANDMARK_SET_PATH = ASSETS_DIR / "landmarks.json"

#: Fewest landmarks per view and in all that a fit accepts: a view needs at least its
#: camera's 2-D similarity (2 points) plus one to constrain the shape; the two views
#: together need enough rows for the pose and the leading shape components. The fit may
#: demand more; these are the floor every file must clear.
MIN_LANDMARKS_PER_VIEW = 3
MIN_LANDMARKS_TOTAL = 6
#: Fewest passpoints from which a view's DLT camera is computed (11 unknowns, seed 000 §2).
MIN_PASSPOINTS = 6

#: Keys only version 2 has (for the hint when a version-1 file uses one).
_V2_VIEW_KEYS = ("calibrated", "mirror_of", "passpoints")

_IBUG = re.compile(r"^ibug(\d\d)$")


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
# The landmark set (assets/landmarks.json): one source of truth for names and ibug aliases


@dataclass(frozen=True, eq=False)
class LandmarkSet:
    """Known landmark names, their model vertices and their iBUG-68 numbers.

    Attributes
    ----------
    names : tuple of str
        Canonical names in file order.
    vertices : dict of str -> int
        Canonical name -> model vertex index (-1 when not known, e.g. built from names).
    ibug : dict of int -> str
        iBUG-68 number (1...68) -> canonical name; the alias ``ibugNN`` resolves through it.
    info : tuple of dict
        The entries of ``assets/landmarks.json`` (name, description, vertex, views, ibug,
        thesis), for user interfaces.
    source : str
    """

    names: tuple
    vertices: dict
    ibug: dict
    info: tuple = ()
    source: str = "<names>"

    @classmethod
    def from_dict(cls, data, source="<dict>"):
        """Build from the parsed ``assets/landmarks.json`` document."""
        if not isinstance(data, dict) or data.get("format") != "headrecon-landmark-set":
            raise ValueError(f"{source}: not a landmark set (expected \"format\": "
                             "\"headrecon-landmark-set\")")
        entries = data.get("landmarks")
        if not isinstance(entries, list) or not entries:
            raise ValueError(f"{source}: landmarks: expected a non-empty list")
        names, vertices, ibug = [], {}, {}
        for i, e in enumerate(entries):
            name = e.get("name") if isinstance(e, dict) else None
            if not isinstance(name, str) or not name or _IBUG.match(name):
                raise ValueError(f"{source}: landmarks[{i}].name: expected a name that is "
                                 f"not an ibug alias, got {name!r}")
            if name in vertices:
                raise ValueError(f"{source}: landmarks[{i}].name: {name!r} listed twice")
            vertex = e.get("vertex")
            if isinstance(vertex, bool) or not isinstance(vertex, int) or vertex < 0:
                raise ValueError(f"{source}: landmarks[{i}].vertex: expected a vertex index, "
                                 f"got {vertex!r}")
            number = e.get("ibug")
            if number is not None:
                if isinstance(number, bool) or not isinstance(number, int) \
                        or not 1 <= number <= 68 or number in ibug:
                    raise ValueError(f"{source}: landmarks[{i}].ibug: expected a free number "
                                     f"1..68 or null, got {number!r}")
                ibug[number] = name
            names.append(name)
            vertices[name] = vertex
        return cls(tuple(names), vertices, ibug, tuple(entries), str(source))

    @classmethod
    def from_names(cls, names):
        """A set from bare names (vertices unknown, no ibug aliases beyond names given)."""
        names = tuple(dict.fromkeys(str(n) for n in names))
        return cls(names, dict.fromkeys(names, -1), {}, (), "<names>")

    def canonical(self, name):
        """Canonical name of ``name`` (itself, or the landmark an ``ibugNN`` alias
        stands for), or None if unknown."""
        if name in self.vertices:
            return name
        m = _IBUG.match(name)
        if m:
            return self.ibug.get(int(m.group(1)))
        return None

    def vertex(self, name):
        """Model vertex index of ``name`` (canonical or ``ibugNN``)."""
        canon = self.canonical(name)
        if canon is None:
            raise ValueError(f"landmark {name!r}: unknown{self.suggestion(name)}")
        return self.vertices[canon]

    def all_names(self):
        """Every accepted spelling: canonical names, then ``ibugNN`` aliases."""
        return list(self.names) + [f"ibug{n:02d}" for n in sorted(self.ibug)]

    def suggestion(self, name):
        """"; did you mean 'x'?" for the closest accepted name, or ""."""
        accepted = self.all_names()
        lower = {n.lower(): n for n in accepted}
        m = re.match(r"^ibug[ _-]?0*(\d+)$", name.strip(), re.IGNORECASE)
        if m and int(m.group(1)) in self.ibug:  # "ibug1", "iBUG_31": the spelling is fixed
            guess = f"ibug{int(m.group(1)):02d}"
        elif name.strip().lower() in lower:  # "Nose_Tip"
            guess = lower[name.strip().lower()]
        else:
            close = difflib.get_close_matches(name, accepted, n=1, cutoff=0.6)
            guess = close[0] if close else None
        return f"; did you mean {guess!r}?" if guess else ""


@functools.lru_cache(maxsize=8)
def _landmark_set_cached(path, mtime):
    return LandmarkSet.from_dict(_read_json(path), str(path))


def load_landmark_set(path=None):
    """The landmark set of ``assets/landmarks.json`` (or ``path``); cached until it changes.

    Raises
    ------
    FileNotFoundError
        The file is missing (the model helper writes ``assets/landmarks.json``).
    ValueError
        The file is not a valid landmark set (message names the file and entry).
    """
    path = Path(path) if path is not None else LANDMARK_SET_PATH
    try:
        mtime = path.stat().st_mtime_ns
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: landmark set not found") from None
    return _landmark_set_cached(str(path), mtime)


def _as_landmark_set(known_names):
    """None (the default set), a LandmarkSet, a HeadModel-like object with
    ``landmark_info``, or an iterable of names -> LandmarkSet."""
    if known_names is None:
        return load_landmark_set()
    if isinstance(known_names, LandmarkSet):
        return known_names
    info = getattr(known_names, "landmark_info", None)
    if info is not None:
        return LandmarkSet.from_dict({"format": "headrecon-landmark-set",
                                      "landmarks": list(info)}, "<model>")
    if isinstance(known_names, str):
        raise ValueError("known_names: expected a LandmarkSet or names, got a string")
    return LandmarkSet.from_names(known_names)


# --------------------------------------------------------------------------------------
# Cameras as the file stores them


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


# Per kind: the fields that make its parameters known (any one present: the object must be
# a complete camera), and the fields that only make sense with them.
_PARAMETER_KEYS = {"dlt": ("parameters", "matrix"), "pinhole": ("rotation", "centre")}
_WITH_PARAMETERS = {"dlt": ("depth_sign", "distortion", "distortion_centre")}


def _has_parameters(value):
    """Whether a camera object of the file gives its parameters (else: to be computed)."""
    keys = _PARAMETER_KEYS.get(value.get("kind"))
    return keys is None or any(k in value for k in keys)


def _non_finite(value, path):
    """Paths (tuples) of the NaN / infinite numbers inside a JSON value."""
    if isinstance(value, float):
        return [] if math.isfinite(value) else [path]
    if isinstance(value, dict):
        return [p for k, v in value.items() for p in _non_finite(v, path + (k,))]
    if isinstance(value, list):
        return [p for i, v in enumerate(value) for p in _non_finite(v, path + (i,))]
    return []


def _camera_object_problems(value, size, where):
    """What a schema cannot say about a camera object of the file (version 2): numbers that
    are not finite, fields that contradict each other, options the camera would refuse.
    ``where`` is the path of the camera; returns (path, message) pairs."""
    problems = [(format_path(p), "not a finite number; NaN and infinity are not allowed")
                for p in _non_finite(value, where)]
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
    elif kind == "pinhole" and not _has_parameters(value):
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
    if not _has_parameters(value) and "size" in value and list(value["size"]) != list(size):
        problems.append((format_path(where + ("size",)),
                         f"camera size {list(value['size'])} differs from the view size "
                         f"{list(size)}"))
    return problems


# --------------------------------------------------------------------------------------
# Data classes


def _as_uv_dict(points):
    return {str(k): tuple(float(c) for c in np.asarray(v, dtype=np.float64).reshape(-1))
            for k, v in points.items()}


@dataclass(eq=False)
class View:
    """One photo and the landmarks placed on it.

    Attributes
    ----------
    name : str
        The view's name (free, e.g. "front").
    image : str or None
        The photo's path relative to the landmarks file (absolute also accepted).
    size : (int, int)
        Image width and height in pixels.
    camera : Camera or None
        Nominal orthographic camera, or one with given parameters. None (version 2): the
        parameters are unknown; ``camera_hints`` says which kind of camera to compute
        (from ``passpoints``, or by self-calibration on the head).
    points : dict of str -> (float, float)
        Landmark name (canonical or ``ibugNN``, as written) -> (u, v) pixels. In a mirror
        view (``mirror_of``) the names are the subject's true ones (already mapped).
    contour : ndarray, shape (n, 2), pixels, or None
        Traced head outline in this photo (any view; hair left out), in drawing order.
    extra : dict
        Keys starting with "x-" (tools' own data), kept on a round trip.
    calibrated : bool or None
        True: keep the camera as given (or as computed from the passpoints). False or None
        (not stated): the camera is a starting guess the fit refines. See ``camera_fixed``.
    mirror_of : str or None
        Name of the view whose photo this view is the mirror image in (one camera and a
        flat mirror): same image and size, a mirrored camera.
    passpoints : dict of str -> (float, float)
        Passpoint name (a key of ``LandmarkCase.passpoints``) -> (u, v) pixels.
    camera_hints : dict
        When ``camera`` is None: the camera object as the file gives it, at least
        ``{"kind": ...}`` plus what is known (e.g. a pinhole's ``lens_mm`` from EXIF).
        Ignored when ``camera`` is set.
    """

    name: str
    image: str | None
    size: tuple
    camera: Camera | None
    points: dict
    contour: np.ndarray | None = None
    extra: dict = field(default_factory=dict)
    calibrated: bool | None = None
    mirror_of: str | None = None
    passpoints: dict = field(default_factory=dict)
    camera_hints: dict = field(default_factory=dict)
    # (camera, its object as the file wrote it, camera.to_dict() then): while the camera is
    # that same unchanged object it is written back as read, so loading and saving a file
    # does not move its numbers by a rounding error (a DLT's b-form is recomputed).
    _camera_source: tuple | None = field(default=None, init=False, repr=False)

    def __post_init__(self):
        # Normalise what callers hand in (numpy arrays, lists) so equality, saving and the
        # checks see one representation. Values stay as given (NaN too): checks report them.
        self.size = tuple(int(x) for x in self.size)
        self.points = _as_uv_dict(self.points)
        self.passpoints = _as_uv_dict(self.passpoints)
        self.camera_hints = dict(self.camera_hints)
        if self.contour is not None:
            self.contour = np.asarray(self.contour, dtype=np.float64).reshape(-1, 2)

    @property
    def camera_kind(self):
        """Kind of the view's camera ("orthographic", "dlt", "pinhole"), known or not."""
        if self.camera is not None:
            return self.camera.kind
        return self.camera_hints.get("kind")

    @property
    def camera_fixed(self):
        """True when the fit must keep the camera (``calibrated`` is True)."""
        return self.calibrated is True

    def version2_features(self):
        """The keys of this view that need version 2 of the file (empty: version 1 holds it).
        """
        out = [k for k, used in (("camera", self.camera is None),
                                 ("calibrated", self.calibrated is not None),
                                 ("mirror_of", self.mirror_of is not None),
                                 ("passpoints", bool(self.passpoints))) if used]
        return out

    def to_dict(self, image=None):
        """The view as stored in a file (``image`` overrides the stored path)."""
        d = {}
        img = self.image if image is None else image
        if img is not None:
            d["image"] = img
        d["size"] = list(self.size)
        src = self._camera_source
        if self.camera is not None and src is not None and src[0] is self.camera \
                and _json_equal(self.camera.to_dict(), src[2]):
            d["camera"] = copy.deepcopy(src[1])
        elif self.camera is not None:
            d["camera"] = camera_to_json(self.camera, self.size)
        else:
            d["camera"] = dict(self.camera_hints)
        if self.calibrated is not None:
            d["calibrated"] = self.calibrated
        if self.mirror_of is not None:
            d["mirror_of"] = self.mirror_of
        d["points"] = {k: list(v) for k, v in self.points.items()}
        if self.passpoints:
            d["passpoints"] = {k: list(v) for k, v in self.passpoints.items()}
        if self.contour is not None:
            d["contour"] = self.contour.tolist()
        d.update(self.extra)
        return d

    def __eq__(self, other):
        if not isinstance(other, View):
            return NotImplemented
        return self.name == other.name and _json_equal(self.to_dict(), other.to_dict())

    def arrays(self, known_names=None):
        """The points as arrays for a fit.

        Parameters
        ----------
        known_names : LandmarkSet, HeadModel-like or None
            Resolves names (None: ``assets/landmarks.json``).

        Returns
        -------
        names : list of str
            Canonical names, in the file's order.
        vertices : ndarray, shape (n,), int64
            Model vertex of each landmark.
        pixels : ndarray, shape (n, 2), float64, pixels
        """
        lms = _as_landmark_set(known_names)
        names = [lms.canonical(k) or k for k in self.points]
        vertices = np.array([lms.vertex(k) for k in self.points], dtype=np.int64)
        pixels = np.array(list(self.points.values()), dtype=np.float64).reshape(-1, 2)
        return names, vertices, pixels


@dataclass(eq=False)
class LandmarkCase:
    """All views of one person.

    Attributes
    ----------
    views : dict of str -> View
    source : str
        File the case was read from, or "<dict>".
    extra : dict
        Top-level keys starting with "x-", kept on a round trip.
    passpoints : dict of str -> ndarray, shape (3,), metres
        Points of a calibration object by name (version 2); views list their pixels.
    """

    views: dict
    source: str = "<dict>"
    extra: dict = field(default_factory=dict)
    passpoints: dict = field(default_factory=dict)

    def __post_init__(self):
        self.passpoints = {str(k): np.asarray(v, dtype=np.float64).reshape(-1)
                           for k, v in self.passpoints.items()}

    @property
    def base_dir(self):
        """Folder image paths are relative to (None when the case has no file)."""
        if self.source.startswith("<"):
            return None
        return Path(self.source).resolve().parent

    def image_path(self, view):
        """Absolute path of a view's photo, or None if the view names none. Relative paths
        resolve against the file's folder (the working folder for a case without file)."""
        img = self.views[view].image
        if img is None:
            return None
        p = Path(img)
        return p if p.is_absolute() else (self.base_dir or Path.cwd()) / p

    @property
    def n_points(self):
        """Landmarks over all views."""
        return sum(len(v.points) for v in self.views.values())

    @property
    def version(self):
        """The file version that holds this case (see ``case_version``)."""
        return case_version(self)

    def passpoint_arrays(self, view):
        """The passpoints a view sees, for a DLT calibration (``solver.dlt.fit_dlt``).

        Parameters
        ----------
        view : str

        Returns
        -------
        names : list of str
            In the view's order.
        points : ndarray, shape (n, 3), float64, metres
        pixels : ndarray, shape (n, 2), float64, pixels

        Raises
        ------
        ValueError
            A passpoint of the view is not defined at the top level (names it).
        """
        v = self.views[view]
        missing = [k for k in v.passpoints if k not in self.passpoints]
        if missing:
            raise ValueError(f"{self.source}: views.{view}.passpoints.{missing[0]}: not "
                             "defined in the top-level 'passpoints'")
        names = list(v.passpoints)
        points = np.array([self.passpoints[k] for k in names], dtype=np.float64)
        pixels = np.array([v.passpoints[k] for k in names], dtype=np.float64)
        return names, points.reshape(-1, 3), pixels.reshape(-1, 2)

    def __eq__(self, other):
        if not isinstance(other, LandmarkCase):
            return NotImplemented
        return _json_equal(landmarks_to_dict(self), landmarks_to_dict(other))


def case_version(case):
    """The lowest file version that holds ``case``: 2 when it uses passpoints, a mirror view,
    ``calibrated`` or a camera of unknown parameters, else 1."""
    if case.passpoints or any(v.version2_features() for v in case.views.values()):
        return 2
    return 1


def _json_equal(a, b):
    # NaN-aware comparison of JSON-like trees (a NaN point equals a NaN point).
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_json_equal(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_json_equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return type(a) is type(b) and a == b


# --------------------------------------------------------------------------------------
# Parsing


@functools.lru_cache(maxsize=4)
def _validator(schema_path):
    return Validator(_read_json(schema_path))


def _strip_camera_prefix(message):
    return message[len("camera: "):] if message.startswith("camera: ") else message


def _read_view(vname, vd, camera, **fields):
    contour = vd.get("contour")
    view = View(
        name=vname, image=vd.get("image"), size=tuple(vd["size"]), camera=camera,
        points=vd["points"],
        contour=None if contour is None else np.array(contour, dtype=np.float64).reshape(-1, 2),
        extra={k: v for k, v in vd.items() if k.startswith("x-")}, **fields)
    if camera is not None and isinstance(vd["camera"], dict):
        view._camera_source = (camera, copy.deepcopy(vd["camera"]), camera.to_dict())
    return view


def _read_v1(data, problems, bad_cameras):
    """Views of a schema-valid version-1 document (problems appended, not raised)."""
    views = {}
    for vname, vd in data["views"].items():
        where = ("views", vname)
        size = tuple(vd["size"])
        value = vd["camera"]
        try:
            if isinstance(value, dict) and not _has_parameters(value):
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
        found = [] if isinstance(value, str) else _camera_object_problems(value, size, where)
        if found:
            problems += found
            bad_cameras.add(vname)
            hints = {"kind": value.get("kind")}
        elif isinstance(value, dict) and not _has_parameters(value):
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
        (``for_fit``) fewer landmarks than the fit needs (per view: only views without
        passpoints, and mirror views) or passpoints that cannot give a camera.
    """
    return _check_case(case, _as_landmark_set(known_names), for_fit, frozenset())


def _check_case(case, lms, for_fit, bad_cameras):
    problems = []
    total = 0
    for vname, view in case.views.items():
        where = ("views", vname)
        w, h = view.size
        problems += _points_problems(view, where, lms)
        if view.contour is not None:
            for i, uv in enumerate(view.contour):
                problems += _point_problems(format_path(where + ("contour", i)), uv, w, h)
        if vname not in bad_cameras:
            problems += _camera_problems(view, where)
        problems += _mirror_problems(case, view, where)
        problems += _passpoint_problems(case, view, where, for_fit and vname not in bad_cameras)
        n = len(view.points)
        total += n
        # Passpoints give a view its camera, so it needs no landmarks of its own; not so a
        # mirror view: the fit derives its camera from the real one through the mirror.
        if for_fit and (not view.passpoints or view.mirror_of is not None):
            need = MIN_LANDMARKS_PER_VIEW
            what = "the fit needs"
            if view.camera is None and view.mirror_of is None and vname not in bad_cameras:
                cls = _camera_class(view.camera_kind)
                if cls is not None and cls.min_refit_points > need:
                    need = cls.min_refit_points
                    what = f"self-calibrating a {view.camera_kind} camera needs"
            if n < need:
                problems.append((format_path(where + ("points",)),
                                 f"{n} landmark{'s' * (n != 1)}; {what} at least {need} per "
                                 "view"))
    for name, xyz in case.passpoints.items():
        at = format_path(("passpoints", name))
        if not name:
            problems.append(("passpoints", "a passpoint without a name"))
        elif xyz.shape != (3,):
            problems.append((at, f"expected [x, y, z], got {xyz.size} numbers"))
        elif not np.isfinite(xyz).all():
            problems.append((at, "not a finite number; NaN and infinity are not allowed"))
    if for_fit and total < MIN_LANDMARKS_TOTAL:
        problems.append(("views", f"{total} landmarks in all; the fit needs at least "
                                  f"{MIN_LANDMARKS_TOTAL}"))
    return problems


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
    return problems


def _camera_class(kind):
    """The Camera class registered for ``kind``, or None."""
    camera_kinds()  # imports the plug-in kinds
    return _cameras._KINDS.get(kind)


def _is_nominal(camera, size):
    return isinstance(camera_to_json(camera, size), str)


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
        if _camera_class(kind) is None:
            return problems + [(format_path(where + ("camera", "kind")),
                                f"unknown kind {kind!r}; known: {', '.join(camera_kinds())}")]
        problems += _camera_object_problems(view.camera_hints, view.size, where + ("camera",))
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
                 for p in _non_finite(value, where + ("camera",))]
    if problems:
        return problems
    cam_size = getattr(cam, "size", None)
    if cam_size is not None and tuple(cam_size) != tuple(view.size):
        problems.append((at, f"camera size {list(cam_size)} differs from the view size "
                             f"{list(view.size)}"))
    if isinstance(cam, OrthographicCamera):
        r = np.asarray(cam.rotation, dtype=np.float64)
        if not np.allclose(r @ r.T, np.eye(3), rtol=0, atol=1e-6):
            problems.append((format_path(where + ("camera", "rotation")),
                             "not a rotation (its rows must be orthonormal)"))
    if view.calibrated is True and _is_nominal(cam, view.size):
        problems.append((format_path(where + ("calibrated",)),
                         f"true, but {camera_to_json(cam, view.size)!r} is a nominal camera "
                         "(its scale and offset a guess): give the camera's parameters to "
                         "keep it fixed"))
    return problems


def _mirrored(camera):
    """True / False for a camera seen in a mirror (rotation determinant -1), None if the
    camera does not say."""
    flag = getattr(camera, "is_mirrored", None)
    if isinstance(flag, bool):
        return flag
    rot = getattr(camera, "rotation", None)
    if rot is None:
        return None
    return bool(np.linalg.det(np.asarray(rot, dtype=np.float64).reshape(3, 3)) < 0)


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
    if cam is not None and _is_nominal(cam, view.size):
        problems.append((format_path(where + ("camera",)),
                         f"{camera_to_json(cam, view.size)!r} cannot see a mirror image (its "
                         "landmarks carry the subject's true names, so the camera is "
                         "mirrored): give {\"kind\": \"dlt\"} to compute it, or a mirrored "
                         "camera's parameters"))
    elif cam is not None and _mirrored(cam) is False:
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
                fit_dlt(xyz, uv, view.size)
            except ValueError as e:
                msg = str(e)
                msg = msg[len("points: "):] if msg.startswith("points: ") else msg
                problems.append((at, f"cannot compute the camera: {msg}"))
    return problems


def _point_problems(at, uv, w, h):
    if len(uv) != 2:
        return [(at, f"expected [u, v], got {len(uv)} numbers")]
    u, v = uv
    if not (math.isfinite(u) and math.isfinite(v)):
        return [(at, f"not a finite number ({u}, {v}); NaN and infinity are not allowed")]
    if not (0.0 <= u <= w and 0.0 <= v <= h):
        return [(at, f"({u:g}, {v:g}) lies outside the {w}x{h} image")]
    return []


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
    errors = _validator(str(schema_path)).errors(data)
    if errors:
        raise LandmarksError(source, [_version_hint(e, version) for e in errors])
    lms = _as_landmark_set(known_names)
    problems = []
    bad_cameras = set()
    views, passpoints = reader(data, problems, bad_cameras)
    case = LandmarkCase(views, source, {k: v for k, v in data.items() if k.startswith("x-")},
                        passpoints)
    problems += _check_case(case, lms, for_fit, bad_cameras)
    if problems:
        raise LandmarksError(source, problems)
    return case


def _version_hint(error, version):
    """(path, message) of a schema error; a version-2 key in a version-1 file says so."""
    path = error.path
    v2_key = (len(path) == 3 and path[0] == "views" and path[2] in _V2_VIEW_KEYS) \
        or path == ("passpoints",)
    if version == 1 and v2_key and error.keyword in ("additionalProperties", "false"):
        return error.where, "a version-2 key in a version-1 file; set \"version\": 2"
    return error.where, error.message


def _reject_duplicate_keys(pairs):
    keys = [k for k, _ in pairs]
    if len(set(keys)) != len(keys):
        dup = next(k for i, k in enumerate(keys) if k in keys[:i])
        raise ValueError(f"key {dup!r} appears twice in one object")
    return dict(pairs)


def _read_json(path):
    """Parse a UTF-8 JSON file; errors name the file (ValueError, FileNotFoundError)."""
    path = str(path)
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise IsADirectoryError(f"{path}: is a folder, not a file") from None
    try:
        text = raw.decode("utf-8-sig")  # tolerate the BOM some Windows editors write
    except UnicodeDecodeError as e:
        raise ValueError(f"{path}: not UTF-8 text (byte 0x{raw[e.start]:02x} at offset "
                         f"{e.start})") from None
    try:
        return json.loads(text, object_pairs_hook=_reject_duplicate_keys)
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}: not valid JSON: {e.msg} (line {e.lineno}, "
                         f"column {e.colno})") from None
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from None


def load_landmarks(path, known_names=None, for_fit=True):
    """Read and validate a landmarks file (see ``parse_landmarks``).

    Raises
    ------
    FileNotFoundError
        No such file (message names it).
    ValueError
        Not UTF-8, not JSON, or any problem ``parse_landmarks`` finds.
    """
    return parse_landmarks(_read_json(path), str(path), known_names, for_fit)


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


def write_file_atomic(path, data):
    """Write ``data`` (str as UTF-8, or bytes) to ``path`` through a temporary file in the
    same folder and ``os.replace``: readers see the old file or the new one, never half.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if isinstance(data, str):
        data = data.encode("utf-8")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        # mkstemp makes the file private (0600); give it the mode a plain open() would.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


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
