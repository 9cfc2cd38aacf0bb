"""Landmarks of the face in a photo: detection, then the face mesh on the detected
square (as MediaPipe does for a still photo), and the iBUG-68 points from the mesh.
Optionally the mesh once more on its own square (MediaPipe's tracking step): measured no
better, so off by default (docs/DECISIONS.md, "Automatic landmarks")."""

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..paths import DETECTOR_DIR
from .face_detection import detect_faces
from .face_landmarks import face_mesh, square_from_detection, square_from_mesh
from .ibug_map import mesh_to_ibug
from .operators import Network

DETECTION_MODEL = "face_detection_short_range.tflite"
LANDMARK_MODEL = "face_landmark.tflite"
#: Below this face-presence probability the mesh is not a face (a profile, a back):
#: the sample's profile photo gives 0.04-0.08, its front photo 1.0.
MIN_PRESENCE = 0.5


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
    """

    mesh: np.ndarray
    ibug: np.ndarray
    score: float
    presence: float

    @property
    def is_face(self):
        """The mesh model sees a face in the detected square (MediaPipe's threshold, 0.5):
        a profile, a face turned away or a false detection does not pass."""
        return self.presence >= MIN_PRESENCE


class Detector:
    """The two MediaPipe networks, read once, run with numpy.

    Parameters
    ----------
    folder : str or Path
        Holds the two ``.tflite`` files (``tools/fetch_detector.py`` puts them in
        ``generated/detector/``).
    """

    def __init__(self, folder=DETECTOR_DIR):
        folder = Path(folder)
        for name in (DETECTION_MODEL, LANDMARK_MODEL):
            if not (folder / name).is_file():
                raise ValueError(f"{folder / name}: missing; fetch the detector models "
                                 f"with ./run detector")
        self.faces_net = Network(folder / DETECTION_MODEL)
        self.mesh_net = Network(folder / LANDMARK_MODEL)

    def detect(self, image, refine=False):
        """The most confident face of ``image`` (H, W, 3) (uint8, or float in [0, 1]),
        or None when the detector finds none. A face the mesh model does not see (a
        profile) comes back with ``is_face`` False. ``refine``: a second mesh pass on the
        first mesh's square."""
        image = np.asarray(image)
        if image.ndim != 3 or image.shape[2] < 3:
            raise ValueError(f"image must be (H, W, 3), got shape {image.shape}")
        image = image[:, :, :3]
        if image.dtype == np.uint8:
            image = image.astype(np.float32) / 255.0
        else:
            image = image.astype(np.float32)
        faces = detect_faces(self.faces_net, image)
        if not faces:
            return None
        face = faces[0]
        mesh, presence = face_mesh(self.mesh_net, image, square_from_detection(face))
        if refine and presence >= MIN_PRESENCE:
            mesh, presence = face_mesh(self.mesh_net, image, square_from_mesh(mesh))
        return DetectedFace(mesh, mesh_to_ibug(mesh[:, :2]), face.score, presence)
