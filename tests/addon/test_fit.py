"""The Fit operator on a synthetic case: shape keys, transform, texture, uncertainty,
residual list, re-fit, live refit, cancel (bpy module, background)."""

import bpy
import numpy as np
import pytest

from tests.addon.support import addon, empty_scene, snapshot, synthetic_files


@pytest.fixture(scope="module")
def files(model, tmp_path_factory):
    addon()
    return synthetic_files(model, tmp_path_factory.mktemp("fit"), seed=5)


def _scene_with(path, texture_size="512"):
    scene = empty_scene()
    assert bpy.ops.headrecon.import_landmarks(filepath=str(path)) == {"FINISHED"}
    scene.headrecon.texture_size = texture_size
    return scene


@pytest.fixture(scope="module")
def fitted(files):
    from headrecon_addon import fit_ops

    path, case, truth = files
    scene = _scene_with(path)
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    return scene, scene.headrecon.head, fit_ops.last_result()


def _keys(head):
    return head.data.shape_keys.key_blocks


def test_shape_keys(model, fitted):
    from headrecon_addon import shape_keys

    scene, head, result = fitted
    keys = _keys(head)
    k = len(result.identity_coeffs)
    expected = (["Basis"] + [f"identity_{i:03d}" for i in range(k)]
                + list(result.regional_names) + ["fit_detail"] + list(model.expression_names))
    assert [kb.name for kb in keys] == expected
    assert len(model.expression_names) == 57
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
    for name in model.expression_names:
        assert keys[name].value == 0.0 and keys[name].slider_max == 1.0


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
    _keys(head)["jawOpen"].value = 1.0
    moved = shape_keys.evaluated_vertices(head, bpy.context.evaluated_depsgraph_get())
    _keys(head)["jawOpen"].value = 0.0
    assert np.abs(moved - local).max() > 1e-3


def test_texture_and_uncertainty(model, fitted, tmp_path):
    from headrecon_addon import fit_ops, material, reference_head

    scene, head, result = fitted
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
    mesh.attributes[fit_ops.UNCERTAINTY_MM].data.foreach_get("value", raw)
    assert np.allclose(raw, result.uncertainty, rtol=1e-5, atol=1e-6)
    col = mesh.color_attributes[fit_ops.UNCERTAINTY_COLOR]
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


def test_refit_replaces_keys_cleanly(model, files):
    from headrecon_addon import fit_ops

    path, _, _ = files
    scene = _scene_with(path)
    props = scene.headrecon
    props.bake_texture = False
    props.n_identity = 20
    props.n_regional = 2
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    head = props.head
    head.shape_key_add(name="artist_key", from_mix=False)
    result = fit_ops.last_result()
    assert len(result.regional_names) == 2 * len(model.region_names)
    assert all(n in _keys(head) for n in result.regional_names)
    objects = snapshot()["objects"]
    props.n_regional = 0
    props.n_identity = 10
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    names = [kb.name for kb in _keys(head)]
    assert len(names) == len(set(names))
    assert "artist_key" in names
    assert not any(n.startswith(model.region_names[0] + "_") for n in names)
    assert sum(n.startswith("identity_") for n in names) == 10
    assert snapshot()["objects"] == objects  # the same head, no second one


def test_live_refit_follows_a_moved_landmark(model, files):
    from headrecon_addon import fit_ops, landmarks, photos, shape_keys

    path, _, _ = files
    scene = _scene_with(path)
    scene.headrecon.bake_texture = False
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    head = scene.headrecon.head
    base = fit_ops.last_result()
    scene.headrecon.live_refit = True
    bpy.context.view_layer.update()  # records the positions; nothing moved yet
    plane = photos.find_plane(scene, "front")
    obj = landmarks.landmark_objects(plane)["nose_tip"]
    obj.location.x += 0.004  # about 10 px to the side
    bpy.context.view_layer.update()  # depsgraph handler -> refit_landmarks
    live = fit_ops.live_stats()
    assert live["error"] == "" and live["ms"] > 0
    result = fit_ops.last_result()
    assert result is not base
    assert not np.allclose(result.identity_coeffs, base.identity_coeffs)
    assert _keys(head)["identity_000"].value == pytest.approx(result.identity_coeffs[0],
                                                               abs=1e-6)
    # while dragging, the coefficient keys are muted and the detail key shows the shape
    assert _keys(head)["identity_000"].mute and shape_keys.in_live_shape(head)
    local = shape_keys.evaluated_vertices(head, bpy.context.evaluated_depsgraph_get())
    assert np.abs(local - result.local_vertices).max() < 1e-5
    # nothing moved: no refit
    assert fit_ops.live_refit_step(scene) is None
    # the drag ends (the timer does this in the UI): keys back to coefficients + detail
    assert fit_ops.finish_live_drag()
    assert not _keys(head)["identity_000"].mute and not shape_keys.in_live_shape(head)
    local = shape_keys.evaluated_vertices(head, bpy.context.evaluated_depsgraph_get())
    assert np.abs(local - result.local_vertices).max() < 1e-5
    detail = shape_keys.get_key_co(_keys(head)["fit_detail"])
    assert np.abs(detail - (model.vertices + result.detail)).max() < 1e-5
    # Quick Refit writes the settled form directly
    obj.location.x -= 0.004
    assert bpy.ops.headrecon.refit_landmarks() == {"FINISHED"}
    assert not shape_keys.in_live_shape(head)
    local = shape_keys.evaluated_vertices(head, bpy.context.evaluated_depsgraph_get())
    assert np.abs(local - fit_ops.last_result().local_vertices).max() < 1e-5
    scene.headrecon.live_refit = False


def test_cancelled_or_failed_fit_leaves_scene_unchanged(files):
    from headrecon_addon import fit_ops, landmarks, photos

    path, _, _ = files
    scene = _scene_with(path)
    before = snapshot()
    job = fit_ops.prepare_job(scene)
    job.cancelled = True
    job.run()
    assert isinstance(job.error, fit_ops.FitCancelled)
    assert snapshot() == before and scene.headrecon.head is None
    # too few landmarks: the operator is greyed out, saying why
    plane = photos.find_plane(scene, "front")
    for name in list(landmarks.landmark_objects(plane))[2:]:
        landmarks.remove_landmark(plane, name)
    before = snapshot()
    with pytest.raises(RuntimeError, match="Too few landmarks on front"):
        bpy.ops.headrecon.fit()
    assert snapshot() == before
