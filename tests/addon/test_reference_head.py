"""The reference head: the model as a mesh with its materials and region vertex groups
(bpy module, background)."""

import bpy
import numpy as np


def test_reference_head(model, scene):
    assert bpy.ops.headrecon.add_head() == {"FINISHED"}
    head = scene.headrecon.head
    mesh = head.data
    assert head.headrecon.role == "HEAD" and head.name in scene.objects
    assert len(mesh.vertices) == model.n_vertices
    assert len(mesh.polygons) == model.face_loop_start.size
    co = np.empty(model.n_vertices * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    assert np.abs(co.reshape(-1, 3) - model.vertices).max() < 1e-6
    lv = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("vertex_index", lv)
    assert np.array_equal(lv, model.loop_vertex)
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    mesh.uv_layers["UVMap"].data.foreach_get("uv", uv)
    assert np.abs(uv.reshape(-1, 2) - model.loop_uv).max() < 1e-6
    # one material per part group, skin first; the eyes' faces use the eye material
    names = [m.get("headrecon_group") for m in mesh.materials]
    assert names[:2] == ["Face", "Head"] and "Eyes" in names and "Teeth" in names
    mi = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("material_index", mi)
    eye = model.part_names.index("Eyeball left")
    assert set(mi[model.face_part == eye]) == {names.index("Eyes")}
    # one vertex group per region, weights = region weights (to 1/1024)
    assert [g.name for g in head.vertex_groups] == list(model.region_names)
    for r in (0, len(model.region_names) - 1):
        g = head.vertex_groups[r]
        idx = np.flatnonzero(model.region_weights[r] > 0.001)
        sample = idx[:: max(1, idx.size // 500)]
        got = np.array([g.weight(int(i)) for i in sample])
        assert np.abs(got - model.region_weights[r, sample]).max() <= 0.5 / 1024 + 1e-6


def test_one_head_per_scene_unless_another_is_asked_for(model, scene):
    assert bpy.ops.headrecon.add_head() == {"FINISHED"}
    first = scene.headrecon.head
    heads = [o for o in scene.objects if o.headrecon.role == "HEAD"]
    # again: the scene's head is selected, no second head
    assert bpy.ops.headrecon.add_head() == {"FINISHED"}
    assert [o for o in scene.objects if o.headrecon.role == "HEAD"] == heads
    assert scene.headrecon.head == first and bpy.context.view_layer.objects.active == first
    # asked for: a second head, which becomes the scene's
    assert bpy.ops.headrecon.add_head(another=True) == {"FINISHED"}
    assert len([o for o in scene.objects if o.headrecon.role == "HEAD"]) == len(heads) + 1
    assert scene.headrecon.head != first


def test_fit_settings_say_what_they_do():
    props = bpy.types.Scene.bl_rna.properties["headrecon"].fixed_type.properties
    for name in ("method", "prior", "texture_size"):
        assert props[name].description, name
