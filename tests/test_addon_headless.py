"""The headless script writes .blend files that reopen with their shape keys and texture;
a batch goes on past a bad file and says so in its exit code (subprocesses)."""

import bpy
import numpy as np
from addon_support import ROOT, addon, run_python, synthetic_files


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
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(("alice", "broken", "1 of"))]
    assert lines[0].startswith("alice: method ") and " px, " in lines[0]
    assert "flagged" in lines[0] and lines[0].endswith("alice.blend")
    assert lines[1].startswith("broken: FAILED: ") and "views" in lines[1]
    assert lines[2] == "1 of 2 heads written"
    assert not (out / "broken.blend").exists()

    head = _open(out / "alice.blend")
    keys = head.data.shape_keys.key_blocks
    names = [kb.name for kb in keys]
    assert names[0] == "Basis" and names[1:31] == [f"identity_{i:03d}" for i in range(30)]
    assert "fit_detail" in names and "jawOpen" in names
    assert len(names) == 1 + 30 + 1 + 57
    assert any(kb.value != 0 for kb in keys[1:31])
    tex = [i for i in bpy.data.images if i.get("headrecon_baked")]
    assert len(tex) == 2 and all(i.packed_file is not None and tuple(i.size) == (256, 256)
                                 for i in tex)
    px = np.empty(256 * 256 * 4, np.float32)
    tex[0].pixels.foreach_get(px)
    assert px.reshape(-1, 4)[:, :3].std() > 0.01
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
