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
camera exactly to its (u, v): the photo lines up with the fitted head.
"""

from pathlib import Path

import bpy
import numpy as np
from mathutils import Matrix

from . import material
from .polls import ObjectModeOperator, poll_result, view3d_problem
from .solver_link import ORTHO_VIEWS, OrthographicCamera, camera_from_json, camera_to_json

PLACEHOLDER = "headrecon_placeholder"  # custom property on stand-in images (no photo)
PLANE_DEPTH = 0.3  # metres behind the head's centre, along the camera's viewing direction
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


def load_image(path):
    """Load a photo (reusing an already loaded one of the same file).

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
    return img


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


def plane_camera(plane):
    """The camera of a plane's view: the stored parameters, or the nominal orthographic
    camera of its ``camera_view`` for its image size."""
    (w, h), _ = plane_size(plane)
    props = plane.headrecon
    if props.camera_json:
        import json

        return camera_from_json(json.loads(props.camera_json), (w, h))
    return OrthographicCamera.nominal(props.camera_view, (w, h))


def set_plane_camera(plane, camera):
    """Remember ``camera`` as the plane's view camera (nominal ones are kept by name)."""
    import json

    (w, h), _ = plane_size(plane)
    as_json = camera_to_json(camera, (w, h))
    if isinstance(as_json, str):
        plane.headrecon.camera_view = as_json
        plane.headrecon.camera_json = ""
    else:
        plane.headrecon.camera_json = json.dumps(as_json)
        plane.headrecon.camera_view = nearest_view(camera)


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


def new_photo_plane(image, view, camera_view="orthographic-front", camera=None,
                    name=None, centre=(0.0, 0.0, 0.0)):
    """A photo plane object for ``image`` (not linked to any scene: the caller links it
    once everything it builds has succeeded).

    Parameters
    ----------
    image : bpy.types.Image
    view : str
        View name in the landmarks file ("front", "side", ...).
    camera_view : str
        Nominal view ("orthographic-front" | "-right" | "-left").
    camera : Camera, optional
        Explicit camera (from a landmarks file); default the nominal one.
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
        nominal = OrthographicCamera.nominal(camera_view, (w, h))
        if camera is not None:
            set_plane_camera(obj, camera)
        cam = camera if isinstance(camera, OrthographicCamera) else nominal
        props.plane_height = h / cam.scale
        _set_plane_mesh(mesh, w, h, props.plane_height)
        mesh.materials.append(material.photo_material(image, name))
        obj.matrix_world = plane_matrix(obj, centre=centre)
        obj.hide_render = True  # a reference, not part of the render
        if hasattr(obj, "visible_shadow"):
            obj.visible_shadow = False
        obj.show_wire = False
    except Exception:
        remove_objects([obj])
        raise
    return obj


def set_plane_image(plane, image):
    """Swap the plane's photo; its landmarks and contour stay (same place relative to the
    photo's centre and height). A stored explicit camera is dropped when the size changes
    (it was calibrated for the old photo)."""
    w, h = image.size
    if w == 0 or h == 0:
        raise ValueError(f"image {image.name!r}: has no pixels (file missing or unreadable?)")
    props = plane.headrecon
    old = tuple(props.image_size)
    props.image = image
    props.image_size = (w, h)
    if old != (w, h):  # a camera (or camera hints) of the old photo says nothing of this one
        props.camera_json = ""
        if props.view_json:
            import json

            data = json.loads(props.view_json)
            data.pop("camera", None)
            props.view_json = json.dumps(data)
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


def remove_objects(objects):
    """Delete objects and the meshes/curves only they used (for clean failure paths)."""
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


def link_object(obj, collection):
    """Link ``obj`` and its children (recursively) into ``collection``."""
    if obj.name not in collection.objects:
        collection.objects.link(obj)
    for child in obj.children:
        link_object(child, collection)


# --------------------------------------------------------------------------------------
# Operators


class HEADRECON_OT_load_photo(ObjectModeOperator, bpy.types.Operator):
    """Choose a photo for this view: it becomes an image plane behind the head (a photo
    already there is swapped and its landmarks stay)"""

    bl_idname = "headrecon.load_photo"
    bl_label = "Load Photo"
    bl_options = {"REGISTER", "UNDO"}

    filepath: bpy.props.StringProperty(subtype="FILE_PATH", options={"SKIP_SAVE"})
    filter_image: bpy.props.BoolProperty(default=True, options={"HIDDEN", "SKIP_SAVE"})
    filter_folder: bpy.props.BoolProperty(default=True, options={"HIDDEN", "SKIP_SAVE"})
    view: bpy.props.StringProperty(name="View", default="front",
                                   description="View name in the landmarks file")
    camera_view: bpy.props.EnumProperty(name="Camera", items=(
        ("orthographic-front", "Front", "Photo taken from the front"),
        ("orthographic-right", "Right Profile", "The subject's right side"),
        ("orthographic-left", "Left Profile", "The subject's left side")))

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        from .data import Transaction

        if not self.view.strip():
            self.report({"ERROR"}, "The view needs a name (e.g. 'front')")
            return {"CANCELLED"}
        scene = context.scene
        try:
            with Transaction():
                image = load_image(bpy.path.abspath(self.filepath))
                plane = find_plane(scene, self.view)
                if plane is not None:
                    set_plane_image(plane, image)
                    if plane.headrecon.camera_view != self.camera_view \
                            and not plane.headrecon.camera_json:
                        plane.headrecon.camera_view = self.camera_view
                        plane.matrix_world = plane_matrix(plane, centre=head_centre(scene))
                else:
                    plane = new_photo_plane(image, self.view, self.camera_view,
                                            centre=head_centre(scene))
                    link_object(plane, context.collection)
        except ValueError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        self.report({"INFO"}, f"{self.view}: {image.name} ({image.size[0]}x{image.size[1]})")
        from .fit_ops import warm_up

        warm_up(scene.headrecon.texture_size)
        return {"FINISHED"}


def head_centre(scene):
    head = scene.headrecon.head
    if head is None:
        return (0.0, 0.0, 0.0)
    from mathutils import Vector

    corners = np.array([head.matrix_world @ Vector(c) for c in head.bound_box])
    return tuple(corners.mean(axis=0))


class HEADRECON_OT_view_photo(bpy.types.Operator):
    """Look at the head through this photo's camera (orthographic), to place landmarks"""

    bl_idname = "headrecon.view_photo"
    bl_label = "View Photo"
    bl_options = {"REGISTER"}

    view: bpy.props.StringProperty(name="View")

    @classmethod
    def poll(cls, context):
        return poll_result(cls, view3d_problem(context))

    def execute(self, context):
        plane = find_plane(context.scene, self.view)
        if plane is None:
            self.report({"ERROR"}, f"No photo for view {self.view!r}")
            return {"CANCELLED"}
        rv3d = context.space_data.region_3d  # the viewport's, also from a sidebar button
        loc, rot, _ = plane.matrix_world.decompose()
        rv3d.view_perspective = "ORTHO"
        rv3d.view_rotation = rot
        rv3d.view_location = loc
        rv3d.view_distance = float(plane.headrecon.plane_height) * max(plane.scale) * 1.1
        return {"FINISHED"}


CLASSES = (HEADRECON_OT_load_photo, HEADRECON_OT_view_photo)
