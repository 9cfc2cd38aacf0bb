"""The lens each orthographic photo of a case was taken with, from the photo's EXIF: the
fit then tells how far the camera stood and whether a parallel projection fits the photo
(``cameras.projection_check.lens_distance``; a phone's 26 mm lens never does). Front-ends
(the command line, the add-on) call it with the photo files they know; files do not store
it."""

from pathlib import Path

from ..cameras import OrthographicCamera
from .camera_json import LENS_MM_RANGE
from .exif import photo_lens_mm

#: Standard deviation (degrees) of where a photo's camera stood around the head, about the
#: yaw its view says and level (``PinholeCamera.direction_prior``): what a person stepping
#: around the sitter keeps (docs/DECISIONS.md, "Photos whose lens is known").
DIRECTION_SIGMA_DEG = 5.0


def plausible_lens(lens_mm, where):
    """(lens, problem) of a lens a photo's EXIF gives (mm, 36 mm equivalent; None: none):
    the lens when it is one a landmarks file accepts (``camera_json.LENS_MM_RANGE``), else
    None and one line naming ``where`` (the photo), as for EXIF that cannot be read."""
    lo, hi = LENS_MM_RANGE
    if lens_mm is None or lo <= lens_mm <= hi:
        return lens_mm, None
    return None, (f"{where}: its EXIF gives a {lens_mm:g} mm lens (36 mm equivalent), "
                  f"outside {lo:g}..{hi:g} mm; the photo is used as if it gave none")


def lens_hints(lens_mm, yaw_deg):
    """The camera to compute for a photo whose lens is known (its EXIF's, mm, 36 mm
    equivalent) and that was taken from about ``yaw_deg`` (degrees from the face's front,
    toward the subject's right positive; a front photo 0, a profile +-90): a pinhole
    camera of that lens, calibrated by the fit on the head, held near that direction. A
    parallel projection of a photo taken from a few metres or nearer distorts the head's
    proportions more than its landmarks' error does (seed 001 eq. 2.2)."""
    return {"kind": "pinhole", "lens_mm": float(lens_mm),
            "direction_prior": [float(yaw_deg), DIRECTION_SIGMA_DEG]}


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
