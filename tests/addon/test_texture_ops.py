"""Save Texture (headrecon_addon/texture_ops.py): the baked texture as a PNG next to the
saved .blend, a path asked for when it is not saved, never over a photo; and the Shading
and Clothes options reaching the bake."""

import bpy
import numpy as np
import pytest

from tests.addon.support import addon, empty_scene, imported_scene, synthetic_files


@pytest.fixture(scope="module")
def fit(model, tmp_path_factory):
    from solver import FitOptions, fit_head

    addon()
    folder = tmp_path_factory.mktemp("texture")
    path, case, _ = synthetic_files(model, folder, seed=9)
    return path, case, fit_head(model, case, FitOptions(n_identity=10))


@pytest.fixture
def head(model, fit):
    from headrecon_addon import head_scene

    empty_scene()
    _, case, result = fit
    head = head_scene.build_scene_from_fit(model, case, result, texture_size=64, name="fay")
    bpy.context.scene.headrecon.head = head
    return head


def test_save_texture_writes_the_tiles_next_to_the_blend(model, head, tmp_path):
    from PIL import Image

    from headrecon_addon import head_scene, texture_ops

    blend = head_scene.save_blend(tmp_path / "fay.blend")
    assert bpy.ops.headrecon.save_texture() == {"FINISHED"}
    png = tmp_path / "fay_texture.png"
    assert texture_ops.default_texture_path() == png
    tiles = texture_ops.baked_tiles(head, model)
    assert sorted(tiles) == [1001, 1002]
    with Image.open(png) as im:
        assert im.size == (128, 64)
        got = np.asarray(im.convert("RGB"), dtype=np.float64) / 255
    want = np.concatenate([tiles[1001][..., :3], tiles[1002][..., :3]], axis=1)
    assert np.abs(got - want).max() < 1.5 / 255  # the images' pixels, left to right
    assert got.std() > 0.01
    assert blend.is_file()


def test_unsaved_blend_needs_a_path_and_a_photo_is_never_overwritten(model, head, fit,
                                                                       tmp_path):
    from headrecon_addon import texture_ops

    assert bpy.data.filepath == ""
    with pytest.raises(RuntimeError, match="Save Texture: save the .blend first, or give a "
                                           "file path"):
        bpy.ops.headrecon.save_texture("EXEC_DEFAULT")
    out = tmp_path / "chosen.png"
    assert bpy.ops.headrecon.save_texture(filepath=str(out)) == {"FINISHED"}
    assert out.stat().st_size > 0
    path, case, _ = fit
    photo = case.image_path("front")
    before = photo.read_bytes()
    with pytest.raises(RuntimeError, match="refusing to overwrite an input"):
        bpy.ops.headrecon.save_texture(filepath=str(photo))
    assert photo.read_bytes() == before
    with pytest.raises(ValueError, match="give a .png file name"):
        texture_ops.save_texture(head, tmp_path / "t.jpg", model)


def test_save_texture_is_greyed_out_without_a_baked_texture(model, fit):
    from headrecon_addon import texture_ops

    empty_scene()
    assert texture_ops.texture_problem(bpy.context) == "Fit a head first"
    assert not bpy.ops.headrecon.save_texture.poll()


def test_the_shading_option_reaches_the_bake(fit):
    from headrecon_addon import fit_job

    path, _, _ = fit
    scene = imported_scene(path, texture_size="256")
    assert scene.headrecon.texture_shading == "keep"
    scene.headrecon.texture_shading = "remove"
    job = fit_job.prepare_job(scene)
    assert job.texture_shading == "remove"


def test_the_clothes_option_reaches_the_bake(model, fit, monkeypatch):
    from headrecon_addon import fit_job, head_scene
    from solver import CLOTHES_MODES, BakeOptions

    path, case, result = fit
    scene = imported_scene(path, texture_size="256")
    items = scene.headrecon.bl_rna.properties["texture_clothes"].enum_items
    assert [i.identifier for i in items] == list(CLOTHES_MODES)
    assert scene.headrecon.texture_clothes == BakeOptions().clothes
    scene.headrecon.texture_clothes = "keep"
    job = fit_job.prepare_job(scene)
    assert job.texture_clothes == "keep"
    seen = []

    def bake(*args, options, **kw):
        seen.append(options.clothes)
        return real(*args, options=options, **kw)

    real = fit_job.bake_fit_texture
    monkeypatch.setattr(fit_job, "bake_fit_texture", bake)
    job.result, job.texture_size = result, 64
    job.run_bake()
    assert job.error is None and job.textures and seen == ["keep"]
    monkeypatch.setattr(head_scene, "bake_fit_texture", bake)
    empty_scene()
    head_scene.build_scene_from_fit(model, case, result, texture_size=64,
                                    texture_clothes="keep")
    head_scene.build_scene_from_fit(model, case, result, texture_size=64)
    assert seen == ["keep", "keep", "leave-out"]
