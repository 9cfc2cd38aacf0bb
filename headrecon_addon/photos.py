"""Photo planes: each photo stands behind the head as an unlit image plane, placed by its
camera so that, looking through that camera, the photo and the head line up.

Plane space. A plane's mesh spans x in [-W/2, W/2], y in [-H/2, H/2] (metres, z = 0) with
H = ``plane_height`` and W = H * w / h for an image of w x h pixels, so

    u = w / 2 + x * h / H,        v = h / 2 - y * h / H        (pixels, v down)

Landmarks and the contour are children of the plane and live in this space: their pixel
coordinates are derived from their local position, never stored twice. Swapping the photo
keeps H, so landmarks keep their place relative to the photo's centre and height.

World placement. For an orthographic camera (pixel = s R[:2] X + o) the plane's matrix has
columns k R0, -k R1, -k R2 (k = (h / H) / s) and puts pixel (w/2, h/2) at depth ``depth``
along the viewing direction R2, so a point in plane space at (x, y) projects through the
camera exactly to its (u, v): the photo lines up with the fitted head. A perspective
camera (DLT, pinhole) becomes a Blender camera object and the plane its child, filling its
view behind the head (photo_cameras.py); views whose camera is still to be computed get a
provisional camera from their nominal direction until a fit places them. Either way the
pixel mapping above is the plane's own, so landmarks, contour and tools never ask which.

What the file says about a view's camera: ``camera_json`` (known parameters), else the
camera object of ``view_json`` (``camera_hints``: kind and what is known, the parameters to
be computed), else the nominal orthographic camera of ``camera_view``.
"""

import dataclasses
import json
from pathlib import Path

import bpy
import numpy as np
from mathutils import Matrix

from . import material, photo_cameras, photo_faces, scene_collections
from .photo_sorting import sort_photos
from .polls import ObjectModeOperator, poll_result, view3d_problem
from .solver_link import (
    ORTHO_VIEWS,
    VIEW_YAW_DEG,
    OrthographicCamera,
    camera_from_json,
    camera_to_json,
    lens_hints,
    orient,
    oriented_size,
    plausible_lens,
    read_photo_exif,
)
from .warm_up import warm_up

PLACEHOLDER = "headrecon_placeholder"  # custom property on stand-in images (no photo)
# custom properties on a photo turned upright (EXIF Orientation): its file, the orientation
UPRIGHT_SOURCE = "headrecon_source"
UPRIGHT_ORIENTATION = "headrecon_orientation"
PLANE_DEPTH = photo_cameras.PLANE_DEPTH  # metres behind the head's centre, along the view
#: Blender colour spaces whose float pixels are not scene-linear colour.
_RAW_SPACES = ("Non-Color", "Raw", "Generic Data")
VIEW_KINDS = {"orthographic-front": "front", "orthographic-right": "right",
              "orthographic-left": "left"}


def is_photo(obj):
    return obj is not None and obj.type == "MESH" and obj.headrecon.role == "PHOTO"


def photo_planes(scene):
    """Photo planes in ``scene``, sorted by view name."""
    return sorted((o for o in scene.objects if is_photo(o)), key=lambda o: o.headrecon.view)


def find_plane(scene, view):
    """The photo plane of view ``view`` in ``scene``, or None."""
    return next((o for o in photo_planes(scene) if o.headrecon.view == view), None)


def plane_of(obj):
    """The photo plane ``obj`` is (or belongs to, for a landmark or contour), or None."""
    while obj is not None:
        if is_photo(obj):
            return obj
        obj = obj.parent
    return None


# --------------------------------------------------------------------------------------
# Images


@dataclasses.dataclass
class LoadedPhoto:
    """A photo file as loaded: its Blender image (upright), what its EXIF says (None:
    nothing), and the one line naming the file when its EXIF could not be read."""

    image: object
    exif: object = None
    problem: str | None = None

    def lens_mm(self):
        """The focal length EXIF gives (mm, 36 mm equivalent across the long side), or
        None (a lens no camera has is ``problem``, loaded as if EXIF gave none)."""
        if self.exif is None:
            return None
        size = tuple(self.image.size)
        stored = oriented_size(size, self.exif.orientation)  # (its own inverse)
        lens = self.exif.lens_36mm(stored)
        return round(lens, 1) if lens else None


def load_photo(path, size=None):
    """Load a photo (reusing an already loaded one of the same file), turned upright as
    its EXIF Orientation says (Blender shows the pixels as stored), with its EXIF.

    Parameters
    ----------
    size : (int, int), optional
        The size a landmarks file gives the photo: a photo turned by 90° whose stored size
        is this one (a file written before orientation was applied) is loaded as stored.

    Raises
    ------
    ValueError
        The file is missing or Blender cannot read it (message names the file).
    """
    p = Path(path)
    if not p.is_file():
        raise ValueError(f"{p}: photo not found")
    try:
        img = bpy.data.images.load(str(p), check_existing=True)
    except RuntimeError as e:
        raise ValueError(f"{p}: cannot read the photo ({e})") from None
    w, h = img.size
    if w == 0 or h == 0:
        if img.users == 0:
            bpy.data.images.remove(img)
        raise ValueError(f"{p}: cannot read the photo (not an image Blender understands)")
    exif, problem = read_photo_exif(p)
    turn = exif.orientation if exif is not None else 1
    if size is not None and tuple(size) == (w, h) != oriented_size((w, h), turn):
        turn = 1
    if turn != 1:
        img = _upright_image(img, turn, p)
    photo = LoadedPhoto(img, exif, problem)
    if problem is None:
        lens, photo.problem = plausible_lens(photo.lens_mm(), p.name)
        if lens is None and photo.problem:
            photo.exif = dataclasses.replace(exif, focal_length_mm=None, focal_35mm=None)
    return photo


def load_image(path, size=None):
    """The Blender image of ``load_photo`` (upright)."""
    return load_photo(path, size).image


def _upright_image(img, orientation, path):
    """The photo ``img`` (as stored) turned upright: a packed image of its own, made once
    per file and orientation (the stored one is removed when nothing uses it)."""
    key = str(path.resolve())
    upright = next((i for i in bpy.data.images if i.get(UPRIGHT_SOURCE) == key
                    and i.get(UPRIGHT_ORIENTATION) == orientation), None)
    if upright is None:
        pixels = np.ascontiguousarray(orient(image_to_array(img), orientation))
        h, w = pixels.shape[:2]
        upright = bpy.data.images.new(path.name, w, h, alpha=False)
        upright.colorspace_settings.name = img.colorspace_settings.name
        upright.pixels.foreach_set(pixels[::-1].ravel())
        upright.update()
        upright.pack()  # its pixels are ours: saved in the .blend
        upright[UPRIGHT_SOURCE] = key
        upright[UPRIGHT_ORIENTATION] = orientation
    if img.users == 0:
        bpy.data.images.remove(img)
    return upright


def photo_source(image):
    """The file a photo came from: the original of an upright copy, else its own file (an
    absolute path), or None."""
    if image is None:
        return None
    if image.get(UPRIGHT_SOURCE):
        return str(image[UPRIGHT_SOURCE])
    if image.source != "FILE" or not image.filepath:
        return None
    return bpy.path.abspath(image.filepath, library=image.library)


def image_to_array(image):
    """Pixels of a Blender image as (H, W, 4) float32, row 0 at the top (the photo's pixel
    convention; Blender stores rows bottom-up). Values are as stored (sRGB-encoded for
    ordinary photos), which is what the texture bake blends."""
    w, h = image.size
    if w == 0 or h == 0:
        raise ValueError(f"image {image.name!r}: has no pixels (file missing or unreadable?)")
    buf = np.empty(w * h * image.channels, dtype=np.float32)
    image.pixels.foreach_get(buf)
    arr = buf.reshape(h, w, image.channels)[::-1]
    if image.channels == 4:
        return np.ascontiguousarray(arr)
    out = np.ones((h, w, 4), dtype=np.float32)
    out[..., :min(3, image.channels)] = arr[..., :3]
    return out


def detector_pixels(image, read=None):
    """A Blender image's pixels as the detector reads a photo: (H, W, 3) float32 in [0, 1],
    row 0 at the top, sRGB-encoded (a float image, which Blender holds in linear light, is
    encoded; an 8-bit one is as stored); (H, W, 4) with its alpha where the photo has
    transparent pixels (a cut-out, which the detector lays on a grey backdrop). ``read``: a
    dict of the images read so far (name -> pixels, read-only), for a job that reads a
    photo twice (Auto Fit)."""
    if read is not None and image.name in read:
        return read[image.name]
    pixels = image_to_array(image)
    cut_out = pixels[:, :, 3].min() < 1.0
    # clamped into a contiguous array in two passes: np.clip on the strided RGB view of
    # the RGBA pixels took 2-3 times as long
    rgb = np.empty((image.size[1], image.size[0], 4 if cut_out else 3), np.float32)
    np.minimum(pixels[:, :, :rgb.shape[2]], np.float32(1.0), out=rgb)
    np.maximum(rgb, np.float32(0.0), out=rgb)
    if image.is_float and image.colorspace_settings.name not in _RAW_SPACES:
        colour = rgb[:, :, :3]
        rgb[:, :, :3] = np.where(colour <= 0.0031308, 12.92 * colour,
                                 1.055 * colour ** (1 / 2.4) - 0.055)
    if read is not None:
        rgb.flags.writeable = False
        read[image.name] = rgb
    return rgb


def array_to_image(array, name, image=None):
    """A Blender image (8-bit, sRGB) holding ``array`` (H, W, 3|4) float in [0, 1], row 0 at
    the top; reuses ``image`` when it has the same size."""
    arr = np.asarray(array, dtype=np.float32)
    h, w = arr.shape[:2]
    if image is None or tuple(image.size) != (w, h):
        image = bpy.data.images.new(name, w, h, alpha=False)
    rgba = np.ones((h, w, 4), dtype=np.float32)
    rgba[..., :3] = np.clip(arr[..., :3], 0.0, 1.0)
    image.pixels.foreach_set(rgba[::-1].ravel())
    image.update()
    return image


# --------------------------------------------------------------------------------------
# Plane geometry


def plane_size(plane):
    """(w, h) pixels and H (plane height, metres) of a photo plane."""
    w, h = plane.headrecon.image_size
    if w <= 0 or h <= 0:
        raise ValueError(f"photo plane {plane.name!r}: has no image size")
    return (int(w), int(h)), float(plane.headrecon.plane_height)


def pixels_from_local(plane, xy):
    """Plane-space points (n, 2+) -> pixels (n, 2)."""
    (w, h), big_h = plane_size(plane)
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, np.shape(xy)[-1])
    k = h / big_h
    return np.column_stack([w / 2.0 + xy[:, 0] * k, h / 2.0 - xy[:, 1] * k])


def local_from_pixels(plane, uv):
    """Pixels (n, 2) -> plane-space (x, y) (n, 2)."""
    (w, h), big_h = plane_size(plane)
    uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
    k = big_h / h
    return np.column_stack([(uv[:, 0] - w / 2.0) * k, (h / 2.0 - uv[:, 1]) * k])


def _set_plane_mesh(mesh, w, h, big_h):
    half_w, half_h = big_h * w / h / 2.0, big_h / 2.0
    co = np.array([[-half_w, -half_h, 0], [half_w, -half_h, 0],
                   [half_w, half_h, 0], [-half_w, half_h, 0]], dtype=np.float32)
    if len(mesh.vertices) != 4:
        mesh.clear_geometry()
        mesh.vertices.add(4)
        mesh.loops.add(4)
        mesh.polygons.add(1)
        mesh.loops.foreach_set("vertex_index", np.arange(4, dtype=np.int32))
        mesh.polygons.foreach_set("loop_start", np.zeros(1, dtype=np.int32))
        mesh.polygons.foreach_set("loop_total", np.full(1, 4, dtype=np.int32))
        uv = mesh.uv_layers.new(name="UVMap")
        uv.data.foreach_set("uv", np.array([0, 0, 1, 0, 1, 1, 0, 1], dtype=np.float32))
    mesh.vertices.foreach_set("co", co.ravel())
    mesh.update(calc_edges=True)


def camera_hints(plane):
    """The camera object the file gave for a view whose camera is to be computed (e.g.
    ``{"kind": "pinhole", "lens_mm": 50}``), or {} when the camera is known or nominal."""
    props = plane.headrecon
    if props.camera_json or not props.view_json:
        return {}
    cam = json.loads(props.view_json).get("camera")
    return dict(cam) if isinstance(cam, dict) else {}


def set_camera_hints(plane, hints):
    """Make the view's camera one to compute (``hints``: its camera object, at least
    "kind"), or the nominal orthographic one (``hints`` empty); a known camera is dropped."""
    props = plane.headrecon
    props.camera_json = ""
    data = json.loads(props.view_json) if props.view_json else {}
    data.pop("camera", None)
    if hints:
        data["camera"] = dict(hints)
    props.view_json = json.dumps(data) if data else ""


def mirror_of(plane):
    """The view whose photo this view is the mirror image in, or None."""
    props = plane.headrecon
    return json.loads(props.view_json).get("mirror_of") if props.view_json else None


def set_mirror_of(plane, view):
    """Make the plane's view the mirror image inside ``view``'s photo (None: seen
    directly). Stored as the file's ``mirror_of``; whether the views agree (same photo, a
    mirrored or to-compute camera) is checked where the case is read (export, fit)."""
    props = plane.headrecon
    data = json.loads(props.view_json) if props.view_json else {}
    if view:
        data["mirror_of"] = str(view)
    else:
        data.pop("mirror_of", None)
    props.view_json = json.dumps(data) if data else ""


def camera_kind(plane):
    """Kind of the view's camera ("orthographic", "dlt", "pinhole"), known or not."""
    props = plane.headrecon
    if props.camera_json:
        return json.loads(props.camera_json).get("kind", "orthographic")
    return camera_hints(plane).get("kind", "orthographic")


def is_perspective(plane):
    """Whether the plane's photo is seen by a perspective camera (a Blender camera)."""
    return camera_kind(plane) in photo_cameras.PERSPECTIVE_KINDS


def lens_hint(plane):
    """The focal length (mm, 36 mm equivalent) known for a pinhole view, or None."""
    props = plane.headrecon
    if props.camera_json:
        return json.loads(props.camera_json).get("lens_mm")
    return camera_hints(plane).get("lens_mm")


def plane_camera(plane):
    """The camera of a plane's view: the stored parameters, the nominal orthographic
    camera of its ``camera_view`` for its image size, or None when it is to be computed."""
    (w, h), _ = plane_size(plane)
    props = plane.headrecon
    if props.camera_json:
        return camera_from_json(json.loads(props.camera_json), (w, h))
    if camera_hints(plane):
        return None
    return OrthographicCamera.nominal(props.camera_view, (w, h))


def set_plane_camera(plane, camera):
    """Remember ``camera`` as the plane's view camera (nominal ones are kept by name)."""
    (w, h), _ = plane_size(plane)
    as_json = camera_to_json(camera, (w, h))
    if isinstance(as_json, str):
        plane.headrecon.camera_view = as_json
        plane.headrecon.camera_json = ""
    else:
        plane.headrecon.camera_json = json.dumps(as_json)
        plane.headrecon.camera_view = nearest_view(camera)


def store_fitted_camera(plane, camera):
    """Remember a fit's camera as the view's known parameters, so an export writes them and
    a later fit starts from them. ``calibrated`` stays as the view had it (absent or false:
    a starting guess the next fit refines); ``camera_view`` stays too (it names the
    landmarks the view shows, which a fit does not change)."""
    (w, h), _ = plane_size(plane)
    as_json = camera_to_json(camera, (w, h))
    if not isinstance(as_json, str):
        plane.headrecon.camera_json = json.dumps(as_json)


def nearest_view(camera, name=""):
    """The nominal orthographic view whose viewing direction is closest to the camera's;
    for a camera not known yet (None), a guess from the view's name."""
    rot = getattr(camera, "rotation", None)
    if rot is None:
        low = name.lower()
        if "left" in low:
            return "orthographic-left"
        if any(w in low for w in ("right", "side", "profile")):
            return "orthographic-right"
        return "orthographic-front"
    d = np.asarray(rot, dtype=np.float64)[2]
    return max(ORTHO_VIEWS, key=lambda k: float(ORTHO_VIEWS[k][2] @ d))


def camera_label(plane):
    """A short description of a view's camera for the panel, e.g. "Front (orthographic)",
    "Pinhole 50 mm, to compute", "DLT, calibrated", "mirror of front"."""
    props = plane.headrecon
    kind = camera_kind(plane)
    extra = json.loads(props.view_json) if props.view_json else {}
    if kind == "orthographic":
        text = {"orthographic-front": "Front", "orthographic-right": "Right profile",
                "orthographic-left": "Left profile"}[props.camera_view] + " (orthographic)"
        yaw = turned_yaw(plane)
        if yaw is not None:
            text += f", seen from {yaw:+.0f} deg"
    else:
        text = "Pinhole" if kind == "pinhole" else kind.upper()
        lens = lens_hint(plane)
        if lens:
            text += f" {float(lens):.0f} mm"
        if not props.camera_json:
            text += ", to compute"
    if extra.get("calibrated") is True:
        text += ", calibrated"
    if extra.get("mirror_of"):
        text += f", mirror of {extra['mirror_of']}"
    return text


def turned_yaw(plane):
    """The yaw (degrees from the face's front, toward the subject's right) a known
    orthographic camera of the view looks from where it is turned from its view's nominal
    direction (a detection placed it so: ``turn_nominal_camera``), else None."""
    props = plane.headrecon
    if not props.camera_json or camera_kind(plane) != "orthographic":
        return None
    d = plane_camera(plane).rotation[2]
    yaw = float(np.degrees(np.arctan2(d[0], d[1])))
    return yaw if abs(yaw - VIEW_YAW_DEG[props.camera_view]) > 0.5 else None


def view_kind(plane):
    """'front', 'right' or 'left': which side of the head the plane's photo shows (the
    ``views`` of assets/landmarks.json)."""
    return VIEW_KINDS[plane.headrecon.camera_view]


def plane_matrix(plane, camera=None, depth=PLANE_DEPTH, centre=(0.0, 0.0, 0.0)):
    """World matrix that lines the plane up with ``camera`` (default: the plane's own).

    Parameters
    ----------
    camera : OrthographicCamera, optional
        Any other camera kind is placed by its nominal view.
    depth : float, metres
        Distance behind ``centre`` along the viewing direction.
    centre : (3,) metres
        The head's centre.
    """
    (w, h), big_h = plane_size(plane)
    cam = plane_camera(plane) if camera is None else camera
    if not isinstance(cam, OrthographicCamera):
        cam = OrthographicCamera.nominal(plane.headrecon.camera_view, (w, h))
    rot = cam.rotation
    s = cam.scale
    k = (h / big_h) / s
    m = np.eye(4)
    m[:3, 0] = k * rot[0]
    m[:3, 1] = -k * rot[1]
    m[:3, 2] = -k * rot[2]
    d = float(np.asarray(centre, dtype=np.float64) @ rot[2]) + depth
    m[:3, 3] = (rot[0] * (w / 2.0 - cam.offset[0]) / s + rot[1] * (h / 2.0 - cam.offset[1]) / s
                + rot[2] * d)
    return Matrix(m.tolist())


def camera_object(plane):
    """The Blender camera of a perspective plane's photo (its parent), or None."""
    parent = plane.parent
    return parent if photo_cameras.is_camera_object(parent) else None


def view_root(plane):
    """The top object of a view: its Blender camera for a perspective photo, else the
    plane (link or remove this and everything under it)."""
    return camera_object(plane) or plane


def view_objects(plane):
    """Every object of a view: camera (if any), plane, landmarks, passpoints, contour."""
    root = view_root(plane)
    return [root, *root.children_recursive]


def provisional_camera(plane, centre=(0.0, 0.0, 0.0)):
    """The stand-in camera of a perspective view whose camera is not known yet: from the
    view's nominal direction, with the file's focal length if it gives one."""
    (w, h), _ = plane_size(plane)
    direction = ORTHO_VIEWS[plane.headrecon.camera_view][2]
    return photo_cameras.provisional_camera((w, h), direction, centre, lens_hint(plane))


def place_plane(plane, camera=None, centre=(0.0, 0.0, 0.0)):
    """Stand the plane where ``camera`` (default: the view's own, or for a camera still to
    be computed a provisional one) sees it: in the world for an orthographic photo, under
    the photo's Blender camera (made when missing) for a perspective one.

    Parameters
    ----------
    camera : Camera, optional
        Shown as the view's camera; it is not stored as the view's (``set_plane_camera``).
    centre : (3,) metres
        The head's centre: the plane stands PLANE_DEPTH behind it.

    Returns
    -------
    list of str
        What the Blender camera could not show (skew, lens distortion dropped).

    Raises
    ------
    ValueError
        A camera Blender cannot show (e.g. a non-positive focal length).
    """
    if not is_perspective(plane):
        cam_obj = camera_object(plane)
        if cam_obj is not None:  # was perspective: the Blender camera goes
            plane.parent = None
            remove_objects([cam_obj])
        plane.matrix_world = plane_matrix(plane, camera, centre=centre)
        return []
    cam = camera if camera is not None else plane_camera(plane)
    if cam is None:
        cam = provisional_camera(plane, centre)
    (w, h), big_h = plane_size(plane)
    settings = photo_cameras.blender_settings(cam)
    obj = camera_object(plane)
    if obj is None:
        obj = photo_cameras.new_camera_object(f"HeadRecon Camera {plane.headrecon.view}")
        scene_collections.link_like(obj, plane)
    photo_cameras.apply_settings(obj, settings)
    photo_cameras.set_background(obj, plane.headrecon.image)
    depth = photo_cameras.camera_depth(obj, centre) + PLANE_DEPTH
    photo_cameras.attach_plane(plane, obj, (w, h), big_h, depth)
    return list(settings["warnings"])


def refresh_plane(plane):
    """Fit a perspective plane to its camera again (after its photo or the camera object's
    settings changed), at the same distance. Orthographic planes need nothing."""
    obj = camera_object(plane)
    if obj is None:
        return
    (w, h), big_h = plane_size(plane)
    photo_cameras.set_background(obj, plane.headrecon.image)
    photo_cameras.attach_plane(plane, obj, (w, h), big_h, photo_cameras.plane_depth(plane))


def new_photo_plane(image, view, camera_view="orthographic-front", camera=None,
                    name=None, centre=(0.0, 0.0, 0.0), hints=None, shown=None):
    """A photo plane object for ``image`` and, for a perspective photo, its Blender camera
    (not linked to any scene: the caller links ``view_root(plane)`` once everything it
    builds has succeeded).

    Parameters
    ----------
    image : bpy.types.Image
    view : str
        View name in the landmarks file ("front", "side", ...).
    camera_view : str
        Nominal view ("orthographic-front" | "-right" | "-left"): the camera of an
        orthographic photo without parameters, the direction of a provisional camera.
    camera : Camera, optional
        Explicit camera (from a landmarks file); default the nominal one.
    hints : dict, optional
        The view's camera is to be computed: its camera object (``{"kind": "pinhole",
        "lens_mm": 50}``); ``camera`` is then not given.
    shown : Camera, optional
        For a camera to be computed: the camera to show until a fit places it (e.g. a DLT
        from the view's passpoints); default a provisional one (``provisional_camera``).
    """
    w, h = image.size
    if w == 0 or h == 0:
        raise ValueError(f"image {image.name!r}: has no pixels (file missing or unreadable?)")
    name = name or f"HeadRecon Photo {view}"
    mesh = bpy.data.meshes.new(name)
    obj = bpy.data.objects.new(name, mesh)
    try:
        props = obj.headrecon
        props.role = "PHOTO"
        props.view = view
        props.camera_view = camera_view
        props.image_size = (w, h)
        props.image = image
        if camera is not None:
            set_plane_camera(obj, camera)
        elif hints:
            set_camera_hints(obj, hints)
        # Orthographic: the plane is the photo at the camera's scale; any other camera:
        # the nominal plane, scaled into the camera's frustum by its object matrix.
        scale = camera.scale if isinstance(camera, OrthographicCamera) else \
            OrthographicCamera.nominal(camera_view, (w, h)).scale
        props.plane_height = h / scale
        _set_plane_mesh(mesh, w, h, props.plane_height)
        mesh.materials.append(material.photo_material(image, name))
        place_plane(obj, shown if camera is None else None, centre=centre)
        obj.hide_render = True  # a reference, not part of the render
        if hasattr(obj, "visible_shadow"):
            obj.visible_shadow = False
        obj.show_wire = False
    except Exception:
        remove_objects(view_objects(obj))
        raise
    return obj


def set_plane_image(plane, image):
    """Swap the plane's photo; its landmarks and contour stay (same place relative to the
    photo's centre and height). A stored explicit camera is dropped when the size changes
    (it was calibrated for the old photo): a perspective view keeps its kind (and a
    pinhole's focal length, which is in 36 mm equivalent) as a camera to compute."""
    w, h = image.size
    if w == 0 or h == 0:
        raise ValueError(f"image {image.name!r}: has no pixels (file missing or unreadable?)")
    props = plane.headrecon
    old = tuple(props.image_size)
    if old != (w, h):  # a camera (or camera hints) of the old photo says nothing of this one
        kind, lens = camera_kind(plane), lens_hint(plane)
        hints = {}
        if kind in photo_cameras.PERSPECTIVE_KINDS:
            hints = {"kind": kind, **({"lens_mm": lens} if kind == "pinhole" and lens else {})}
        set_camera_hints(plane, hints)
    props.image = image
    props.image_size = (w, h)
    _set_plane_mesh(plane.data, w, h, props.plane_height)
    mat = plane.data.materials[0] if len(plane.data.materials) else None
    if mat is not None and material.photo_image(mat) is not None:
        material.set_photo_image(mat, image)
    else:
        new = material.photo_material(image, plane.name)
        if mat is None:
            plane.data.materials.append(new)
        else:
            plane.data.materials[0] = new
    refresh_plane(plane)


def remove_objects(objects):
    """Delete objects and the meshes/curves/cameras only they used (for clean failure
    paths)."""
    for obj in list(objects):
        if obj is None:
            continue
        try:
            data = obj.data
        except ReferenceError:
            continue
        bpy.data.objects.remove(obj, do_unlink=True)
        if data is not None and data.users == 0:
            if isinstance(data, bpy.types.Mesh):
                mats = [m for m in data.materials if m is not None]
                bpy.data.meshes.remove(data)
                for m in mats:
                    if m.users == 0:
                        bpy.data.materials.remove(m)
            elif isinstance(data, bpy.types.Curve):
                bpy.data.curves.remove(data)
            elif isinstance(data, bpy.types.Camera):
                bpy.data.cameras.remove(data)


def free_view_name(scene, base):
    """``base`` if no photo has that view name, else ``base2``, ``base3``, ..."""
    taken = {p.headrecon.view for p in photo_planes(scene)}
    if base not in taken:
        return base
    return next(f"{base}{i}" for i in range(2, len(taken) + 3) if f"{base}{i}" not in taken)


def on_camera_view(plane, scene):
    """The artist turned a view's nominal direction (e.g. right -> left profile): stand an
    orthographic photo there, or move a provisional camera there, and hold a camera to
    compute near it (its ``direction_prior``, where it has one). Known cameras stay."""
    if plane.headrecon.camera_json or plane.headrecon.image_size[1] <= 0:
        return
    hold_camera_near(plane, VIEW_YAW_DEG[plane.headrecon.camera_view])
    place_plane(plane, centre=head_centre(scene))


def held_near(hints, yaw_deg):
    """Camera hints (the file's camera object of a camera to compute) held near ``yaw_deg``
    (degrees from the face's front, toward the subject's right) where they hold the camera
    near a direction (``direction_prior``, a photo loaded with its EXIF lens); else the
    hints as they are. No bpy: Auto Fit's merged case uses it in any thread."""
    if not isinstance(hints, dict) or not hints.get("direction_prior"):
        return hints
    return {**hints, "direction_prior": [float(yaw_deg), hints["direction_prior"][1]]}


def hold_camera_near(plane, yaw_deg):
    """The plane's camera to compute held near ``yaw_deg`` from now on (``held_near``);
    other cameras are left as they are."""
    hints = camera_hints(plane)
    if hints.get("direction_prior"):
        set_camera_hints(plane, held_near(hints, yaw_deg))


def has_nominal_camera(plane):
    """Whether the view's camera is the nominal orthographic one of its ``camera_view``
    (neither known nor to compute)."""
    return not (plane.headrecon.camera_json or camera_hints(plane))


def turn_nominal_camera(plane, camera, centre=(0.0, 0.0, 0.0)):
    """Make ``camera`` the view's and stand the plane there, where the view's camera is
    the nominal orthographic one (a photo turned to the yaw its face was seen from, as
    ``detect_job`` places it); a known camera or one to compute stays."""
    if not has_nominal_camera(plane):
        return
    set_plane_camera(plane, camera)
    place_plane(plane, centre=centre)


def turned_view_camera(value, camera, size):
    """The landmarks file's camera of a view (``value``) with ``turn_nominal_camera``'s rule:
    ``camera``'s parameters where ``value`` names the nominal view, else ``value``. No bpy
    (Auto Fit's merged case uses it in any thread)."""
    return camera_to_json(camera, size) if isinstance(value, str) else value


# --------------------------------------------------------------------------------------
# Operators


PROJECTIONS = (
    ("FROM_EXIF", "From the Photo",
     "A photo whose EXIF gives its lens is perspective, its camera held near its direction "
     "(a camera's photo from a few metres or nearer: a parallel projection would distort "
     "the head); one without, orthographic"),
    ("ORTHOGRAPHIC", "Orthographic",
     "A front or profile photo taken from far away (long lens): parallel projection"),
    ("PERSPECTIVE", "Perspective",
     "A photo from any camera at any angle: the fit computes (self-calibrates) its camera"),
)


AUTO = "AUTO"  # the operator's direction: each photo's from its name and shape


class HEADRECON_OT_load_photo(ObjectModeOperator, bpy.types.Operator):
    """Choose photos: each becomes an image plane behind the head, or for a perspective
    photo a camera looking at the head with the photo in its view; several photos are
    sorted into views (front, profile) by their names and shapes; photos are turned
    upright as their EXIF says and a perspective photo takes its focal length from it (a
    photo already in its view is swapped and its landmarks stay)"""

    bl_idname = "headrecon.load_photo"
    bl_label = "Load Photos"
    bl_options = {"REGISTER", "UNDO"}

    filepath: bpy.props.StringProperty(subtype="FILE_PATH", options={"SKIP_SAVE"},
                                       description="The photo file")
    files: bpy.props.CollectionProperty(type=bpy.types.OperatorFileListElement,
                                        options={"HIDDEN", "SKIP_SAVE"})
    directory: bpy.props.StringProperty(subtype="DIR_PATH", options={"HIDDEN", "SKIP_SAVE"})
    filter_image: bpy.props.BoolProperty(default=True, options={"HIDDEN", "SKIP_SAVE"})
    filter_folder: bpy.props.BoolProperty(default=True, options={"HIDDEN", "SKIP_SAVE"})
    view: bpy.props.StringProperty(
        name="View", default="", options={"SKIP_SAVE"},
        description="View name in the landmarks file (empty, or several photos: each a new "
                    "view, named after its camera)")
    projection: bpy.props.EnumProperty(name="Projection", items=PROJECTIONS,
                                       default="FROM_EXIF",
                                       description="How the photos were taken: with the "
                                                   "lens their EXIF gives, from far away "
                                                   "(orthographic) or by any camera")
    camera_view: bpy.props.EnumProperty(
        name="Direction", items=(
            (AUTO, "From the Photos",
             "Each photo's direction from its file name (front, side, profile, right, "
             "left), else its shape: the narrowest is the front, the widest the profile"),
            ("orthographic-front", "Front", "Photo taken from the front"),
            ("orthographic-right", "Right Profile", "The subject's right side"),
            ("orthographic-left", "Left Profile", "The subject's left side")),
        default="orthographic-front",
        description="Where the camera stood (for a perspective photo: roughly; the fit "
                    "finds the camera)")
    lens_mm: bpy.props.FloatProperty(
        name="Focal Length", default=0.0, min=0.0, soft_max=300.0, unit="CAMERA",
        description="Perspective photo: the lens's focal length in mm, full-frame (36 mm) "
                    "equivalent (0: from the photo's EXIF data, else unknown)")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(self, "view")
        layout.prop(self, "projection")
        layout.prop(self, "camera_view")
        row = layout.row()
        row.enabled = self.projection != "ORTHOGRAPHIC"
        row.prop(self, "lens_mm")

    def _paths(self):
        names = sorted(f.name for f in self.files if f.name)
        if names and self.directory:
            folder = Path(bpy.path.abspath(self.directory))
            return [str(folder / n) for n in names]
        return [bpy.path.abspath(self.filepath)]

    def _hints(self, photo, direction):
        """The camera to compute for a perspective photo, with the operator's focal length
        or else the EXIF's; and whether the EXIF's was taken. "From the Photo": a photo
        whose EXIF gives its lens gets ``lens_hints`` (held near ``direction``), one
        without none (orthographic)."""
        if self.projection == "FROM_EXIF":
            lens = self.lens_mm if self.lens_mm > 0 else photo.lens_mm()
            if not lens:
                return {}, False
            return lens_hints(lens, VIEW_YAW_DEG[direction]), self.lens_mm <= 0
        if self.projection != "PERSPECTIVE":
            return {}, False
        lens, exif = self.lens_mm, False
        if lens <= 0:
            lens, exif = photo.lens_mm() or 0.0, True
        return {"kind": "pinhole", **({"lens_mm": lens} if lens > 0 else {})}, exif and lens > 0

    def _directions(self, scene, paths, loaded):
        if self.camera_view != AUTO:
            return [self.camera_view] * len(paths)
        existing = find_plane(scene, self.view.strip()) if len(paths) == 1 else None
        if existing is not None:
            return [existing.headrecon.camera_view]
        taken = {p.headrecon.camera_view for p in photo_planes(scene)}
        return sort_photos([(Path(p).name, tuple(ph.image.size))
                            for p, ph in zip(paths, loaded, strict=True)], taken,
                           face_direction=lambda i: photo_faces.face_direction(
                               detector_pixels(loaded[i].image)))

    def execute(self, context):
        from .data import Transaction

        scene = context.scene
        paths = self._paths()
        done = []
        try:
            with Transaction():
                loaded = [load_photo(p) for p in paths]
                directions = self._directions(scene, paths, loaded)
                for photo, direction in zip(loaded, directions, strict=True):
                    done.append(self._place(scene, photo, direction, len(paths) == 1))
        except ValueError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        for photo in loaded:
            if photo.problem:
                self.report({"WARNING"}, photo.problem)
        self.report({"INFO"}, "; ".join(done))
        warm_up(scene.headrecon.texture_size)
        return {"FINISHED"}

    def _place(self, scene, photo, direction, single):
        """Put one loaded photo into its view (a new one, or the view named); returns a
        line saying where it went."""
        image = photo.image
        hints, from_exif = self._hints(photo, direction)
        view = (self.view.strip() if single else "") or free_view_name(
            scene, "photo" if self.projection == "PERSPECTIVE"
            else VIEW_KINDS[direction].replace("right", "side"))
        plane = find_plane(scene, view)
        if plane is not None:
            set_plane_image(plane, image)
            self._retarget(plane, hints, scene, direction)
        else:
            plane = new_photo_plane(image, view, direction, hints=hints,
                                    centre=head_centre(scene))
            scene_collections.link_tree(scene, view_root(plane))
        plane.headrecon.lens_from_exif = from_exif and lens_hint(plane) is not None
        lens = f", {hints['lens_mm']:.0f} mm{' (EXIF)' if from_exif else ''}" \
            if "lens_mm" in hints else ""
        return f"{view}: {image.name} ({image.size[0]}x{image.size[1]}{lens})"

    def _retarget(self, plane, hints, scene, direction):
        """A swapped photo's camera as asked: another projection or direction makes the
        view's camera one to compute again; a known camera of the same kind stays."""
        props = plane.headrecon
        same = bool(hints) == is_perspective(plane)
        if same and (props.camera_json or props.camera_view == direction):
            if hints and "lens_mm" in hints and camera_hints(plane):
                set_camera_hints(plane, {**camera_hints(plane), **hints})
                place_plane(plane, centre=head_centre(scene))
            return
        set_camera_hints(plane, hints)
        props.camera_view = direction
        place_plane(plane, centre=head_centre(scene))


def set_lens_hint(plane, lens_mm, scene=None):
    """The artist's focal length (mm, 36 mm equivalent; 0: unknown) for a pinhole photo:
    its camera becomes one to compute from this focal length (a fitted camera too), and
    the provisional camera shows it. Other cameras take none."""
    if camera_kind(plane) != "pinhole":
        return
    hints = {k: v for k, v in camera_hints(plane).items() if k != "lens_mm"}
    hints["kind"] = "pinhole"
    if lens_mm > 0:
        hints["lens_mm"] = float(lens_mm)
    set_camera_hints(plane, hints)
    plane.headrecon.lens_from_exif = False
    place_plane(plane, centre=head_centre(scene or bpy.context.scene))


def head_centre(scene):
    head = scene.headrecon.head
    if head is None:
        return (0.0, 0.0, 0.0)
    from mathutils import Vector

    corners = np.array([head.matrix_world @ Vector(c) for c in head.bound_box])
    return tuple(corners.mean(axis=0))


def look_through(context, plane):
    """Show the head through this photo's camera in the context's 3D viewport: the camera
    view of a perspective photo (its Blender camera becomes the scene's, with the photo's
    resolution), an orthographic view down the camera axis otherwise."""
    rv3d = context.space_data.region_3d  # the viewport's, also from a sidebar button
    obj = camera_object(plane)
    if obj is not None:
        photo_cameras.look_through(context.scene, obj, plane_size(plane)[0])
        rv3d.view_perspective = "CAMERA"
        rv3d.view_camera_zoom = 0.0
        rv3d.view_camera_offset = (0.0, 0.0)
        return
    loc, rot, _ = plane.matrix_world.decompose()
    rv3d.view_perspective = "ORTHO"
    rv3d.view_rotation = rot
    rv3d.view_location = loc
    rv3d.view_distance = float(plane.headrecon.plane_height) * max(plane.scale) * 1.1


class HEADRECON_OT_view_photo(bpy.types.Operator):
    """Look at the head through this photo's camera, to place landmarks"""

    bl_idname = "headrecon.view_photo"
    bl_label = "View Photo"
    bl_options = {"REGISTER"}

    view: bpy.props.StringProperty(name="View", description="Photo view name to look through")

    @classmethod
    def poll(cls, context):
        return poll_result(cls, view3d_problem(context))

    def execute(self, context):
        plane = find_plane(context.scene, self.view)
        if plane is None:
            self.report({"ERROR"}, f"No photo for view {self.view!r}")
            return {"CANCELLED"}
        look_through(context, plane)
        return {"FINISHED"}


CLASSES = (HEADRECON_OT_load_photo, HEADRECON_OT_view_photo)
