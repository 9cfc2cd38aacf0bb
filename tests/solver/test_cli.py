"""The command line (``python -m solver``): bad input ends with exit code 1 and one line
naming the file, view and key; a real fit writes the OBJ, texture and report."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from solver import load_landmark_set
from tests import ROOT
from tests.solver.io.support import read_obj_records

W, H = 600, 800


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


def landmarks_doc(w=W, h=H, margin=50, seed=5, front=(0, 20), side=(30, 40)):
    """A valid version-1 document: the landmark set's names ``front`` and ``side`` (index
    ranges) at random pixels ``margin`` inside a ``w`` x ``h`` front and profile photo."""
    names = list(load_landmark_set().names)
    rng = np.random.default_rng(seed)
    pts = rng.uniform([margin, margin], [w - margin, h - margin], size=(len(names), 2))
    pts = pts.round(1)

    def points(lo, hi):
        return {names[i]: pts[i].tolist() for i in range(lo, hi)}

    return {"format": "headrecon-landmarks", "version": 1, "views": {
        "front": {"image": "front.png", "size": [w, h], "camera": "orthographic-front",
                  "points": points(*front)},
        "side": {"image": "side.png", "size": [w, h], "camera": "orthographic-right",
                 "points": points(*side)}}}


@pytest.fixture(scope="module")
def case_doc():
    return landmarks_doc()


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
    assert proc.returncode == 1 and "wip.json: views.side.points: 1 usable landmark;" in proc.stderr


def test_landmarks_listing():
    proc = run_cli("landmarks")
    assert proc.returncode == 0
    line = next(x for x in proc.stdout.splitlines() if x.startswith("nose_tip "))
    assert "ibug31" in line
    proc = run_cli("landmarks", "--json")
    entries = json.loads(proc.stdout)
    assert "nose_tip" in {e["name"] for e in entries}
    assert len(entries) == len(load_landmark_set().names)


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

    v, vt, faces, mats, mtllib = read_obj_records(out)
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
    # the irises' colour read off the front photo: its ramp's blue is 127 everywhere
    assert report["iris_srgb"][2] == pytest.approx(127 / 255, abs=0.005)
    # the estimated placement noise and the head's plausibility are in the report; the
    # noise floor (1 px at the settings' size) in these 512-px photos' pixels
    from solver.fitting.views import photo_scale

    noise = report["info"]["noise"]
    assert set(noise["landmark_px"]) == set(case.views)
    assert noise["floor_px"] == pytest.approx(max(photo_scale(model, case), 0.5))
    assert 0.5 <= noise["floor_px"] < 1.0
    assert 0 <= report["info"]["plausibility"]["percentile"] <= 100


def test_fit_warns_of_an_implausible_head_and_what_to_check(tmp_path, model):
    from solver.io.landmarks_file import save_landmarks
    from solver.synthetic import make_case

    # a head four times as far from the mean as the model's own heads
    case, _ = make_case(model, 1003, noise_px=1.0, coeff_scale=4.0, image_height=512)
    path = tmp_path / "case.json"
    save_landmarks(case, path)
    proc = run_cli("fit", path, "--out", tmp_path / "head.obj", "--components", 40, "--quiet")
    assert proc.returncode == 0, proc.stderr
    (line,) = [x for x in proc.stderr.splitlines() if "implausible" in x]
    assert line.startswith("warning: the fitted head is implausible")
    assert "check the flagged landmarks" in line and "--noise-px" in line


def test_fit_with_fixed_noise(tmp_path, model):
    from solver.io.landmarks_file import save_landmarks
    from solver.synthetic import make_case

    case, _ = make_case(model, 12, noise_px=0.5, image_height=512)
    name, view = next((n, v) for n, v in case.views.items() if v.contour is not None)
    # a contour traced every tenth of a pixel: thinned for the fit, and the fit says so
    c = view.contour
    t = np.linspace(0, len(c) - 1, 10 * len(c))
    view.contour = np.column_stack([np.interp(t, np.arange(len(c)), c[:, 0]),
                                    np.interp(t, np.arange(len(c)), c[:, 1])])
    path = tmp_path / "case.json"
    save_landmarks(case, path)
    proc = run_cli("fit", path, "--out", tmp_path / "head.obj", "--report",
                   tmp_path / "report.json", "--components", 20, "--noise", "fixed",
                   "--noise-px", 2)
    assert proc.returncode == 0, proc.stderr
    assert f"notice: {path}: views.{name}.contour: {10 * len(c)} points thinned to " \
        in proc.stderr
    report = json.loads((tmp_path / "report.json").read_text(encoding="utf-8"))
    assert "noise" not in report["info"]  # nothing estimated: every landmark at 2 px
    proc = run_cli("fit", path, "--out", tmp_path / "head.obj", "--noise", "guess")
    assert proc.returncode == 2 and "--noise" in proc.stderr


# --------------------------------------------------------------------------------------
# Bad input and faults: one line, never a user's file destroyed


def test_deeply_nested_json_is_one_line(tmp_path, case_doc):
    text = json.dumps(case_doc)[:-1] + ', "x-tool": ' + "[" * 1000 + "]" * 1000 + "}"
    case = tmp_path / "case.json"
    case.write_text(text, encoding="utf-8")
    assert_one_line_error(run_cli("validate", case), "case.json: arrays and objects nested "
                                                     "1001 deep; at most 64 are read")
    proc = run_cli("fit", case, "--out", tmp_path / "h.obj")
    assert_one_line_error(proc, "case.json: arrays and objects nested 1001 deep")


def test_an_option_out_of_range_names_its_range(tmp_path, case_doc):
    case = write_case(tmp_path, case_doc)
    proc = run_cli("fit", case, "--out", tmp_path / "h.obj", "--lambda2", "1e300")
    assert_one_line_error(proc, "--lambda2: must be a number in [0, 1e+06], got 1e+300")
    proc = run_cli("fit", case, "--out", tmp_path / "h.obj", "--max-iterations", "0")
    assert_one_line_error(proc, "--max-iterations: must be an integer in 1..10000, got 0")
    assert not (tmp_path / "h.obj").exists()


@pytest.mark.parametrize("args, fragments", [
    (["--report", "case.json"], ["--report", "is the landmarks file", "case.json"]),
    (["--out", "case.json"], ["--out", "is the landmarks file"]),
    (["--texture", "front.png"], ["--texture", "is the photo of view 'front'", "front.png"]),
    (["--texture", "head.mtl"], ["the .mtl of --out (head.mtl)", "is also --texture"]),
    (["--report", "head.obj"], ["--report", "is also --out", "head.obj"]),
    (["--report", "link.json"], ["--report", "is the landmarks file"]),
    (["--out", "model.npz", "--model", "model.npz"], ["--out", "is --model"]),
])
def test_outputs_never_overwrite_inputs_or_each_other(tmp_path, case_doc, args, fragments):
    from PIL import Image

    case = write_case(tmp_path, case_doc)
    (tmp_path / "link.json").symlink_to(case)
    Image.new("RGB", (W, H)).save(tmp_path / "front.png")
    for name in ("head.obj", "head.mtl", "model.npz"):
        (tmp_path / name).write_bytes(b"old " + name.encode())
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    argv = ["fit", "case.json", "--out", "head.obj", *args]
    proc = run_cli(*argv, cwd=tmp_path)
    assert_one_line_error(proc, *fragments)
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


def _claiming_png(path, width, height):
    """A valid 1x1 PNG whose header then claims width x height (CRC fixed up)."""
    import struct
    import zlib

    from PIL import Image

    Image.new("RGB", (1, 1)).save(path)
    data = bytearray(path.read_bytes())
    data[16:24] = struct.pack(">II", width, height)
    data[29:33] = struct.pack(">I", zlib.crc32(bytes(data[12:29])))
    path.write_bytes(bytes(data))


def test_a_photo_over_the_pixel_limit_is_named_with_its_size(tmp_path, case_doc):
    doc = json.loads(json.dumps(case_doc))
    doc["views"]["front"]["size"] = [60000, 60000]
    case = write_case(tmp_path, doc)
    _claiming_png(tmp_path / "front.png", 60000, 60000)
    proc = run_cli("fit", case, "--out", tmp_path / "h.obj", "--texture", tmp_path / "t.png")
    assert_one_line_error(proc, "case.json: views.front.image: front.png is 60000x60000 "
                                "pixels (3600 megapixels); photos up to 200 megapixels")


def test_a_big_photo_is_read_reduced_for_the_bake(tmp_path, case_doc):
    from PIL import Image

    from solver.cli import _read_photo
    from solver.io.landmarks_file import load_landmarks

    doc = json.loads(json.dumps(case_doc))
    doc["views"]["front"]["size"] = [6000, 3000]
    case = load_landmarks(write_case(tmp_path, doc))
    Image.new("RGB", (6000, 3000), (255, 128, 0)).save(tmp_path / "front.png")
    photo = _read_photo(case, "front", 128)
    assert photo.shape == (1024, 2048, 3) and photo.dtype == np.float32
    np.testing.assert_allclose(photo[500, 1000], [1.0, 128 / 255, 0.0], atol=1e-6)
    assert _read_photo(case, "front", 2048).shape == (3000, 6000, 3)  # needed whole


def test_photos_are_read_upright_as_their_exif_says(tmp_path):
    from solver.cli import _read_photo, load_photo
    from solver.io import exif
    from solver.io.landmarks_file import load_landmarks
    from tests.solver.io.exif_jpeg import jpeg, tiff

    stored = np.full((240, 320, 3), 40, np.uint8)
    stored[:40, :40] = 255  # top-left as stored: top-right once turned 90° clockwise
    (tmp_path / "front.jpg").write_bytes(jpeg(tiff([(exif.ORIENTATION, 3, [6])]),
                                              pixels=stored))
    for size, shape in (((240, 320), (320, 240, 3)),  # upright
                        ((320, 240), (240, 320, 3))):  # as stored: a file of before
        doc = landmarks_doc(w=min(size), h=min(size), margin=10)
        doc["views"]["front"].update(image="front.jpg", size=list(size))
        case = load_landmarks(write_case(tmp_path, doc))
        assert _read_photo(case, "front", 128).shape == shape
    photo = _read_photo(load_landmarks(write_case(tmp_path, {
        **doc, "views": {**doc["views"], "front": {**doc["views"]["front"],
                                                   "size": [240, 320]}}})), "front", 128)
    for arr in (photo, load_photo(tmp_path / "front.jpg") / 255.0):
        assert arr.shape == (320, 240, 3)
        assert arr[:30, -30:].min() > 0.9 and arr[:30, :30].max() < 0.5


def test_a_grey_photo_of_16_bits_or_floats_is_read_as_its_8_bit_grey(tmp_path):
    from PIL import Image

    from solver.cli import _read_photo, load_photo
    from solver.io.landmarks_file import load_landmarks

    grey = np.tile(np.linspace(0, 255, 240).round().astype(np.uint8), (320, 1))
    Image.fromarray(grey.astype(np.uint16) * 257).save(tmp_path / "front.png")  # I;16
    Image.fromarray(grey.astype(np.float32) / 255).save(tmp_path / "float.tif")  # F
    Image.fromarray(grey.astype(np.int32)).save(tmp_path / "int.tif")  # I, 8-bit values
    for name in ("front.png", "float.tif", "int.tif"):
        photo = load_photo(tmp_path / name)  # Pillow's own conversion clips to white
        assert photo.shape == (320, 240, 3) and np.abs(photo - grey[..., None]).max() <= 1
    doc = landmarks_doc(w=240, h=320, margin=10)
    doc["views"]["front"].update(image="front.png", size=[240, 320])
    photo = _read_photo(load_landmarks(write_case(tmp_path, doc)), "front", 256)
    assert np.abs(photo * 255 - grey[..., None]).max() <= 1


def test_a_cut_out_photo_is_read_with_its_transparency(tmp_path):
    """A PNG cut out around the person, RGBA or a palette with a transparent colour, keeps
    its alpha for the detector (``Detector.detect`` lays it on grey); an opaque one is RGB."""
    from PIL import Image

    from solver.cli import load_photo

    rgb = np.zeros((40, 30, 3), np.uint8)
    rgb[10:30, 5:25] = (200, 150, 120)
    alpha = np.where(rgb[..., 0] > 0, 255, 0).astype(np.uint8)
    Image.fromarray(np.dstack([rgb, alpha])).save(tmp_path / "rgba.png")
    palette = Image.frombytes("P", (30, 40), (alpha > 0).astype(np.uint8).tobytes())
    palette.putpalette([0, 0, 0, 200, 150, 120])
    palette.save(tmp_path / "palette.png", transparency=0)
    Image.fromarray(rgb).save(tmp_path / "opaque.png")
    for name in ("rgba.png", "palette.png"):
        photo = load_photo(tmp_path / name)
        assert photo.shape == (40, 30, 4), name
        np.testing.assert_array_equal(photo[..., 3], alpha)
        np.testing.assert_array_equal(photo[alpha > 0, :3], rgb[alpha > 0])
    assert load_photo(tmp_path / "opaque.png").shape == (40, 30, 3)


def test_an_orthographic_phone_photo_is_warned_about_from_its_exif_lens(tmp_path, model):
    from solver.io import exif
    from solver.io.landmarks_file import save_landmarks
    from solver.synthetic import make_case
    from tests.solver.io.exif_jpeg import jpeg, tiff

    case, _ = make_case(model, 13, noise_px=0.5, image_height=256)
    w, h = case.views["front"].size
    case.views["front"].image = "front.jpg"
    (tmp_path / "front.jpg").write_bytes(jpeg(tiff([], [(exif.FOCAL_35MM, 3, [26])]),
                                              pixels=np.zeros((h, w, 3), np.uint8)))
    save_landmarks(case, tmp_path / "case.json")
    proc = run_cli("fit", "case.json", "--out", "head.obj", "--components", 10, "-q",
                   cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    warned = [line for line in proc.stderr.splitlines() if "parallel projection" in line]
    assert len(warned) == 1 and "view 'front'" in warned[0] and "mm lens, EXIF" in warned[0]
    assert "lens_mm" not in (tmp_path / "case.json").read_text()  # the input is untouched


def test_a_failed_write_leaves_the_old_output_set_and_names_the_file(tmp_path, model):
    import resource

    from PIL import Image

    from solver.io.landmarks_file import save_landmarks
    from solver.synthetic import make_case

    case, _ = make_case(model, 13, noise_px=0.5, image_height=256)
    for name, view in case.views.items():
        view.image = f"{name}.png"
        Image.new("RGB", tuple(view.size), (200, 150, 100)).save(tmp_path / f"{name}.png")
    save_landmarks(case, tmp_path / "case.json")
    argv = ["fit", "case.json", "--out", "out/head.obj", "--texture", "out/head.png",
            "--texture-size", 64, "--report", "out/report.json", "--components", 10, "-q"]
    assert run_cli(*argv, cwd=tmp_path).returncode == 0
    old = {p.name: p.read_bytes() for p in (tmp_path / "out").iterdir()}
    assert set(old) == {"head.obj", "head.mtl", "head.png", "report.json"}

    def small_files():  # ulimit -f: writing past 200 kB fails with "File too large"
        resource.setrlimit(resource.RLIMIT_FSIZE, (200_000, resource.RLIM_INFINITY))

    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.run([sys.executable, "-m", "solver", *map(str, argv)],
                          cwd=tmp_path, capture_output=True, text=True, env=env,
                          timeout=600, preexec_fn=small_files)
    assert_one_line_error(proc, "File too large", "head.obj")
    assert ".tmp" not in proc.stderr
    assert {p.name: p.read_bytes() for p in (tmp_path / "out").iterdir()} == old


def test_a_fit_failure_the_checks_let_through_names_the_file():
    from types import SimpleNamespace

    from solver.cli import _fit_failure

    case = SimpleNamespace(source="case.json")
    assert _fit_failure(case, ValueError("view 'front': 2 usable landmarks")) == \
        "case.json: view 'front': 2 usable landmarks"
    msg = _fit_failure(case, OverflowError("(34, 'Numerical result out of range')"))
    assert msg.startswith("case.json: the fit failed (OverflowError: ") and \
        msg.endswith("'python -m solver validate case.json' checks each view's camera and "
                     "landmarks")


def test_a_failure_that_names_its_view_is_given_with_the_file():
    from types import SimpleNamespace

    from solver.cli import _fit_failure

    case = SimpleNamespace(source="case.json", views={})
    error = ValueError("view 'side': camera refit (orthographic-right): source/target: "
                       "points are degenerate; the rotation is undetermined")
    assert _fit_failure(case, error) == f"case.json: {error}"


def _dlt_of_focal(focal_px):
    from solver import DLTCamera, PinholeCamera

    pin = PinholeCamera.look_at([0.3, -1.2, 0.0], [0, 0, 0], (W, H), lens_mm=50)
    k = pin.intrinsics
    k[0, 0] = k[1, 1] = focal_px
    return DLTCamera.from_krc(k, pin.rotation, pin.centre, (W, H)).to_dict()


def _three_landmarks_twice(doc):
    names = list(doc["views"]["front"]["points"])[:3]
    doc["views"]["side"]["points"] = {n: doc["views"]["front"]["points"][n] for n in names}
    doc["views"]["front"]["points"] = dict(doc["views"]["side"]["points"])


def _flat_outline_alone(doc):
    doc["views"]["side"]["points"] = {}
    doc["views"]["side"]["contour"] = [[100.0 + 3 * i, 400.0] for i in range(50)]


def _side_camera(camera, calibrated=None):
    def change(doc):
        doc["version"] = 2
        doc["views"]["side"]["camera"] = camera
        if calibrated is not None:
            doc["views"]["side"]["calibrated"] = calibrated
    return change


@pytest.mark.parametrize("change, fragments", [
    # pinhole fields that once ended in "points: row 3 is not finite", "SVD did not
    # converge in Linear Least Squares" and "singular system: ... identity_002 ..."
    (_side_camera({"kind": "pinhole", "lens_mm": 1e-9}),
     ["views.side.camera.lens_mm: 1e-09 mm is outside 2..5000 mm"]),
    (_side_camera({"kind": "pinhole", "focal_px": 1e300}),
     ["views.side.camera.focal_px: 1e+300 px is outside"]),
    (_side_camera({"kind": "pinhole", "lens_mm": 50, "principal_point": [1e5, 10.0]}),
     ["views.side.camera.principal_point: (100000, 10) lies outside the 600x800 photo"]),
    # a kept DLT of 1e12 px: "singular system: the rows do not determine 'translation x'"
    (_side_camera(_dlt_of_focal(1e12), calibrated=True),
     ["views.side.camera: its parameters give a focal length of 1e+12 x 1e+12 px"]),
    # "source: needs at least 4 points, got 3"
    (_three_landmarks_twice, ["views: 3 different landmarks in all"]),
    # "outline: it has no height to lay the head's profile onto"
    (_flat_outline_alone, ["views.side.contour: all 50 points lie on one line"]),
])
def test_inputs_that_once_failed_in_the_fit_naming_nothing_are_named(tmp_path, case_doc,
                                                                     change, fragments):
    doc = json.loads(json.dumps(case_doc))
    change(doc)
    case = write_case(tmp_path, doc)
    for command in (["validate", case], ["fit", case, "--out", tmp_path / "h.obj"]):
        proc = run_cli(*command)
        assert_one_line_error(proc, "case.json: ", *fragments)
    assert not (tmp_path / "h.obj").exists()


def test_detect_errors_name_the_photo(tmp_path):
    from PIL import Image

    if not (ROOT / "generated" / "detector" / "face_landmark.tflite").is_file():
        pytest.skip("detector models missing: run ./run detector")
    blank = tmp_path / "blank.png"
    Image.new("RGB", (200, 300), (128, 128, 128)).save(blank)
    proc = run_cli("detect", blank, "--out", tmp_path / "case.json")
    assert_one_line_error(proc, "blank.png", "no face found")
    proc = run_cli("detect", tmp_path / "missing.png", "--out", tmp_path / "case.json")
    assert_one_line_error(proc, "missing.png", "not found")
    (tmp_path / "text.png").write_text("not an image")
    proc = run_cli("detect", tmp_path / "text.png", "--out", tmp_path / "case.json")
    assert_one_line_error(proc, "text.png", "not an image")
    (tmp_path / "photos").mkdir()
    proc = run_cli("detect", tmp_path / "photos", "--out", tmp_path / "case.json")
    assert_one_line_error(proc, "photos", "a folder, not a photo")
    assert not (tmp_path / "case.json").exists()


def _painted_case(tmp_path, model, paint):
    """A small synthetic case saved as ``case.json`` with photos ``paint(w, h)`` (uint8
    (h, w, 3)) beside it."""
    from PIL import Image

    from solver.io.landmarks_file import save_landmarks
    from solver.synthetic import make_case

    case, _ = make_case(model, 17, noise_px=0.5, image_height=256)
    for name, view in case.views.items():
        view.image = f"{name}.png"
        Image.fromarray(paint(*view.size)).save(tmp_path / f"{name}.png")
    save_landmarks(case, tmp_path / "case.json")


def _textured_fit(tmp_path, flag, value):
    """``solver fit case.json --texture`` with ``flag value`` into ``value/``: (the
    texture as float (H, W, 3), the report)."""
    from PIL import Image

    proc = run_cli("fit", "case.json", "--out", f"{value}/head.obj", "--texture",
                   f"{value}/head.png", "--texture-size", 64, "--components", 10, "--noise",
                   "fixed", "-q", flag, value, "--report", f"{value}/report.json",
                   cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    with Image.open(tmp_path / value / "head.png") as tex:
        rgb = np.asarray(tex.convert("RGB"), dtype=np.float64)
    return rgb, json.loads((tmp_path / value / "report.json").read_text(encoding="utf-8"))


def test_texture_shading_remove_flattens_the_light_of_the_photos(tmp_path, model):
    def lit(w, h):  # a key light from one side
        light = np.linspace(0.3, 1.0, w)[None, :, None]
        return np.broadcast_to(light * np.array([230, 170, 140]), (h, w, 3)).astype(np.uint8)

    _painted_case(tmp_path, model, lit)
    spread = {}
    for shading in ("keep", "remove"):
        rgb, report = _textured_fit(tmp_path, "--texture-shading", shading)
        lum = rgb @ np.array([0.299, 0.587, 0.114])
        spread[shading] = lum.std() / lum.mean()
        assert report["options"]["texture_shading"] == shading
    assert spread["remove"] < 0.5 * spread["keep"], spread
    proc = run_cli("fit", "case.json", "--out", "h.obj", "--texture-shading", "flat",
                   cwd=tmp_path)
    assert proc.returncode == 2 and "--texture-shading" in proc.stderr


def test_texture_clothes_keep_bakes_the_shirt_that_leave_out_leaves_off(tmp_path, model):
    from solver.cli import build_parser
    from solver.texture.bake import BakeOptions

    def shirt(w, h):
        img = np.tile(np.uint8([230, 170, 140]), (h, w, 1))  # skin
        img[int(0.75 * h):] = (70, 90, 120)  # a grey-blue shirt up from the bottom edge
        return img

    _painted_case(tmp_path, model, shirt)
    cold = {}
    for clothes in ("leave-out", "keep"):
        rgb, report = _textured_fit(tmp_path, "--texture-clothes", clothes)
        cold[clothes] = np.count_nonzero(rgb[..., 2] > rgb[..., 0])  # the shirt, never skin
        assert report["options"]["texture_clothes"] == clothes
    assert cold["leave-out"] == 0 < cold["keep"], cold
    # without the flag: the bake's own default
    args = build_parser().parse_args(["fit", "case.json", "--out", "h.obj"])
    assert args.texture_clothes == BakeOptions().clothes
    proc = run_cli("fit", "case.json", "--out", "h.obj", "--texture-clothes", "leave out",
                   cwd=tmp_path)
    last = proc.stderr.strip().splitlines()[-1]
    assert proc.returncode == 2 and "--texture-clothes" in last and "leave-out" in last, \
        proc.stderr


def test_detect_names_the_views_and_says_a_mislabelled_profile(sample, tmp_path):
    """``solver detect`` on the rendered sample's photos: the front and the right profile
    told apart (whatever the order), each point with its uncertainty; ``--view`` names a
    photo, and a profile given the wrong side is corrected in one warning line."""
    from solver import load_landmarks

    folder, _ = sample
    front, side = folder / "front.png", folder / "side.png"
    out = tmp_path / "case.json"
    proc = run_cli("detect", side, front, "--out", out)
    assert proc.returncode == 0, proc.stderr
    case = load_landmarks(out)                                  # ready for a fit
    assert set(case.views) == {"front", "right"}
    assert case.views["front"].camera.view == "orthographic-front"
    assert case.views["right"].camera.view == "orthographic-right"
    assert len(case.views["front"].points) == 68
    # the profile's landmarks read off its outline
    assert {"nasion", "nose_tip", "subnasale", "pogonion", "chin_bottom"} <= set(
        case.views["right"].points)
    assert set(case.views["front"].uncertainty) == set(case.views["front"].points)
    assert [ln for ln in proc.stderr.splitlines() if ln.startswith("note:")] == [
        ln for ln in proc.stderr.splitlines() if "side.png" in ln and "profile" in ln
        and "read off its outline" in ln]
    # a left profile given, a right one detected: said once, written as the right one
    proc = run_cli("detect", front, "--view", f"left={side}", "--out", out, "-q")
    assert proc.returncode == 0, proc.stderr
    warnings = [ln for ln in proc.stderr.splitlines() if ln.startswith("warning:")]
    assert len(warnings) == 1 and "side.png" in warnings[0] and "'left'" in warnings[0] \
        and "written as view 'right'" in warnings[0]
    assert set(load_landmarks(out).views) == {"front", "right"}
    # any other name only names the view
    proc = run_cli("detect", "--view", f"me={front}", "--out", out, "-q")
    assert proc.returncode == 0 and proc.stderr == ""
    assert load_landmarks(out).views["me"].camera.view == "orthographic-front"
    proc = run_cli("detect", front, "--view", "side.png", "--out", out)
    assert_one_line_error(proc, "--view 'side.png'", "NAME=PHOTO")


def test_detect_gives_a_photo_of_a_known_lens_its_pinhole_unless_told(lens_sample, tmp_path):
    """Photos whose EXIF gives their lens: pinhole cameras of it in the file, held near
    their views' directions; ``--orthographic`` keeps them parallel projections."""
    from solver import DIRECTION_SIGMA_DEG, load_landmarks

    folder, _ = lens_sample
    out = tmp_path / "case.json"
    photos = (folder / "front.jpg", folder / "side.jpg")
    proc = run_cli("detect", *photos, "--out", out, "-q")
    assert proc.returncode == 0, proc.stderr
    case = load_landmarks(out)
    side = case.views["right"]
    assert side.camera is None and side.camera_hints["kind"] == "pinhole"
    assert side.camera_hints["direction_prior"] == [90.0, DIRECTION_SIGMA_DEG]
    assert abs(side.camera_hints["lens_mm"] - 50.0) < 0.5
    proc = run_cli("detect", *photos, "--out", out, "-q", "--orthographic")
    assert proc.returncode == 0, proc.stderr
    case = load_landmarks(out)
    assert case.views["front"].camera.view == "orthographic-front"
    assert case.views["right"].camera.view == "orthographic-right"
    proc = run_cli("detect", *photos, "--out", out, "-q", "--orthographic", "--lens", "50")
    assert_one_line_error(proc, "--lens and --orthographic")


def test_detect_lens_makes_photos_without_exif_perspective(sample, tmp_path):
    from solver import load_landmarks

    folder, _ = sample
    out = tmp_path / "case.json"
    photos = (folder / "front.png", folder / "side.png")  # no EXIF
    proc = run_cli("detect", *photos, "--out", out, "-q", "--lens", "26")
    assert proc.returncode == 0, proc.stderr
    front = load_landmarks(out).views["front"]
    assert front.camera is None and front.camera_hints["kind"] == "pinhole"
    assert front.camera_hints["lens_mm"] == 26.0
    for bad in ("1", "nan", "wide"):
        proc = run_cli("detect", *photos, "--out", out, "--lens", bad)
        assert proc.returncode == 2 and "--lens" in proc.stderr, proc.stderr
