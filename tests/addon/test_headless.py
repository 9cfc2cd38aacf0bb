"""The headless script writes .blend files that reopen with their shape keys and texture;
a batch goes on past a bad file and says so in its exit code (subprocesses); a batch at
--jobs 2 plans and waits without importing bpy."""

import json
import struct
from pathlib import Path

import bpy
import numpy as np

from tests.addon.support import (
    ROOT,
    addon,
    run_python,
    synthetic_files,
)


def _open(path):
    addon()
    bpy.ops.wm.open_mainfile(filepath=str(path))
    heads = [o for o in bpy.data.objects if o.headrecon.role == "HEAD"]
    assert len(heads) == 1
    return heads[0]


def test_headless_batch(model, tmp_path):
    src = tmp_path / "in"
    good, case, _ = synthetic_files(model, src, seed=11, name="alice")
    bad = src / "broken.json"
    bad.write_text('{"format": "headrecon-landmarks", "version": 1, "views": {}}')
    out = tmp_path / "out"
    proc = run_python(["-m", "headrecon_addon.headless", good, bad, "--out", out,
                       "--texture-size", "256", "--components", "30"])
    assert proc.returncode == 1, proc.stderr
    # heads are fitted in parallel (two cores: two workers): lines come as heads finish
    lines = sorted(ln for ln in proc.stdout.splitlines()
                   if ln.startswith(("alice", "broken", "1 of")))
    assert lines[1].startswith("alice: method ") and " px, " in lines[1]
    # by default the .blend and the baked texture as a PNG beside it
    assert "flagged" in lines[1] and lines[1].endswith("alice.blend, " + str(
        out / "alice_texture.png"))
    assert lines[2].startswith(f"broken: FAILED: {bad}: ") and "views" in lines[2]
    assert lines[0] == "1 of 2 heads written" and proc.stdout.splitlines()[-1] == lines[0]
    assert not (out / "broken.blend").exists()

    head = _open(out / "alice.blend")
    keys = head.data.shape_keys.key_blocks
    names = [kb.name for kb in keys]
    assert names[0] == "Basis" and names[1:31] == [f"identity_{i:03d}" for i in range(30)]
    assert "fit_detail" in names and "jawOpen" in names
    assert len(names) == 1 + 30 + 1 + 59
    assert any(kb.value != 0 for kb in keys[1:31])
    tex = [i for i in bpy.data.images if i.get("headrecon_baked")]
    assert len(tex) == 2 and all(i.packed_file is not None and tuple(i.size) == (256, 256)
                                 for i in tex)
    px = np.empty(256 * 256 * 4, np.float32)
    tex[0].pixels.foreach_get(px)
    assert px.reshape(-1, 4)[:, :3].std() > 0.01
    from PIL import Image

    with Image.open(out / "alice_texture.png") as png:  # the tiles side by side
        assert png.size == (512, 256) and np.asarray(png).std() > 2
    photos = [o for o in bpy.data.objects if o.headrecon.role == "PHOTO"]
    assert sorted(p.headrecon.view for p in photos) == sorted(case.views)
    assert all(p.headrecon.image.packed_file is not None for p in photos)
    assert sum(o.headrecon.role == "LANDMARK" for o in bpy.data.objects) == case.n_points


def test_headless_as_a_blender_script(model, tmp_path):
    # `blender -b -P headrecon_addon/headless.py -- ...` runs the file as __main__ with no
    # package; the same path is taken here with plain Python and the "--" separator.
    good, _, _ = synthetic_files(model, tmp_path, seed=12, name="bob", photos=False)
    out = tmp_path / "bob_head.blend"
    proc = run_python([ROOT / "headrecon_addon" / "headless.py", "--", good, "--out", out,
                       "--components", "20", "--no-texture"], cwd=tmp_path,
                      env={"PYTHONPATH": ""})
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "1 of 1 heads written" in proc.stdout
    head = _open(out)
    assert head.name == "bob"
    assert sum(kb.name.startswith("identity_") for kb in head.data.shape_keys.key_blocks) == 20


def _glb_json(path):
    """The JSON chunk of a binary glTF file."""
    data = Path(path).read_bytes()
    assert data[:4] == b"glTF"
    n = struct.unpack("<I", data[12:16])[0]
    return json.loads(data[20:20 + n])


def test_summary_names_the_winning_approach(model, tmp_path, monkeypatch, capsys):
    # A "combined" fit runs both approaches and keeps the better one: the summary line
    # (and the head) must name that one, not the method that was asked for.
    from headrecon_addon import batch_head, headless

    path, _, _ = synthetic_files(model, tmp_path, seed=13, name="carol", photos=False)
    fits = []
    fit_head = batch_head.fit_head

    def keep_result(*args, **kw):
        fits.append(fit_head(*args, **kw))
        return fits[-1]

    monkeypatch.setattr(batch_head, "fit_head", keep_result)
    code = headless.main([str(path), "--out", str(tmp_path / "carol.blend"), "--method",
                          "combined", "--components", "20", "--no-texture", "--glb"])
    assert code == 0 and len(fits) == 1
    won = fits[0].info["approach"]
    assert fits[0].method == "combined" and won in ("approach1", "approach2")
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("carol:"))
    assert line.startswith(f"carol: method {won}, RMS ")
    assert bpy.data.objects["carol"].headrecon.fit_method == won
    # the .glb holds the fitted head with its expression keys as morph targets (identity
    # applied, no morph normals), and the lashes as an alpha-blended texture (not opaque
    # strips over the eyes); the .blend keeps its identity keys
    doc = _glb_json(tmp_path / "carol.glb")
    assert [n["name"] for n in doc["nodes"]] == ["carol"]
    targets = {len(p.get("targets", ())) for p in doc["meshes"][0]["primitives"]}
    assert targets == {59}  # 51 ARKit + 8 extras
    assert not any("NORMAL" in t for p in doc["meshes"][0]["primitives"] for t in p["targets"])
    assert doc["meshes"][0]["extras"]["targetNames"][:2] == ["eyeBlinkLeft", "eyeLookDownLeft"]
    lashes = next(m for m in doc["materials"] if m["name"].endswith("Eyelashes"))
    assert lashes["alphaMode"] == "BLEND"
    assert "baseColorTexture" in lashes["pbrMetallicRoughness"]
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "carol.blend"))
    assert "identity_000" in bpy.data.objects["carol"].data.shape_keys.key_blocks


def test_headless_fits_straight_from_photos(sample, tmp_path):
    """``--detect FRONT SIDE --out head.blend``: the landmarks detected (the detect
    command's file, beside the .blend), then the usual fit and outputs; run again, the
    head is unchanged and skipped."""
    import shutil

    from solver import load_landmarks

    folder, _ = sample
    photos = tmp_path / "alice"
    photos.mkdir()
    for view in ("front", "side"):
        shutil.copy(folder / f"{view}.png", photos / f"{view}.png")
    out = tmp_path / "out" / "head.blend"
    args = ["-m", "headrecon_addon.headless", "--detect", photos / "front.png",
            photos / "side.png", "--out", out, "--texture-size", "128", "--outputs",
            "blend,report"]
    proc = run_python(args)
    assert proc.returncode == 0, proc.stderr
    assert "1 of 1 heads written" in proc.stdout and "head: method" in proc.stdout
    case = load_landmarks(out.with_name("head.landmarks.json"))
    assert set(case.views) == {"front", "right"}
    assert case.image_path("front").resolve() == (photos / "front.png").resolve()
    report = json.loads(out.with_name("head.report.json").read_text())
    assert "front" in json.dumps(report) and "right" in json.dumps(report)
    head = _open(out)
    assert head.data.shape_keys is not None and len(head.data.shape_keys.key_blocks) > 10
    proc = run_python(args)
    assert proc.returncode == 0 and "unchanged, skipped" in proc.stdout, proc.stdout
    # the photos' lens given (they have no EXIF): the detected file changes, so the head
    # is fitted again, through pinhole cameras of that lens
    proc = run_python(args + ["--lens", "50"])
    assert proc.returncode == 0 and "head: method" in proc.stdout, proc.stdout
    case = load_landmarks(out.with_name("head.landmarks.json"))
    assert {v.camera_hints.get("lens_mm") for v in case.views.values()} == {50.0}


def test_headless_detect_folder_of_heads_fails_a_photo_without_a_face(sample, tmp_path):
    """``--detect FOLDER`` of sub-folders: one head each; a head whose photo shows no face
    fails alone, its error naming the photo."""
    import shutil

    from PIL import Image

    folder, _ = sample
    heads = tmp_path / "heads"
    (heads / "alice").mkdir(parents=True)
    shutil.copy(folder / "front.png", heads / "alice" / "front.png")
    (heads / "nobody").mkdir()
    Image.new("RGB", (200, 300), (128, 128, 128)).save(heads / "nobody" / "wall.png")
    out = tmp_path / "out"
    proc = run_python(["-m", "headrecon_addon.headless", "--detect", heads, "--out", out,
                       "--no-texture"])
    assert proc.returncode == 1, proc.stderr
    assert "1 of 2 heads written" in proc.stdout
    failed = [ln for ln in proc.stdout.splitlines() if ln.startswith("nobody: FAILED")]
    assert len(failed) == 1 and "wall.png: no face found" in failed[0]
    assert (out / "alice.blend").is_file() and (out / "alice.landmarks.json").is_file()
    (tmp_path / "empty").mkdir()                                    # a bad command line
    proc = run_python(["-m", "headrecon_addon.headless", "--detect", tmp_path / "empty",
                       "--out", out])
    assert proc.returncode == 2 and "empty: no photos in it" in proc.stderr, proc.stderr


def test_a_detected_head_s_summary_row_gives_its_detection_s_warnings(sample, tmp_path):
    """``--detect FOLDER`` of two heads, one's front photo upside down beside its profile:
    that head's summary row lists the detection's warning naming the profile (whose turn
    is not told); the other's none of it."""
    import shutil

    from PIL import Image

    folder, _ = sample
    heads = tmp_path / "heads"
    front = np.asarray(Image.open(folder / "front.png").convert("RGB"))
    for name, photo in (("alice", front), ("carol", np.ascontiguousarray(front[::-1, ::-1]))):
        (heads / name).mkdir(parents=True)
        Image.fromarray(photo).save(heads / name / "front.png")
        shutil.copy(folder / "side.png", heads / name / "side.png")
    out = tmp_path / "out"
    proc = run_python(["-m", "headrecon_addon.headless", "--detect", heads, "--out", out,
                       "--no-texture", "--outputs", "report", "--jobs", "1"])
    assert proc.returncode == 0, proc.stderr
    rows = {r["name"]: r for r in map(json.loads,
                                      (out / "summary.jsonl").read_text().splitlines())}
    check = [w for w in rows["carol"]["warnings"] if "check that this one is upright" in w]
    assert len(check) == 1 and check[0].startswith(str(heads / "carol" / "side.png"))
    assert not any("upright" in w for w in rows["alice"]["warnings"])
    assert "front.png: the face is upside down in the photo" in proc.stderr


def test_a_manifest_photos_column_is_detected(sample, tmp_path):
    """A manifest row with ``photos`` (";"-separated, relative to the manifest) instead of
    a landmarks file: detected, then fitted with the row's own options."""
    import shutil

    folder, _ = sample
    (tmp_path / "bob").mkdir()
    for view in ("front", "side"):
        shutil.copy(folder / f"{view}.png", tmp_path / "bob" / f"{view}.png")
    m = tmp_path / "heads.csv"
    m.write_text("name,photos,components\nbob,bob/front.png;bob/side.png,12\n"
                 "ghost,bob/missing.png,\n")
    out = tmp_path / "out"
    proc = run_python(["-m", "headrecon_addon.headless", m, "--out", out, "--no-texture",
                       "--outputs", "report", "--jobs", "1"])
    assert proc.returncode == 1, proc.stderr
    assert "1 of 2 heads written" in proc.stdout
    ghost = [ln for ln in proc.stdout.splitlines() if ln.startswith("ghost: FAILED")]
    assert len(ghost) == 1 and f"{m} row 3" in ghost[0] and "missing.png" in ghost[0]
    views = json.loads((out / "bob.landmarks.json").read_text())["views"]
    assert set(views) == {"front", "right"}
    report = json.loads((out / "bob.report.json").read_text())
    assert report["options"]["components"] == 12                    # the row's own option
    assert len(report["coefficients"]["identity"]) == 12


def test_an_orthographic_phone_photo_is_warned_about(model, tmp_path):
    """A front photo with a phone's lens in its EXIF, fitted as orthographic: the head's
    line on stderr says it was taken too close for a parallel projection."""
    from solver.io import exif, landmarks_file
    from tests.solver.io.exif_jpeg import jpeg, tiff

    path, case, _ = synthetic_files(model, tmp_path, seed=14, name="phone", photos=False,
                                    image_height=256)
    w, h = case.views["front"].size
    (tmp_path / "front.jpg").write_bytes(jpeg(tiff([], [(exif.FOCAL_35MM, 3, [26])]),
                                              pixels=np.full((h, w, 3), 90, np.uint8)))
    case.views["front"].image = "front.jpg"
    landmarks_file.save_landmarks(case, path)
    proc = run_python(["-m", "headrecon_addon.headless", path, "--out", tmp_path / "o.blend",
                       "--components", "10", "--no-texture", "--jobs", "1"])
    assert proc.returncode == 0, proc.stderr
    warned = [ln for ln in proc.stderr.splitlines() if "parallel projection" in ln]
    assert len(warned) == 1 and warned[0].startswith("phone: warning: view 'front'")
    assert "mm lens, EXIF" in warned[0]


def test_lens_is_only_for_photos_the_batch_detects(model, tmp_path, capsys):
    from headrecon_addon import headless

    path, _, _ = synthetic_files(model, tmp_path, seed=13, name="dora", photos=False)
    code = headless.main([str(path), "--out", str(tmp_path / "dora.blend"), "--lens", "26"])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("headless: --lens 26: only for photos")
    assert not (tmp_path / "dora.blend").exists()
