"""Export presets for game engines: the fitted head as .glb (or .fbx) with its expressions.

What an engine gets: the fitted face as the base mesh (identity applied on a temporary
copy of the head, so the scene is not changed), the expression keys as morph targets /
blend shapes by Apple's ARKit names (plus the model's extras), all at weight 0, the baked
texture embedded, the eyes painted as an image (the eye shader's nodes do not export), and
no morph normals unless asked for (they double the file and
engines recompute normals). The fitted similarity stays the node's transform.

The glTF exporter embeds images from their pixels; the FBX exporter only embeds image
files, so for .fbx every image without a file on disk (the baked textures) is written as a
PNG into ``<name>_textures/`` beside the .fbx, and the copy's materials use those files.
"""

import gc
from contextlib import contextmanager
from pathlib import Path

import bpy
import numpy as np

from . import apply_identity, material

FORMATS = ("GLB", "FBX")
SUFFIX = {"GLB": ".glb", "FBX": ".fbx"}
_EXPORTERS = {"GLB": ("io_scene_gltf2", "EXPORT_SCENE_OT_gltf"),
              "FBX": ("io_scene_fbx", "EXPORT_SCENE_OT_fbx")}


def exporter_available(fmt):
    """True when Blender's exporter for ``fmt`` ("GLB" | "FBX") can be used (enabling its
    bundled add-on if needed)."""
    import addon_utils

    module, op = _EXPORTERS[fmt]
    if not hasattr(bpy.types, op):
        try:
            addon_utils.enable(module, default_set=False)
        except Exception:
            return False
    return hasattr(bpy.types, op)


@contextmanager
def _game_copy(head, model_expression_names, scene):
    """A temporary copy of ``head`` under its name, identity applied (when it has identity
    keys), linked to ``scene``; removed afterwards and the head's name given back."""
    mesh = head.data.copy()
    copy = head.copy()
    copy.data = mesh  # the mesh's copy has its own copy of the shape keys (and their action)
    name = head.name
    scene.collection.objects.link(copy)
    try:
        head.name = name + " (exporting)"
        copy.name = name
        if apply_identity.identity_key_names(copy, model_expression_names):
            apply_identity.apply_identity(copy, model_expression_names)
        yield copy
    finally:
        bpy.data.objects.remove(copy)
        bpy.data.meshes.remove(mesh)
        head.name = name


@contextmanager
def _painted_eyes(obj):
    """``obj``'s (a game copy's own mesh) eye material replaced, for the export, by one
    whose base colour is the eyes painted as an image (``material.eye_image``, each eye in
    its own half with its UVs squeezed into it, the iris's colour as the head's eye
    material has it): exporters cannot follow the eye shader's nodes and would write a
    white eyeball. One material and one image: no extra mesh part for the exporter to
    split off. Undone afterwards."""
    mesh = obj.data
    slot = next((i for i, m in enumerate(mesh.materials)
                 if m is not None and m.get(material.GROUP_KEY) == "Eyes"), None)
    if slot is None or mesh.uv_layers.active is None:
        yield
        return
    eyes = mesh.materials[slot]
    layer = mesh.uv_layers.active.data
    pixels, uv, squeezed = material.eye_image(mesh, slot, material.iris_colours(eyes))
    img = bpy.data.images.new(f"{eyes.name} Image", pixels.shape[1], pixels.shape[0])
    flat = None
    try:
        img.pixels.foreach_set(pixels.ravel())
        flat = bpy.data.materials.new(eyes.name)
        tex = material.set_skin_texture(flat, img)  # the image as its base colour
        tex.outputs["Color"].links[0].to_node.inputs["Roughness"].default_value = 0.1
        layer.foreach_set("uv", squeezed.ravel())
        mesh.materials[slot] = flat
        yield
    finally:
        layer.foreach_set("uv", uv.ravel())
        mesh.materials[slot] = eyes
        if flat is not None:
            bpy.data.materials.remove(flat)
        bpy.data.images.remove(img)


def _on_disk(img):
    return img.source == "FILE" and bool(img.filepath) and Path(
        bpy.path.abspath(img.filepath)).is_file()


def _image_file(img, folder):
    """A new image with ``img``'s pixels saved as ``folder/<name>.png`` (bpy Image)."""
    w, h = img.size
    px = np.empty(w * h * 4, dtype=np.float32)
    img.pixels.foreach_get(px)
    out = bpy.data.images.new(img.name + " (file)", w, h, alpha=True)
    out.pixels.foreach_set(px)
    folder.mkdir(parents=True, exist_ok=True)
    out.filepath_raw = str(folder / (bpy.path.clean_name(img.name) + ".png"))
    out.file_format = "PNG"
    out.save()
    return out


@contextmanager
def _textures_as_files(obj, folder):
    """Give ``obj`` (the temporary copy) copies of its materials whose images without a
    file are saved into ``folder``; the copies are removed afterwards (the files stay)."""
    materials, images = [], {}

    def needs_file(node):
        return (node.type == "TEX_IMAGE" and node.image is not None and node.image.has_data
                and not _on_disk(node.image))

    try:
        for slot in obj.material_slots:
            mat = slot.material
            if mat is None or mat.node_tree is None or not any(
                    needs_file(n) for n in mat.node_tree.nodes):
                continue
            new = mat.copy()
            materials.append(new)
            slot.material = new
            for node in filter(needs_file, new.node_tree.nodes):
                if node.image.name not in images:
                    images[node.image.name] = _image_file(node.image, folder)
                node.image = images[node.image.name]
        yield
    finally:
        if materials:
            bpy.data.batch_remove(materials)
        if images:
            bpy.data.batch_remove(list(images.values()))


def _select_only(obj):
    layer = bpy.context.view_layer
    layer.update()  # objects linked since the last update are not in layer.objects yet
    for o in layer.objects:
        o.select_set(o == obj)
    layer.objects.active = obj


def export_head(path, head, model_expression_names, fmt="GLB", morph_normals=False,
                scene=None):
    """Write ``head`` for a game engine.

    Parameters
    ----------
    path : str or Path
        The file to write (its suffix is set to ``fmt``'s).
    head : bpy.types.Object
        A fitted head (identity applied or not: the file always has the fitted base).
    model_expression_names : sequence of str
        ``HeadModel.expression_names`` (tells the identity keys from the expressions).
    fmt : {"GLB", "FBX"}
    morph_normals : bool
        Also write each morph target's normals (.glb only).
    scene : bpy.types.Scene, optional
        Default: the current scene.

    Returns
    -------
    Path
        The file written.
    """
    if fmt not in FORMATS:
        raise ValueError(f"export format {fmt!r}: expected one of {', '.join(FORMATS)}")
    if not exporter_available(fmt):
        raise RuntimeError(f"Blender's {fmt} exporter is not available here")
    path = Path(path).with_suffix(SUFFIX[fmt]).resolve()
    path.parent.mkdir(parents=True, exist_ok=True)
    scene = scene or bpy.context.scene
    selected = [o for o in bpy.context.view_layer.objects if o.select_get()]
    active = bpy.context.view_layer.objects.active
    try:
        with _game_copy(head, model_expression_names, scene) as copy, _painted_eyes(copy):
            _select_only(copy)
            if fmt == "GLB":
                bpy.ops.export_scene.gltf(
                    filepath=str(path), export_format="GLB", use_selection=True,
                    export_apply=False, export_morph=True, export_morph_normal=morph_normals,
                    export_morph_tangent=False, export_try_sparse_sk=True)
            else:
                with _textures_as_files(copy, path.parent / f"{path.stem}_textures"):
                    bpy.ops.export_scene.fbx(
                        filepath=str(path), use_selection=True, object_types={"MESH"},
                        use_mesh_modifiers=False, add_leaf_bones=False, path_mode="COPY",
                        embed_textures=True, bake_anim=False)
    finally:
        layer = bpy.context.view_layer
        for o in layer.objects:
            o.select_set(o in selected)
        layer.objects.active = active
        # The exporter leaves its data in reference cycles (about 13 600 objects for a
        # head's .glb, 60-100 MB that a batch worker otherwise kept into the next head):
        # collected now, not whenever Python next gets round to it (20-40 ms).
        gc.collect()
    return path
