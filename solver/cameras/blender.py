"""Conversion between DLT cameras (or K, R, C) and Blender camera settings; all Blender
camera conventions live in this one module. Pure numpy: the add-on applies the returned
plain dict with bpy.

Blender's perspective camera (from its view-plane computation):

- The camera object looks down its local -Z axis with +Y up and +X right. Our cameras
  (solver/cameras.py) use OpenCV rows (u right, v down, viewing direction), so the local
  axes in world space are x = R[0], y = -R[1], z = -R[2]; the object's rotation (local ->
  world) is ``R.T @ diag(1, -1, -1)`` and its location is the camera centre C.
- The sensor size (mm) spans one image side, chosen by ``sensor_fit``: HORIZONTAL uses
  ``sensor_width`` across the width, VERTICAL ``sensor_height`` across the height, AUTO
  uses ``sensor_width`` across whichever of (width * pixel_aspect_x, height *
  pixel_aspect_y) is larger. With ``viewfac`` the fitted side in pixels (width, or
  height * ycor, ycor = pixel_aspect_y / pixel_aspect_x)::

      fx = lens * viewfac / sensor          (pixels)
      fy = fx / ycor
      cx = width / 2  - shift_x * viewfac
      cy = height / 2 + shift_y * viewfac / ycor      (v down; shift_y moves the view up)

  i.e. shifts are fractions of the fitted side, positive shift_x moves the frame right.
- Pixels here are continuous with (0, 0) at the image's top-left corner (pixel centres at
  half-integers), as Blender's view plane spans exactly the rendered pixels. Resolution
  is the rendered size (``resolution_x * resolution_percentage / 100``).

Blender cannot represent skew or lens distortion: ``to_blender`` drops them and says how
many pixels that moves (skew) or that it was dropped (distortion). A mirrored camera
(solver/mirror.py; rotation with determinant -1) is no Blender camera; with
``allow_flip=True`` the result is the real camera that sees the photo flipped left-right
(u -> width - u), flagged ``"flip_x": True`` so the add-on flips the background image.
"""

import numpy as np

from .dlt import DLTCamera

# local camera axes of Blender in OpenCV's camera frame (and back): diag(1, -1, -1)
_FLIP_YZ = np.diag([1.0, -1.0, -1.0])


def euler_xyz_from_matrix(rot):
    """Blender 'XYZ' Euler angles (R = Rz(z) Ry(y) Rx(x)) of a rotation matrix, radians.

    Parameters
    ----------
    rot : array_like, shape (3, 3)
        Proper rotation (local -> world).

    Returns
    -------
    ndarray, shape (3,)
    """
    r = np.asarray(rot, dtype=np.float64).reshape(3, 3)
    cy = np.hypot(r[2, 1], r[2, 2])
    y = np.arctan2(-r[2, 0], cy)
    if cy > 1e-9:
        x = np.arctan2(r[2, 1], r[2, 2])
        z = np.arctan2(r[1, 0], r[0, 0])
    else:  # gimbal lock: only x - z (or x + z) is defined; put it all in z
        x = 0.0
        z = np.arctan2(-r[0, 1], r[1, 1])
    return np.array([x, y, z])


def matrix_from_euler_xyz(angles):
    """Rotation matrix of Blender 'XYZ' Euler angles (radians): Rz @ Ry @ Rx, shape (3, 3)."""
    x, y, z = (float(a) for a in angles)
    cx, sx, cy, sy, cz, sz = np.cos(x), np.sin(x), np.cos(y), np.sin(y), np.cos(z), np.sin(z)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def krc_to_blender(K, R, C, size, sensor_size=36.0, allow_flip=False):
    """Blender camera settings of ``P = K R [I | -C]``.

    Parameters
    ----------
    K : array_like, shape (3, 3)
        Intrinsics in pixels (upper triangular, K[2, 2] = 1).
    R : array_like, shape (3, 3)
        World -> camera, rows (u axis, v axis, viewing direction).
    C : array_like, shape (3,), metres
    size : (int, int)
        Image width and height in pixels.
    sensor_size : float, mm
        Sensor size across the longer image side (36 mm makes ``lens`` the full-frame
        equivalent focal length); written as both sensor_width and sensor_height with an
        explicit fit, which is what AUTO fit does.
    allow_flip : bool
        For a mirrored camera (det R < 0): return the camera of the left-right flipped
        photo instead of raising.

    Returns
    -------
    dict
        ``lens`` (mm), ``sensor_width``, ``sensor_height`` (mm), ``sensor_fit``
        ("HORIZONTAL" or "VERTICAL"), ``shift_x``, ``shift_y``, ``resolution_x``,
        ``resolution_y``, ``resolution_percentage`` (100), ``pixel_aspect_x``,
        ``pixel_aspect_y``, ``location`` (3, m), ``rotation_euler`` (3, rad, 'XYZ'),
        ``matrix_world`` (4x4 nested lists), ``flip_x`` (bool), ``dropped_skew_px``
        (largest pixel shift inside the image from dropping the skew), ``warnings``.

    Raises
    ------
    ValueError
        A mirrored camera without ``allow_flip``; a non-positive focal length or size.
    """
    k = np.asarray(K, dtype=np.float64).reshape(3, 3)
    r = np.asarray(R, dtype=np.float64).reshape(3, 3)
    c = np.asarray(C, dtype=np.float64).reshape(3)
    w, h = float(size[0]), float(size[1])
    if not (w > 0 and h > 0):
        raise ValueError(f"size: width and height must be positive, got {size!r}")
    if not sensor_size > 0:
        raise ValueError(f"sensor_size: must be positive, got {sensor_size!r}")
    k = k / k[2, 2]
    flip = False
    if np.linalg.det(r) < 0:
        if not allow_flip:
            raise ValueError("camera: a mirrored camera (rotation with determinant -1) has no "
                             "Blender camera; pass allow_flip=True to get the camera of the "
                             "left-right flipped photo")
        # K R = (K D)(D R), D = diag(-1, 1, 1); flipping u -> w - u makes K D a proper K
        d = np.diag([-1.0, 1.0, 1.0])
        f = np.array([[-1.0, 0, w], [0, 1, 0], [0, 0, 1]])
        k = f @ k @ d
        r = d @ r
        flip = True
    fx, skew, cx = k[0]
    fy, cy = k[1, 1], k[1, 2]
    if not (fx > 0 and fy > 0):
        raise ValueError(f"camera: focal lengths must be positive, got fx={fx}, fy={fy}")
    ycor = fx / fy  # pixel_aspect_y / pixel_aspect_x
    aspx, aspy = (1.0, ycor) if ycor >= 1.0 else (1.0 / ycor, 1.0)
    horizontal = aspx * w >= aspy * h
    viewfac = w if horizontal else ycor * h
    warnings = []
    # dropping the skew moves a pixel by skew * (v - cy) / fy; largest at the top/bottom edge
    dropped = abs(skew) * max(abs(cy), abs(h - cy)) / fy
    if dropped > 1e-6:
        warnings.append(f"skew dropped (Blender has none): moves pixels by up to "
                        f"{dropped:.3g} px")
    rot = r.T @ _FLIP_YZ
    mw = np.eye(4)
    mw[:3, :3] = rot
    mw[:3, 3] = c
    return {
        "lens": float(fx * sensor_size / viewfac),
        "sensor_width": float(sensor_size),
        "sensor_height": float(sensor_size),
        "sensor_fit": "HORIZONTAL" if horizontal else "VERTICAL",
        "shift_x": float((w / 2.0 - cx) / viewfac),
        "shift_y": float((cy - h / 2.0) * ycor / viewfac),
        "resolution_x": int(round(w)),
        "resolution_y": int(round(h)),
        "resolution_percentage": 100,
        "pixel_aspect_x": float(aspx),
        "pixel_aspect_y": float(aspy),
        "location": c.tolist(),
        "rotation_euler": euler_xyz_from_matrix(rot).tolist(),
        "matrix_world": mw.tolist(),
        "flip_x": flip,
        "dropped_skew_px": float(dropped),
        "warnings": warnings,
    }


def dlt_to_blender(camera, sensor_size=36.0, allow_flip=False):
    """Blender camera settings of a DLT camera (``krc_to_blender`` of its decomposition).

    Parameters
    ----------
    camera : DLTCamera
    sensor_size : float, mm
    allow_flip : bool

    Returns
    -------
    dict
        As ``krc_to_blender``; a warning is added when lens distortion is dropped.
    """
    if not isinstance(camera, DLTCamera):
        raise ValueError(f"camera: expected a DLTCamera, got {type(camera).__name__}")
    k, r, c = camera.decompose()
    out = krc_to_blender(k, r, c, camera.size, sensor_size, allow_flip)
    if camera.has_distortion:
        out["warnings"].append("lens distortion (b12..b16) dropped: Blender cameras have "
                               "none; undistort the photo to match exactly")
    return out


def _get(params, key, default=None):
    if key in params:
        return params[key]
    if default is None:
        raise ValueError(f"blender camera: missing field {key!r}")
    return default


def blender_to_krc(params):
    """K, R, C and image size of Blender camera settings (inverse of ``krc_to_blender``).

    Parameters
    ----------
    params : dict
        ``lens``, ``resolution_x``, ``resolution_y`` and either ``matrix_world`` (4x4; any
        object scale is removed) or ``location`` + ``rotation_euler`` ('XYZ'). Optional:
        ``sensor_width`` (36), ``sensor_height`` (24), ``sensor_fit`` ("AUTO"),
        ``shift_x``, ``shift_y`` (0), ``resolution_percentage`` (100),
        ``pixel_aspect_x``, ``pixel_aspect_y`` (1), ``flip_x`` (False: True returns the
        camera of the un-flipped photo, a mirrored one).

    Returns
    -------
    K : ndarray, shape (3, 3), pixels
    R : ndarray, shape (3, 3)
        World -> camera (rows u, v, viewing direction).
    C : ndarray, shape (3,), metres
    size : (int, int)
    """
    lens = float(_get(params, "lens"))
    pct = float(params.get("resolution_percentage", 100)) / 100.0
    w = float(_get(params, "resolution_x")) * pct
    h = float(_get(params, "resolution_y")) * pct
    aspx = float(params.get("pixel_aspect_x", 1.0))
    aspy = float(params.get("pixel_aspect_y", 1.0))
    fit = params.get("sensor_fit", "AUTO")
    if fit not in ("AUTO", "HORIZONTAL", "VERTICAL"):
        raise ValueError(f"blender camera: sensor_fit must be AUTO, HORIZONTAL or VERTICAL, "
                         f"got {fit!r}")
    if not (lens > 0 and w > 0 and h > 0 and aspx > 0 and aspy > 0):
        raise ValueError("blender camera: lens, resolution and pixel aspect must be positive")
    ycor = aspy / aspx
    horizontal = fit == "HORIZONTAL" or (fit == "AUTO" and aspx * w >= aspy * h)
    sensor = float(params.get("sensor_height", 24.0)) if fit == "VERTICAL" else \
        float(params.get("sensor_width", 36.0))
    viewfac = w if horizontal else ycor * h
    fx = lens * viewfac / sensor
    k = np.array([[fx, 0.0, w / 2.0 - float(params.get("shift_x", 0.0)) * viewfac],
                  [0.0, fx / ycor, h / 2.0 + float(params.get("shift_y", 0.0)) * viewfac / ycor],
                  [0.0, 0.0, 1.0]])
    if "matrix_world" in params:
        mw = np.asarray(params["matrix_world"], dtype=np.float64).reshape(4, 4)
        rot = mw[:3, :3] / np.linalg.norm(mw[:3, :3], axis=0)
        c = mw[:3, 3].copy()
    else:
        rot = matrix_from_euler_xyz(_get(params, "rotation_euler"))
        c = np.asarray(_get(params, "location"), dtype=np.float64).reshape(3)
    if np.linalg.det(rot) < 0:
        raise ValueError("blender camera: matrix_world has a negative scale (mirrored)")
    r = _FLIP_YZ @ rot.T
    if params.get("flip_x", False):
        d = np.diag([-1.0, 1.0, 1.0])
        f = np.array([[-1.0, 0, w], [0, 1, 0], [0, 0, 1]])
        k = f @ k @ d  # F is its own inverse, as is D
        r = d @ r
    return k, r, c, (int(round(w)), int(round(h)))


def blender_to_dlt(params):
    """DLT camera of Blender camera settings (see ``blender_to_krc``).

    Returns
    -------
    DLTCamera
    """
    k, r, c, size = blender_to_krc(params)
    return DLTCamera.from_krc(k, r, c, size)
