"""The "HeadRecon" tab of the 3D viewport's sidebar: one panel per step of the artist's
flow (reference head, photos, landmarks, fit, result)."""

import bpy

from . import calibration_object, landmarks, photos, reference_head
from .live_refit import LIVE
from .properties import ADVANCED_FIT_SETTINGS


class _Panel:
    # No bl_idname: a panel's ID is its class name.
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "HeadRecon"


class HEADRECON_PT_head(_Panel, bpy.types.Panel):
    bl_label = "1. Reference Head"

    def draw(self, context):
        layout = self.layout
        head = context.scene.headrecon.head
        if reference_head.is_head(head):
            layout.label(text=head.name, icon="USER")
            # one head per scene: a second one only when asked for by name
            layout.operator("headrecon.add_head", text="Add Another Head",
                            icon="ADD").another = True
        else:
            layout.label(text="No head yet (Fit makes one too)", icon="INFO")
            layout.operator("headrecon.add_head", icon="ADD")
        layout.prop(context.scene.headrecon, "head")


def _load_photo(layout, text, icon, view="", projection="PERSPECTIVE",
                camera_view="orthographic-front", lens_mm=0.0):
    op = layout.operator("headrecon.load_photo", text=text, icon=icon)
    op.view = view
    op.projection = projection
    op.camera_view = camera_view
    op.lens_mm = lens_mm


class HEADRECON_PT_photos(_Panel, bpy.types.Panel):
    bl_label = "2. Photos"

    def draw(self, context):
        layout = self.layout
        planes = photos.photo_planes(context.scene)
        # several photos at once, each into its view by its name and shape
        _load_photo(layout, "Load Photos...", "FILE_IMAGE", "", "FROM_EXIF", photos.AUTO)
        kinds = set()
        for plane in planes:
            props = plane.headrecon
            perspective = photos.is_perspective(plane)
            kinds.add("front" if photos.view_kind(plane) == "front" else "side")
            box = layout.box()
            row = box.row(align=True)
            img = props.image
            row.label(text=f"{props.view}: {img.name if img else '(no photo)'}",
                      icon="IMAGE_DATA")
            row.operator("headrecon.view_photo", text="",
                         icon="VIEW_CAMERA" if perspective else "HIDE_OFF").view = props.view
            _load_photo(row, "", "FILEBROWSER", props.view,
                        "PERSPECTIVE" if perspective else "FROM_EXIF", props.camera_view,
                        float(photos.lens_hint(plane) or 0.0))
            row.operator("headrecon.remove_photo", text="", icon="X").view = props.view
            box.label(text=photos.camera_label(plane),
                      icon="CAMERA_DATA" if perspective else "VIEW_ORTHO")
            if photos.camera_kind(plane) == "pinhole":
                box.prop(props, "lens_mm", text="Focal Length (EXIF)" if props.lens_from_exif
                         else "Focal Length")
            if not props.camera_json and not landmarks.passpoint_objects(plane):
                # the nominal camera, or where a camera to compute starts (passpoints place
                # theirs)
                box.prop(props, "camera_view", text="Direction")
            if len(planes) > 1 or photos.mirror_of(plane):
                box.prop(props, "mirror_of")
        if "front" not in kinds:
            _load_photo(layout, "Load Front Photo...", "FILEBROWSER", "front", "FROM_EXIF")
        if "side" not in kinds:
            _load_photo(layout, "Load Profile Photo...", "FILEBROWSER", "side", "FROM_EXIF",
                        "orthographic-right")
        _load_photo(layout, "Add Photo (Any Camera)...", "ADD")


class HEADRECON_PT_calibration(_Panel, bpy.types.Panel):
    """The calibration object's points (3-D positions) that photos' passpoints refer to."""

    bl_label = "Calibration Object"
    bl_parent_id = "HEADRECON_PT_photos"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        points = calibration_object.case_passpoints(context.scene)
        if not points:
            layout.label(text="No passpoints (3-D points of a calibration object)", icon="INFO")
        col = layout.column(align=True)
        for name, xyz in points.items():
            row = col.row(align=True)
            row.label(text=f"{name}: " + ", ".join(f"{c:.4f}" for c in xyz) + " m")
            op = row.operator("headrecon.edit_passpoint", text="", icon="GREASEPENCIL")
            op.name, op.location = name, xyz
            op = row.operator("headrecon.edit_passpoint", text="", icon="X")
            op.name, op.remove = name, True
        layout.operator("headrecon.edit_passpoint", text="Add Passpoint...", icon="ADD")


class HEADRECON_PT_landmarks(_Panel, bpy.types.Panel):
    bl_label = "3. Landmarks"

    def draw(self, context):
        layout = self.layout
        planes = photos.photo_planes(context.scene)
        case_passpoints = calibration_object.case_passpoints(context.scene)
        if not planes:
            layout.label(text="Load the photos first", icon="INFO")
        replace = context.scene.headrecon.replace_hand_placed
        for plane in planes:
            view = plane.headrecon.view
            placed = len(landmarks.landmark_objects(plane))
            detected = len(landmarks.detected_landmarks(plane))
            total = len(landmarks.landmark_definitions(photos.view_kind(plane)))
            box = layout.box()
            box.label(text=f"{view}: {placed} / {total} placed"
                      + (f" ({detected} detected)" if detected else ""), icon="EMPTY_AXIS")
            row = box.row(align=True)
            row.operator("headrecon.place_landmarks", text="Place",
                         icon="RESTRICT_SELECT_OFF").view = view
            op = row.operator("headrecon.detect_landmarks", text="Detect", icon="VIEWZOOM")
            op.view = view
            op.replace_hand_placed = replace
            op = row.operator("headrecon.detect_outline", text="Outline", icon="MOD_MASK")
            op.view = view
            op.replace_hand_placed = replace
            if photos.view_kind(plane) != "front":
                n = len(landmarks.contour_local(plane))
                row.operator("headrecon.draw_contour", text=f"Contour ({n})",
                             icon="CURVE_PATH").view = view
            row.operator("headrecon.clear_landmarks", text="", icon="TRASH").view = view
            if case_passpoints and photos.is_perspective(plane):
                n = len(landmarks.passpoint_objects(plane))
                op = box.operator("headrecon.place_landmarks",
                                  text=f"Passpoints ({n} / {len(case_passpoints)})",
                                  icon="PIVOT_CURSOR")
                op.view = view
                op.passpoints = True
        if planes:
            col = layout.column(align=True)
            op = col.operator("headrecon.detect_landmarks", text="Detect on All Photos",
                              icon="VIEWZOOM")
            op.replace_hand_placed = replace
            op = col.operator("headrecon.detect_outline", text="Detect Outline on All Photos",
                              icon="MOD_MASK")
            op.replace_hand_placed = replace
            col.operator("headrecon.auto_fit", icon="AUTO").replace_hand_placed = replace
            col.prop(context.scene.headrecon, "replace_hand_placed")
        row = layout.row(align=True)
        row.operator("headrecon.import_landmarks", text="Import...", icon="IMPORT")
        row.operator("headrecon.export_landmarks", text="Export...", icon="EXPORT")


class HEADRECON_PT_fit(_Panel, bpy.types.Panel):
    bl_label = "4. Fit"

    def draw(self, context):
        layout = self.layout
        props = context.scene.headrecon
        col = layout.column()
        col.use_property_split = True
        col.use_property_decorate = False
        col.prop(props, "method")
        col.prop(props, "bake_texture")
        sub = col.row()
        sub.enabled = props.bake_texture
        sub.prop(props, "texture_size")
        sub = col.row()
        sub.enabled = props.bake_texture
        sub.prop(props, "texture_shading")
        sub = col.row()
        sub.enabled = props.bake_texture
        sub.prop(props, "texture_clothes")
        layout.operator("headrecon.fit", icon="MOD_SHRINKWRAP")
        row = layout.row(align=True)
        row.prop(props, "live_refit", toggle=True, icon="PLAY")
        row.operator("headrecon.refit_landmarks", text="", icon="FILE_REFRESH")
        stats = LIVE.stats()
        if props.live_refit:
            if not stats["ready"]:
                layout.label(text="Live refit starts after a Fit", icon="INFO")
            elif stats["error"]:
                layout.label(text=stats["error"], icon="ERROR")
            elif stats["ms"]:
                layout.label(text=f"Last refit: {stats['ms']:.0f} ms", icon="TIME")
        if stats["moved"] and not stats["error"]:
            # a live or quick refit keeps the cameras and the outline: it moves the head
            # little (docs/DECISIONS.md, "six ways at hair")
            layout.label(text="Fit again to take the moved points in", icon="INFO")
        if props.status:
            layout.label(text=props.status, icon="CHECKMARK")


class HEADRECON_PT_fit_advanced(_Panel, bpy.types.Panel):
    """The fit's model and weights (the defaults work): components, λ1, λ2, prior,
    landmark weight, exact landmarks, and a reset to the defaults."""

    bl_label = "Advanced"
    bl_parent_id = "HEADRECON_PT_fit"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        props = context.scene.headrecon
        col = layout.column()
        col.use_property_split = True
        col.use_property_decorate = False
        for name in ADVANCED_FIT_SETTINGS:
            col.prop(props, name)
        layout.operator("headrecon.reset_fit_settings", icon="LOOP_BACK")


class HEADRECON_UL_residuals(bpy.types.UIList):
    """Residuals of the last fit, landmarks and passpoints (a photo's calibration);
    suspect passpoints first, then flagged landmarks."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname,
                  index=0):
        row = layout.row(align=True)
        what = "passpoint " if item.kind == "PASSPOINT" else ""
        row.label(text=f"{item.view}: {what}{item.landmark}",
                  icon="ERROR" if item.flagged else "CHECKMARK")
        row.label(text=f"{item.pixels:.1f} px")


class HEADRECON_PT_result(_Panel, bpy.types.Panel):
    bl_label = "5. Result"

    def draw(self, context):
        layout = self.layout
        scene = context.scene
        head = scene.headrecon.head
        if not reference_head.is_head(head) or head.data.shape_keys is None:
            layout.label(text="Fit the head to see its result", icon="INFO")
            return
        props = head.headrecon
        col = layout.column(align=True)
        col.label(text=f"Method: {props.fit_method}")
        col.label(text=f"RMS residual: {props.fit_rms_px:.2f} px")
        rows = scene.headrecon.residuals
        flagged = sum(1 for r in rows if r.flagged and r.kind == "LANDMARK")
        col.label(text=f"Flagged landmarks: {flagged}",
                  icon="ERROR" if flagged else "CHECKMARK")
        if any(r.kind == "PASSPOINT" for r in rows):
            suspects = sum(1 for r in rows if r.flagged and r.kind == "PASSPOINT")
            col.label(text=f"Suspect passpoints: {suspects}",
                      icon="ERROR" if suspects else "CHECKMARK")
        active = scene.headrecon.residual_index
        if 0 <= active < len(rows) and rows[active].message:
            col.label(text=rows[active].message, icon="INFO")
        if props.uncertainty_max_mm > 0:
            col.label(text=f"Uncertainty colours: blue 0 mm, red ≥ "
                           f"{props.uncertainty_max_mm:.1f} mm")
        layout.template_list("HEADRECON_UL_residuals", "", scene.headrecon, "residuals",
                             scene.headrecon, "residual_index", rows=6)
        key = head.data.shape_keys
        layout.label(text=f"{len(key.key_blocks) - 1} shape keys (Object Data > Shape Keys)",
                     icon="SHAPEKEY_DATA")
        col = layout.column(align=True)
        col.operator("headrecon.apply_identity", icon="SHAPEKEY_DATA")
        col.operator("headrecon.import_arkit_animation", text="Import ARKit Animation...",
                     icon="ACTION")
        col.operator("headrecon.export_head", text="Export Head (.glb / .fbx)...",
                     icon="EXPORT")
        col.operator("headrecon.save_texture", icon="IMAGE_DATA")


CLASSES = (HEADRECON_PT_head, HEADRECON_PT_photos, HEADRECON_PT_calibration,
           HEADRECON_PT_landmarks, HEADRECON_PT_fit, HEADRECON_PT_fit_advanced,
           HEADRECON_UL_residuals, HEADRECON_PT_result)
