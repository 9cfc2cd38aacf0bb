"""Export presets: the .glb (and .fbx) of a fitted head holds the fitted face as its base,
the expression keys by Apple's names at weight 0, the texture embedded, no morph normals
unless asked; the scene is left as it was; re-imported, Blender shows the fitted face."""

import gc
import json
import struct
from pathlib import Path

import bpy
import numpy as np
import pytest
from scipy.spatial import cKDTree

from tests.addon.support import addon, empty_scene, key_blocks, snapshot, synthetic_files


@pytest.fixture(scope="module")
def fit(model, tmp_path_factory):
    from solver import FitOptions, fit_head

    addon()
    path, case, _ = synthetic_files(model, tmp_path_factory.mktemp("export"), seed=8)
    return path, case, fit_head(model, case, FitOptions(n_identity=20))


@pytest.fixture
def head(model, fit):
    from headrecon_addon import head_scene

    empty_scene()
    _, case, result = fit
    head = head_scene.build_scene_from_fit(model, case, result, texture_size=128, name="erin")
    bpy.context.scene.headrecon.head = head
    return head


def glb_json(path):
    """The JSON chunk of a binary glTF file."""
    data = Path(path).read_bytes()
    assert data[:4] == b"glTF"
    n = struct.unpack("<I", data[12:16])[0]
    return json.loads(data[20:20 + n])


def _head_state(head):
    from headrecon_addon import shape_keys

    return (head.name, [(kb.name, kb.value, kb.mute) for kb in key_blocks(head)],
            shape_keys.get_key_co(head.data.shape_keys.reference_key).copy())


def test_glb_holds_the_fitted_face_and_the_arkit_keys(model, head, tmp_path):
    from headrecon_addon import arkit, export

    before, state = snapshot(), _head_state(head)
    n_keys = len(bpy.data.shape_keys)
    path = export.export_head(tmp_path / "erin", head, model.expression_names)
    assert path == (tmp_path / "erin.glb").resolve() and path.stat().st_size > 0
    # the scene is as it was: no copy left, the head keeps its name and identity keys
    assert snapshot() == before and len(bpy.data.shape_keys) == n_keys
    after = _head_state(head)
    assert after[:2] == state[:2] and np.array_equal(after[2], state[2])
    doc = glb_json(path)
    assert [n["name"] for n in doc["nodes"]] == ["erin"]
    mesh = doc["meshes"][0]
    names = arkit.expression_key_names(model.expression_names)
    assert mesh["extras"]["targetNames"] == names
    assert all(len(p["targets"]) == len(names) for p in mesh["primitives"])
    assert not any("NORMAL" in t for p in mesh["primitives"] for t in p["targets"])
    assert not any(mesh.get("weights", [0.0]))  # no key value set
    assert doc["images"] and all("bufferView" in im and "uri" not in im for im in doc["images"])


def test_the_exporter_s_garbage_is_collected_with_the_export(model, head, tmp_path):
    """Blender's glTF exporter leaves its data in reference cycles (about 13 600 objects
    for a head); the export collects them, so a batch worker does not carry them into
    the next head (docs/DECISIONS.md, "A batch worker forgets")."""
    from headrecon_addon import export

    gc.collect()
    frozen = gc.isenabled()
    gc.disable()  # no collection but the export's own from here
    try:
        export.export_head(tmp_path / "cycles", head, model.expression_names)
        left = gc.collect()
    finally:
        if frozen:
            gc.enable()
    assert left < 500, left


def test_morph_normals_only_when_asked(model, head, tmp_path):
    from headrecon_addon import export

    plain = export.export_head(tmp_path / "plain.glb", head, model.expression_names)
    normals = export.export_head(tmp_path / "normals.glb", head, model.expression_names,
                                 morph_normals=True)
    doc = glb_json(normals)
    assert all("NORMAL" in t for p in doc["meshes"][0]["primitives"] for t in p["targets"])
    assert normals.stat().st_size > plain.stat().st_size


def _reimport(path):
    empty_scene()
    if path.suffix == ".glb":
        bpy.ops.import_scene.gltf(filepath=str(path))
    else:
        bpy.ops.import_scene.fbx(filepath=str(path))
    meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    assert len(meshes) == 1
    return meshes[0]


def _local(obj):
    from headrecon_addon import shape_keys

    return shape_keys.evaluated_vertices(obj, bpy.context.evaluated_depsgraph_get())


@pytest.mark.parametrize("fmt", ["GLB", "FBX"])
def test_reimported_it_shows_the_fitted_face_with_no_key_set(model, fit, head, tmp_path, fmt):
    from headrecon_addon import arkit, export

    _, _, result = fit
    if not export.exporter_available(fmt):
        pytest.skip(f"no {fmt} exporter in this Blender")
    matrix = np.array(head.matrix_world)
    before = snapshot()
    path = export.export_head(tmp_path / "erin", head, model.expression_names, fmt)
    assert snapshot() == before  # the copy, its materials and images are gone again
    obj = _reimport(path)
    keys = key_blocks(obj)
    have = {kb.name for kb in keys}
    assert set(arkit.ARKIT_NAMES) - have == {"tongueOut"}
    assert all(kb.value == 0.0 for kb in keys[1:])
    assert not any(n.startswith("identity_") or n == "fit_detail" for n in have)
    # the baked texture came along (embedded)
    faces = [im for im in bpy.data.images if "Face_Texture" in im.name.replace(" ", "_")]
    assert faces and all(tuple(im.size) == (128, 128) and im.has_data for im in faces)
    # every vertex of the imported mesh lies on the fitted head (the exporters split
    # vertices along UV seams), in world space, and that is not the mean head
    m = np.array(obj.matrix_world)
    world = _local(obj) @ m[:3, :3].T + m[:3, 3]
    fitted = result.local_vertices @ matrix[:3, :3].T + matrix[:3, 3]
    mean = model.vertices @ matrix[:3, :3].T + matrix[:3, 3]
    assert cKDTree(fitted).query(world)[0].max() < 2e-5
    assert cKDTree(mean).query(world)[0].max() > 1e-3
    # and an expression key moves it as on the fitted head
    keys["jawOpen"].value = 1.0
    opened = _local(obj) @ m[:3, :3].T + m[:3, 3]
    jaw = model.expressions[list(model.expression_names).index("jawOpen")]
    want = (result.local_vertices + jaw) @ matrix[:3, :3].T + matrix[:3, 3]
    assert cKDTree(want).query(opened)[0].max() < 2e-5


@pytest.mark.parametrize("fmt", ["GLB", "FBX"])
def test_the_eyes_arrive_painted_in_the_iris_colour_each_eye_its_own(model, head, tmp_path,
                                                                     fmt):
    from headrecon_addon import export, material, reference_head
    from solver.texture.shading import linear_to_srgb, srgb_to_linear

    if not export.exporter_available(fmt):
        pytest.skip(f"no {fmt} exporter in this Blender")
    brown = np.array([0.45, 0.28, 0.15])
    material.set_iris_colour(reference_head.part_material(head, "Eyes"), brown)
    before = snapshot()
    path = export.export_head(tmp_path / "erin", head, model.expression_names, fmt)
    assert snapshot() == before  # the painted eyes' materials and images are gone again
    obj = _reimport(path)
    # the eyeballs' material has an image: each eye in its own half
    mat = next(m for m in obj.data.materials if m is not None and m.name.startswith(
        "HeadRecon Eyes"))
    img = next(n.image for n in mat.node_tree.nodes if n.type == "TEX_IMAGE")
    w, h = img.size
    assert (w, h) == (2 * material.EYE_IMAGE_SIZE, material.EYE_IMAGE_SIZE)
    px = np.empty(w * h * 4, np.float32)
    img.pixels.foreach_get(px)
    # the iris painted as the eye shader's ramp has it on average: the colour set
    iris = linear_to_srgb(srgb_to_linear(brown) * np.mean(material.IRIS_SPREAD))
    for half in np.split(px.reshape(h, w, 4)[..., :3], 2, axis=1):
        rgb = half.reshape(-1, 3)
        n_iris = np.count_nonzero(np.abs(rgb - iris).max(axis=1) < 0.02)
        assert 0.01 < n_iris / len(rgb) < 0.05, n_iris / len(rgb)  # an iris, not the ball
        assert (rgb.max(axis=1) < 0.1).mean() > 0.002  # its pupil
    # each eye's faces look at their own half: every eyeball corner's u within its half
    uv = np.empty(len(obj.data.loops) * 2, np.float32)
    obj.data.uv_layers.active.data.foreach_get("uv", uv)
    index = np.empty(len(obj.data.polygons), np.int64)
    obj.data.polygons.foreach_get("material_index", index)
    slot = list(obj.data.materials).index(mat)
    starts, totals, loop_vertex = material.mesh_corners(obj.data)
    us = [uv[0::2][s:s + n] for s, n in zip(starts[index == slot], totals[index == slot],
                                              strict=True)]
    halves = {int(np.floor(2 * u.mean())) for u in us}
    assert halves == {0, 1} and all(np.ptp(np.floor(2 * u)) == 0 for u in us)


def test_the_operator_writes_the_file(model, head, tmp_path):
    target = tmp_path / "op.glb"
    assert bpy.ops.headrecon.export_head(filepath=str(target), export_format="GLB") == \
        {"FINISHED"}
    assert target.is_file()
    with pytest.raises(RuntimeError, match="Export Head"):
        bpy.ops.headrecon.export_head(filepath="")


def test_headless_bakes_the_identity_and_exports(model, fit, tmp_path, capsys):
    from headrecon_addon import headless

    path, _, _ = fit
    code = headless.main([str(path), "--out", str(tmp_path / "frank.blend"), "--components",
                          "10", "--no-texture", "--bake-identity", "--export", "glb"])
    assert code == 0, capsys.readouterr()
    assert (tmp_path / "frank.glb").is_file()
    addon()
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "frank.blend"))
    head = next(o for o in bpy.data.objects if o.headrecon.role == "HEAD")
    names = [kb.name for kb in key_blocks(head)]
    assert "jawOpen" in names and not any(n.startswith("identity_") for n in names)
    assert "fit_detail" not in names


def test_headless_exports_the_head_its_blend_holds(model, fit, tmp_path, capsys):
    from headrecon_addon import export, headless

    path, _, _ = fit
    code = headless.main([str(path), "--out", str(tmp_path / "gina.blend"), "--components",
                          "10", "--no-texture", "--export", "glb"])
    assert code == 0, capsys.readouterr()
    addon()
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "gina.blend"))
    head = next(o for o in bpy.data.objects if o.headrecon.role == "HEAD")
    names = [kb.name for kb in key_blocks(head)]
    assert "jawOpen" in names and any(n.startswith("identity_") for n in names)
    again = export.export_head(tmp_path / "again.glb", head, model.expression_names)
    assert (tmp_path / "gina.glb").read_bytes() == again.read_bytes()
