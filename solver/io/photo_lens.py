"""The lens each orthographic photo of a case was taken with, from the photo's EXIF: the
fit then tells how far the camera stood and whether a parallel projection fits the photo
(``cameras.projection_check.lens_distance``; a phone's 26 mm lens never does). Front-ends
(the command line, the add-on) call it with the photo files they know; files do not store
it."""

from pathlib import Path

from ..cameras import OrthographicCamera
from .exif import photo_lens_mm


def orthographic_lenses(case, photo_paths=None):
    """Set ``camera_hints["lens_mm"]`` of every orthographic view whose photo's EXIF gives
    a focal length.

    Parameters
    ----------
    case : LandmarkCase
        Changed in place (only its views' ``camera_hints``).
    photo_paths : dict of str -> path-like or None, optional
        View name -> the photo file (views missing or None, and files that do not exist,
        are skipped). Default: the photos the case names (``case.image_path``).

    Returns
    -------
    dict of str -> float
        View name -> the lens set (mm, 36 mm equivalent across the long side).
    """
    if photo_paths is None:
        photo_paths = {name: case.image_path(name) for name, view in case.views.items()
                       if view.image is not None}
    found = {}
    for name, view in case.views.items():
        path = photo_paths.get(name)
        if not isinstance(view.camera, OrthographicCamera) or path is None \
                or not Path(path).is_file():
            continue
        lens = photo_lens_mm(path, view.size)
        if lens:
            view.camera_hints["lens_mm"] = found[name] = float(lens)
    return found
