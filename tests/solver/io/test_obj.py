"""OBJ files (solver/io/obj.py): writing a head (vertices, faces, UVs, materials, axes) and
reading positions, UVs and polygons back."""

import os

import numpy as np
import pytest

from solver.io.obj import (
    obj_text,
    parse_obj,
    parse_obj_positions,
    read_obj,
    read_obj_positions,
    write_obj,
)
from tests.solver.io.support import read_obj_records

# --------------------------------------------------------------------------------------
# Writing


def small_mesh():
    """A quad and two triangles sharing vertices; loops not in face order on purpose."""
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1], [0.5, -1, 0.5]], float)
    # faces: quad (0,1,2,3) stored at loops 3..6, triangles (1,4,2) at 0..2 and (0,4,1) 7..9
    loop_vertex = np.array([1, 4, 2, 0, 1, 2, 3, 0, 4, 1])
    face_loop_start = np.array([3, 0, 7])
    face_loop_total = np.array([4, 3, 3])
    loop_uv = np.array([[0.5, 0.25], [0.75, 0.5], [0.5, 0.75],  # tri 1
                        [0.0, 0.25], [0.5, 0.25], [0.5, 0.75], [0.0, 0.75],  # quad
                        [0.0, 0.25], [1.5, 0.5], [0.5, 0.25]])  # tri 2 (u 1.5: tile 1002)
    return vertices, loop_vertex, face_loop_start, face_loop_total, loop_uv


def test_obj_round_trip_vertices_faces_uvs(tmp_path):
    vertices, lv, start, total, uv = small_mesh()
    path = tmp_path / "m.obj"
    written = write_obj(path, vertices, lv, start, total, uv, axes="blender")
    assert written == [path]
    v, vt, faces, _, mtllib = read_obj_records(path)
    assert mtllib is None
    np.testing.assert_allclose(v, vertices, atol=1e-6)
    assert [[c[0] for c in f] for f in faces] == [[0, 1, 2, 3], [1, 4, 2], [0, 4, 1]]
    # every corner's UV comes back; identical UVs are written once
    loops = [list(range(s, s + n)) for s, n in zip(start, total, strict=True)]
    for f, ls in zip(faces, loops, strict=True):
        np.testing.assert_allclose(vt[[c[1] for c in f]], uv[ls], atol=1e-6)
    assert len(vt) == len(np.unique(uv, axis=0)) == 6


def test_obj_default_axes_are_y_up(tmp_path):
    vertices, lv, start, total, _ = small_mesh()
    path = tmp_path / "m.obj"
    write_obj(path, vertices, lv, start, total)
    v, vt, faces, _, _ = read_obj_records(path)
    # OBJ (x, y, z) = Blender (x, z, -y): Blender's own OBJ exporter convention
    np.testing.assert_allclose(v, np.column_stack([vertices[:, 0], vertices[:, 2],
                                                   -vertices[:, 1]]), atol=1e-6)
    assert len(vt) == 0 and all(c[1] == -1 for f in faces for c in f)


def test_obj_with_material_and_untextured_faces(tmp_path):
    vertices, lv, start, total, uv = small_mesh()
    (tmp_path / "tex").mkdir()
    path = tmp_path / "out" / "head.obj"
    path.parent.mkdir()
    written = write_obj(path, vertices, lv, start, total, uv,
                        mtl_texture=tmp_path / "tex" / "skin.png",
                        textured_faces=np.array([True, False, True]))
    assert written == [path, path.with_suffix(".mtl")]
    _, _, faces, mats, mtllib = read_obj_records(path)
    assert mtllib == "head.mtl" and mats == ["head", "untextured", "head"]
    mtl = path.with_suffix(".mtl").read_text(encoding="utf-8")
    assert "newmtl head" in mtl and "map_Kd ../tex/skin.png" in mtl
    assert sorted(os.listdir(path.parent)) == ["head.mtl", "head.obj"]  # no temp files left


def test_obj_rejects_bad_input(tmp_path):
    vertices, lv, start, total, uv = small_mesh()
    with pytest.raises(ValueError, match=r"vertices: expected shape \(V, 3\)"):
        obj_text(vertices[:, :2], lv, start, total)
    with pytest.raises(ValueError, match="loop_vertex: indices must be in 0..4"):
        obj_text(vertices, lv + 1, start, total)
    with pytest.raises(ValueError, match=r"loop_uv: expected shape \(10, 2\)"):
        obj_text(vertices, lv, start, total, uv[:5])
    bad = vertices.copy()
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match="vertices: row 2 is not finite"):
        obj_text(bad, lv, start, total)
    with pytest.raises(ValueError, match="face_loop_total: face 1 has fewer than 3"):
        obj_text(vertices, lv, start, np.array([4, 2, 3]))
    path = tmp_path / "keep.obj"
    path.write_text("old", encoding="utf-8")
    with pytest.raises(ValueError):
        write_obj(path, bad, lv, start, total)
    assert path.read_text(encoding="utf-8") == "old"


def test_obj_of_the_head_model(tmp_path, model):
    path = tmp_path / "head.obj"
    write_obj(path, model.vertices, model.loop_vertex, model.face_loop_start,
              model.face_loop_total, model.loop_uv, axes="blender")
    v, vt, faces, _, _ = read_obj_records(path)
    np.testing.assert_allclose(v, model.vertices, atol=6e-7)
    assert len(faces) == len(model.face_loop_total)
    f = [len(x) for x in faces]
    assert f == model.face_loop_total.tolist()
    corner_v = np.concatenate([[c[0] for c in x] for x in faces])
    corner_t = np.concatenate([[c[1] for c in x] for x in faces])
    np.testing.assert_array_equal(corner_v, model.loop_vertex)  # loops are in face order
    np.testing.assert_allclose(vt[corner_t], model.loop_uv, atol=6e-7)


# --------------------------------------------------------------------------------------
# Reading

OBJ_TEXT = """# tiny
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 2 0.5 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
f 1/1/1 2/2/1 3/3/1 4/4/1
f 2/2 5/3 3/3
"""


def test_parse_obj_quads_triangles_and_uvs():
    m = parse_obj(OBJ_TEXT)
    assert m.positions.shape == (5, 3) and m.uvs.shape == (4, 2)
    np.testing.assert_array_equal(m.loop_vertex, [0, 1, 2, 3, 1, 4, 2])
    np.testing.assert_array_equal(m.loop_uv, [0, 1, 2, 3, 1, 2, 2])
    np.testing.assert_array_equal(m.face_loop_start, [0, 4])
    np.testing.assert_array_equal(m.face_loop_total, [4, 3])
    m2 = parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//1 2//1 3//1\n")
    np.testing.assert_array_equal(m2.loop_uv, [-1, -1, -1])
    np.testing.assert_allclose(parse_obj_positions(OBJ_TEXT)[4], [2, 0.5, 0])


def test_parse_obj_rejects_bad_indices():
    with pytest.raises(ValueError, match="vertex 9"):
        parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "bad.obj")
    with pytest.raises(ValueError, match="negative"):
        parse_obj("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -3\n", "rel.obj")
    with pytest.raises(ValueError, match="no faces"):
        parse_obj("v 0 0 0\n", "empty.obj")


def test_read_obj_gives_back_what_write_obj_wrote(tmp_path):
    vertices, lv, start, total, uv = small_mesh()
    path = tmp_path / "m.obj"
    write_obj(path, vertices, lv, start, total, uv, axes="blender")
    mesh = read_obj(path)
    np.testing.assert_allclose(mesh.positions, vertices, atol=1e-6)
    np.testing.assert_allclose(read_obj_positions(path), vertices, atol=1e-6)
    # the written file has its faces in order, corners one after the other
    loops = np.concatenate([np.arange(s, s + n) for s, n in zip(start, total, strict=True)])
    np.testing.assert_array_equal(mesh.face_loop_total, total)
    np.testing.assert_array_equal(mesh.loop_vertex, lv[loops])
    np.testing.assert_allclose(mesh.uvs[mesh.loop_uv], uv[loops], atol=1e-6)

