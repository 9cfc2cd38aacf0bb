"""A fit written into the scene: shape keys, transform, texture, uncertainty, residual
list and landmark colours (bpy module, background)."""

import bpy
import numpy as np
import pytest

from tests.addon.support import imported_scene, key_blocks

FILES_SEED = 5  # the head of the ``files`` fixture (tests/addon/conftest.py)


@pytest.fixture(scope="module")
def fitted(files):
    from headrecon_addon.live_refit import LIVE

    path, case, truth = files
    scene = imported_scene(path)
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    return scene, scene.headrecon.head, LIVE.result


def test_shapekey_blocks(model, fitted):
    from headrecon_addon import arkit, shape_keys

    scene, head, result = fitted
    keys = key_blocks(head)
    k = len(result.identity_coeffs)
    expressions = arkit.expression_key_names(model.expression_names)
    expected = (["Basis"] + [f"identity_{i:03d}" for i in range(k)]
                + list(result.regional_names) + ["fit_detail"] + expressions)
    assert [kb.name for kb in keys] == expected
    assert expressions[:3] == ["eyeBlinkLeft", "eyeLookDownLeft", "eyeLookInLeft"]
    assert keys["Basis"] == head.data.shape_keys.reference_key
    base = shape_keys.get_key_co(keys["Basis"])
    assert np.abs(base - model.vertices).max() < 1e-6
    for i, c in enumerate(result.identity_coeffs):
        kb = keys[f"identity_{i:03d}"]
        assert kb.slider_min <= -3 and kb.slider_max >= 3
        assert kb.slider_min <= c <= kb.slider_max
        assert kb.value == pytest.approx(c, abs=1e-6)
        if abs(c) <= 3:
            assert (kb.slider_min, kb.slider_max) == (-3, 3)
    kb = keys["identity_000"]
    assert np.abs(shape_keys.get_key_co(kb) - (model.vertices + model.identity.basis[0])
                  ).max() < 1e-6
    assert keys["fit_detail"].value == 1.0
    for name in expressions:
        assert keys[name].value == 0.0 and keys[name].slider_max == 1.0
    names = list(model.expression_names)
    blink = shape_keys.get_key_co(keys["eyeBlinkLeft"]) - base
    assert np.abs(blink - model.expressions[names.index("eyeBlink_L")]).max() < 1e-6


def test_sliders_reproduce_the_solver(model, fitted):
    from headrecon_addon import shape_keys

    scene, head, result = fitted
    dg = bpy.context.evaluated_depsgraph_get()
    local = shape_keys.evaluated_vertices(head, dg)
    assert np.abs(local - result.local_vertices).max() < 1e-5
    m = np.array(head.matrix_world)
    world = local @ m[:3, :3].T + m[:3, 3]
    assert np.abs(world - result.world_vertices).max() < 1e-5
    # an expression key moves the head when dialled in (ready to animate)
    key_blocks(head)["jawOpen"].value = 1.0
    moved = shape_keys.evaluated_vertices(head, bpy.context.evaluated_depsgraph_get())
    key_blocks(head)["jawOpen"].value = 0.0
    assert np.abs(moved - local).max() > 1e-3


def test_texture_and_uncertainty(model, fitted, tmp_path):
    from headrecon_addon import material, reference_head, result_to_scene

    scene, head, result = fitted
    # the Fit read the irises' colour off the photos with its bake: the eyes have it
    ramp = reference_head.part_material(head, "Eyes").node_tree.nodes[
        material.IRIS_NODE].color_ramp.elements
    dark, light = (np.array(e.color[:3]) for e in ramp)
    assert not np.allclose(dark, material.DEFAULT_IRIS[0])
    k = material.IRIS_SPREAD
    np.testing.assert_allclose(np.minimum(dark / k[0] * k[1], 1.0), light, atol=1e-5)
    images = []
    for group in ("Face", "Head"):
        img = material.skin_texture(reference_head.part_material(head, group))
        assert img is not None and tuple(img.size) == (512, 512)
        px = np.empty(512 * 512 * 4, np.float32)
        img.pixels.foreach_get(px)
        assert px.reshape(-1, 4)[:, :3].std() > 0.01  # photo colours, not a flat fill
        images.append(img)
    # saving the file packs the baked textures into it
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "saved.blend"), copy=True)
    assert all(img.packed_file is not None for img in images)
    mesh = head.data
    raw = np.empty(len(mesh.vertices), np.float32)
    mesh.attributes[result_to_scene.UNCERTAINTY_MM].data.foreach_get("value", raw)
    assert np.allclose(raw, result.uncertainty, rtol=1e-5, atol=1e-6)
    col = mesh.color_attributes[result_to_scene.UNCERTAINTY_COLOR]
    assert col.domain == "POINT"
    rgba = np.empty(len(mesh.vertices) * 4, np.float32)
    col.data.foreach_get("color", rgba)
    rgba = rgba.reshape(-1, 4)
    lo, hi = np.argmin(result.uncertainty), np.argmax(result.uncertainty)
    assert rgba[lo, 2] > rgba[lo, 0] and rgba[hi, 0] > rgba[hi, 2]  # blue certain, red not


def test_residual_list_and_landmark_colours(fitted):
    from headrecon_addon import landmarks, photos

    scene, head, result = fitted
    items = list(scene.headrecon.residuals)
    assert len(items) == sum(len(r.names) for r in result.residuals.values())
    flags = [it.flagged for it in items]
    assert flags == sorted(flags, reverse=True)  # flagged first
    n_flag = sum(flags)
    assert n_flag == len(result.flagged())
    rest = [it.pixels for it in items[n_flag:]]
    assert rest == sorted(rest, reverse=True)
    # clicking a row selects that landmark
    scene.headrecon.residual_index = len(items) - 1
    it = items[-1]
    obj = landmarks.landmark_objects(photos.find_plane(scene, it.view))[it.landmark]
    assert bpy.context.view_layer.objects.active == obj and obj.select_get()
    for r in result.residuals.values():
        for name in r.flagged:
            plane = next(p for p in photos.photo_planes(scene)
                         if landmarks.landmark_objects(p).get(name) is not None)
            o = landmarks.landmark_objects(plane)[name]
            assert o.headrecon.flagged and "Flagged" in o.material_slots[0].material.name


def test_residual_list_shows_down_weighted_landmarks_first(fitted):
    import dataclasses

    from headrecon_addon.result_to_scene import residual_rows

    _, _, result = fitted
    view = next(iter(result.residuals))
    name = result.residuals[view].names[-1]
    noise = {**result.info.get("noise", {}), "down_weighted": {view: {name: 0.01}}}
    down = dataclasses.replace(result, info={**result.info, "noise": noise})
    rows = residual_rows(down)
    ranked = [(rank, v, n, message) for rank, _, v, n, _, message in rows]
    first = [r for r in ranked if r[0] < 2]
    assert (1, view, name) in [(r[0], r[1], r[2]) for r in first]
    assert "1 % of a landmark's weight" in next(r[3] for r in ranked if r[2] == name
                                                   and r[1] == view)
