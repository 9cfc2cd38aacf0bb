"""Which way a detected face looks: the photo's view (front, right or left profile, or a
three-quarter view between) and the camera a landmarks file starts the fit from, guessed
from the detection itself; and which detected points to keep in a profile, with each
point's uncertainty in pixels.

The yaw (the camera's direction from the face's front, toward the subject's right
positive, as ``orthographic-right`` is at +90) comes from the face mesh when it sees a face:
the line between the eye corners (mesh 33 -> 263 and 133 -> 362) in the mesh's own depth,
``atan2(depth, image length)``. On james' two real photos it gave 29.6 and -21.3 degrees,
their calibrated cameras 29.5 and -20.9 (``bench.bench_detect``). Where the mesh sees no
face (past about 60 degrees: the sample's profile photo, presence 0.03-0.08), or the
detector's eye keypoints nearly coincide (``DetectedFace.is_profile``), the photo is a
profile, its side from the detector's keypoints: the nose tip lies beyond the eyes on the
side the face looks to (in a right profile the face points to the image's right,
``solver.cameras.ORTHO_VIEWS``); its yaw 90 degrees unless the face is seen short of a
profile (``profile_yaw_deg``). How a case's cameras stand to each other is one rule,
``placed``: in the face's frame where a profile's yaw was measured, else in the frame of
the orthographic front photo. Landmarks placed by hand show a photo's yaw too
(``points_yaw_deg``), and a case whose profile they show short of one is placed by the same
rule (``placed_by_landmarks``, before every fit).
"""

import copy
import functools
from dataclasses import dataclass, replace

import numpy as np

from ..cameras import OrthographicCamera
from ..cameras.orthographic import VIEW_YAW_DEG
from ..io.camera_json import is_nominal
from ..io.json_file import read_json
from ..io.photo_lens import DIRECTION_SIGMA_DEG, lens_hints
from .ibug_map import MAP_PATH

#: Within this yaw (degrees) of the front a photo is written as an orthographic front
#: photo (the fit turns the head in it); farther, as a three-quarter view whose pinhole
#: camera the fit calibrates on the head (``{"kind": "pinhole"}``, held near the yaw).
FRONT_MAX_DEG = 15.0
#: A profile's nose-tip keypoint is at least this far (fraction of the detector box's
#: width) beyond the eyes' midpoint: 0.24 on the sample's profile; 0.02 on its front photo.
PROFILE_MIN_NOSE = 0.1
#: Mesh vertex pairs (subject's right, left) whose 3-D line gives the yaw: the outer and
#: the inner eye corners.
EYE_PAIRS = ((33, 263), (133, 362))
#: A side photo's yaw from how far apart the detector's eye keypoints are (a fraction of
#: its box's width, ``DetectedFace.eyes_apart``): ``PROFILE_YAW[0] - PROFILE_YAW[1] *
#: apart`` degrees; a line through 14 side photos of rendered heads at 57-90 degrees (2.4
#: degrees RMS, docs/DECISIONS.md: "A side photo short of a profile").
PROFILE_YAW = (91.4, 152.5)
#: A side photo is read short of a profile only where both say so: its eyes at least
#: TURNED_EYES apart (79 degrees by the line) and the mesh seeing a face (presence at least
#: TURNED_PRESENCE). Either alone also meets exact profiles with hair, a beard or glasses
#: painted on (eyes 0.005-0.19 apart, presence up to 0.98); side photos 15-33 degrees
#: short of a profile had both (0.083-0.228, 0.99-1.00).
TURNED_EYES = 0.08
TURNED_PRESENCE = 0.9
#: Per coordinate standard deviation of a 2-D Gaussian error / its median length.
MEDIAN_TO_SIGMA = 1.0 / np.sqrt(2.0 * np.log(2.0))
#: A three-quarter view's points are further off than the front table says: their median
#: error grows by the table's once per this many degrees of yaw past ``FRONT_MAX_DEG``
#: (measured on rendered heads at 15-56 degrees: docs/DECISIONS.md).
GROWTH_DEG = 30.0


@dataclass(frozen=True)
class ViewGuess:
    """Which way a face in a photo looks.

    Attributes
    ----------
    name : str
        "front", "right", "left" (profiles), "three_quarter_right", "three_quarter_left".
    yaw_deg : float
        The camera's direction from the face's front, degrees, toward the subject's right
        positive (a profile's from its eye keypoints, ``profile_yaw_deg``).
    turned : bool
        Its camera an orthographic one turned to ``yaw_deg`` (``placed``: a case in the
        face's frame); a profile read short of 90 degrees is turned either way.
    """

    name: str
    yaw_deg: float
    turned: bool = False

    @property
    def profile(self):
        return self.name in ("right", "left")

    @property
    def side(self):
        """"right", "left" (the side of the subject the camera is on) or None (front)."""
        if self.name == "front":
            return None
        return "right" if self.name.endswith("right") else "left"

    def camera(self, size, lens_mm=None):
        """(camera, hints) for a view of this photo. A photo whose lens is known (its
        EXIF's, 36 mm equivalent): None with ``lens_hints`` (a pinhole camera of that lens
        held near this view's yaw). Without one: a nominal orthographic camera for the
        front and the profiles; for a three-quarter view a pinhole camera the fit
        calibrates, held near this yaw as one of a known lens is (Blender's Detect holds it
        so too). A profile read short of 90 degrees gets its orthographic camera turned to
        its yaw (``OrthographicCamera.turned``): the photos' angle apart is then what they
        show, not a nominal 90 degrees from the front photo's. So is a front photo placed
        in the face's frame (``turned``)."""
        if lens_mm:
            return None, lens_hints(lens_mm, self.yaw_deg)
        if self.turned or self.measured_profile:
            view = self.name if self.profile else "front"
            return OrthographicCamera.turned(f"orthographic-{view}", size, self.yaw_deg), {}
        if self.name in ("front", "right", "left"):
            return OrthographicCamera.nominal(f"orthographic-{self.name}", size), {}
        return None, {"kind": "pinhole",
                      "direction_prior": [float(self.yaw_deg), DIRECTION_SIGMA_DEG]}

    @property
    def measured_profile(self):
        """A profile whose yaw was measured: read short of 90 degrees (``profile_yaw_deg``)."""
        return self.profile and abs(self.yaw_deg) < 90.0

    def beside(self, front_yaw_deg):
        """This photo's guess in a case whose front photo has the nominal orthographic
        camera while its face was measured at ``front_yaw_deg``: the fit turns the head by
        that yaw, so this camera sits at its own yaw less that one. A front stays, and so
        does a profile read at 90 degrees (its yaw not measured: ``profile_yaw_deg``); none
        goes past a profile."""
        if self.name == "front" or (self.profile and not self.measured_profile):
            return self
        return replace(self, yaw_deg=float(np.clip(self.yaw_deg - front_yaw_deg, -90.0, 90.0)))

    def describe(self):
        """A few words for messages."""
        if self.profile:
            short = 90.0 - abs(self.yaw_deg)
            turned = f", {short:.0f} deg short of a profile" if short > 0.5 else ""
            return (f"a {self.name} profile (the face looks to the image's "
                    f"{self.name}, the camera at the subject's {self.name}{turned})")
        if self.name == "front":
            return f"a front photo (yaw {self.yaw_deg:+.0f} deg)"
        return (f"a three-quarter view from the subject's {self.side} "
                f"(yaw {self.yaw_deg:+.0f} deg)")


def beside_front(guesses, orthographic):
    """Each photo's guess (``ViewGuess.beside``) in the frame of the first front photo whose
    camera is orthographic (``orthographic[i]``: the photo's camera is the nominal one, no
    lens): the cameras' angles apart are then what the photos show. Without such a front
    photo, the guesses as they are."""
    front = next((g.yaw_deg for g, ortho in zip(guesses, orthographic, strict=True)
                  if ortho and g.name == "front"), None)
    return list(guesses) if front is None else [g.beside(front) for g in guesses]


def placed(guesses, orthographic):
    """The one rule a case's cameras are placed by (``solver detect``, Blender's Detect
    Landmarks and Auto Fit): each photo's guess as its camera is to be placed.
    ``orthographic[i]``: the photo's camera may be orthographic (no lens).

    A case with a profile read short of a profile (its yaw measured) is placed in the
    face's frame: each such profile, and each front photo that may be orthographic, an
    orthographic camera turned to its own yaw (``turned``): the head then starts square to
    the world and the cameras stand as far apart as the photos show (a three-quarter photo
    stays a pinhole held near its yaw: docs/DECISIONS.md, "The cameras in the face's
    frame"). Any other case in the frame of its orthographic front photo
    (``beside_front``)."""
    if not any(g.measured_profile for g in guesses):
        return beside_front(guesses, orthographic)
    return [replace(g, turned=True) if ortho and g.name == "front" else g
            for g, ortho in zip(guesses, orthographic, strict=True)]


#: Fewest landmarks (with a model vertex) ``points_yaw_deg`` reads a yaw from: an affine
#: camera has 8 unknowns.
POINTS_YAW_MIN = 6
#: ... and it reads it again without the points this many times the median distance off
#: the first reading's camera.
POINTS_YAW_OUTLIER = 4.0


def points_yaw_deg(model, points):
    """The yaw (degrees, as ``ViewGuess.yaw_deg``) that a photo's landmarks show, or None
    where fewer than ``POINTS_YAW_MIN`` of them name a model vertex or they lie on a line:
    the viewing direction of the affine camera that best projects the mean head's
    landmark vertices onto them. It serves a photo whose landmarks were placed by hand, so
    its face was never detected: 1-3 degrees off on rendered heads (docs/DECISIONS.md).

    Parameters
    ----------
    model : HeadModel
    points : dict of str -> (u, v)
        Landmark name -> pixel (v down), the names as a landmarks file gives them.
    """
    lms = model.landmark_set
    keys = [k for k in points if lms.canonical(k) is not None]
    if len(keys) < POINTS_YAW_MIN:
        return None
    x = model.vertices[[lms.vertices[lms.canonical(k)] for k in keys]]
    a = np.column_stack([x, np.ones(len(x))])
    uv = np.asarray([points[k] for k in keys], dtype=np.float64).reshape(-1, 2)
    rows, *_ = np.linalg.lstsq(a, uv, rcond=None)
    # once more without the points far off the others (a misplaced one would turn it)
    off = np.linalg.norm(a @ rows - uv, axis=1)
    keep = off <= POINTS_YAW_OUTLIER * max(float(np.median(off)), 1e-9)
    if POINTS_YAW_MIN <= keep.sum() < len(keep):
        rows, *_ = np.linalg.lstsq(a[keep], uv[keep], rcond=None)
    forward = np.cross(rows[:3, 0], rows[:3, 1])  # u x v: into the scene (OpenCV rows)
    if not np.isfinite(forward).all() or np.linalg.norm(forward) <= 1e-12:
        return None
    return float(np.degrees(np.arctan2(forward[0], forward[1])))


#: A profile placed by hand is read short of a profile only where its landmarks show at
#: least this many degrees short: on exact profiles of rendered heads they read 84-95.
POINTS_SHORT_DEG = 8.0
#: ``points_yaw_deg`` reads a profile only from this many landmarks off the face's middle
#: (their vertices at least ``OFF_MIDDLE_M`` from it): a profile's middle points alone
#: (those read off its outline) lie in one plane and give no yaw.
POINTS_OFF_MIDDLE = 6
OFF_MIDDLE_M = 0.01


def placed_by_landmarks(model, case):
    """The case with its nominal orthographic cameras placed by the yaws their landmarks
    show (``points_yaw_deg``), by the rule of ``placed``, where a profile's landmarks show
    it at least ``POINTS_SHORT_DEG`` short of a profile: a side photo taken short of a
    profile, its landmarks placed by hand. Cameras given any other way (turned, with a
    lens, computed) and mirror views stay. Returns (case, notes): the case itself and no
    note where nothing is turned; else a copy and a note per turned camera."""
    lms = model.landmark_set
    nominal, guesses = {}, {}
    for name, view in case.views.items():
        cam = view.camera
        if view.mirror_of is not None or not isinstance(cam, OrthographicCamera) \
                or not is_nominal(cam, view.size) or cam.view not in VIEW_YAW_DEG:
            continue
        side = cam.view.removeprefix("orthographic-")
        points = {k: p for k, p in view.points.items() if lms.canonical(k) is not None
                  and lms.has_meaning_in(lms.canonical(k), side)}
        yaw = points_yaw_deg(model, points)
        if yaw is None:
            continue
        if side != "front":
            off = [k for k in points
                   if abs(model.vertices[lms.vertices[lms.canonical(k)], 0]) >= OFF_MIDDLE_M]
            sign = 1.0 if side == "right" else -1.0
            if len(off) < POINTS_OFF_MIDDLE or sign * yaw <= 0.0:  # (mislabelled: checks.py)
                continue
            yaw = sign * min(abs(yaw), 90.0)
        nominal[name] = cam
        guesses[name] = ViewGuess(side, yaw)
    if not any(g.profile and abs(g.yaw_deg) <= 90.0 - POINTS_SHORT_DEG
               for g in guesses.values()):
        return case, []
    names = list(guesses)
    out = copy.deepcopy(case)
    notes = []
    for name, g in zip(names, placed([guesses[n] for n in names], [True] * len(names)),
                       strict=True):
        if not (g.turned or g.measured_profile):
            continue
        out.views[name].camera, _ = g.camera(nominal[name].size)
        if abs(g.yaw_deg - VIEW_YAW_DEG[nominal[name].view]) < 0.5:
            continue  # (turned by less than shows)
        notes.append(f"view {name!r}: its landmarks show {g.describe()}: its camera was "
                     f"turned to {g.yaw_deg:+.0f} deg from the face's front")
    return out, notes


def mesh_yaw_deg(mesh):
    """The yaw (degrees, toward the subject's right positive) of a face mesh (468, 3)."""
    m = np.asarray(mesh, float)
    d = sum(m[left] - m[right] for right, left in EYE_PAIRS)
    return float(np.degrees(np.arctan2(d[2], np.hypot(d[0], d[1]))))


def guess_view(face):
    """The :class:`ViewGuess` of a :class:`~.detector.DetectedFace`, or None when neither
    the mesh nor the detector's keypoints say which way the face looks."""
    if not face.is_profile:
        yaw = mesh_yaw_deg(face.mesh)
        if abs(yaw) <= FRONT_MAX_DEG:
            return ViewGuess("front", yaw)
        return ViewGuess("three_quarter_right" if yaw > 0 else "three_quarter_left", yaw)
    if face.keypoints is None or face.face_size is None:
        return None
    kp = np.asarray(face.keypoints, float)
    ahead = (kp[2, 0] - 0.5 * (kp[0, 0] + kp[1, 0])) / face.face_size
    if abs(ahead) < PROFILE_MIN_NOSE:
        return None
    yaw = profile_yaw_deg(face)
    return ViewGuess("right", yaw) if ahead > 0 else ViewGuess("left", -yaw)


def profile_yaw_deg(face):
    """A profile photo's yaw, degrees (on the camera's side), from its
    :class:`~.detector.DetectedFace`: 90 unless the face is seen short of a profile
    (``TURNED_EYES``, ``TURNED_PRESENCE``), then from how far apart its eye keypoints are
    (``PROFILE_YAW``): the eyes move apart as the face turns toward the camera."""
    apart = face.eyes_apart
    if apart is None or apart < TURNED_EYES or face.presence < TURNED_PRESENCE:
        return 90.0
    return float(np.clip(PROFILE_YAW[0] - PROFILE_YAW[1] * apart, 0.0, 90.0))


@functools.cache
def uncertainty_table(path=MAP_PATH):
    """{"front": {iBUG number: fraction}, "profile": {...}}: each point's median error as
    a fraction of the detector box's width (``assets/mediapipe_ibug68.json``
    "uncertainty"); the profile's lists only the points kept there."""
    data = read_json(path).get("uncertainty")
    if not isinstance(data, dict) or not all(
            isinstance(data.get(k), dict) for k in ("front", "profile")):
        raise ValueError(f"{path}: 'uncertainty' must give 'front' and 'profile' tables")
    out = {}
    for kind in ("front", "profile"):
        table = {int(k): float(v) for k, v in data[kind].items()
                 if not k.startswith("_")}
        if not all(1 <= k <= 68 and v > 0 for k, v in table.items()):
            raise ValueError(f"{path}: uncertainty.{kind}: iBUG numbers 1..68 -> fractions > 0")
        out[kind] = table
    if set(out["front"]) != set(range(1, 69)):
        raise ValueError(f"{path}: uncertainty.front must give every iBUG point 1..68")
    return out


def point_uncertainty(face):
    """{iBUG number: standard deviation px} of the points to keep of a face: all 68 unless
    it is a profile (``DetectedFace.is_profile``), in a profile only those
    ``uncertainty.profile`` lists (measured trustworthy there). Each is the measured median
    error (a fraction of the face's size) times the detector box's width, as a
    per-coordinate deviation, times ``yaw_growth`` in a three-quarter view; None for every
    point of a face without a box."""
    if face.face_size is None:
        return dict.fromkeys(range(1, 69))
    table = uncertainty_table()["profile" if face.is_profile else "front"]
    grow = 1.0 if face.is_profile else yaw_growth(mesh_yaw_deg(face.mesh))
    return {i: f * face.face_size * MEDIAN_TO_SIGMA * grow for i, f in table.items()}


def yaw_growth(yaw_deg):
    """How many times the front table's error a point of a face seen from ``yaw_deg``
    (degrees) has: 1 within ``FRONT_MAX_DEG``, growing by 1 per ``GROWTH_DEG`` beyond."""
    return 1.0 + max(abs(float(yaw_deg)) - FRONT_MAX_DEG, 0.0) / GROWTH_DEG
