"""A scene built from a finished fit, without the UI: given textures are used as they are,
and the photos' cameras and the passpoint checks are those of the Fit button's scene."""

import numpy as np

from tests.addon.support import add_passpoints, addon, empty_scene, synthetic_files


def test_given_textures_are_used_without_a_second_bake(model, tmp_path, monkeypatch):
    from headrecon_addon import head_scene, material, reference_head
    from solver.fitting.fit import FitOptions, fit_head

    _, case, _ = synthetic_files(model, tmp_path, seed=14, name="dave")
    result = fit_head(model, case, FitOptions(n_identity=10))
    rng = np.random.default_rng(0)
    given = {tile: rng.integers(0, 256, (48, 64, 3)) / 255.0 for tile in (1001, 1002)}

    def no_bake(*args, **kw):
        raise AssertionError("build_scene_from_fit baked although textures were given")

    monkeypatch.setattr(head_scene, "bake_fit_texture", no_bake)
    head_scene.reset_scene()
    head = head_scene.build_scene_from_fit(model, case, result, textures=given,
                                           iris=np.array([0.5, 0.3, 0.2]))
    # the irises' colour given with the bake is the eyes' (linear, its darker streak first)
    ramp = reference_head.part_material(head, "Eyes").node_tree.nodes[
        material.IRIS_NODE].color_ramp.elements
    red, _, blue = ramp[0].color[:3]
    assert red > 2 * blue
    for group, tile in (("Face", 1001), ("Head", 1002)):
        img = material.skin_texture(reference_head.part_material(head, group))
        assert img is not None and tuple(img.size) == (64, 48)
        px = np.empty(64 * 48 * 4, np.float32)
        img.pixels.foreach_get(px)
        got = px.reshape(48, 64, 4)[::-1, :, :3]  # Blender's rows run bottom-up
        np.testing.assert_allclose(got, given[tile], atol=1e-6)


def test_the_scene_has_the_fitted_cameras_and_checks(model):
    # the batch's and the demo's scene shows the cameras and checks the Fit button's does
    from headrecon_addon import head_scene, photo_cameras, photos, result_to_scene
    from solver import synthetic
    from solver.fitting import fit

    addon()
    case, truth = synthetic.make_perspective_case(model, 2, n_views=2, head_px=(300.0, 320.0))
    names = add_passpoints(case, truth, "photo1", np.random.default_rng(3))
    result = fit.fit_head(model, case, fit.FitOptions(n_identity=10))
    scene = empty_scene()
    head_scene.build_scene_from_fit(model, case, result, bake=False)
    for v in case.views:
        cam_obj = photos.camera_object(photos.find_plane(scene, v))
        want = photo_cameras.blender_settings(result.cameras[v])
        assert np.allclose(np.array(cam_obj.matrix_world), want["matrix_world"], atol=1e-5)
        assert cam_obj.name in scene.objects
    rows = result_to_scene.residual_rows(result, result_to_scene.calibration_checks(case)[0])
    items = list(scene.headrecon.residuals)
    assert [(it.view, it.landmark, it.kind) for it in items] == \
        [(r[2], r[3], r[4]) for r in rows]
    assert sorted(it.landmark for it in items if it.kind == "PASSPOINT") == sorted(names)
    assert not any(it.flagged for it in items if it.kind == "PASSPOINT")
