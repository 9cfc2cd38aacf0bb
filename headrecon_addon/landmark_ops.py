"""The landmark tools and operators: placing landmarks and passpoints by clicking on a
photo, tracing the contour, clearing a photo, importing and exporting the landmarks file,
editing the calibration object's points, selecting a landmark.

Modal operators cannot run in background tests, so their logic lives in plain functions
and in ``PlacementSession`` / ``ContourSession``; the operators only translate events.
"""

import bpy
from bpy.props import StringProperty
from bpy_extras.io_utils import ExportHelper, ImportHelper
from mathutils import Vector

from . import calibration_object, case_to_scene, landmarks, photos, scene_to_case
from .polls import ObjectModeOperator, object_mode_problem, poll_result, view3d_problem
from .warm_up import warm_up

# --------------------------------------------------------------------------------------
# Interactive tools: logic


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
            defs = landmarks.landmark_definitions(photos.view_kind(plane))
        else:
            known = {e["name"]: e for e in landmarks.landmark_set().info}
            defs = [known.get(landmarks.canonical_name(n), {"name": n, "description": ""})
                    for n in names]
        self.definitions = defs
        placed = landmarks.marker_objects(plane, role)
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
        landmarks.place_marker_local(self.plane, self.current["name"], xy, self.role)
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
            landmarks.remove_landmark(self.plane, self.current["name"], self.role)

    def header(self):
        n = len(self.definitions)
        what = "Passpoint" if self.role == "PASSPOINT" else "Landmark"
        if self.done:
            return f"HeadRecon: all {n} {what.lower()}s visited. Esc: done"
        d = self.current
        placed = d["name"] in landmarks.marker_objects(self.plane, self.role)
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
        landmarks.add_contour_point_local(self.plane, xy)
        self.added += 1
        return True

    def undo_point(self):
        landmarks.remove_last_contour_point(self.plane)

    def header(self):
        n = len(landmarks.contour_local(self.plane))
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
            passpoints = calibration_object.case_passpoints(context.scene)
            self.session = PlacementSession(plane, role="PASSPOINT", passpoints=passpoints)
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

    view: StringProperty(name="View", options={"SKIP_SAVE"},
                         description="Photo view name (empty: the active object's photo)")

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
        landmarks.clear_landmarks(plane)
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
            planes = case_to_scene.import_landmarks(context, self.filepath)
        except (ValueError, OSError) as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        n = sum(len(landmarks.landmark_objects(p)) for p in planes)
        self.report({"INFO"}, f"Imported {n} landmarks on {len(planes)} photos")
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
            case = scene_to_case.export_landmarks(context.scene, self.filepath)
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
                calibration_object.remove_case_passpoint(context.scene, self.name)
            else:
                calibration_object.set_case_passpoint(context.scene, self.name, self.location)
        except ValueError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        return {"FINISHED"}


class HEADRECON_OT_select_landmark(ObjectModeOperator, bpy.types.Operator):
    """Select this landmark"""

    bl_idname = "headrecon.select_landmark"
    bl_label = "Select Landmark"
    bl_options = {"REGISTER", "UNDO"}

    view: StringProperty(name="View", description="Photo view name of the landmark")
    landmark: StringProperty(name="Landmark", description="Landmark or passpoint name")

    def execute(self, context):
        if landmarks.select_landmark(context, self.view, self.landmark) is None:
            self.report({"ERROR"}, f"Landmark {self.landmark!r} of view {self.view!r} is not "
                        "placed")
            return {"CANCELLED"}
        return {"FINISHED"}


CLASSES = (HEADRECON_OT_place_landmarks, HEADRECON_OT_draw_contour,
           HEADRECON_OT_clear_landmarks, HEADRECON_OT_import_landmarks,
           HEADRECON_OT_export_landmarks, HEADRECON_OT_edit_passpoint,
           HEADRECON_OT_select_landmark)
