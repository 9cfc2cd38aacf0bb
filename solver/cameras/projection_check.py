"""May a photo be treated as a parallel (orthographic) projection? Seed 001 (Hashimoto
1984) chapter 2.2.1.

A photo is a central projection. An object of size A at distance L images at a = l A / L;
moved back by ΔL it images at a' = l A / (L + ΔL) (eq. 2.1). A parallel projection keeps
the size fixed, so it may stand in for the photo only while the relative change

    ε = (a - a') / a = ΔL / (L + ΔL)                                        (eq. 2.2)

stays below ε_max, the relative error already present from reading the image (landmark
placement error over the object's image size, γ of eq. 2.5). Equivalently the camera must be
farther than

    L > (1 - ε_max) / ε_max · ΔL                                            (eq. 2.3)

For a head, ΔL is its depth along the line of sight and L the distance from the camera
centre to its nearest point, so ε = 1 - d_min / d_max over the head's depths: at 1 m a
0.1 m deep head gives 0.1 / 1.1 ≈ 9 %, while landmarks read to 2 px on a 600 px head are
good to 0.3 %; the orthographic cameras then distort the head's proportions far more than
the landmark error does, and a perspective (DLT) camera should be used.

``check_projection`` measures L and ΔL with a calibrated perspective camera (DLT or
pinhole); ``check_orthographic`` does it for a photo treated as orthographic, whose
distance the photo cannot tell, from a distance the user gives or the lens the photo was
taken with (``lens_distance``: its EXIF focal length and the head's size in the photo).
"""

from dataclasses import dataclass

import numpy as np

from ..errors import as_points
from .dlt import DLTCamera
from .orthographic import OrthographicCamera
from .pinhole import PinholeCamera


def perspective_ratio(depth_extent, distance):
    """ε = ΔL / (L + ΔL) (eq. 2.2).

    Parameters
    ----------
    depth_extent : float or ndarray, metres
        ΔL, the object's depth along the line of sight.
    distance : float or ndarray, metres
        L, the distance to the object's nearest point.

    Returns
    -------
    float or ndarray
    """
    dl = np.asarray(depth_extent, dtype=np.float64)
    el = np.asarray(distance, dtype=np.float64)
    if (dl < 0).any() or (el <= 0).any():
        raise ValueError("perspective_ratio: depth_extent must be >= 0 and distance > 0")
    return dl / (el + dl)


def lens_distance(camera, lens_mm):
    """How far from the head a photo fitted as orthographic was taken, from its lens.

    A lens of focal length f (pixels) images the head at f / L pixels per metre at
    distance L; the fitted orthographic camera's ``scale`` is that magnification, so
    L = f / scale (the head at the model's size: photos without a calibration object cannot
    tell its true size).

    Parameters
    ----------
    camera : OrthographicCamera
    lens_mm : float
        Focal length, mm on a sensor 36 mm across the photo's long side (EXIF's, as
        ``Exif.lens_36mm`` gives it).

    Returns
    -------
    float, metres (to the head's middle)
    """
    lens = float(lens_mm)
    if not lens > 0 or not camera.scale > 0:
        raise ValueError(f"lens_distance: lens_mm must be > 0 and the camera's scale > 0, "
                         f"got {lens_mm!r} and {camera.scale!r}")
    return lens * PinholeCamera.px_per_mm(camera.size) / camera.scale


def min_distance(depth_extent, epsilon_max):
    """Smallest camera distance for a parallel projection, (1 - ε_max) / ε_max · ΔL
    (eq. 2.3), metres."""
    e = float(epsilon_max)
    if not 0 < e < 1:
        raise ValueError(f"epsilon_max: must lie in (0, 1), got {epsilon_max!r}")
    return (1.0 - e) / e * float(depth_extent)


@dataclass
class ProjectionCheck:
    """ε of one photo (``check_projection``).

    Attributes
    ----------
    view : str
    distance : float, metres
        L: depth of the head's nearest point.
    depth_extent : float, metres
        ΔL: the head's extent along the viewing direction.
    epsilon : float
        ΔL / (L + ΔL) (eq. 2.2).
    epsilon_max : float
        The allowed ε (the reading error relative to the head's image size).
    min_distance : float, metres
        Eq. 2.3 for this head.
    exceeds : bool
        epsilon > epsilon_max: a parallel projection is not good enough for this photo.
    message : str
        Empty when fine, else a warning for the user.
    """

    view: str
    distance: float
    depth_extent: float
    epsilon: float
    epsilon_max: float
    min_distance: float
    exceeds: bool
    message: str


def check_projection(camera, points, epsilon_max=None, reading_error_px=2.0, view="photo"):
    """ε of a photo for head points seen by a calibrated perspective camera.

    Parameters
    ----------
    camera : DLTCamera or PinholeCamera
        The photo's calibrated camera (a mirrored one too: depths are along its viewing
        direction).
    points : array_like, shape (n, 3), metres
        Head points (e.g. landmark vertices or the whole skin) in the camera's world.
    epsilon_max : float, optional
        Allowed ε. Default: ``reading_error_px`` over the head's image size (the longer
        side of its projected bounding box), γ of eq. 2.5.
    reading_error_px : float, pixels
        Landmark placement error used for the default ε_max.
    view : str
        Name used in the message.

    Returns
    -------
    ProjectionCheck

    Raises
    ------
    ValueError
        Not a perspective camera, or head points on or behind the camera.
    """
    if not isinstance(camera, DLTCamera | PinholeCamera):
        raise ValueError(f"view {view!r}: the projection check needs a calibrated "
                         f"perspective (DLT or pinhole) camera, got {type(camera).__name__}")
    x = as_points(points, "points", min_count=2)
    depth = camera.depth(x)
    if (depth <= 0).any():
        raise ValueError(f"view {view!r}: {int((depth <= 0).sum())} head point(s) lie on or "
                         "behind the camera")
    near, far = float(depth.min()), float(depth.max())
    return _check(view, near, far - near, camera.project(x), epsilon_max, reading_error_px,
                  "the camera is")


def check_orthographic(camera, points, distance, epsilon_max=None, reading_error_px=2.0,
                       view="photo"):
    """ε of a photo fitted as a parallel projection, taken from a given distance.

    The photo itself cannot tell how far the camera was; ``distance`` (metres, from the
    camera to the middle of the head) says it. ΔL is the head's extent along the camera's
    viewing direction, L = ``distance`` - ΔL / 2 the distance to its nearest point.

    Parameters
    ----------
    camera : OrthographicCamera
    points : array_like, shape (n, 3), metres
        Head points (e.g. the fitted skin) in the camera's world.
    distance : float, metres
    epsilon_max, reading_error_px, view : see ``check_projection``

    Returns
    -------
    ProjectionCheck

    Raises
    ------
    ValueError
        Not an orthographic camera, or a distance not beyond half the head's depth.
    """
    if not isinstance(camera, OrthographicCamera):
        raise ValueError(f"view {view!r}: expected an orthographic camera, got "
                         f"{type(camera).__name__}")
    x = as_points(points, "points", min_count=2)
    depth = x @ camera.rotation[2]
    extent = float(depth.max() - depth.min())
    near = float(distance) - 0.5 * extent
    if not near > 0:
        raise ValueError(f"view {view!r}: camera distance {float(distance):.3f} m does not "
                         f"clear the head ({extent * 100:.1f} cm deep)")
    return _check(view, near, extent, camera.project(x), epsilon_max, reading_error_px,
                  "the photo was taken")


def _check(view, near, extent, px, epsilon_max, reading_error_px, what):
    eps = float(perspective_ratio(extent, near))
    if epsilon_max is None:
        span = float(np.max(px.max(axis=0) - px.min(axis=0)))
        if not span > 0:
            raise ValueError(f"view {view!r}: the head points project to one pixel")
        epsilon_max = float(reading_error_px) / span
    epsilon_max = float(epsilon_max)
    lmin = min_distance(extent, epsilon_max) if epsilon_max < 1 else 0.0
    exceeds = eps > epsilon_max
    msg = ""
    if exceeds:
        msg = (f"view {view!r}: {what} {near:.2f} m from a head {extent * 100:.1f} cm "
               f"deep, so a parallel projection is off by {eps * 100:.1f} % (eq. 2.2) while "
               f"landmarks are good to {epsilon_max * 100:.2f} %; treat this photo as a "
               f"perspective (pinhole or DLT) camera, or shoot from at least {lmin:.1f} m")
    return ProjectionCheck(view, near, extent, eps, epsilon_max, lmin, exceeds, msg)
