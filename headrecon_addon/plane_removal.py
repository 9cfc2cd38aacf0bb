"""A photo leaving the scene: *Remove Photo* (its plane, landmarks, passpoints, contour and
camera in one undoable step), and the markers of a plane deleted by other means.

Deleting a parent in Blender (X in the viewport, the Outliner, ``bpy.data.objects.remove``)
leaves its children unparented with their own transform, which for a landmark is its
position in the gone plane's space: it jumps to near the world origin, inside the head. A
fit never reads such a marker (the scene is read plane by plane, ``scene_to_case``), but
the artist would see it. So a depsgraph handler parks these orphans: hidden, kept as they
are (their plane-space position and view name), and re-attached when a photo is loaded
into that view again (``sweep``, ``rehome``: the landmarks keep their place relative to the
photo's centre and height, as a swapped photo's do; a name the new plane has already, e.g.
from an imported file, stays hidden). Undo brings the plane back with its markers
(the handler runs after the delete's undo step). The Fit's report names the parked ones.

A perspective photo's Blender camera deleted alone (its plane kept) is made again from the
view's stored camera (``restore_camera``).
"""

import bpy
from bpy.app.handlers import persistent

from . import app_handlers, photo_cameras, photos
from .live_refit import LIVE
from .polls import ObjectModeOperator

MARKER_ROLES = ("LANDMARK", "PASSPOINT", "CONTOUR")


def _what(objs, first=()):
    """'12 landmarks, 2 passpoints and the contour' for marker objects (after ``first``)."""
    roles = [o.headrecon.role for o in objs]
    parts = list(first)
    for role, word in (("LANDMARK", "landmark"), ("PASSPOINT", "passpoint")):
        n = roles.count(role)
        if n:
            parts.append(f"{n} {word}{'s' * (n != 1)}")
    if "CONTOUR" in roles:
        parts.append("the contour")
    return " and ".join([", ".join(parts[:-1]), parts[-1]] if len(parts) > 1 else parts)


def orphan_markers(scene):
    """Markers (landmarks, passpoints, contours) in ``scene`` that belong to no photo
    plane: dict view name -> [objects]."""
    out = {}
    for obj in scene.objects:
        if obj.headrecon.role in MARKER_ROLES and photos.plane_of(obj) is None:
            out.setdefault(obj.headrecon.view, []).append(obj)
    return out


def cameraless_planes(scene):
    """Perspective photo planes of ``scene`` whose Blender camera is gone."""
    return [p for p in photos.photo_planes(scene)
            if photos.is_perspective(p) and photos.camera_object(p) is None]


def restore_camera(plane):
    """Make a perspective photo's Blender camera again after it alone was deleted (which
    leaves the plane at its camera-space transform, off in the world): from the view's
    stored camera (the last fit's, the file's, or a provisional one for a camera still to
    compute), the plane at the distance it had. The view stays as it was rather than
    leaving the fit like a deleted plane's: its photo and landmarks are still in the scene,
    and the camera object only shows the camera the view keeps (the fit reads that one);
    Remove Photo takes the whole view."""
    depth = photo_cameras.plane_depth(plane)  # its basis is still its camera-space matrix
    photos.place_plane(plane)
    if depth > photo_cameras.MIN_DEPTH:
        (w, h), big_h = photos.plane_size(plane)
        photo_cameras.attach_plane(plane, photos.camera_object(plane), (w, h), big_h, depth)


def sweep(scene):
    """Tidy the orphaned markers of ``scene`` (idempotent): those of a view that has a
    photo plane again are re-attached to it (``rehome``), the others hidden; a perspective
    photo whose camera was deleted gets it again (``restore_camera``). Returns (parked,
    rehomed): how many markers were newly hidden and re-attached."""
    for plane in cameraless_planes(scene):
        restore_camera(plane)
    orphans = orphan_markers(scene)
    if not orphans:
        return 0, 0
    rehomed = 0
    for view in orphans:
        plane = photos.find_plane(scene, view)
        if plane is not None:
            rehomed += rehome(scene, plane)
    parked = 0
    for obj in (o for objs in orphan_markers(scene).values() for o in objs):
        if not obj.hide_viewport:
            obj.hide_viewport = True
            obj.hide_select = True
            parked += 1
    return parked, rehomed


def deleted_views(scene):
    """Views whose photo plane is gone but whose markers are parked (sorted names)."""
    return sorted(v for v in orphan_markers(scene) if photos.find_plane(scene, v) is None)


def orphan_notes(scene):
    """One line per view with parked markers: its photo plane is gone, or the photo
    loaded since has markers of those names."""
    notes = []
    for view, objs in sorted(orphan_markers(scene).items()):
        if photos.find_plane(scene, view) is None:
            notes.append(f"view {view!r}: its photo plane was deleted; {_what(objs)} kept "
                         f"hidden, not fitted (load a photo into {view!r} to get them back, "
                         "or Remove Photo)")
        else:
            notes.append(f"view {view!r}: {_what(objs)} of a deleted photo plane kept hidden, "
                         "not fitted (its photo has its own; Remove Photo removes both)")
    return notes


def rehome(scene, plane):
    """Attach the parked markers of ``plane``'s view to it (a new plane for that view),
    those of a name the plane has not got. Returns the number re-attached."""
    view = plane.headrecon.view
    have = {(c.headrecon.role, c.headrecon.landmark) for c in plane.children}
    n = 0
    for obj in orphan_markers(scene).get(view, []):
        key = (obj.headrecon.role, obj.headrecon.landmark)
        if key in have:
            continue
        obj.parent = plane  # (its local transform is its plane-space position)
        obj.hide_viewport = False
        obj.hide_select = False
        have.add(key)
        n += 1
    return n


def remove_view(scene, plane):
    """Remove a photo's view: camera (if any), plane, landmarks, passpoints, contour and
    that view's parked markers; a view that was its mirror image is seen directly now.
    Returns a line saying what went."""
    view = plane.headrecon.view
    objs = photos.view_objects(plane)
    parked = orphan_markers(scene).get(view, [])
    markers = [o for o in objs if o.headrecon.role in MARKER_ROLES] + parked
    first = ["its camera"] if photos.camera_object(plane) is not None else []
    what = _what(markers, [*first, "the plane" if first or markers else "its plane"])
    mirrors = [p for p in photos.photo_planes(scene)
               if p != plane and photos.mirror_of(p) == view]
    photos.remove_objects([*objs, *parked])
    for p in mirrors:
        photos.set_mirror_of(p, None)
    line = f"Removed photo {view!r}: {what}"
    if mirrors:
        line += "; " + ", ".join(repr(p.headrecon.view) for p in mirrors) + \
            " no longer mirror it"
    return line


class HEADRECON_OT_remove_photo(ObjectModeOperator, bpy.types.Operator):
    """Remove this photo from the scene: its image plane, its landmarks, passpoints and
    contour, and its camera (undo brings them back)"""

    bl_idname = "headrecon.remove_photo"
    bl_label = "Remove Photo"
    bl_options = {"REGISTER", "UNDO"}

    view: bpy.props.StringProperty(name="View", description="Photo view name to remove")

    def execute(self, context):
        scene = context.scene
        plane = photos.find_plane(scene, self.view)
        if plane is None:  # checked before anything changes
            self.report({"ERROR"}, f"No photo for view {self.view!r}")
            return {"CANCELLED"}
        line = remove_view(scene, plane)
        LIVE.forget()  # the fit in memory had this view
        self.report({"INFO"}, line)
        return {"FINISHED"}


_seen = {}  # scene pointer -> how many objects it had at the last sweep


@persistent
def _on_depsgraph_update(scene, depsgraph):
    if getattr(scene, "headrecon", None) is None or not depsgraph.id_type_updated("OBJECT"):
        return
    # Only when objects came or went (a deleted plane, a new one): not on every drag.
    count = len(scene.objects)
    if _seen.get(scene.as_pointer()) == count:
        return
    _seen[scene.as_pointer()] = count
    try:
        parked, rehomed = sweep(scene)
        if parked or rehomed:
            LIVE.forget()  # the fit in memory had another set of views
    except Exception as e:  # noqa: BLE001  (a handler must not raise)
        print(f"HeadRecon: tidying after a deleted photo or camera failed: {e}")


_HANDLERS = (("depsgraph_update_post", _on_depsgraph_update),)


def register_handlers():
    app_handlers.add(_HANDLERS)


def unregister_handlers():
    _seen.clear()
    app_handlers.remove(_HANDLERS)


CLASSES = (HEADRECON_OT_remove_photo,)
