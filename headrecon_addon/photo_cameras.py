"""Blender cameras of perspective photos (DLT and pinhole views): one camera object per
photo, the photo as its background image, and the photo plane inside its frustum.

Every Blender camera convention lives in ``solver/cameras/blender.py``: a solver camera
becomes a settings dict there (``lens``, sensor, shift, pixel aspect, ``matrix_world``,
``flip_x``), applied here as it is; reading a camera object back goes through the same
module (``blender_to_krc``), so the plane follows whatever the camera object says, also
after the artist changes its lens by hand.

The plane. A photo plane (photos.py: plane space x in [-W/2, W/2], y in [-H/2, H/2], pixel
u = w/2 + x h/H, v = h/2 - y h/H) is parented to the camera with a local matrix that puts
plane point (x, y) on the ray of its pixel at distance ``depth`` in front of the camera::

    x_cam = s * x * (h/H) depth/fx + (w/2 - cx) depth/fx
    y_cam =     y * (h/H) depth/fy + (cy - h/2) depth/fy,       z_cam = -depth

with (fx, fy, cx, cy) the Blender camera's intrinsics (skew and lens distortion are not
representable in Blender and are ignored for display: the landmarks' pixels stay exact,
only the photo's alignment with the head is off by what those terms move) and s = -1 for
a mirrored camera: Blender has none, so the camera shown is the real one that sees the
photo flipped left-right, and plane and background image are flipped to match.

Render resolution and pixel aspect are scene settings in Blender, not camera settings:
``look_through`` sets them to the photo's when the artist looks through its camera.
"""

import bpy
import numpy as np
from mathutils import Matrix, Vector

from .solver_link import DLTCamera, PinholeCamera, blender_to_krc, dlt_to_blender

PLANE_DEPTH = 0.3  # metres behind the head's centre (as orthographic planes stand)
MIN_DEPTH = 0.05  # metres: a plane never closer to its camera than this
DISPLAY_SIZE = 0.1  # metres: the camera's drawn size in the viewport (a head is ~0.25 m)
PERSPECTIVE_KINDS = ("dlt", "pinhole")
DEFAULT_LENS_MM = 50.0  # the provisional camera's lens when the file gives none
HEAD_FILL = 0.8  # a provisional camera frames the head (0.3 m) to this part of the height
HEAD_HEIGHT = 0.3


def is_camera_object(obj):
    return obj is not None and obj.type == "CAMERA" and obj.headrecon.role == "CAMERA"


def blender_settings(camera):
    """Blender camera settings of a perspective solver camera (``dlt_to_blender``'s dict:
    a mirrored camera gives the left-right flipped photo's camera, ``flip_x`` True).

    Raises
    ------
    ValueError
        Not a DLT or pinhole camera, or one Blender cannot show (non-positive focal).
    """
    if isinstance(camera, DLTCamera):
        return dlt_to_blender(camera, allow_flip=True)
    if isinstance(camera, PinholeCamera):
        return camera.to_blender(allow_flip=True)
    raise ValueError(f"camera: a {getattr(camera, 'kind', type(camera).__name__)} camera "
                     "has no perspective Blender camera")


def new_camera_object(name):
    """A perspective camera object (not linked to a scene)."""
    data = bpy.data.cameras.new(name)
    obj = bpy.data.objects.new(name, data)
    obj.headrecon.role = "CAMERA"
    data.display_size = DISPLAY_SIZE
    data.clip_start = 0.01
    obj.hide_render = True
    return obj


def set_lens(data, params):
    """Make a Blender camera (its data) the perspective camera of a ``blender_settings``
    dict: lens, sensor and shift (the object's place and the pixel aspect are its own)."""
    data.type = "PERSP"
    data.lens_unit = "MILLIMETERS"
    data.sensor_width = params["sensor_width"]
    data.sensor_height = params["sensor_height"]
    data.sensor_fit = params["sensor_fit"]
    data.lens = params["lens"]
    data.shift_x = params["shift_x"]
    data.shift_y = params["shift_y"]


def apply_settings(obj, params):
    """Set a camera object from a ``blender_settings`` dict."""
    data = obj.data
    set_lens(data, params)
    obj.headrecon.pixel_aspect = (params["pixel_aspect_x"], params["pixel_aspect_y"])
    obj.headrecon.flip_x = bool(params["flip_x"])
    obj.matrix_world = Matrix(params["matrix_world"])
    for bg in data.background_images:
        bg.use_flip_x = obj.headrecon.flip_x


def settings_of(obj, size):
    """The settings dict of a camera object for a photo of ``size`` (w, h): what
    ``blender_to_krc`` reads."""
    data = obj.data
    return {"lens": data.lens, "sensor_width": data.sensor_width,
            "sensor_height": data.sensor_height, "sensor_fit": data.sensor_fit,
            "shift_x": data.shift_x, "shift_y": data.shift_y,
            "resolution_x": int(size[0]), "resolution_y": int(size[1]),
            "resolution_percentage": 100,
            "pixel_aspect_x": obj.headrecon.pixel_aspect[0],
            "pixel_aspect_y": obj.headrecon.pixel_aspect[1],
            "matrix_world": [list(r) for r in obj.matrix_world],
            "flip_x": obj.headrecon.flip_x}


def set_background(obj, image):
    """Show ``image`` as the camera's background, filling its frame."""
    data = obj.data
    bg = data.background_images[0] if len(data.background_images) else \
        data.background_images.new()
    bg.image = image
    bg.frame_method = "STRETCH"  # the frame has the photo's aspect (look_through)
    bg.display_depth = "BACK"
    bg.alpha = 1.0
    bg.use_flip_x = obj.headrecon.flip_x
    data.show_background_images = True


def camera_depth(obj, point):
    """Distance of a world point in front of the camera (along its viewing axis), metres."""
    return -float((obj.matrix_world.inverted() @ Vector(point)).z)


def plane_local_matrix(obj, size, plane_height, depth):
    """The photo plane's matrix in the camera's space (module docstring).

    Parameters
    ----------
    obj : bpy.types.Object
        The camera.
    size : (int, int)
        Photo width and height, pixels.
    plane_height : float
        H, the plane's height in its own space.
    depth : float, metres
        Distance of the plane in front of the camera.
    """
    w, h = float(size[0]), float(size[1])
    k, _, _, _ = blender_to_krc({**settings_of(obj, size), "flip_x": False,
                                 "matrix_world": np.eye(4).tolist()})
    fx, cx, fy, cy = k[0, 0], k[0, 2], k[1, 1], k[1, 2]
    per = h / float(plane_height)  # pixels per plane unit
    sx, sy = per * depth / fx, per * depth / fy
    sign = -1.0 if obj.headrecon.flip_x else 1.0
    return Matrix(((sign * sx, 0.0, 0.0, (w / 2.0 - cx) * depth / fx),
                   (0.0, sy, 0.0, (cy - h / 2.0) * depth / fy),
                   (0.0, 0.0, sx, -depth),
                   (0.0, 0.0, 0.0, 1.0)))


def attach_plane(plane, obj, size, plane_height, depth):
    """Parent the plane to the camera at ``depth`` in front of it, filling its view; the
    camera's far clip is pushed beyond it."""
    depth = max(float(depth), MIN_DEPTH)
    plane.parent = obj
    plane.matrix_parent_inverse.identity()
    plane.matrix_basis = plane_local_matrix(obj, size, plane_height, depth)
    obj.data.clip_end = max(obj.data.clip_end, 2.0 * depth)


def plane_depth(plane):
    """The plane's current distance in front of its camera, metres."""
    return -float(plane.matrix_basis.translation.z)


def look_through(scene, obj, size):
    """Make ``obj`` the scene's camera with the photo's resolution and pixel aspect (render
    settings are the scene's in Blender), so its frame is the photo's."""
    scene.camera = obj
    render = scene.render
    render.resolution_x, render.resolution_y = int(size[0]), int(size[1])
    render.resolution_percentage = 100
    render.pixel_aspect_x, render.pixel_aspect_y = obj.headrecon.pixel_aspect


def provisional_camera(size, view_dir, target=(0.0, 0.0, 0.0), lens_mm=None):
    """A stand-in pinhole camera for a photo whose camera is not known yet (the fit will
    self-calibrate it): looking along ``view_dir`` at ``target`` from where the head (0.3 m)
    fills 80 % of the photo's height, with the given lens (default 50 mm equivalent)."""
    lens = float(lens_mm) if lens_mm else DEFAULT_LENS_MM
    f_px = lens * PinholeCamera.px_per_mm(size)
    dist = f_px * HEAD_HEIGHT / (HEAD_FILL * float(size[1]))
    d = np.asarray(view_dir, dtype=np.float64)
    t = np.asarray(target, dtype=np.float64)
    return PinholeCamera.look_at(t - dist * d / np.linalg.norm(d), t, size, f_px=f_px)
