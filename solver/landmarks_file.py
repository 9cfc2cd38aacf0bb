"""The landmarks file: the interface every caller (add-on, command line, tests) uses to hand
landmarks placed on photos to the fit.

A file is JSON (UTF-8) with pixel coordinates, origin at the image's top-left corner, u to
the right, v down::

    {"format": "headrecon-landmarks", "version": 1,
     "views": {"front": {"image": "front.jpg", "size": [768, 1024],
                         "camera": "orthographic-front",
                         "points": {"nose_tip": [384.5, 540.0]}},
               "side": {"image": "side.jpg", "size": [768, 1024],
                        "camera": "orthographic-right",
                        "points": {"nose_tip": [150.0, 541.0]},
                        "contour": [[140.0, 120.0], [138.5, 131.0]]}}}

Checking happens in two layers: the JSON Schema ``assets/landmarks.schema.json`` (structure
and types, validated with our own ``jsonschema_lite`` because Blender lacks ``jsonschema``),
then the checks a schema cannot express: landmark names against ``assets/landmarks.json``,
points inside the image, finite numbers, one landmark given twice, enough landmarks for a
fit. Every problem is a ``ValueError`` naming the file, the view and the key.

The version of the format is dispatched in one place (``_VERSIONS``): a later version adds
an entry (its schema and reader) there; ``landmarks_to_dict`` writes ``CURRENT_VERSION``.
"""

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

from .cameras import ORTHO_VIEWS, Camera, OrthographicCamera, camera_from_dict
from .jsonschema_lite import Validator, format_path

FORMAT = "headrecon-landmarks"
CURRENT_VERSION = 1
ASSETS_DIR = Path(__file__).resolve().parent.parent / "assets"
SCHEMA_PATH = ASSETS_DIR / "landmarks.schema.json"
LANDMARK_SET_PATH = ASSETS_DIR / "landmarks.json"

#: Fewest landmarks per view and in all that a fit accepts: a view needs at least its
#: camera's 2-D similarity (2 points) plus one to constrain the shape; the two views
#: together need enough rows for the pose and the leading shape components. The fit may
#: demand more; these are the floor every file must clear.
MIN_LANDMARKS_PER_VIEW = 3
MIN_LANDMARKS_TOTAL = 6

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
# Data classes


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
    """Inverse of ``camera_to_json``: a nominal view string or a ``{"kind": ...}`` object.

    Raises
    ------
    ValueError
        Unknown string or kind, bad parameters, or a camera whose size disagrees.
    """
    if isinstance(value, str):
        return OrthographicCamera.nominal(value, size)
    if not isinstance(value, dict):
        raise ValueError(f"expected a view name or a camera object, got {value!r}")
    try:
        cam = camera_from_dict(value)
    except (KeyError, TypeError, IndexError) as e:
        raise ValueError(f"bad camera parameters ({type(e).__name__}: {e})") from None
    cam_size = getattr(cam, "size", None)
    if cam_size is not None and tuple(cam_size) != tuple(size):
        raise ValueError(f"camera size {list(cam_size)} differs from the view size "
                         f"{list(size)}")
    return cam


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
    camera : Camera
        Nominal orthographic camera, or one with given parameters.
    points : dict of str -> (float, float)
        Landmark name (canonical or ``ibugNN``, as written) -> (u, v) pixels.
    contour : ndarray, shape (n, 2), pixels, or None
        Traced head outline of a profile photo (hair left out), in drawing order.
    extra : dict
        Keys starting with "x-" (tools' own data), kept on a round trip.
    """

    name: str
    image: str | None
    size: tuple
    camera: Camera
    points: dict
    contour: np.ndarray | None = None
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        # Normalise what callers hand in (numpy arrays, lists) so equality, saving and the
        # checks see one representation. Values stay as given (NaN too): checks report them.
        self.size = tuple(int(x) for x in self.size)
        self.points = {str(k): tuple(float(c) for c in np.asarray(v, dtype=np.float64)
                                     .reshape(-1)) for k, v in self.points.items()}
        if self.contour is not None:
            self.contour = np.asarray(self.contour, dtype=np.float64).reshape(-1, 2)

    def to_dict(self, image=None):
        """The view as stored in a file (``image`` overrides the stored path)."""
        d = {}
        img = self.image if image is None else image
        if img is not None:
            d["image"] = img
        d["size"] = list(self.size)
        d["camera"] = camera_to_json(self.camera, self.size)
        d["points"] = {k: list(v) for k, v in self.points.items()}
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
    """

    views: dict
    source: str = "<dict>"
    extra: dict = field(default_factory=dict)

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

    def __eq__(self, other):
        if not isinstance(other, LandmarkCase):
            return NotImplemented
        return _json_equal(landmarks_to_dict(self), landmarks_to_dict(other))


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


def _read_v1(data, problems):
    """Views of a schema-valid version-1 document (problems appended, not raised)."""
    views = {}
    for vname, vd in data["views"].items():
        where = ("views", vname)
        size = tuple(vd["size"])
        try:
            camera = camera_from_json(vd["camera"], size)
        except ValueError as e:
            msg = str(e)
            msg = msg[len("camera: "):] if msg.startswith("camera: ") else msg
            problems.append((format_path(where + ("camera",)), msg))
            camera = OrthographicCamera.nominal("orthographic-front", size)
        contour = vd.get("contour")
        views[vname] = View(
            name=vname, image=vd.get("image"), size=size, camera=camera,
            points=vd["points"],
            contour=None if contour is None else np.array(contour, dtype=np.float64)
            .reshape(-1, 2),
            extra={k: v for k, v in vd.items() if k.startswith("x-")})
    return views


# version -> (schema file, reader). A new version adds its entry here.
_VERSIONS = {1: (SCHEMA_PATH, _read_v1)}


def check_case(case, known_names=None, for_fit=True):
    """The checks a schema cannot express, on a built case.

    Returns
    -------
    list of (str, str)
        (JSON path, message) per problem: unknown landmark names (with the closest known
        name), one landmark given twice (a name and its ibug alias), non-finite numbers,
        points outside the image, and (``for_fit``) fewer landmarks than the fit needs.
    """
    lms = _as_landmark_set(known_names)
    problems = []
    total = 0
    for vname, view in case.views.items():
        where = ("views", vname)
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
        if view.contour is not None:
            for i, uv in enumerate(view.contour):
                problems += _point_problems(format_path(where + ("contour", i)), uv, w, h)
        n = len(view.points)
        total += n
        if for_fit and n < MIN_LANDMARKS_PER_VIEW:
            problems.append((format_path(where + ("points",)),
                             f"{n} landmark{'s' * (n != 1)}; the fit needs at least "
                             f"{MIN_LANDMARKS_PER_VIEW} per view"))
    if for_fit and total < MIN_LANDMARKS_TOTAL:
        problems.append(("views", f"{total} landmarks in all; the fit needs at least "
                                  f"{MIN_LANDMARKS_TOTAL}"))
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
    """Validate a landmarks document and build the case.

    Parameters
    ----------
    data : dict
        The parsed JSON.
    source : str
        File name used in messages (and to resolve image paths).
    known_names : LandmarkSet, HeadModel-like, iterable of str, or None
        Accepted landmark names (None: ``assets/landmarks.json``).
    for_fit : bool
        Also require enough landmarks for a fit (False for work in progress).

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
        known = ", ".join(str(v) for v in sorted(_VERSIONS))
        raise LandmarksError(source, [("version", f"unsupported version {version!r}; this "
                                                  f"HeadRecon reads version {known} (a newer "
                                                  "HeadRecon may read it)")])
    schema_path, reader = _VERSIONS[int(version)]
    errors = _validator(str(schema_path)).errors(data)
    if errors:
        raise LandmarksError(source, [(e.where, e.message) for e in errors])
    lms = _as_landmark_set(known_names)
    problems = []
    views = reader(data, problems)
    case = LandmarkCase(views, source, {k: v for k, v in data.items() if k.startswith("x-")})
    problems += check_case(case, lms, for_fit)
    if problems:
        raise LandmarksError(source, problems)
    return case


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


def landmarks_to_dict(case, base_dir=None):
    """The case as a JSON-ready dict (format version ``CURRENT_VERSION``).

    Parameters
    ----------
    case : LandmarkCase
    base_dir : path-like, optional
        Folder the document will be saved in: relative image paths are rewritten to stay
        pointing at the same photos (default: the case's own folder, paths unchanged).
    """
    out = {"format": FORMAT, "version": CURRENT_VERSION, "views": {}}
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
    out.update(case.extra)
    return out


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


def save_landmarks(case, path, known_names=None):
    """Write ``case`` to ``path`` atomically (temp file in the same folder, then rename).

    The document is validated first (as work in progress: without the landmark count
    floor), so a file this writes always loads again. Relative image paths are rewritten
    if the file moves to another folder.

    Raises
    ------
    ValueError
        The case has problems (nothing is written).
    """
    path = Path(path)
    data = landmarks_to_dict(case, path.parent)
    problems = [(e.where, e.message) for e in _validator(str(SCHEMA_PATH)).errors(data)]
    if not problems:
        problems = check_case(case, known_names, for_fit=False)
    if problems:
        raise LandmarksError(str(path), problems)
    write_file_atomic(path, _dumps(data) + "\n")
