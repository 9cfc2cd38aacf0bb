"""Detected faces as a landmarks case: one view per photo, its iBUG-68 points under the
project's landmark names, so ``python -m solver detect`` writes a file the fit reads."""

import os
from pathlib import Path

from ..cameras import OrthographicCamera
from ..io.case import LandmarkCase, View
from ..io.landmark_set import load_landmark_set

#: Every detected photo is written as a front photo for now (guessing a profile or a
#: three-quarter view from the detection is still to come): issue 16.
CAMERA = "orthographic-front"


def detected_case(photos, faces, base_dir=None):
    """A :class:`LandmarkCase` from detected faces.

    Parameters
    ----------
    photos : list of (view name, photo path, (width, height))
    faces : list of DetectedFace
        One per photo.
    base_dir : Path, optional
        Photo paths are written relative to it (the landmarks file's folder).
    """
    names = load_landmark_set().ibug
    views = {}
    for (name, path, size), face in zip(photos, faces, strict=True):
        w, h = size
        points = {}
        for number, (u, v) in enumerate(face.ibug, start=1):
            if number in names and 0 <= u <= w and 0 <= v <= h:
                points[names[number]] = (float(u), float(v))
        image = Path(path).absolute()
        if base_dir is not None:
            image = Path(os.path.relpath(image, Path(base_dir).absolute()))
        views[name] = View(name, image.as_posix(), (w, h),
                           OrthographicCamera.nominal(CAMERA, (w, h)), points)
    return LandmarkCase(views)
