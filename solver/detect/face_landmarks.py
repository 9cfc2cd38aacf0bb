"""MediaPipe's face mesh (``face_landmark.tflite``): 468 points of the face from a
192-px crop square around it, upright along the eye line.

The crop is MediaPipe's: from a detection, the box's centre, rotated so the eyes are
level, its longer side × 1.5; from a previous mesh (a second, tighter pass), the mesh's
own box along the line between the outer eye corners 33 and 263, × 1.5.
"""

import numpy as np

from .crop import Square, crop

INPUT = 192
SCALE = 1.5
#: Mesh vertices of the subject's right and left outer eye corners (for the crop's angle).
EYE_CORNERS = (33, 263)


def eye_line_angle(keypoints):
    """The angle (radians, as ``Square.angle`` takes it) of the line from the face
    detector's first eye keypoint to its second (``keypoints`` (6, 2) px): a square turned
    by it holds the face upright."""
    d = np.asarray(keypoints[1], float) - np.asarray(keypoints[0], float)
    return float(np.arctan2(d[1], d[0]))


def square_from_detection(face):
    """The landmark model's crop for a :class:`~.face_detection.Face`."""
    angle = eye_line_angle(face.keypoints)
    box = face.box
    centre = ((box[0] + box[2]) / 2, (box[1] + box[3]) / 2)
    return Square(centre, SCALE * float(max(box[2] - box[0], box[3] - box[1])), angle)


def square_from_mesh(points):
    """The landmark model's crop around ``points`` (468, 2+) px of a previous pass: the
    box of the points in the frame of the eye line, its longer side × 1.5."""
    p = np.asarray(points, float)[:, :2]
    d = p[EYE_CORNERS[1]] - p[EYE_CORNERS[0]]
    angle = float(np.arctan2(d[1], d[0]))
    c, s = np.cos(angle), np.sin(angle)
    local = p @ np.array([[c, -s], [s, c]])       # coordinates along (ex, ey)
    lo, hi = local.min(0), local.max(0)
    mid = (lo + hi) / 2
    centre = mid[0] * np.array([c, s]) + mid[1] * np.array([-s, c])
    return Square(tuple(centre), SCALE * float(max(hi - lo)), angle)


def face_mesh(network, image, square):
    """The 468 mesh points in ``square`` of ``image`` (H, W, 3) float32 in [0, 1].

    Returns
    -------
    points : ndarray (468, 3)
        u, v in photo pixels; z (depth, toward the camera negative) in the same pixel
        scale, relative to the face's centre.
    presence : float
        The model's face-presence probability for the crop.
    """
    x = crop(image, square, INPUT, border="edge")
    raw, flag = network(x[None])
    pts = np.asarray(raw, float).reshape(-1, 3)
    uv = square.to_photo(pts[:, :2], INPUT)
    z = pts[:, 2:] * square.size / INPUT
    presence = float(1 / (1 + np.exp(-np.clip(float(np.ravel(flag)[0]), -100, 100))))
    return np.hstack([uv, z]), presence
