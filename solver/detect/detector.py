"""Landmarks of the face in a photo: detection, then the face mesh on the detected
square (as MediaPipe does for a still photo), and the iBUG-68 points from the mesh.
Optionally the mesh once more on its own square (MediaPipe's tracking step): measured no
better, so off by default (docs/DECISIONS.md, "Automatic landmarks"). Where the mesh sees
no face on the detector's square, or the detector's two eye keypoints nearly coincide (a
profile: the square's angle from them is arbitrary, often upside down), the mesh is run once more
on the same square upright: on the sample's profile photo its iBUG points came 22 px
(median) from the truth so, 177 px on the tilted square; only a few of them are kept
there (``views.PROFILE_KEEP``). A face upside down or a quarter round in the photo is
detected on the photo turned upright (``photo_turn``)."""

import functools
import threading
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..paths import DETECTOR_DIR
from ..photo_colour import stretched_to_white
from .covered import covered_note, covered_points
from .crop import Square
from .face_detection import detect_faces
from .face_landmarks import eye_line_angle, face_mesh, square_from_detection, square_from_mesh
from .ibug_map import mesh_to_ibug
from .operators import Network
from .outline import head_outline
from .overexposed import clipped_share, overexposed_note
from .photo_turn import quarter_turn, to_photo, to_turned, turned

DETECTION_MODEL = "face_detection_short_range.tflite"
LANDMARK_MODEL = "face_landmark.tflite"
SEGMENTATION_MODEL = "selfie_segmentation.tflite"
#: Below this face-presence probability the mesh is not a face (a profile, a back):
#: the sample's profile photo gives 0.04-0.08, its front photo 1.0.
MIN_PRESENCE = 0.5
#: The detector's eye keypoints closer than this (fraction of its box's width) are a
#: profile's (the sample's profile 0.05, its mirror image 0.06; front photos 0.45, james'
#: three-quarter views at 22 and 30 degrees 0.38 and 0.35). The mesh may still report a
#: face there (0.51 on the mirrored profile) while its points are 45 px off.
PROFILE_EYES = 0.2
#: A face turned further than this in the photo (the detector's eye keypoints' line, the
#: first square's angle) gets the mesh's second pass on its own square (``refine``): on
#: the sample's front photo turned 45 or 90 degrees the first pass's points lie 4-5 % of
#: the face's size (p90) off the upright photo's, the second pass's 1.3-1.6 %, while at
#: 20-25 degrees the first pass is as near or nearer (docs/DECISIONS.md, "A face turned
#: far in the photo").
REFINE_TURN_DEG = 35.0
#: The grey a cut-out photo (transparent around the person) is laid on before detection,
#: sRGB in [0, 1]: the ten rendered heads cut out and left white under the transparency fit
#: 2.1 times worse than from their photos, laid on this grey as well as from their photos
#: (docs/DECISIONS.md, "Cut-out photos").
CUTOUT_BACKDROP = 0.5
#: A photo whose face the detector is surer of turned half round than as given, by more
#: than this, shows the face upside down: the detector reads it as if it were upright (its
#: keypoints, and the mesh's eyes on the chin). On 30 rendered heads' photos and james' two,
#: as rendered and through 22 of ``bench_photo_variants``' changes, the two scores were
#: 0.02 or more apart, the upright one always the higher. A profile's score is no guide,
#: so a face read as a profile is turned only where the photo turned shows a face the
#: mesh sees that is not a profile (a three-quarter face upside down or a quarter round
#: is read as a profile) (docs/DECISIONS.md, "A photo upside down", "A photo turned").
UPSIDE_DOWN_MARGIN = 0.0
#: A face whose eye line (the detector's keypoints) lies further than this from level, or
#: that the detector is surer of upside down, is looked for on the photo turned each way,
#: and the turn it is surest of is taken: the keypoints of a face turned a quarter round
#: lie 70-90 degrees from level, of one turned further read upside down (on the sample's,
#: a window-lit head's and james' photos turned, docs/DECISIONS.md, "A photo turned").
LEVEL_EYES_DEG = 30.0


@dataclass
class DetectedFace:
    """A face found in a photo.

    Attributes
    ----------
    mesh : ndarray (468, 3)
        MediaPipe's mesh points: u, v px, relative depth in px.
    ibug : ndarray (68, 2)
        The iBUG-68 points (row i - 1 is iBUG i), px.
    score : float
        The detector's confidence.
    presence : float
        The mesh model's face-presence probability.
    keypoints : ndarray (6, 2) or None
        The detector's keypoints (``face_detection.KEYPOINTS``: eyes, nose tip, mouth,
        tragions), px.
    box : ndarray (4,) or None
        The detector's box (u_min, v_min, u_max, v_max), px: the face's size in the photo.
    covered : frozenset of int
        iBUG numbers of the points whose part of the face is covered (a beard over the
        jaw: ``covered.covered_points``); a case leaves them and the mesh's depths out.
    others : int
        How many other, smaller faces the photo shows (``other_faces_note``).
    clipped : float
        The share of the face's skin the photo clipped to white (a front or three-quarter
        face: ``overexposed.clipped_share``; 0 for a profile).
    turn : int
        The quarter turns anticlockwise (``photo_turn``) the photo was turned by to show
        the face upright, 0-3: the points above lie on the photo so turned
        (:meth:`in_photo` gives them on the photo as given).
    photo_size : tuple of int
        The photo's (w, h) as given.
    given_score : float or None
        The detector's confidence in the face on the photo as given (0: none found there),
        where it was turned.
    """

    mesh: np.ndarray
    ibug: np.ndarray
    score: float
    presence: float
    keypoints: np.ndarray | None = None
    box: np.ndarray | None = None
    covered: frozenset = frozenset()
    others: int = 0
    clipped: float = 0.0
    turn: int = 0
    photo_size: tuple | None = None
    given_score: float | None = None

    def in_photo(self, points):
        """Pixels (n, 2) on the photo turned by :attr:`turn` -> on the photo as given."""
        return to_photo(points, self.turn, self.photo_size)

    def in_frame(self, points):
        """Pixels (n, 2) on the photo as given -> on it turned by :attr:`turn`."""
        return to_turned(points, self.turn, self.photo_size)

    @property
    def face_size(self):
        """The detector box's width, px (None without a box)."""
        return None if self.box is None else float(self.box[2] - self.box[0])

    @property
    def eyes_apart(self):
        """The detector's eye keypoints' distance / its box's width (None without them)."""
        if self.keypoints is None or self.box is None:
            return None
        return _eyes_apart(self)

    @property
    def is_profile(self):
        """A face seen from the side: the mesh sees none, or the detector's eyes nearly
        coincide (``PROFILE_EYES``)."""
        apart = self.eyes_apart
        return not self.is_face or (apart is not None and apart < PROFILE_EYES)

    @property
    def is_face(self):
        """The mesh model sees a face in the detected square (MediaPipe's threshold, 0.5):
        a profile, a face turned away or a false detection does not pass."""
        return self.presence >= MIN_PRESENCE


def _network(folder, name):
    path = Path(folder) / name
    if not path.is_file():
        raise ValueError(f"{path}: missing; fetch the detector models with ./run detector")
    return Network(path)


class Detector:
    """The MediaPipe networks, read once (the segmentation when first used), run with
    numpy. A detector may examine several photos at once, one per thread.

    Parameters
    ----------
    folder : str or Path
        Holds the ``.tflite`` files (``tools/fetch_detector.py`` puts them in
        ``generated/detector/``).
    """

    def __init__(self, folder=DETECTOR_DIR):
        self.folder = Path(folder)
        self.faces_net = _network(folder, DETECTION_MODEL)
        self.mesh_net = _network(folder, LANDMARK_MODEL)
        self._segmentation_net = None
        self._segmentation_lock = threading.Lock()  # photos may be examined in threads

    def outline(self, image, face):
        """The head's outline around ``face`` (a :class:`DetectedFace` of ``image``
        (H, W, 3), uint8 or float in [0, 1]): ``outline.head_outline``'s
        :class:`~.outline.Outline`. Raises ``ValueError`` (no person, no skin on its
        edge) without naming the photo. It is traced on the photo turned as the face was
        detected (``DetectedFace.turn``) and given on the photo as it is."""
        with self._segmentation_lock:
            if self._segmentation_net is None:
                self._segmentation_net = _network(self.folder, SEGMENTATION_MODEL)
        found = head_outline(turned(_as_float(image), face.turn), face, self._segmentation_net)
        return replace(found, points=face.in_photo(found.points)) if face.turn else found

    def detect(self, image, refine=False):
        """The largest face of ``image`` (H, W, 3) (uint8, or float in [0, 1]; (H, W, 4): a
        cut-out, its alpha fourth, laid on a grey backdrop: :func:`on_backdrop`), the
        subject's (``face_detection.detect_faces``), or None when the detector finds
        none. A face the mesh model does not see (a profile) comes back with ``is_face``
        False. ``refine``: a second mesh pass on the first mesh's square, which a face
        turned in the photo further than ``REFINE_TURN_DEG`` always gets (the detector's
        eye keypoints turn the first square less surely than the mesh's eye corners do).
        A face a quarter round (the detector's eye keypoints) or upside down (the detector
        surer of it turned half round: ``UPSIDE_DOWN_MARGIN``) is detected on the photo
        turned upright (``DetectedFace.turn``); so is one read as a profile, or not found,
        where the photo turned shows a face that is not a profile, surer."""
        image = _as_float(image)
        size = (image.shape[1], image.shape[0])
        faces = detect_faces(self.faces_net, image)
        given_score = float(faces[0].score) if faces else 0.0  # 0: none found as given
        look = functools.partial(self._look, image)
        if not faces or _eyes_apart(faces[0]) < PROFILE_EYES:
            turn, faces = self._turned_from_profile(image, faces, look)
        else:
            turn, faces = self._turned_from_front(faces, look)
        if not faces:
            return None
        out = self._face(turned(image, turn), faces, refine)
        out.turn, out.photo_size = turn, size
        out.given_score = given_score if turn else None
        return out

    def _look(self, image, turn):
        """``detect_faces`` on ``image`` turned by ``turn`` (a view, not a copy: the
        detector crops it, and the same faces come 3-6 ms sooner a turn)."""
        return detect_faces(self.faces_net, np.rot90(image, turn))

    def _turned_from_front(self, faces, look):
        """(turn, faces) for a photo whose largest face (of ``faces``) is seen from the
        front or three-quarter (``look``: turn -> the faces on the photo so turned): as
        given where its eye line lies within ``LEVEL_EYES_DEG`` of level and the detector
        is not surer of it turned half round (``UPSIDE_DOWN_MARGIN``); else the turn (0-3)
        whose photo the detector is surest of (:func:`_nearest_level`), with its faces."""
        found = {0: faces, 2: look(2)}
        level = _off_level(faces[0]) <= LEVEL_EYES_DEG
        if level and not (found[2] and found[2][0].score > faces[0].score + UPSIDE_DOWN_MARGIN):
            return 0, faces
        found.update({t: look(t) for t in (1, 3)})
        best = _nearest_level(found, max((t for t in found if found[t]),
                                         key=lambda t: found[t][0].score))
        return best, found[best]

    def _turned_from_profile(self, image, faces, look):
        """(turn, faces) for a photo whose largest face (of ``faces``, maybe none) is read
        as a profile (``look`` as :meth:`_turned_from_front` takes it): the turn (1-3)
        whose photo shows the surest face, surer than as given (``UPSIDE_DOWN_MARGIN``),
        that is not a profile (:func:`_nearest_level`), with its faces (a three-quarter
        face turned in the photo reads as a profile); else (0, ``faces``). A profile's own
        score is no guide to its turn."""
        least = faces[0].score + UPSIDE_DOWN_MARGIN if faces else 0.0
        found = {0: faces}
        found.update({t: look(t) for t in (1, 2, 3)})
        seen = [t for t in (1, 2, 3) if found[t] and found[t][0].score > least
                and _eyes_apart(found[t][0]) >= PROFILE_EYES]
        if not seen:
            return 0, faces
        best = _nearest_level(found, max(seen, key=lambda t: found[t][0].score))
        if not self._mesh_sees(turned(image, best), found[best][0]):
            return 0, faces
        return best, found[best]

    def _mesh_sees(self, image, face):
        """Whether the mesh sees a face that is not a profile on ``face``'s square of
        ``image`` (``DetectedFace.is_profile``)."""
        mesh, presence = face_mesh(self.mesh_net, image, square_from_detection(face))
        seen = DetectedFace(mesh, mesh_to_ibug(mesh[:, :2]), float(face.score), presence,
                            np.asarray(face.keypoints, float), np.asarray(face.box, float))
        return not seen.is_profile

    def _face(self, image, faces, refine):
        """The :class:`DetectedFace` of the largest of ``faces`` (``detect_faces`` on
        ``image``, float): the mesh, its iBUG points and what covers the face."""
        face = faces[0]
        square = square_from_detection(face)
        mesh, presence = face_mesh(self.mesh_net, image, square)
        out = DetectedFace(mesh, mesh_to_ibug(mesh[:, :2]), float(face.score), presence,
                           np.asarray(face.keypoints, float), np.asarray(face.box, float),
                           others=len(faces) - 1)
        if out.is_profile:  # the square upright, not turned by the eyes
            mesh, _ = face_mesh(self.mesh_net, image, Square(square.center, square.size))
        elif refine or abs(np.degrees(square.angle)) > REFINE_TURN_DEG:
            mesh, out.presence = face_mesh(self.mesh_net, image, square_from_mesh(mesh))
        out.mesh, out.ibug = mesh, mesh_to_ibug(mesh[:, :2])
        if not out.is_profile:
            out.covered = covered_points(image, out)
            out.clipped = clipped_share(image, out)
        return out


def _nearest_level(found, best):
    """``best`` (a turn, a key of ``found``: turn -> ``detect_faces`` on the photo so
    turned), or the turn a quarter from it its face's eye line points to, where the face
    there is seen from the front and nearer level: a face turned about half way between
    two quarter turns gets the detector's confidence alike in both (on the rendered heads'
    photos turned 25 degrees and a quarter round, the one 65 degrees from level was often
    taken; its points 0.8-1.8 % of the face's size off the other's)."""
    nearer = (best + quarter_turn(eye_line_angle(found[best][0].keypoints))) % 4
    there = found.get(nearer)
    if nearer != best and there and _eyes_apart(there[0]) >= PROFILE_EYES \
            and _off_level(there[0]) < _off_level(found[best][0]):
        return nearer
    return best


def _off_level(face):
    """How far the eye line of a ``face_detection.Face`` lies from level, degrees."""
    return abs(np.degrees(eye_line_angle(face.keypoints)))


def _eyes_apart(face):
    """The face detector's eye keypoints' distance / its box's width (``PROFILE_EYES``), of
    a ``face_detection.Face`` or a :class:`DetectedFace`."""
    return float(np.linalg.norm(face.keypoints[1] - face.keypoints[0])) \
        / float(face.box[2] - face.box[0])


def turn_note(face):
    """What the report says of a face detected on its photo turned (``DetectedFace.turn``),
    a phrase, or None."""
    if not face.turn:
        return None
    how = {1: "a quarter round clockwise", 2: "upside down",
           3: "a quarter round anticlockwise"}[face.turn]
    return (f"the face is {how} in the photo: detected on the photo turned upright (the "
            f"face detector's confidence {face.score:.2f} there, {face.given_score:.2f} as "
            "given); its points are given on the photo as it is")


def other_faces_note(face):
    """What the report says of the other faces in a face's photo
    (``DetectedFace.others``), a phrase, or None when it shows one."""
    if not face.others:
        return None
    n = face.others
    return (f"{n} other, smaller face{'s' if n > 1 else ''} in the photo: the largest is "
            "taken as the subject's")


def face_notes(face):
    """What the report says of a detected face beyond where it is and which way it looks:
    its covered points (``covered.covered_note``), its skin clipped white
    (``overexposed.overexposed_note``) and the other faces in its photo
    (:func:`other_faces_note`), and first the photo's turn to show it upright
    (:func:`turn_note`), the phrases that apply."""
    return [n for n in (turn_note(face), covered_note(face), overexposed_note(face),
                        other_faces_note(face)) if n]


def _as_float(image):
    """(H, W, 3) or (H, W, 4) uint8 or float -> (H, W, 3) float32 in [0, 1], stretched to
    the photo's white (``photo_colour.stretched_to_white``): a photo darkened or given a
    colour cast after it was taken is detected as it was shot. A fourth channel is alpha:
    a cut-out photo is laid on ``CUTOUT_BACKDROP`` first (:func:`on_backdrop`)."""
    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] not in (3, 4):
        raise ValueError(f"image must be (H, W, 3) or (H, W, 4), got shape {image.shape}")
    image = image.astype(np.float32) / 255.0 if image.dtype == np.uint8 \
        else image.astype(np.float32)
    return stretched_to_white(on_backdrop(image))


def on_backdrop(image):
    """``image`` (H, W, 3|4) float32 in [0, 1] as (H, W, 3): RGB as it is, or RGBA (straight
    alpha) laid on the plain grey ``CUTOUT_BACKDROP`` where it is transparent. A cut-out's
    colours under its transparent pixels are whatever the tool left there (black, white,
    the old background), and the person's segmentation and the outline's colour rules
    read them as a background."""
    if image.shape[2] == 3:
        return image
    alpha = image[:, :, 3]
    if alpha.min() >= 1.0:
        return image[:, :, :3]
    alpha = np.clip(alpha, 0.0, 1.0)[:, :, None]
    return image[:, :, :3] * alpha + np.float32(CUTOUT_BACKDROP) * (1.0 - alpha)
