"""The landmarks file's data: a :class:`LandmarkCase` of one person, its :class:`View`
per photo (camera, landmarks, contour, passpoints), and ``case_version``, the lowest file
version that holds a case."""

import copy
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..cameras import Camera
from .camera_json import camera_to_json
from .landmark_set import as_landmark_set


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
        When ``camera`` is set only an orthographic photo's ``lens_mm`` is read (its EXIF
        lens, for the fit's parallel-projection check); front-ends take it from the photo,
        files do not store it.
    uncertainty : dict of str -> float
        Optional, per landmark (a key of ``points``): how far off it may be, the standard
        deviation in pixels (a detector's points: ``solver.detect``). The fit weighs the
        view's landmarks relative to each other by ``1 / uncertainty^2`` (its estimate of
        the view's noise scaled by this landmark's uncertainty over the view's median), and
        never assumes a landmark placed more precisely than its uncertainty (its noise
        floor). ``solver.fitting.views.uncertainty_factors``.
    depth : dict of str -> float
        Optional, per landmark with an ``uncertainty``: how far it lies toward the camera,
        pixels at the photo's scale, relative to the view's other points (a detector's
        face mesh estimates it: ``solver.detect``). The fit holds the depth differences
        of mirror pairs of such points in an orthographic or a pinhole photo
        (``solver.fitting.depth``), which tell how the head is turned.
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
    uncertainty: dict = field(default_factory=dict)
    depth: dict = field(default_factory=dict)
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
        self.uncertainty = {str(k): float(v) for k, v in self.uncertainty.items()}
        self.depth = {str(k): float(v) for k, v in self.depth.items()}
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

    def keep_camera_as_read(self, value):
        """Remember ``value``, the camera object as the file wrote it: while ``camera`` is
        the same unchanged object, ``to_dict`` writes ``value`` back."""
        self._camera_source = (self.camera, copy.deepcopy(value), self.camera.to_dict())

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
        if self.uncertainty:
            d["uncertainty"] = dict(self.uncertainty)
        if self.depth:
            d["depth"] = dict(self.depth)
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
        lms = as_landmark_set(known_names)
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
        return _json_equal(_stored(self), _stored(other))


def case_version(case):
    """The lowest file version that holds ``case``: 2 when it uses passpoints, a mirror view,
    ``calibrated`` or a camera of unknown parameters, else 1."""
    if case.passpoints or any(v.version2_features() for v in case.views.values()):
        return 2
    return 1


def _stored(case):
    """What a file holds of ``case`` (image paths as given; the version follows from it)."""
    out = {"views": {name: view.to_dict() for name, view in case.views.items()}}
    if case.passpoints:
        out["passpoints"] = {k: v.tolist() for k, v in case.passpoints.items()}
    out.update(case.extra)
    return out


def _json_equal(a, b):
    # NaN-aware comparison of JSON-like trees (a NaN point equals a NaN point).
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_json_equal(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_json_equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return type(a) is type(b) and a == b
