"""The fitted head's files (solver/io/export.py): the baked UDIM tiles side by side in one
texture, and the OBJ + PNG + .mtl written together."""

import io
import os

import numpy as np
from PIL import Image

from solver import uv_tiles
from solver.io.export import png_bytes, texture_atlas, write_head_obj
from tests.solver.io.support import read_obj_records


def test_texture_atlas_puts_tiles_side_by_side(model):
    tiles = uv_tiles(model)
    size = 16
    values = {t: 0.1 + 0.2 * i for i, t in enumerate(tiles)}
    images = {t: np.full((size, size, 3), v, np.float32) for t, v in values.items()}
    atlas, loop_uv, textured = texture_atlas(model, images)
    assert atlas.shape == (size, size * len(tiles), 3)
    start, total = model.face_loop_start, model.face_loop_total
    skin_parts = [model.part_names.index(p) for p in ("Face", "Head and Neck")]
    assert textured.any() and np.isin(model.face_part[textured], skin_parts).all()
    # each textured face's centre samples its own tile's colour in the atlas
    face = np.flatnonzero(textured)
    centre_new = np.array([loop_uv[start[f]:start[f] + total[f]].mean(0) for f in face[::50]])
    centre_old = np.array([model.loop_uv[start[f]:start[f] + total[f]].mean(0)
                           for f in face[::50]])
    assert (centre_new >= 0).all() and (centre_new <= 1).all()
    col = np.clip((centre_new[:, 0] * atlas.shape[1]).astype(int), 0, atlas.shape[1] - 1)
    row = np.clip(((1 - centre_new[:, 1]) * size).astype(int), 0, size - 1)
    tile = 1001 + np.floor(centre_old[:, 0]).astype(int) + 10 * np.floor(centre_old[:, 1]) \
        .astype(int)
    np.testing.assert_allclose(atlas[row, col, 0], [values[t] for t in tile], atol=1e-6)
    # faces outside the atlas keep the model's UVs
    untextured_loops = np.concatenate([np.arange(start[f], start[f] + total[f])
                                       for f in np.flatnonzero(~textured)[:100]])
    np.testing.assert_array_equal(loop_uv[untextured_loops], model.loop_uv[untextured_loops])


def test_png_bytes_are_the_image_in_8_bits(tmp_path):
    image = np.zeros((2, 3, 4))
    image[0, 0] = (1.0, 0.5, 0.0, 1.0)
    image[1, 2] = (np.nan, 2.0, -1.0, 0.25)
    path = tmp_path / "t.png"
    path.write_bytes(png_bytes(image))
    with Image.open(path) as im:
        assert im.mode == "RGBA" and im.size == (3, 2)
        px = np.asarray(im)
    assert px[0, 0].tolist() == [255, 128, 0, 255]
    assert px[1, 2].tolist() == [0, 255, 0, 64]  # NaN -> 0, clipped to [0, 1]


def test_png_bytes_convert_a_band_of_rows_at_a_time_as_all_at_once(monkeypatch):
    """The 8-bit conversion goes a band of rows at a time (``PNG_ROWS``, to bound its
    memory): bands not dividing the rows, float32 or float64, NaN and infinities give the
    pixels of the whole image converted at once."""
    from solver.io import export

    rng = np.random.default_rng(4)
    for dtype in (np.float32, np.float64):
        image = rng.normal(0.5, 0.6, size=(37, 11, 3)).astype(dtype)
        image[0, 0, 0], image[20, 3, 1], image[36, 10, 2] = np.nan, np.inf, -np.inf
        image[5, :, 0] = (np.arange(11) + 0.5) / 255.0  # halfway between two levels
        whole = np.round(np.clip(np.nan_to_num(image.astype(np.float64)), 0.0, 1.0)
                         * 255.0).astype(np.uint8)
        monkeypatch.setattr(export, "PNG_ROWS", 8)  # 37 rows: four bands and a short one
        with Image.open(io.BytesIO(png_bytes(image))) as im:
            np.testing.assert_array_equal(np.asarray(im), whole)


def test_write_head_obj_with_texture_and_a_face_subset(tmp_path, model):
    size = 8
    tiles = {t: np.full((size, size, 3), 0.5, np.float32) for t in uv_tiles(model)}
    keep = model.face_part != model.part_names.index("Head and Neck")
    out = tmp_path / "out"
    out.mkdir()
    written = write_head_obj(out / "head.obj", model, model.vertices, tiles,
                             out / "head.png", faces=keep)
    assert written == {"texture": out / "head.png", "obj": out / "head.obj",
                       "mtl": out / "head.mtl"}
    assert sorted(os.listdir(out)) == ["head.mtl", "head.obj", "head.png"]
    with Image.open(out / "head.png") as im:
        assert im.size == (size * len(tiles), size)
    v, vt, faces, mats, mtllib = read_obj_records(out / "head.obj")
    assert v.shape == (model.n_vertices, 3)  # every vertex, only the kept polygons
    assert len(faces) == int(keep.sum()) and mtllib == "head.mtl"
    atlas, loop_uv, textured = texture_atlas(model, tiles)
    assert mats == ["head" if t else "untextured" for t in textured[keep]]
    kept = np.flatnonzero(keep)
    for k in (0, len(kept) // 2, len(kept) - 1):
        f = kept[k]
        corners = np.arange(model.face_loop_start[f],
                            model.face_loop_start[f] + model.face_loop_total[f])
        assert [c[0] for c in faces[k]] == model.loop_vertex[corners].tolist()
        np.testing.assert_allclose(vt[[c[1] for c in faces[k]]], loop_uv[corners], atol=1e-6)
    assert "map_Kd head.png" in (out / "head.mtl").read_text(encoding="utf-8")


def test_write_head_obj_without_texture(tmp_path, model):
    written = write_head_obj(tmp_path / "head.obj", model, model.vertices)
    assert written == {"obj": tmp_path / "head.obj"}
    assert os.listdir(tmp_path) == ["head.obj"]
    _, _, faces, mats, mtllib = read_obj_records(tmp_path / "head.obj")
    assert len(faces) == len(model.face_loop_total) and mtllib is None
    assert set(mats) == {None}
