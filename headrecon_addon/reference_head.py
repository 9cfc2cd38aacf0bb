"""The bundled head as a Blender mesh: the model's mean shape, whole head with all its parts,
the ICT UVs, one material per part group, and a vertex group per region of the regional
model (weights = the region blend weights). Built with foreach_set throughout.
"""

import bpy
import numpy as np

from . import material, scene_collections
from .polls import ObjectModeOperator
from .solver_link import load_model

HEAD_NAME = "HeadRecon Head"


def _vertex_group_from_weights(obj, name, weights):
    """A vertex group with per-vertex ``weights`` (V,). Blender adds one weight per call,
    so vertices are grouped by weight quantised to 1/1024: at most ~1000 calls per group,
    never one per vertex."""
    vg = obj.vertex_groups.new(name=name)
    q = np.round(np.asarray(weights, dtype=np.float64) * 1024.0).astype(np.int64)
    idx = np.flatnonzero(q > 0)
    if idx.size == 0:
        return vg
    order = np.argsort(q[idx], kind="stable")
    idx = idx[order]
    levels, starts = np.unique(q[idx], return_index=True)
    bounds = np.append(starts, idx.size)
    for level, a, b in zip(levels, bounds[:-1], bounds[1:], strict=True):
        vg.add(idx[a:b].tolist(), float(level) / 1024.0, "REPLACE")
    return vg


def build_head_mesh(model, name=HEAD_NAME):
    """Mesh of the model's mean head: vertices, polygons, UVs, smooth shading, the eye
    material's attribute, material slots (one per part group, each a new material)."""
    mesh = bpy.data.meshes.new(name)
    n_v, n_l, n_f = model.n_vertices, model.loop_vertex.size, model.face_loop_start.size
    mesh.vertices.add(n_v)
    mesh.vertices.foreach_set("co", model.vertices.astype(np.float32).ravel())
    mesh.loops.add(n_l)
    mesh.loops.foreach_set("vertex_index", model.loop_vertex.astype(np.int32))
    mesh.polygons.add(n_f)
    mesh.polygons.foreach_set("loop_start", model.face_loop_start.astype(np.int32))
    mesh.polygons.foreach_set("loop_total", model.face_loop_total.astype(np.int32))
    uv = mesh.uv_layers.new(name="UVMap")
    uv.data.foreach_set("uv", model.loop_uv.astype(np.float32).ravel())

    groups = [material.part_group(p) for p in model.part_names]
    used = [g for g in material.SLOT_ORDER if g in groups]
    slot = {g: i for i, g in enumerate(used)}
    part_slot = np.array([slot[g] for g in groups], dtype=np.int32)
    mesh.polygons.foreach_set("material_index", part_slot[model.face_part])
    mesh.polygons.foreach_set("use_smooth", np.ones(n_f, dtype=bool))
    eye = mesh.attributes.new(material.EYE_ATTRIBUTE, "FLOAT", "POINT")
    eye.data.foreach_set("value", material.eye_attribute(model.vertices))
    mesh.update(calc_edges=True)
    for g in used:
        mesh.materials.append(material.new_part_material(g))
    return mesh


def new_head_object(model=None, name=HEAD_NAME):
    """A head object (not linked to a scene) with the mean shape, materials, and one vertex
    group per region."""
    model = model or load_model()
    mesh = build_head_mesh(model, name)
    obj = bpy.data.objects.new(name, mesh)
    obj.headrecon.role = "HEAD"
    for r, region in enumerate(model.region_names):
        _vertex_group_from_weights(obj, region, model.region_weights[r])
    return obj


def part_material(obj, group):
    """The head's material of a part group (e.g. "Face"), or None."""
    for mat in obj.data.materials:
        if mat is not None and mat.get(material.GROUP_KEY) == group:
            return mat
    return None


def is_head(obj):
    return obj is not None and obj.type == "MESH" and obj.headrecon.role == "HEAD"


class HEADRECON_OT_add_head(ObjectModeOperator, bpy.types.Operator):
    """Add the bundled reference head (the model's mean shape) to the scene"""

    bl_idname = "headrecon.add_head"
    bl_label = "Add Reference Head"
    bl_options = {"REGISTER", "UNDO"}

    another: bpy.props.BoolProperty(
        name="Another Head", options={"SKIP_SAVE"},
        description="Add a second head although the scene has one (Fit updates the "
                    "scene's head)")

    def execute(self, context):
        from .data import Transaction

        existing = context.scene.headrecon.head
        if not self.another and is_head(existing) and existing.name in context.scene.objects:
            # one head per scene unless asked: select it; the redo panel offers another
            _select_only(context, existing)
            self.report({"INFO"}, f"The scene has a head already ({existing.name!r}): "
                                  "selected it; tick Another Head to add a second one")
            return {"FINISHED"}
        try:
            with Transaction():
                model = load_model()
                obj = new_head_object(model)
                scene_collections.link(context.scene, obj)
        except (FileNotFoundError, ValueError) as e:
            self.report({"ERROR"}, f"Cannot load the head model: {e}")
            return {"CANCELLED"}
        context.scene.headrecon.head = obj
        _select_only(context, obj)
        return {"FINISHED"}



def scene_head(context):
    """The scene's reference head (``scene.headrecon.head``), or None when it is unset or
    no longer a head."""
    head = context.scene.headrecon.head
    return head if is_head(head) else None


def fitted_head_problem(context):
    """"Fit a head first" while the scene has no fitted head (a head with shape keys)."""
    head = scene_head(context)
    if head is None or head.data.shape_keys is None:
        return "Fit a head first"
    return None

def _select_only(context, obj):
    """Make ``obj`` the only selected object and the active one."""
    for o in context.selected_objects:
        o.select_set(False)
    obj.select_set(True)
    context.view_layer.objects.active = obj


CLASSES = (HEADRECON_OT_add_head,)
