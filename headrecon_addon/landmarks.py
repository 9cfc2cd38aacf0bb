"""Landmarks, passpoints and the traced outline on the photo planes; import and export of
the landmarks file; the place-landmarks and draw-contour tools.

A landmark is a small sphere parented to its photo plane (so it moves with the plane, can
be grabbed, undone and is saved in the .blend), its position in plane space being the one
source of truth for its pixel coordinates (see photos.py). A passpoint (where a point of a
calibration object, whose 3-D position the file gives, is seen) is the same kind of marker
in another colour and role. The contour is a poly curve parented to the plane the same way.
The file format is the solver's: reading and writing go through ``solver/landmarks_file.py``
only.

Modal operators cannot run in background tests, so their logic lives in plain functions
and in ``PlacementSession`` / ``ContourSession``; the operators only translate events.
"""

import json
import os
from pathlib import Path

import bmesh
import bpy
import numpy as np
from bpy.props import StringProperty
from bpy_extras.io_utils import ExportHelper, ImportHelper
from mathutils import Vector

from . import material, photos
from .data import Transaction
from .polls import ObjectModeOperator, object_mode_problem, poll_result, view3d_problem
from .solver_link import (
    fit_dlt,
    landmarks_file,
    load_landmark_set,
    load_landmarks,
    save_landmarks,
)

MARKER_RADIUS = 0.0025  # metres (plane space): about 7 px on a 1024 px photo
LIFT = 0.001  # landmarks and contour float this far in front of the photo (plane +z)
MARKER_MESH = "HeadRecon Landmark Marker"
PIXEL_DECIMALS = 3


# --------------------------------------------------------------------------------------
# The landmark set


def landmark_set():
    """The known landmarks (``assets/landmarks.json`` through the solver)."""
    return load_landmark_set()


def landmark_definitions(kind):
    """Entries of assets/landmarks.json visible in a view of ``kind`` ('front', 'right',
    'left'), in file order: dicts with name, description, vertex, views, ibug, thesis."""
    return [e for e in landmark_set().info if kind in e.get("views", ())]


def canonical_name(name):
    """Canonical landmark name (``ibugNN`` aliases resolved; unknown names unchanged)."""
    return landmark_set().canonical(name) or name


# --------------------------------------------------------------------------------------
# Landmark objects


def _marker_mesh():
    mesh = bpy.data.meshes.get(MARKER_MESH)
    if mesh is not None and mesh.library is None:
        return mesh
    mesh = bpy.data.meshes.new(MARKER_MESH)
    bm = bmesh.new()
    try:
        bmesh.ops.create_icosphere(bm, subdivisions=2, radius=MARKER_RADIUS)
        bm.to_mesh(mesh)
    finally:
        bm.free()
    mesh.materials.append(material.landmark_material("PLACED"))
    return mesh


MARKER_ROLES = ("LANDMARK", "PASSPOINT")


def is_landmark(obj):
    return obj is not None and obj.headrecon.role == "LANDMARK"


def marker_objects(plane, role="LANDMARK"):
    """Markers of a photo plane with ``role`` ("LANDMARK" or "PASSPOINT"): dict name ->
    object (creation order)."""
    return {c.headrecon.landmark: c for c in plane.children if c.headrecon.role == role}


def landmark_objects(plane):
    """Landmarks of a photo plane: dict name -> object (creation order)."""
    return marker_objects(plane, "LANDMARK")


def passpoint_objects(plane):
    """Passpoints of a photo plane: dict name -> object (creation order)."""
    return marker_objects(plane, "PASSPOINT")


def _link_like(obj, plane):
    for coll in plane.users_collection:
        if obj.name not in coll.objects:
            coll.objects.link(obj)


def set_landmark_state(obj, flagged, residual_px=-1.0):
    """Colour a marker as placed (landmarks green, passpoints blue) or flagged (red)."""
    obj.headrecon.flagged = bool(flagged)
    obj.headrecon.residual_px = float(residual_px)
    base = "PASSPOINT" if obj.headrecon.role == "PASSPOINT" else "PLACED"
    state = "FLAGGED" if flagged else base
    obj.material_slots[0].material = material.landmark_material(state)
    obj.color = material.LANDMARK_COLOURS[state]


def place_marker_local(plane, name, xy, role="LANDMARK"):
    """Put marker ``name`` of ``role`` at plane-space (x, y) (creates it or moves it).
    Landmark names are made canonical. Returns the object."""
    if role == "LANDMARK":
        name = canonical_name(name)
    obj = marker_objects(plane, role).get(name)
    if obj is None:
        view = plane.headrecon.view
        label = name if role == "LANDMARK" else f"passpoint {name}"
        obj = bpy.data.objects.new(f"HR {view} {label}", _marker_mesh())
        obj.headrecon.role = role
        obj.headrecon.view = view
        obj.headrecon.landmark = name
        obj.parent = plane
        obj.matrix_parent_inverse.identity()
        obj.material_slots[0].link = "OBJECT"
        set_landmark_state(obj, False)
        obj.show_in_front = True
        obj.hide_render = True
        obj.lock_location[2] = True  # grabbing keeps it on the photo
        _link_like(obj, plane)
    obj.location = (float(xy[0]), float(xy[1]), LIFT)
    return obj


def place_landmark_local(plane, name, xy):
    """Put landmark ``name`` at plane-space (x, y) (creates it or moves it). Returns it."""
    return place_marker_local(plane, name, xy, "LANDMARK")


def place_landmark(plane, name, uv, role="LANDMARK"):
    """Put landmark (or passpoint, ``role``) ``name`` at pixel ``uv`` = (u, v) of the
    plane's photo. Returns it."""
    xy = photos.local_from_pixels(plane, [uv])[0]
    return place_marker_local(plane, name, xy, role)


def remove_landmark(plane, name, role="LANDMARK"):
    """Unplace landmark (or passpoint) ``name`` (no error if it was not placed). Returns
    True if removed."""
    key = canonical_name(name) if role == "LANDMARK" else name
    obj = marker_objects(plane, role).get(key)
    if obj is None:
        return False
    bpy.data.objects.remove(obj, do_unlink=True)
    return True


def clear_landmarks(plane):
    """Remove every landmark and the contour of a plane."""
    objs = [c for c in plane.children if c.headrecon.role in ("LANDMARK", "CONTOUR")]
    photos.remove_objects(objs)


def landmark_pixels(plane, role="LANDMARK"):
    """Placed landmarks (or passpoints, ``role``) of a plane: dict name -> (u, v) pixels;
    landmarks in the landmark set's order (names it does not know last), passpoints by
    name."""
    objs = marker_objects(plane, role)
    if not objs:
        return {}
    order = {n: i for i, n in enumerate(landmark_set().names)} if role == "LANDMARK" else {}
    names = sorted(objs, key=lambda n: (order.get(n, len(order)), n))
    xy = np.array([_plane_xy(objs[n]) for n in names], dtype=np.float64)
    # Locations are float32 (~2e-5 px here); rounding to 1/1000 px gives back exactly the
    # coordinates a file had (import -> export round-trips) and loses nothing a hand or a
    # detector can place.
    uv = np.round(photos.pixels_from_local(plane, xy), PIXEL_DECIMALS)
    return {n: (float(u), float(v)) for n, (u, v) in zip(names, uv, strict=True)}


def _plane_xy(obj):
    """A child's position in its plane's space (its own transform, not the evaluated world
    matrix, which is stale until the depsgraph runs)."""
    t = (obj.matrix_parent_inverse @ obj.matrix_basis).translation
    return (t.x, t.y)


def landmark_signature(planes):
    """Every landmark's plane-space position as one array (cheap change detection)."""
    rows = []
    for plane in planes:
        for obj in plane.children:
            if obj.headrecon.role == "LANDMARK":
                rows.append(_plane_xy(obj))
            elif obj.headrecon.role == "CONTOUR":
                rows.append((len(obj.data.splines), 0.0))
    return np.array(rows, dtype=np.float64)


def select_landmark(context, view, name, role="LANDMARK"):
    """Make landmark (or passpoint, ``role``) ``name`` of view ``view`` the only selected,
    active object."""
    plane = photos.find_plane(context.scene, view)
    obj = marker_objects(plane, role).get(name) if plane is not None else None
    if obj is None:
        return None
    layer = context.view_layer
    for o in context.selected_objects:
        o.select_set(False)
    if obj.name in layer.objects:
        obj.hide_set(False)
        obj.select_set(True)
        layer.objects.active = obj
    return obj


# --------------------------------------------------------------------------------------
# The contour


def contour_object(plane):
    return next((c for c in plane.children if c.headrecon.role == "CONTOUR"), None)


def set_contour_local(plane, xy):
    """Replace the plane's contour with plane-space points (n, 2); n = 0 removes it."""
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    obj = contour_object(plane)
    if len(xy) == 0:
        if obj is not None:
            photos.remove_objects([obj])
        return None
    if obj is None:
        name = f"HR {plane.headrecon.view} contour"
        curve = bpy.data.curves.new(name, "CURVE")
        curve.dimensions = "3D"
        obj = bpy.data.objects.new(name, curve)
        obj.headrecon.role = "CONTOUR"
        obj.headrecon.view = plane.headrecon.view
        obj.parent = plane
        obj.matrix_parent_inverse.identity()
        obj.show_in_front = True
        obj.hide_render = True
        obj.lock_location[2] = True
        _link_like(obj, plane)
    curve = obj.data
    curve.splines.clear()
    spline = curve.splines.new("POLY")
    spline.points.add(len(xy) - 1)
    co = np.zeros((len(xy), 4), dtype=np.float32)
    co[:, :2] = xy
    co[:, 2] = LIFT
    co[:, 3] = 1.0
    spline.points.foreach_set("co", co.ravel())
    curve.update_tag()
    return obj


def set_contour(plane, pixels):
    """Replace the plane's contour with pixel points (n, 2)."""
    px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    return set_contour_local(plane, photos.local_from_pixels(plane, px) if len(px) else px)


def contour_local(plane):
    """The contour's plane-space points (n, 2) (object transform included), or (0, 2)."""
    obj = contour_object(plane)
    if obj is None or not obj.data.splines:
        return np.zeros((0, 2))
    pts = []
    m = np.array(obj.matrix_parent_inverse @ obj.matrix_basis)
    for spline in obj.data.splines:
        co = np.empty(len(spline.points) * 4, dtype=np.float32)
        spline.points.foreach_get("co", co)
        pts.append(co.reshape(-1, 4)[:, :3])
    p = np.concatenate(pts).astype(np.float64)
    return (p @ m[:3, :3].T + m[:3, 3])[:, :2]


def contour_pixels(plane):
    """The contour in pixels (n, 2), or None when the plane has none."""
    xy = contour_local(plane)
    return np.round(photos.pixels_from_local(plane, xy), PIXEL_DECIMALS) if len(xy) else None


def add_contour_point_local(plane, xy):
    pts = contour_local(plane)
    return set_contour_local(plane, np.vstack([pts, np.reshape(xy, (1, 2))]))


def remove_last_contour_point(plane):
    pts = contour_local(plane)
    return set_contour_local(plane, pts[:-1])


# --------------------------------------------------------------------------------------
# Scene <-> landmarks file


def hit_plane(plane, origin, direction):
    """Where a ray (world origin and direction) meets the plane, in plane space (x, y), or
    None when it misses the photo."""
    inv = plane.matrix_world.inverted()
    o = inv @ Vector(origin)
    d = inv.to_3x3() @ Vector(direction)
    if abs(d.z) < 1e-12:
        return None
    t = -o.z / d.z
    p = o + t * d
    (w, h), big_h = photos.plane_size(plane)
    half_w, half_h = big_h * w / h / 2.0, big_h / 2.0
    if abs(p.x) > half_w or abs(p.y) > half_h:
        return None
    return (p.x, p.y)


def _image_ref(image, base_dir):
    """Path of a photo for the file: relative to ``base_dir`` when possible."""
    if image is None or image.source != "FILE" or not image.filepath:
        return None
    path = Path(bpy.path.abspath(image.filepath, library=image.library))
    if base_dir is None:
        return str(path)
    try:
        return Path(os.path.relpath(path, base_dir)).as_posix()
    except ValueError:  # another drive (Windows)
        return str(path)


_EDITED = ("image", "size", "points", "contour", "camera", "passpoints")


def view_dict_from_plane(plane, base_dir=None):
    """A photo plane as a view of the landmarks file (its JSON form): size, photo,
    camera and the landmark and contour pixels from the scene; every other key as the
    imported file had it (``view_json``)."""
    (w, h), _ = photos.plane_size(plane)
    props = plane.headrecon
    d = json.loads(props.view_json) if props.view_json else {}
    if props.camera_json:
        d["camera"] = json.loads(props.camera_json)
    elif not isinstance(d.get("camera"), dict):  # (a dict here: hints, camera unknown)
        d["camera"] = props.camera_view
    image = _image_ref(props.image, base_dir)
    if image is None:
        d.pop("image", None)
    else:
        d["image"] = image
    d["size"] = [w, h]
    d["points"] = {k: list(v) for k, v in landmark_pixels(plane).items()}
    passpoints = landmark_pixels(plane, "PASSPOINT")
    if passpoints:
        d["passpoints"] = {k: list(v) for k, v in passpoints.items()}
    else:
        d.pop("passpoints", None)
    contour = contour_pixels(plane)
    if contour is None:
        d.pop("contour", None)
    else:
        d["contour"] = contour.tolist()
    return d


def case_dict_from_scene(scene, base_dir=None):
    """The scene's photos and landmarks as a landmarks document (a dict).

    Raises
    ------
    ValueError
        No photo planes, or two planes claim one view name.
    """
    planes = photos.photo_planes(scene)
    if not planes:
        raise ValueError("the scene has no photos: load a front and a profile photo first")
    views = {}
    for plane in planes:
        v = plane.headrecon.view
        if v in views:
            raise ValueError(f"view {v!r}: two photo planes claim it ({plane.name!r} and "
                             f"another); rename one view")
        views[v] = view_dict_from_plane(plane, base_dir)
    doc = {"format": landmarks_file.FORMAT, "version": landmarks_file.CURRENT_VERSION,
           "views": views}
    if scene.headrecon.case_json:
        doc.update(json.loads(scene.headrecon.case_json))
    return doc


def case_from_scene(scene, base_dir=None, source=None):
    """The scene's photos and landmarks as a LandmarkCase, checked by the solver's own
    parser (as work in progress: without the fit's landmark count floor).

    Parameters
    ----------
    base_dir : path-like, optional
        Folder photo paths are written relative to (absolute paths when None).
    source : str, optional
        Name for messages and for resolving photos (default: a file in ``base_dir``).

    Raises
    ------
    ValueError
        No photos, two planes with one view name, or what the parser finds (a landmark
        dragged off its photo, ...), naming view and landmark.
    """
    doc = case_dict_from_scene(scene, base_dir)
    if source is None:
        source = str(Path(base_dir) / "scene.json") if base_dir is not None else "<scene>"
    return landmarks_file.parse_landmarks(doc, source, for_fit=False)


def store_case_level(scene, case):
    """Remember the case's top-level keys besides the views (passpoints, x- keys)."""
    doc = landmarks_file.landmarks_to_dict(case)
    rest = {k: v for k, v in doc.items() if k not in ("format", "version", "views")}
    scene.headrecon.case_json = json.dumps(rest) if rest else ""


def case_passpoints(scene):
    """The calibration object's passpoints of the scene's case: dict name -> [x, y, z]
    metres (from the imported file), in the file's order."""
    props = scene.headrecon
    return dict(json.loads(props.case_json).get("passpoints", {})) if props.case_json else {}


def set_case_passpoint(scene, name, xyz):
    """Define (or move) the calibration object's passpoint ``name`` at ``xyz`` (metres,
    Blender axes): the file's top-level ``passpoints``, written on export.

    Raises
    ------
    ValueError
        An empty name or a coordinate that is not a finite number (names the passpoint).
    """
    name = str(name).strip()
    if not name:
        raise ValueError("passpoint: give it a name")
    xyz = np.asarray(xyz, dtype=np.float64).reshape(-1)
    if xyz.shape != (3,) or not np.all(np.isfinite(xyz)):
        raise ValueError(f"passpoint {name!r}: expected 3 finite coordinates (metres), got "
                         f"{xyz.tolist()}")
    _write_case_passpoints(scene, {**case_passpoints(scene), name: [float(c) for c in xyz]})


def remove_case_passpoint(scene, name):
    """Forget the calibration object's passpoint ``name``.

    Raises
    ------
    ValueError
        It is not defined, or a photo still has it placed (names the views).
    """
    points = case_passpoints(scene)
    if name not in points:
        raise ValueError(f"passpoint {name!r}: not defined")
    used = [p.headrecon.view for p in photos.photo_planes(scene)
            if name in passpoint_objects(p)]
    if used:
        raise ValueError(f"passpoint {name!r}: still placed on view(s) "
                         f"{', '.join(map(repr, used))}; remove it there first")
    del points[name]
    _write_case_passpoints(scene, points)


def _write_case_passpoints(scene, points):
    props = scene.headrecon
    rest = json.loads(props.case_json) if props.case_json else {}
    rest.pop("passpoints", None)
    if points:
        rest["passpoints"] = points
    props.case_json = json.dumps(rest) if rest else ""


def placeholder_image(view, size):
    """A plain grey image standing in for a view whose file names no photo."""
    w, h = size
    img = bpy.data.images.new(f"HeadRecon {view} (no photo)", int(w), int(h), alpha=False)
    img.generated_color = (0.5, 0.5, 0.5, 1.0)
    img[photos.PLACEHOLDER] = True
    return img


def build_view_planes(case, images, centre=(0.0, 0.0, 0.0)):
    """Photo planes with their landmarks, passpoints and contours for every view of
    ``case``, with a Blender camera for each perspective photo (not linked to a scene: link
    ``photos.view_root(plane)``). ``images``: dict view -> bpy Image."""
    planes = []
    for name, view in case.views.items():
        img = images[name]
        if tuple(img.size) != tuple(view.size):
            raise ValueError(f"view {name!r}: the photo {img.name!r} is "
                             f"{img.size[0]}x{img.size[1]} pixels but the landmarks file "
                             f"says {view.size[0]}x{view.size[1]}")
        vd = view.to_dict()  # the file's form: a camera keeps its numbers as read
        keep = {k: v for k, v in vd.items() if k not in _EDITED}
        hints, shown = None, None
        if view.camera is None:
            keep["camera"] = hints = vd["camera"]  # the fit computes this camera
            shown = passpoint_camera(case, name)
        plane = photos.new_photo_plane(
            img, name, photos.nearest_view(view.camera or shown, name), camera=view.camera,
            centre=centre, hints=hints, shown=shown)
        planes.append(plane)
        if view.camera is not None and not isinstance(vd["camera"], str):
            plane.headrecon.camera_json = json.dumps(vd["camera"])
        plane.headrecon.view_json = json.dumps(keep) if keep else ""
        for lm, uv in view.points.items():
            place_landmark(plane, lm, uv)
        for pp, uv in view.passpoints.items():
            place_landmark(plane, pp, uv, "PASSPOINT")
        if view.contour is not None and len(view.contour):
            set_contour(plane, view.contour)
    return planes


def passpoint_camera(case, view):
    """The DLT camera of a view's passpoints (what the fit starts from for a camera to be
    computed), or None when they cannot give one (too few, coplanar, undefined)."""
    if len(case.views[view].passpoints) < landmarks_file.MIN_PASSPOINTS:
        return None
    try:
        _, xyz, uv = case.passpoint_arrays(view)
        return fit_dlt(xyz, uv, case.views[view].size).camera
    except ValueError:
        return None


def load_case_images(case):
    """Each view's photo as a bpy Image (a grey placeholder for views without one).

    Raises ValueError naming the view and the file when a photo is missing or unreadable.
    """
    images = {}
    for name in case.views:
        path = case.image_path(name)
        if path is None:
            images[name] = placeholder_image(name, case.views[name].size)
            continue
        try:
            images[name] = photos.load_image(path)
        except ValueError as e:
            raise ValueError(f"{case.source}: view {name!r}: {e}") from None
    return images


def import_landmarks(context, path):
    """Read a landmarks file into the scene: one photo plane per view with its landmarks
    and contour; planes of the same views are replaced. All or nothing.

    Returns
    -------
    list of bpy.types.Object
        The new photo planes.

    Raises
    ------
    ValueError, OSError
        The file is unreadable or invalid, or a photo is missing (scene unchanged).
    """
    case = load_landmarks(path, for_fit=False)
    scene = context.scene
    with Transaction():
        images = load_case_images(case)
        centre = photos.head_centre(scene)
        planes = build_view_planes(case, images, centre)
        # Everything is built: now replace the old planes and link the new ones.
        for name in case.views:
            old = photos.find_plane(scene, name)
            if old is not None:
                photos.remove_objects(photos.view_objects(old))
        for plane in planes:
            photos.link_object(photos.view_root(plane), scene.collection)
        store_case_level(scene, case)
    return planes


def export_landmarks(scene, path):
    """Write the scene's landmarks to ``path`` (atomically, validated by the solver)."""
    path = Path(path)
    case = case_from_scene(scene, base_dir=path.resolve().parent, source=str(path))
    save_landmarks(case, path)
    return case


# --------------------------------------------------------------------------------------
# Interactive tools: logic


def _passpoint_description(xyz):
    if xyz is None:
        return "not defined in the file's passpoints"
    return "calibration point at (" + ", ".join(f"{c:g}" for c in xyz) + ") m"


class PlacementSession:
    """Walk through the landmarks (or passpoints) of one photo: place the current one,
    skip it, go back.

    Parameters
    ----------
    plane : bpy.types.Object
        The photo plane.
    names : list of str, optional
        Markers to walk (default: the landmarks of assets/landmarks.json visible in the
        plane's view, in file order; for passpoints, ``passpoints``' names). The walk
        starts at the first one not yet placed.
    role : {"LANDMARK", "PASSPOINT"}
    passpoints : dict of str -> (3,) metres, optional
        The calibration object's passpoints (``case_passpoints``), for ``role``
        "PASSPOINT".
    """

    def __init__(self, plane, names=None, role="LANDMARK", passpoints=None):
        self.plane_name = plane.name
        self.role = role
        if role == "PASSPOINT":
            xyz = dict(passpoints or {})
            defs = [{"name": n, "description": _passpoint_description(xyz.get(n))}
                    for n in (list(xyz) if names is None else names)]
        elif names is None:
            defs = landmark_definitions(photos.view_kind(plane))
        else:
            known = {e["name"]: e for e in landmark_set().info}
            defs = [known.get(canonical_name(n), {"name": n, "description": ""})
                    for n in names]
        self.definitions = defs
        placed = marker_objects(plane, role)
        self.index = next((i for i, d in enumerate(defs) if d["name"] not in placed),
                          len(defs))
        self.placed = 0

    @property
    def plane(self):
        return bpy.data.objects.get(self.plane_name)

    @property
    def done(self):
        return self.index >= len(self.definitions)

    @property
    def current(self):
        """The definition dict of the marker to place next, or None when done."""
        return None if self.done else self.definitions[self.index]

    def click(self, origin, direction):
        """A click along a view ray: place the current marker where the ray meets the
        photo and move on. Returns False when the ray misses the photo."""
        xy = hit_plane(self.plane, origin, direction)
        if xy is None or self.done:
            return False
        self.place_local(xy)
        return True

    def place_local(self, xy):
        place_marker_local(self.plane, self.current["name"], xy, self.role)
        self.placed += 1
        self.index += 1

    def skip(self):
        """Leave the current marker as it is (unplaced stays unplaced)."""
        self.index = min(self.index + 1, len(self.definitions))

    def back(self):
        self.index = max(self.index - 1, 0)

    def unplace(self):
        """Remove the current marker from the photo."""
        if not self.done:
            remove_landmark(self.plane, self.current["name"], self.role)

    def header(self):
        n = len(self.definitions)
        what = "Passpoint" if self.role == "PASSPOINT" else "Landmark"
        if self.done:
            return f"HeadRecon: all {n} {what.lower()}s visited. Esc: done"
        d = self.current
        placed = d["name"] in marker_objects(self.plane, self.role)
        state = " (placed: click to move)" if placed else ""
        return (f"{what} {self.index + 1}/{n}: {d['name']}{state} — "
                f"{d.get('description', '')}")


STATUS_PLACE = ("Click: place   S / →: skip   Backspace / ←: back   X / Del: unplace   "
                "Esc / right click: done")
STATUS_CONTOUR = ("Click: add point   Backspace: remove last point   "
                  "Enter / Esc / right click: done")


class ContourSession:
    """Trace the head's outline on a photo: every click adds a point to the plane's contour."""

    done = False  # a contour takes points until the artist ends the tool

    def __init__(self, plane):
        self.plane_name = plane.name
        self.added = 0

    @property
    def plane(self):
        return bpy.data.objects.get(self.plane_name)

    def click(self, origin, direction):
        xy = hit_plane(self.plane, origin, direction)
        if xy is None:
            return False
        add_contour_point_local(self.plane, xy)
        self.added += 1
        return True

    def undo_point(self):
        remove_last_contour_point(self.plane)

    def header(self):
        n = len(contour_local(self.plane))
        return f"HeadRecon contour: {n} points. Click along the head's outline (not the hair)"


# --------------------------------------------------------------------------------------
# Operators


def _target_plane(context, view):
    """The plane an operator works on: the named view, else the active object's plane."""
    if view:
        return photos.find_plane(context.scene, view)
    return photos.plane_of(context.active_object)


def viewport_region_at(area, x, y):
    """The 3D viewport region (type WINDOW, one of four in quad view) of ``area`` under
    the window coordinates (x, y), with the mouse position inside it; or (None, None).

    A tool started from a sidebar button gets the sidebar as ``context.region``, so the
    region to cast rays from is looked up from the mouse position, not taken from there.
    """
    for region in area.regions:
        if region.type == "WINDOW" and region.data is not None \
                and region.x <= x < region.x + region.width \
                and region.y <= y < region.y + region.height:
            return region, (x - region.x, y - region.y)
    return None, None


def _ray(context, event):
    """World ray (origin, direction) under the mouse, or None when the mouse is not over
    the 3D viewport itself (sidebar, header, toolbar)."""
    from bpy_extras import view3d_utils

    region, co = viewport_region_at(context.area, event.mouse_x, event.mouse_y)
    if region is None:
        return None
    rv3d = region.data
    return (view3d_utils.region_2d_to_origin_3d(region, rv3d, co),
            view3d_utils.region_2d_to_vector_3d(region, rv3d, co))


_NAVIGATION = {"MIDDLEMOUSE", "WHEELUPMOUSE", "WHEELDOWNMOUSE", "TRACKPADPAN", "TRACKPADZOOM",
               "MOUSEROTATE", "MOUSESMARTZOOM", "NDOF_MOTION", "NUMPAD_1", "NUMPAD_3",
               "NUMPAD_5", "NUMPAD_PERIOD", "NUMPAD_PLUS", "NUMPAD_MINUS", "HOME"}


def _photos_problem(context, message="Load a photo first (Photos panel)"):
    return None if photos.photo_planes(context.scene) else message


class _PlaneToolMixin:
    """What the two click tools share: the target plane, header and status texts, and the
    modal loop (navigation passes through, a click on the photo goes to the session, a
    click elsewhere to Blender). Subclasses set STATUS and DONE_KEYS and implement
    ``_key`` (their own shortcuts) and ``_edited`` (whether anything changed)."""

    view: StringProperty(name="View", description="Photo view name (empty: the active "
                         "object's photo)", options={"SKIP_SAVE"})
    STATUS = ""
    DONE_KEYS = {"ESC", "RIGHTMOUSE"}

    @classmethod
    def poll(cls, context):
        return poll_result(cls, view3d_problem(context) or object_mode_problem(context)
                           or _photos_problem(context))

    def _start(self, context):
        plane = _target_plane(context, self.view)
        if plane is None:
            self.report({"ERROR"}, f"No photo for view {self.view!r}" if self.view else
                        "Select a photo plane (or one of its landmarks) first")
            return None
        return plane

    def _run(self, context):
        """Show the session's header and hand events to ``modal``."""
        self._refresh(context)
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _refresh(self, context):
        context.area.header_text_set(self.session.header())
        if context.workspace is not None:
            context.workspace.status_text_set(self.STATUS)

    def _finish(self, context):
        context.area.header_text_set(None)
        if context.workspace is not None:
            context.workspace.status_text_set(None)

    def modal(self, context, event):
        if self.session.plane is None:
            self._finish(context)
            return {"CANCELLED"}
        if event.type in _NAVIGATION:
            return {"PASS_THROUGH"}
        if event.value != "PRESS":
            return {"RUNNING_MODAL"}
        if event.type in self.DONE_KEYS:
            self._finish(context)
            return {"FINISHED"} if self._edited() else {"CANCELLED"}
        if event.type == "LEFTMOUSE":
            ray = _ray(context, event)
            if ray is None:
                return {"PASS_THROUGH"}  # a click on the sidebar or header: theirs
            if not self.session.done and not self.session.click(*ray):
                self.report({"WARNING"}, "Click on the photo")
        elif not self._key(event.type):
            return {"RUNNING_MODAL"}
        self._refresh(context)
        return {"RUNNING_MODAL"}


class HEADRECON_OT_place_landmarks(_PlaneToolMixin, bpy.types.Operator):
    """Click the landmarks (or passpoints) on a photo one after the other; the header
    names the next one"""

    bl_idname = "headrecon.place_landmarks"
    bl_label = "Place Landmarks"
    bl_options = {"REGISTER", "UNDO"}
    STATUS = STATUS_PLACE

    passpoints: bpy.props.BoolProperty(
        name="Passpoints", options={"SKIP_SAVE"},
        description="Place the calibration object's passpoints instead of landmarks")

    def invoke(self, context, event):
        plane = self._start(context)
        if plane is None:
            return {"CANCELLED"}
        if self.passpoints:
            self.session = PlacementSession(plane, role="PASSPOINT",
                                            passpoints=case_passpoints(context.scene))
            if not self.session.definitions:
                self.report({"ERROR"}, "The landmarks file defines no passpoints (a "
                            "calibration object's points, top-level 'passpoints')")
                return {"CANCELLED"}
        else:
            self.session = PlacementSession(plane)
        if not self.session.definitions:
            self.report({"ERROR"}, f"No landmarks are defined for a {photos.view_kind(plane)} "
                        "view")
            return {"CANCELLED"}
        if self.session.done:  # everything placed already: walk from the start to adjust
            self.session.index = 0
        return self._run(context)

    def _edited(self):
        return self.session.placed > 0

    def _key(self, key):
        if key in {"S", "RIGHT_ARROW", "SPACE"}:
            self.session.skip()
        elif key in {"BACK_SPACE", "LEFT_ARROW"}:
            self.session.back()
        elif key in {"X", "DEL"}:
            self.session.unplace()
        else:
            return False
        return True


class HEADRECON_OT_draw_contour(_PlaneToolMixin, bpy.types.Operator):
    """Trace the head's outline on the profile photo by clicking points along it"""

    bl_idname = "headrecon.draw_contour"
    bl_label = "Draw Contour"
    bl_options = {"REGISTER", "UNDO"}
    STATUS = STATUS_CONTOUR
    DONE_KEYS = {"ESC", "RIGHTMOUSE", "RET", "NUMPAD_ENTER"}

    def invoke(self, context, event):
        plane = self._start(context)
        if plane is None:
            return {"CANCELLED"}
        self.session = ContourSession(plane)
        return self._run(context)

    def _edited(self):
        return self.session.added > 0

    def _key(self, key):
        if key in {"BACK_SPACE", "DEL"}:
            self.session.undo_point()
            return True
        return False


class HEADRECON_OT_clear_landmarks(bpy.types.Operator):
    """Remove every landmark and the contour of a photo"""

    bl_idname = "headrecon.clear_landmarks"
    bl_label = "Clear Landmarks"
    bl_options = {"REGISTER", "UNDO"}

    view: StringProperty(name="View", options={"SKIP_SAVE"})

    @classmethod
    def poll(cls, context):
        return poll_result(cls, _photos_problem(context, "There are no photos"))

    def invoke(self, context, event):
        return context.window_manager.invoke_confirm(self, event)

    def execute(self, context):
        plane = _target_plane(context, self.view)
        if plane is None:
            self.report({"ERROR"}, f"No photo for view {self.view!r}" if self.view else
                        "Select a photo plane first")
            return {"CANCELLED"}
        clear_landmarks(plane)
        return {"FINISHED"}


class HEADRECON_OT_import_landmarks(ObjectModeOperator, bpy.types.Operator,
                                    ImportHelper):
    """Read a HeadRecon landmarks file (JSON): its photos become photo planes with their
    landmarks and contour"""

    bl_idname = "headrecon.import_landmarks"
    bl_label = "Import Landmarks"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".json"
    filter_glob: StringProperty(default="*.json", options={"HIDDEN"})

    def execute(self, context):
        try:
            planes = import_landmarks(context, self.filepath)
        except (ValueError, OSError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        n = sum(len(landmark_objects(p)) for p in planes)
        self.report({"INFO"}, f"Imported {n} landmarks on {len(planes)} photos")
        from .fit_ops import warm_up

        warm_up(context.scene.headrecon.texture_size)
        return {"FINISHED"}


class HEADRECON_OT_export_landmarks(bpy.types.Operator, ExportHelper):
    """Write the landmarks of the photos to a HeadRecon landmarks file (JSON)"""

    bl_idname = "headrecon.export_landmarks"
    bl_label = "Export Landmarks"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".json"
    filter_glob: StringProperty(default="*.json", options={"HIDDEN"})

    @classmethod
    def poll(cls, context):
        return poll_result(cls, _photos_problem(
            context, "There are no photos with landmarks to export"))

    def execute(self, context):
        try:
            case = export_landmarks(context.scene, self.filepath)
        except (ValueError, OSError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        self.report({"INFO"}, f"Wrote {case.n_points} landmarks to {self.filepath}")
        return {"FINISHED"}


class HEADRECON_OT_edit_passpoint(bpy.types.Operator):
    """Define, move or remove a point of the calibration object: its name and its 3-D
    position (metres), which the photos' passpoints refer to"""

    bl_idname = "headrecon.edit_passpoint"
    bl_label = "Calibration Passpoint"
    bl_options = {"REGISTER", "UNDO"}

    name: StringProperty(name="Name", options={"SKIP_SAVE"},
                         description="The passpoint's name (as placed on the photos)")
    location: bpy.props.FloatVectorProperty(
        name="Position", size=3, subtype="TRANSLATION", unit="LENGTH", options={"SKIP_SAVE"},
        description="Where the point is on the calibration object, metres (Blender axes)")
    remove: bpy.props.BoolProperty(name="Remove", options={"SKIP_SAVE"},
                                   description="Forget this passpoint")

    def invoke(self, context, event):
        if self.remove:
            return self.execute(context)
        return context.window_manager.invoke_props_dialog(self)

    def execute(self, context):
        try:
            if self.remove:
                remove_case_passpoint(context.scene, self.name)
            else:
                set_case_passpoint(context.scene, self.name, self.location)
        except ValueError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        return {"FINISHED"}


class HEADRECON_OT_select_landmark(ObjectModeOperator, bpy.types.Operator):
    """Select this landmark"""

    bl_idname = "headrecon.select_landmark"
    bl_label = "Select Landmark"
    bl_options = {"REGISTER", "UNDO"}

    view: StringProperty(name="View")
    landmark: StringProperty(name="Landmark")

    def execute(self, context):
        if select_landmark(context, self.view, self.landmark) is None:
            self.report({"ERROR"}, f"Landmark {self.landmark!r} of view {self.view!r} is not "
                        "placed")
            return {"CANCELLED"}
        return {"FINISHED"}


CLASSES = (HEADRECON_OT_place_landmarks, HEADRECON_OT_draw_contour,
           HEADRECON_OT_clear_landmarks, HEADRECON_OT_import_landmarks,
           HEADRECON_OT_export_landmarks, HEADRECON_OT_edit_passpoint,
           HEADRECON_OT_select_landmark)
