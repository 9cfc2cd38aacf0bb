"""Landmarks, passpoints and the traced outline as objects on the photo planes.

A landmark is a small sphere parented to its photo plane (so it moves with the plane, can
be grabbed, undone and is saved in the .blend), its position in plane space being the one
source of truth for its pixel coordinates (see photos.py). A passpoint (where a point of a
calibration object, whose 3-D position the file gives, is seen) is the same kind of marker
in another colour and role. The contour is a poly curve parented to the plane the same way.
"""

import bmesh
import bpy
import numpy as np

from . import material, photos, scene_collections
from .solver_link import load_landmark_set

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
        scene_collections.link_like(obj, plane)
    obj.location = (float(xy[0]), float(xy[1]), LIFT)
    return obj


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
    # Locations are float32: rounding to 1/1000 px gives back exactly the coordinates a
    # file had (import -> export round-trips) and loses nothing a hand or a detector can
    # place.
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
        scene_collections.link_like(obj, plane)
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
