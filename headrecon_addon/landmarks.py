"""Landmarks, passpoints and the traced outline as objects on the photo planes.

A landmark is a small sphere parented to its photo plane (so it moves with the plane, can
be grabbed, undone and is saved in the .blend), its position in plane space being the one
source of truth for its pixel coordinates (see photos.py). A passpoint (where a point of a
calibration object, whose 3-D position the file gives, is seen) is the same kind of marker
in another colour and role. The contour is a poly curve parented to the plane the same way.

A landmark is hand-placed or detected. A detected one (Detect Landmarks, or a file's point
with an uncertainty) has its own colour, keeps the detector's uncertainty for the fit and
remembers where it was put: moved from there (grabbed, placed again with the tool) it is
hand-placed, which ``is_detected`` reads from its position (so no event can be missed) and
a depsgraph handler shows by its colour.
"""

import bmesh
import bpy
import numpy as np
from bpy.app.handlers import persistent

from . import app_handlers, material, photos, scene_collections
from .solver_link import load_landmark_set

MARKER_RADIUS = 0.0025  # metres (plane space): about 7 px on a 1024 px photo
LIFT = 0.001  # landmarks and contour float this far in front of the photo (plane +z)
MARKER_MESH = "HeadRecon Landmark Marker"
PIXEL_DECIMALS = 3
#: A detected landmark farther than this (metres, plane space) from where the detector put
#: it was moved by hand (a marker's location is float32: about 1e-8 m at a photo's edge).
MOVED_M = 1e-6


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


def marker_state(obj):
    """A marker's state as its colour shows it: "FLAGGED" (by the last fit), "PASSPOINT",
    "DETECTED" (``is_detected``) or "PLACED" (by hand)."""
    if obj.headrecon.flagged:
        return "FLAGGED"
    if obj.headrecon.role == "PASSPOINT":
        return "PASSPOINT"
    return "DETECTED" if is_detected(obj) else "PLACED"


def show_state(obj):
    """Colour a marker by ``marker_state`` (its material only changes when the state does)."""
    state = marker_state(obj)
    mat = material.landmark_material(state)
    if obj.material_slots[0].material != mat:
        obj.material_slots[0].material = mat
        obj.color = material.LANDMARK_COLOURS[state]


def set_landmark_state(obj, flagged, residual_px=-1.0):
    """Set a marker's fit flag and residual and colour it: placed by hand (landmarks green,
    passpoints blue), detected (orange), flagged (red)."""
    obj.headrecon.flagged = bool(flagged)
    obj.headrecon.residual_px = float(residual_px)
    show_state(obj)


def is_detected(obj):
    """A landmark the detector placed (or a file gave with its uncertainty), still where it
    was put: not hand-placed."""
    props = obj.headrecon
    if not props.detected or props.role != "LANDMARK":
        return False
    x, y = _plane_xy(obj)
    return float(np.hypot(x - props.detected_at[0], y - props.detected_at[1])) <= MOVED_M


def set_hand_placed(obj):
    """Make a landmark hand-placed: the detector's mark, uncertainty and depth forgotten."""
    obj.headrecon.detected = False
    obj.headrecon.uncertainty_px = 0.0
    obj.headrecon.has_depth = False
    show_state(obj)


def place_detected(plane, name, uv, uncertainty_px=None, depth_px=None):
    """Put landmark ``name`` at pixel ``uv`` as detected, with its uncertainty (standard
    deviation, pixels; None: none) and depth toward the camera (pixels; None: none).
    Returns it."""
    obj = place_landmark(plane, name, uv)
    props = obj.headrecon
    props.detected = True
    props.uncertainty_px = float(uncertainty_px or 0.0)
    props.has_depth = depth_px is not None
    props.depth_px = float(depth_px or 0.0)
    props.detected_at = _plane_xy(obj)
    set_landmark_state(obj, False)  # a new point: the last fit's flag was for another
    return obj


def detected_landmarks(plane):
    """Landmarks of a plane that are detected (``is_detected``): dict name -> object."""
    return {n: o for n, o in landmark_objects(plane).items() if is_detected(o)}


def hand_placed_landmarks(plane):
    """Landmarks of a plane placed (or moved) by hand: dict name -> object."""
    return {n: o for n, o in landmark_objects(plane).items() if not is_detected(o)}


def landmark_uncertainty(plane):
    """The uncertainty (pixels) of each detected landmark of a plane that has one: dict
    name -> px (the landmarks file's per-view ``uncertainty``)."""
    return {n: round(float(o.headrecon.uncertainty_px), PIXEL_DECIMALS)
            for n, o in detected_landmarks(plane).items() if o.headrecon.uncertainty_px > 0}


def landmark_depth(plane):
    """The depth (pixels toward the camera) of each detected landmark of a plane that has
    one and an uncertainty: dict name -> px (the landmarks file's per-view ``depth``)."""
    return {n: round(float(o.headrecon.depth_px), PIXEL_DECIMALS)
            for n, o in detected_landmarks(plane).items()
            if o.headrecon.has_depth and o.headrecon.uncertainty_px > 0}


def settle_moved(objects):
    """Detected landmarks among ``objects`` that were moved become hand-placed (their
    colour too). Returns how many."""
    moved = [o for o in objects if o.headrecon.role == "LANDMARK" and o.headrecon.detected
             and not is_detected(o)]
    for obj in moved:
        set_hand_placed(obj)
    return len(moved)


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
    if obj.headrecon.detected:  # placed again by hand
        set_hand_placed(obj)
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


def set_contour_local(plane, xy, breaks=()):
    """Replace the plane's contour with plane-space points (n, 2); n = 0 removes it.
    ``breaks``: the indices where a new part begins (drawn apart, read back in order)."""
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
    for part in np.split(xy, np.asarray(breaks, dtype=np.intp)):
        if not len(part):
            continue
        spline = curve.splines.new("POLY")
        spline.points.add(len(part) - 1)
        co = np.zeros((len(part), 4), dtype=np.float32)
        co[:, :2] = part
        co[:, 2] = LIFT
        co[:, 3] = 1.0
        spline.points.foreach_set("co", co.ravel())
    curve.update_tag()
    return obj


#: A step between a contour's points longer than this many times its median step (and
#: ``CONTOUR_JUMP_PX``) starts a new part: a detected outline goes on across hair or the
#: photo's border without points there, and is drawn as its parts, not with a chord.
CONTOUR_JUMP = 8.0
CONTOUR_JUMP_PX = 20.0


def contour_parts(pixels):
    """The indices (k,) where a new part of the contour ``pixels`` (n, 2) begins."""
    px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    if len(px) < 3:
        return np.zeros(0, dtype=np.intp)
    step = np.linalg.norm(np.diff(px, axis=0), axis=1)
    return np.flatnonzero(step > max(CONTOUR_JUMP * np.median(step), CONTOUR_JUMP_PX)) + 1


def set_contour(plane, pixels):
    """Replace the plane's contour with pixel points (n, 2), drawn as its parts
    (:func:`contour_parts`)."""
    px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    return set_contour_local(plane, photos.local_from_pixels(plane, px) if len(px) else px,
                             contour_parts(px))


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


#: On a contour drawn by Detect Outline: a checksum of its plane-space points, so a
#: contour edited or traced since reads as the artist's (``contour_is_detected``).
DETECTED_CONTOUR = "headrecon_detected_contour"


def _contour_checksum(xy):
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    return [float(len(xy)), float(np.round(np.abs(xy).sum(), 4))]


def set_detected_contour(plane, pixels):
    """Replace the plane's contour with the detected outline's pixel points (n, 2), marked
    as detected (``contour_is_detected``)."""
    obj = set_contour(plane, pixels)
    if obj is not None:
        obj[DETECTED_CONTOUR] = _contour_checksum(contour_local(plane))
    return obj


def contour_is_detected(plane):
    """Whether the plane's contour is the one Detect Outline drew, unchanged since (False
    when it has none, or one traced or edited by hand)."""
    obj = contour_object(plane)
    if obj is None or DETECTED_CONTOUR not in obj:
        return False
    return np.allclose(list(obj[DETECTED_CONTOUR]), _contour_checksum(contour_local(plane)),
                       rtol=0, atol=1e-3)


def _contour_breaks(plane):
    """Where each of the plane's contour's parts after the first begins (indices)."""
    obj = contour_object(plane)
    if obj is None:
        return []
    return list(np.cumsum([len(sp.points) for sp in obj.data.splines])[:-1])


def add_contour_point_local(plane, xy):
    pts = contour_local(plane)
    return set_contour_local(plane, np.vstack([pts, np.reshape(xy, (1, 2))]),
                             _contour_breaks(plane))


def remove_last_contour_point(plane):
    pts = contour_local(plane)
    return set_contour_local(plane, pts[:-1], [b for b in _contour_breaks(plane)
                                               if b < len(pts) - 1])


# --------------------------------------------------------------------------------------
# A detected landmark moved by hand shows it at once


@persistent
def _on_depsgraph_update(scene, depsgraph):
    if not depsgraph.id_type_updated("OBJECT"):
        return
    try:
        moved = [u.id.original for u in depsgraph.updates
                 if u.is_updated_transform and isinstance(u.id, bpy.types.Object)]
        settle_moved([o for o in moved if o.headrecon.role == "LANDMARK"])
    except Exception as e:  # noqa: BLE001  (a handler must not raise)
        print(f"HeadRecon: recolouring a moved landmark failed: {e}")


_HANDLERS = (("depsgraph_update_post", _on_depsgraph_update),)


def register_handlers():
    app_handlers.add(_HANDLERS)


def unregister_handlers():
    app_handlers.remove(_HANDLERS)
