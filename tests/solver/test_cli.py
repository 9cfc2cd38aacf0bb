"""OBJ export and the command line (``python -m solver``): bad input ends with exit code 1
and one line naming the file, view and key; a real fit writes the OBJ, texture and report."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from solver.io.landmarks_file import load_landmark_set
from solver.io.obj import obj_text, write_obj
from tests import ROOT

W, H = 600, 800


# --------------------------------------------------------------------------------------
# OBJ export


def read_obj(path):
    """Minimal independent OBJ reader: v, vt, faces as (vertex, vt) index lists (0-based),
    and the material in force for each face."""
    v, vt, faces, mats, mtllib = [], [], [], [], None
    material = None
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            v.append([float(x) for x in parts[1:4]])
        elif parts[0] == "vt":
            vt.append([float(x) for x in parts[1:3]])
        elif parts[0] == "f":
            corners = [c.split("/") for c in parts[1:]]
            faces.append([(int(c[0]) - 1, int(c[1]) - 1 if len(c) > 1 else -1)
                          for c in corners])
            mats.append(material)
        elif parts[0] == "usemtl":
            material = parts[1]
        elif parts[0] == "mtllib":
            mtllib = parts[1]
    return np.array(v), np.array(vt).reshape(-1, 2), faces, mats, mtllib


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
    v, vt, faces, _, mtllib = read_obj(path)
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
    v, vt, faces, _, _ = read_obj(path)
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
    _, _, faces, mats, mtllib = read_obj(path)
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
    v, vt, faces, _, _ = read_obj(path)
    np.testing.assert_allclose(v, model.vertices, atol=6e-7)
    assert len(faces) == len(model.face_loop_total)
    f = [len(x) for x in faces]
    assert f == model.face_loop_total.tolist()
    corner_v = np.concatenate([[c[0] for c in x] for x in faces])
    corner_t = np.concatenate([[c[1] for c in x] for x in faces])
    np.testing.assert_array_equal(corner_v, model.loop_vertex)  # loops are in face order
    np.testing.assert_allclose(vt[corner_t], model.loop_uv, atol=6e-7)


# --------------------------------------------------------------------------------------
# Command line


def run_cli(*args, cwd=None, **env_vars):
    env = dict(os.environ, PYTHONPATH=str(ROOT), **env_vars)
    return subprocess.run([sys.executable, "-m", "solver", *map(str, args)], cwd=cwd or ROOT,
                          capture_output=True, text=True, env=env, timeout=600)


def assert_one_line_error(proc, *fragments):
    assert proc.returncode == 1, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    for frag in fragments:
        assert frag in lines[0], (frag, lines[0])


@pytest.fixture(scope="module")
def case_doc():
    lms = load_landmark_set()
    names = list(lms.names)
    rng = np.random.default_rng(5)
    pts = rng.uniform([50, 50], [W - 50, H - 50], size=(len(names), 2)).round(1)
    return {"format": "headrecon-landmarks", "version": 1, "views": {
        "front": {"image": "front.png", "size": [W, H], "camera": "orthographic-front",
                  "points": {n: pts[i].tolist() for i, n in enumerate(names[:20])}},
        "side": {"image": "side.png", "size": [W, H], "camera": "orthographic-right",
                 "points": {n: pts[i].tolist() for i, n in enumerate(names[30:40])}}}}


def write_case(folder, doc, name="case.json"):
    path = Path(folder) / name
    path.write_text(json.dumps(doc), encoding="utf-8")
    return path


def test_help():
    proc = run_cli("--help")
    assert proc.returncode == 0 and "fit" in proc.stdout and "validate" in proc.stdout
    proc = run_cli("fit", "--help")
    assert proc.returncode == 0
    for option in ("--out", "--texture", "--report", "--method", "--components", "--regional",
                   "--exact"):
        assert option in proc.stdout


def test_usage_errors_exit_2(tmp_path, case_doc):
    case = write_case(tmp_path, case_doc)
    proc = run_cli("fit", case)  # --out missing
    assert proc.returncode == 2 and "--out" in proc.stderr
    proc = run_cli("fit", case, "--out", tmp_path / "h.obj", "--method", "magic")
    assert proc.returncode == 2 and "magic" in proc.stderr


def test_fit_missing_file(tmp_path):
    proc = run_cli("fit", tmp_path / "nothere.json", "--out", tmp_path / "h.obj")
    assert_one_line_error(proc, "nothere.json", "no such file")
    assert not (tmp_path / "h.obj").exists()


def test_fit_invalid_landmarks(tmp_path, case_doc):
    doc = json.loads(json.dumps(case_doc))
    doc["views"]["side"]["points"]["nose_tpi"] = [100.0, 100.0]
    doc["views"]["front"]["points"]["nose_tip"] = [W + 10.0, 100.0]
    case = write_case(tmp_path, doc)
    proc = run_cli("fit", case, "--out", tmp_path / "h.obj")
    assert_one_line_error(proc, "case.json: views.front.points.nose_tip: ",
                          "outside the 600x800 image", "(and 1 more problem)")
    assert not (tmp_path / "h.obj").exists()


def test_fit_not_json(tmp_path):
    case = tmp_path / "case.json"
    case.write_text("front: nose_tip 1 2\n", encoding="utf-8")
    proc = run_cli("fit", case, "--out", tmp_path / "h.obj")
    assert_one_line_error(proc, "case.json: not valid JSON")


def test_fit_texture_needs_the_photos(tmp_path, case_doc):
    case = write_case(tmp_path, case_doc)
    proc = run_cli("fit", case, "--out", tmp_path / "h.obj", "--texture", tmp_path / "h.png")
    assert_one_line_error(proc, "case.json: views.front.image: photo 'front.png' not found")
    from PIL import Image

    Image.new("RGB", (W, H)).save(tmp_path / "front.png")
    Image.new("RGB", (W // 2, H // 2)).save(tmp_path / "side.png")
    proc = run_cli("fit", case, "--out", tmp_path / "h.obj", "--texture", tmp_path / "h.png")
    assert_one_line_error(proc, "case.json: views.side.size: the file says 600x800 but "
                                "side.png is 300x400 pixels")
    (tmp_path / "side.png").write_bytes(b"not an image")
    proc = run_cli("fit", case, "--out", tmp_path / "h.obj", "--texture", tmp_path / "h.png")
    assert_one_line_error(proc, "views.side.image: side.png is not an image")
    assert not (tmp_path / "h.obj").exists() and not (tmp_path / "h.png").exists()


def test_fit_without_a_model_or_photos(tmp_path, case_doc):
    case = write_case(tmp_path, case_doc)
    proc = run_cli("fit", case, "--out", tmp_path / "h.obj",
                   HEADRECON_MODEL=str(tmp_path / "none.npz"))
    assert_one_line_error(proc, "head model not found", "none.npz", "./run model")
    doc = json.loads(json.dumps(case_doc))
    for view in doc["views"].values():
        del view["image"]
    case = write_case(tmp_path, doc)
    proc = run_cli("fit", case, "--out", tmp_path / "h.obj", "--texture", tmp_path / "t.png")
    assert_one_line_error(proc, "--texture: ", "no view names a photo")


def test_validate(tmp_path, case_doc):
    good = write_case(tmp_path, case_doc)
    proc = run_cli("validate", good)
    assert proc.returncode == 0, proc.stderr
    assert "case.json: OK (front 20 landmarks; side 10 landmarks)" in proc.stdout
    assert "photo 'front.png' not found" in proc.stderr  # a warning only
    doc = json.loads(json.dumps(case_doc))
    doc["views"]["side"]["points"]["nose_tpi"] = [100.0, 100.0]
    doc["views"]["front"]["camera"] = "orthographic-frnt"
    bad = write_case(tmp_path, doc, "bad.json")
    proc = run_cli("validate", good, bad)
    assert proc.returncode == 1
    assert "Traceback" not in proc.stderr
    # schema problems come first; the name check runs once the structure is right
    assert "bad.json: views.front.camera: \"orthographic-frnt\" is not one of" in proc.stderr
    doc["views"]["front"]["camera"] = "orthographic-front"
    write_case(tmp_path, doc, "bad.json")
    proc = run_cli("validate", bad)
    assert "bad.json: views.side.points.nose_tpi: unknown landmark; did you mean 'nose_tip'?" \
        in proc.stderr
    # work in progress: too few landmarks is fine with --draft, not without
    doc = json.loads(json.dumps(case_doc))
    doc["views"]["side"]["points"] = dict(list(doc["views"]["side"]["points"].items())[:1])
    wip = write_case(tmp_path, doc, "wip.json")
    assert run_cli("validate", "--draft", wip).returncode == 0
    proc = run_cli("validate", wip)
    assert proc.returncode == 1 and "wip.json: views.side.points: 1 landmark;" in proc.stderr


def test_landmarks_listing():
    proc = run_cli("landmarks")
    assert proc.returncode == 0
    line = next(x for x in proc.stdout.splitlines() if x.startswith("nose_tip "))
    assert "ibug31" in line
    proc = run_cli("landmarks", "--json")
    entries = json.loads(proc.stdout)
    assert "nose_tip" in {e["name"] for e in entries}
    assert len(entries) == len(load_landmark_set().names)


def test_texture_atlas_puts_tiles_side_by_side(model):
    from solver.cli import texture_atlas
    from solver.texture.bake import uv_tiles

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


def test_fit_a_synthetic_case_writes_obj_texture_and_report(tmp_path, model):
    from PIL import Image

    from solver.io.landmarks_file import save_landmarks
    from solver.synthetic import make_case

    case, truth = make_case(model, 11, noise_px=0.5, image_height=512)
    for name, view in case.views.items():
        view.image = f"photos/{name}.png"
    (tmp_path / "photos").mkdir()
    for name, view in case.views.items():  # a colour ramp: every texel gets some colour
        w, h = view.size
        ramp = np.stack(np.meshgrid(np.linspace(0, 1, w), np.linspace(0, 1, h)) +
                        [np.full((h, w), 0.5)], axis=-1)
        Image.fromarray((ramp * 255).astype(np.uint8)).save(tmp_path / "photos" / f"{name}.png")
    path = tmp_path / "case.json"
    save_landmarks(case, path)

    out = tmp_path / "out" / "head.obj"
    proc = run_cli("fit", path, "--out", out, "--texture", tmp_path / "out" / "head.png",
                   "--texture-size", 128, "--report", tmp_path / "out" / "report.json",
                   "--components", 40)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr
    assert any(line.startswith("[") and "%]" in line for line in proc.stderr.splitlines())

    v, vt, faces, mats, mtllib = read_obj(out)
    assert v.shape == (model.n_vertices, 3) and len(faces) == len(model.face_loop_total)
    assert mtllib == "head.mtl" and set(mats) == {"head", "untextured"}
    assert "map_Kd head.png" in (tmp_path / "out" / "head.mtl").read_text(encoding="utf-8")
    assert ((vt >= 0) & (vt <= 7)).all()
    # local frame, Y up: the fitted head is close to the true one (metres)
    truth_obj = np.column_stack([truth.local_vertices[:, 0], truth.local_vertices[:, 2],
                                 -truth.local_vertices[:, 1]])
    err = np.linalg.norm(v - truth_obj, axis=1)[model.skin]
    assert np.median(err) < 0.005, np.median(err)

    with Image.open(tmp_path / "out" / "head.png") as tex:
        n_tiles = tex.size[0] // 128  # the skin's UDIM tiles side by side
        assert tex.size == (128 * n_tiles, 128) and n_tiles >= 1
        assert np.asarray(tex).std() > 1  # the photos' colours arrived

    report = json.loads((tmp_path / "out" / "report.json").read_text(encoding="utf-8"))
    assert report["format"] == "headrecon-fit-report"
    assert report["method"] in ("combined", "approach1", "approach2")
    assert len(report["coefficients"]["identity"]) == 40
    assert set(report["residuals"]) == set(case.views)
    for name, r in report["residuals"].items():
        assert set(r["landmarks"]) <= set(case.views[name].points)
        assert 0 <= r["mean_px"] < 5, (name, r["mean_px"])
    assert report["uncertainty_mm"]["median"] > 0
    assert report["timings_s"]["fit"] > 0
    assert set(report["outputs"]) == {"obj", "mtl", "texture", "report"}
