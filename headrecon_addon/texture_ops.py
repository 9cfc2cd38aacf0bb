"""Save Texture: the fitted head's baked texture written as a PNG file, the skin's UV tiles
side by side (the layout of the OBJ's texture and of the headless ``texture`` output,
``solver/io/export.py::texture_atlas``), by default next to the saved .blend as
``<blend name>_texture.png``. Any image file the scene uses (the photos) is never
overwritten (``solver/io/atomic.py::check_outputs``).

:func:`save_texture` is the plain function for scripts; the operator asks for a path when
the .blend is not saved yet.
"""

from pathlib import Path

import bpy
from bpy.props import StringProperty

from . import material, photos, reference_head, result_to_scene
from .polls import poll_result
from .reference_head import fitted_head_problem, scene_head
from .solver_link import load_model, solver_module

SUFFIX = "_texture.png"


def baked_tiles(head, model):
    """The head's baked skin textures: dict UDIM tile -> ndarray (S, S, 4) float32, row 0 at
    the top (empty when nothing is baked)."""
    tiles = {}
    for group, tile in result_to_scene.skin_group_tiles(model).items():
        mat = reference_head.part_material(head, group)
        img = material.skin_texture(mat) if mat is not None else None
        if img is not None and img.get(result_to_scene.BAKED):
            tiles[tile] = photos.image_to_array(img)
    return tiles


def default_texture_path(blend_path=None):
    """``<blend>_texture.png`` beside the .blend (default the open file), or None when the
    file is not saved."""
    blend = blend_path if blend_path is not None else bpy.data.filepath
    if not blend:
        return None
    blend = Path(blend)
    return blend.with_name(blend.stem + SUFFIX)


def _used_image_files():
    """What each image file the open .blend uses is called in a message -> its path."""
    out = {}
    for img in bpy.data.images:
        if img.source == "FILE" and img.filepath and not img.get(result_to_scene.BAKED):
            out[f"the image {img.name!r}"] = Path(bpy.path.abspath(img.filepath,
                                                                   library=img.library))
    return out


def save_texture(head, path, model=None):
    """Write the head's baked texture to ``path`` (PNG, written atomically).

    Parameters
    ----------
    head : bpy.types.Object
        The fitted head.
    path : path-like
        The PNG to write; refused (``ValueError`` naming both files) when it is an image
        file the scene uses, e.g. a photo.
    model : HeadModel, optional
        Default ``load_model()``.

    Returns
    -------
    Path
        The file written.
    """
    model = model if model is not None else load_model()
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ValueError(f"{path}: give a .png file name")
    tiles = baked_tiles(head, model)
    if not tiles:
        raise ValueError(f"{head.name} has no baked texture (Fit with Bake Texture on)")
    solver_module("io.atomic").check_outputs({"the texture": path}, _used_image_files())
    atlas, _, _ = solver_module("io.export").texture_atlas(model, tiles)
    path.parent.mkdir(parents=True, exist_ok=True)
    solver_module("io.atomic").write_file_atomic(
        path, solver_module("io.export").png_bytes(atlas[..., :3]))
    return path


def texture_problem(context):
    """Why Save Texture cannot run (no fitted head, nothing baked), or None."""
    problem = fitted_head_problem(context)
    if problem:
        return problem
    for mat in scene_head(context).data.materials:
        img = material.skin_texture(mat) if mat is not None else None
        if img is not None and img.get(result_to_scene.BAKED):
            return None
    return "The head has no baked texture: Fit with Bake Texture on"


class HEADRECON_OT_save_texture(bpy.types.Operator):
    """Write the head's baked texture as a PNG (the skin's UV tiles side by side, as the
    OBJ export uses) next to the saved .blend, or where you choose when it is not saved"""

    bl_idname = "headrecon.save_texture"
    bl_label = "Save Texture"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(subtype="FILE_PATH", options={"SKIP_SAVE"},
                             description="The PNG file to write the baked texture to "
                                         "(never a photo the scene uses)")
    filter_glob: StringProperty(default="*.png", options={"HIDDEN"})

    @classmethod
    def poll(cls, context):
        return poll_result(cls, texture_problem(context))

    def invoke(self, context, event):
        if self.filepath or bpy.data.filepath:
            return self.execute(context)
        self.filepath = bpy.path.clean_name(scene_head(context).name) + SUFFIX
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        path = bpy.path.abspath(self.filepath) if self.filepath else default_texture_path()
        if not path:
            self.report({"ERROR"}, "Save Texture: save the .blend first, or give a file path")
            return {"CANCELLED"}
        try:
            written = save_texture(scene_head(context), path)
        except (ValueError, OSError) as e:
            self.report({"ERROR"}, f"Save Texture: {e}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"Wrote {written} ({written.stat().st_size / 1e6:.1f} MB)")
        return {"FINISHED"}


CLASSES = (HEADRECON_OT_save_texture,)
