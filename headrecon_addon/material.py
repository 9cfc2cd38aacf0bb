"""Materials of the head, the photo planes and the landmarks, and the uncertainty colour ramp.

Node trees are built by name so they work unchanged on Blender 4.2 and 5.x (the socket
names used here, "Base Color", "Roughness", "Alpha", "Color", "Strength", exist in both).
"""

import bpy
import numpy as np

# Part groups of the ICT mesh: (material suffix, keywords in the ICT part name, colour RGBA).
# First match wins.
PART_GROUPS = (
    ("Eye Wetness", ("lacrimal", "blend", "occlusion"), (1.0, 1.0, 1.0, 0.0)),
    # ICT's eyelashes are flat strips made for an alpha-mapped texture: opaque, they read
    # as grey slabs over the eyes, so they start invisible (still deformed by the keys).
    ("Eyelashes", ("eyelash",), (0.02, 0.015, 0.01, 0.0)),
    ("Eyes", ("eyeball",), (0.85, 0.85, 0.82, 1.0)),
    ("Teeth", ("teeth", "tooth"), (0.9, 0.87, 0.78, 1.0)),
    ("Mouth", ("mouth", "gum", "tongue"), (0.45, 0.12, 0.12, 1.0)),
    ("Sockets", ("socket",), (0.05, 0.02, 0.02, 1.0)),
    ("Face", ("face",), (0.8, 0.6, 0.5, 1.0)),
    ("Head", ("head", "neck"), (0.8, 0.6, 0.5, 1.0)),
)
# Material slot order on the head: the skin first.
SLOT_ORDER = ("Face", "Head", "Eyes", "Eye Wetness", "Eyelashes", "Mouth", "Teeth", "Sockets")
# The skin groups: what the photos texture (one UV tile each in the ICT layout).
SKIN_GROUPS = ("Face", "Head")
TEXTURE_NODE = "HeadRecon Texture"
GROUP_KEY = "headrecon_group"  # custom property naming a head material's part group
PHOTO_NODE = "HeadRecon Photo"

LANDMARK_COLOURS = {
    "PLACED": (0.1, 0.85, 0.2, 1.0),
    "FLAGGED": (1.0, 0.08, 0.05, 1.0),
}


def part_group(part_name):
    """Material group (a PART_GROUPS suffix) of an ICT geometry part name."""
    low = part_name.lower()
    for group, words, _ in PART_GROUPS:
        if any(w in low for w in words):
            return group
    return "Face"


def ensure_nodes(mat):
    """Give ``mat`` its node tree (always there from Blender 5.0, where ``use_nodes`` is
    deprecated; 4.x needs it switched on)."""
    if bpy.app.version < (5, 0, 0) and not mat.use_nodes:
        mat.use_nodes = True
    return mat.node_tree


def _principled(mat):
    ensure_nodes(mat)
    nodes = mat.node_tree.nodes
    bsdf = next((n for n in nodes if n.type == "BSDF_PRINCIPLED"), None)
    if bsdf is None:
        nodes.clear()
        out = nodes.new("ShaderNodeOutputMaterial")
        bsdf = nodes.new("ShaderNodeBsdfPrincipled")
        mat.node_tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return bsdf


def _set_transparent(mat):
    # 4.2+ (EEVEE Next): surface_render_method; blend_method is only kept for old files.
    if hasattr(mat, "surface_render_method"):
        mat.surface_render_method = "DITHERED"
    elif hasattr(mat, "blend_method"):
        mat.blend_method = "HASHED"


def new_part_material(group, name_prefix="HeadRecon"):
    """A new material for one part group of the head (not shared: each head owns its own,
    so a re-fit or a delete of one head never touches another's)."""
    colour = next(c for g, _, c in PART_GROUPS if g == group)
    mat = bpy.data.materials.new(f"{name_prefix} {group}")
    mat[GROUP_KEY] = group
    bsdf = _principled(mat)
    bsdf.inputs["Base Color"].default_value = colour[:3] + (1.0,)
    bsdf.inputs["Roughness"].default_value = 0.1 if group in ("Eyes", "Eye Wetness") else 0.55
    mat.diffuse_color = colour
    if colour[3] < 1.0:
        bsdf.inputs["Alpha"].default_value = colour[3]
        _set_transparent(mat)
    return mat


def set_skin_texture(mat, image):
    """Use ``image`` as the skin's base colour (adds or reuses the texture node)."""
    bsdf = _principled(mat)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    tex = nodes.get(TEXTURE_NODE)
    if tex is None:
        tex = nodes.new("ShaderNodeTexImage")
        tex.name = tex.label = TEXTURE_NODE
        tex.location = (bsdf.location.x - 320, bsdf.location.y)
    tex.image = image
    links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    mat.diffuse_color = (1.0, 1.0, 1.0, 1.0)
    return tex


def skin_texture(mat):
    """The image of the skin's texture node, or None."""
    if mat is None or mat.node_tree is None:
        return None
    tex = mat.node_tree.nodes.get(TEXTURE_NODE)
    return tex.image if tex is not None else None


def photo_material(image, name):
    """Unlit material showing ``image`` as it is: emission of strength 1, no lighting, so the
    photo's colours stay true and nothing shades or shadows it."""
    mat = bpy.data.materials.new(name)
    ensure_nodes(mat)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    out.location = (300, 0)
    emit = nodes.new("ShaderNodeEmission")
    emit.inputs["Strength"].default_value = 1.0
    tex = nodes.new("ShaderNodeTexImage")
    tex.name = tex.label = PHOTO_NODE
    tex.location = (-300, 0)
    tex.image = image
    tex.extension = "CLIP"
    links.new(tex.outputs["Color"], emit.inputs["Color"])
    links.new(emit.outputs["Emission"], out.inputs["Surface"])
    mat.diffuse_color = (1.0, 1.0, 1.0, 1.0)
    mat.use_backface_culling = False
    return mat


def photo_image(mat):
    """The photo shown by a photo material, or None."""
    if mat is None or mat.node_tree is None:
        return None
    tex = mat.node_tree.nodes.get(PHOTO_NODE)
    return tex.image if tex is not None else None


def set_photo_image(mat, image):
    mat.node_tree.nodes[PHOTO_NODE].image = image


def landmark_material(state):
    """The shared material of landmarks in ``state`` ("PLACED" or "FLAGGED"), unlit so the
    state colour reads the same in every viewport mode."""
    name = f"HeadRecon Landmark {state.title()}"
    mat = bpy.data.materials.get(name)
    if mat is not None and mat.library is None:
        return mat
    colour = LANDMARK_COLOURS[state]
    mat = bpy.data.materials.new(name)
    ensure_nodes(mat)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    out = nodes.new("ShaderNodeOutputMaterial")
    emit = nodes.new("ShaderNodeEmission")
    emit.inputs["Color"].default_value = colour
    links.new(emit.outputs["Emission"], out.inputs["Surface"])
    mat.diffuse_color = colour
    return mat


# Uncertainty colour ramp: blue (well determined) - cyan - green - yellow - red (uncertain).
_RAMP_POS = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
_RAMP_RGB = np.array([[0.05, 0.1, 0.9], [0.0, 0.8, 0.9], [0.1, 0.85, 0.1],
                      [1.0, 0.85, 0.0], [0.95, 0.05, 0.05]])


def uncertainty_colors(mm, vmax_mm=None):
    """Map per-vertex uncertainty to colours.

    Parameters
    ----------
    mm : ndarray, shape (V,), millimetres
    vmax_mm : float, optional
        The value shown red (default: the 99th percentile, at least 1 mm).

    Returns
    -------
    rgba : ndarray, shape (V, 4), float32 in [0, 1]
    vmax_mm : float
    """
    mm = np.nan_to_num(np.asarray(mm, dtype=np.float64), nan=0.0, posinf=0.0)
    if vmax_mm is None:
        vmax_mm = max(1.0, float(np.percentile(mm, 99))) if mm.size else 1.0
    t = np.clip(mm / vmax_mm, 0.0, 1.0)
    rgba = np.ones((mm.size, 4), dtype=np.float32)
    for c in range(3):
        rgba[:, c] = np.interp(t, _RAMP_POS, _RAMP_RGB[:, c])
    return rgba, float(vmax_mm)
