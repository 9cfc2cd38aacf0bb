"""A photo turned by quarter turns so its face is upright, and the pixel maps between that
frame and the photo as given: the detection runs on a face upright (the face detector,
the mesh, the outline's rules of hair above and neck below all assume one), and what it
finds is given back on the photo as the user gave it, where the fit, the texture and the
add-on's image planes read it.

A turn is ``np.rot90``'s ``k``: quarter turns anticlockwise on screen, 0-3. Pixels are
continuous: pixel (row r, column c) covers [c, c + 1) x [r, r + 1).
"""

import numpy as np

from ..cameras import OrthographicCamera


def turned(image, turn):
    """``image`` (H, W, ...) turned by ``turn`` quarter turns anticlockwise, contiguous."""
    return np.ascontiguousarray(np.rot90(image, turn % 4))


def quarter_turn(angle):
    """The quarter turns (0-3) that bring a face whose eye line lies at ``angle`` (radians,
    ``face_landmarks.eye_line_angle``: 0 upright, v pointing down) nearest to upright."""
    return int(np.round(angle / (np.pi / 2))) % 4


def turned_size(size, turn):
    """The (w, h) of a photo of ``size`` (w, h) turned by ``turn``."""
    w, h = size
    return (h, w) if turn % 2 else (w, h)


def _map(turn, size):
    """(A, b) with photo = A @ turned + b for pixels of a photo of ``size`` (w, h) seen
    turned by ``turn``."""
    w, h = size
    return {0: (np.eye(2), np.zeros(2)),
            1: (np.array([[0.0, -1.0], [1.0, 0.0]]), np.array([w, 0.0])),
            2: (-np.eye(2), np.array([w, h], float)),
            3: (np.array([[0.0, 1.0], [-1.0, 0.0]]), np.array([0.0, h]))}[turn % 4]


def to_photo(points, turn, size):
    """Pixels (n, 2) of the photo of ``size`` (w, h) turned by ``turn`` -> the same places'
    pixels on the photo as given."""
    p = np.asarray(points, float)
    if not turn % 4:
        return p
    a, b = _map(turn, size)
    return p @ a.T + b


def to_turned(points, turn, size):
    """Pixels (n, 2) of the photo of ``size`` (w, h) as given -> the same places' pixels on
    it turned by ``turn`` (the inverse of :func:`to_photo`)."""
    p = np.asarray(points, float)
    if not turn % 4:
        return p
    a, b = _map(turn, size)
    return (p - b) @ a  # a is a rotation: its inverse is its transpose


def camera_to_photo(camera, turn, size):
    """An orthographic ``camera`` of the photo of ``size`` (w, h) turned by ``turn`` as the
    camera of the photo as given (the same projection followed by :func:`to_photo`: turned
    in its plane, its size the photo's); any other camera (None, a pinhole to calibrate)
    as it is."""
    if not turn % 4 or not isinstance(camera, OrthographicCamera):
        return camera
    a, b = _map(turn, size)
    rotation = camera.rotation.copy()
    rotation[:2] = a @ camera.rotation[:2]
    return OrthographicCamera(rotation, camera.scale, a @ camera.offset + b, size, camera.view)
