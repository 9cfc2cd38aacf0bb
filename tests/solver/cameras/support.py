"""Synthetic perspective cameras for the camera tests (DLT, triangulation, mirror, Blender
conversion, passpoint checks): a full-HD camera at a given place looking at a target.

The rotation comes from the solver's own ``PinholeCamera.look_at``, so the tests and the
solver agree on one convention: rows (u right, v down, viewing direction).
"""

import numpy as np

from solver import DLTCamera, PinholeCamera

SIZE = (1920, 1080)
# 1500 px focal length (a 28 mm lens on full frame), principal point at the image centre
K = np.array([[1500.0, 0.0, 960.0], [0.0, 1500.0, 540.0], [0.0, 0.0, 1.0]])


def look_at(centre, target, up=(0.0, 0.0, 1.0)):
    """World -> camera rotation (3, 3) of a camera at ``centre`` looking at ``target``
    with ``up`` pointing up in the image."""
    return PinholeCamera.look_at(centre, target, SIZE, f_px=1.0, up=up).rotation


def dlt_camera(centre, target=(0.0, 0.0, 0.0), k=K, size=SIZE, distortion=None):
    """A DLTCamera with intrinsics ``k`` at ``centre`` (metres) looking at ``target``;
    ``distortion`` (b12..b16, 5 lens terms) for a DLT-16 camera."""
    centre = np.asarray(centre, dtype=np.float64)
    return DLTCamera.from_krc(k, look_at(centre, target), centre, size, distortion)
