"""Operators of the Result panel on the fitted head: Apply Identity, Export Head (game
presets) and Import ARKit Animation (a Live Link Face CSV on the expression keys)."""

import bpy
from bpy.props import BoolProperty, EnumProperty, StringProperty

from . import apply_identity, arkit_animation, export
from .polls import object_mode_problem, poll_result
from .reference_head import fitted_head_problem, scene_head
from .solver_link import load_model


class HEADRECON_OT_apply_identity(bpy.types.Operator):
    """Make the fitted face the head's base mesh: the identity keys go into the Basis and
    the expression keys still give the same expressions on top of it (for engines and tools
    that ignore shape key values)"""

    bl_idname = "headrecon.apply_identity"
    bl_label = "Apply Identity"
    bl_options = {"REGISTER", "UNDO"}

    keep_muted: BoolProperty(
        name="Keep Identity Keys",
        description="Keep the identity keys, muted, instead of removing them (unmuting them "
                    "would add the identity a second time)",
        default=False)

    @classmethod
    def poll(cls, context):
        problem = object_mode_problem(context) or fitted_head_problem(context)
        if problem is None:
            problem = apply_identity.identity_problem(scene_head(context),
                                                      load_model().expression_names)
        return poll_result(cls, problem)

    def execute(self, context):
        head = scene_head(context)
        try:
            names = apply_identity.apply_identity(head, load_model().expression_names,
                                                  keep_muted=self.keep_muted)
        except Exception as e:
            self.report({"ERROR"}, f"Apply Identity: {e}")
            return {"CANCELLED"}
        kept = "kept muted" if self.keep_muted else "removed"
        self.report({"INFO"}, f"{head.name}: the fitted face is the base mesh; "
                              f"{len(names)} identity keys {kept}")
        return {"FINISHED"}


_FORMAT_HELP = {"GLB": "Binary glTF, texture embedded (Unity, Unreal, Godot, three.js)",
                "FBX": "FBX with blend shapes, texture embedded and as PNG files beside it"}
_FORMAT_ITEMS = [(f, f".{f.lower()}", _FORMAT_HELP[f]) for f in export.FORMATS]


class HEADRECON_OT_export_head(bpy.types.Operator):
    """Export the fitted head for a game engine: the fitted face as the base mesh, the ARKit
    expression keys as morph targets at 0, the texture embedded"""

    bl_idname = "headrecon.export_head"
    bl_label = "Export Head"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(subtype="FILE_PATH", options={"SKIP_SAVE"},
                             description="Where the .glb or .fbx is written")
    filter_glob: StringProperty(default="*.glb;*.fbx", options={"HIDDEN"})
    export_format: EnumProperty(name="Format", items=_FORMAT_ITEMS,
                                description="The file format to write")
    morph_normals: BoolProperty(
        name="Morph Normals",
        description="Write each expression's normals too (.glb; about doubles the file, "
                    "most engines recompute them)",
        default=False)

    @classmethod
    def poll(cls, context):
        return poll_result(cls, object_mode_problem(context) or fitted_head_problem(context))

    def invoke(self, context, event):
        if not self.filepath:  # next to the .blend when it is saved
            name = bpy.path.clean_name(scene_head(context).name) + export.SUFFIX[self.export_format]
            self.filepath = bpy.path.abspath("//" + name) if bpy.data.filepath else name
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        if not self.filepath:
            self.report({"ERROR"}, "Export Head: no file given")
            return {"CANCELLED"}
        try:
            path = export.export_head(bpy.path.abspath(self.filepath), scene_head(context),
                                      load_model().expression_names, self.export_format,
                                      morph_normals=self.morph_normals, scene=context.scene)
        except Exception as e:
            self.report({"ERROR"}, f"Export Head: {e}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Wrote {path} ({path.stat().st_size / 1e6:.1f} MB)")
        return {"FINISHED"}


class HEADRECON_OT_import_arkit_animation(bpy.types.Operator):
    """Play an ARKit capture on the head: a Live Link Face CSV becomes an action on the
    expression keys (by Apple's names), one keyframe per row"""

    bl_idname = "headrecon.import_arkit_animation"
    bl_label = "Import ARKit Animation"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(subtype="FILE_PATH", options={"SKIP_SAVE"},
                             description="The Live Link Face CSV take to import")
    filter_glob: StringProperty(default="*.csv", options={"HIDDEN"})
    timecode_fps: EnumProperty(
        name="Timecode Rate",
        items=[(str(f), f"{f} fps", f"The capture's timecode counts {f} frames a second")
               for f in arkit_animation.TIMECODE_RATES],
        default=str(arkit_animation.DEFAULT_TIMECODE_FPS),
        description="Frame rate of the capture's timecode (Live Link Face records 60 fps)")

    @classmethod
    def poll(cls, context):
        return poll_result(cls, object_mode_problem(context) or fitted_head_problem(context))

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        try:
            take = arkit_animation.read_live_link_csv(self.filepath, int(self.timecode_fps))
            action, skipped = arkit_animation.apply_take(scene_head(context), take, context.scene)
        except ValueError as e:  # the file's problem, said with its line and column
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        except Exception as e:
            self.report({"ERROR"}, f"Import ARKit Animation: {type(e).__name__}: {e}")
            return {"CANCELLED"}
        note = f"; no key for {', '.join(skipped)}" if skipped else ""
        self.report({"INFO"}, f"{action.name}: {len(take.times)} frames on "
                              f"{len(take.names) - len(skipped)} keys{note}")
        return {"FINISHED"}


CLASSES = (HEADRECON_OT_apply_identity, HEADRECON_OT_export_head,
           HEADRECON_OT_import_arkit_animation)
