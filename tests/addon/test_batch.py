"""The batch at scale: manifests with per-head options and their row-level problems, worker
processes, output choices, resuming (skipped unless changed or --force), a killed batch,
the summary files and the progress line."""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.addon.support import ROOT, run_python, synthetic_files


def _manifest(folder, rows, header="name,landmarks,components"):
    path = Path(folder) / "heads.csv"
    path.write_text(header + "\n" + "".join(r + "\n" for r in rows))
    return path


def _summary(out):
    with open(out / "summary.csv", newline="") as f:
        by_csv = {r["name"]: r for r in csv.DictReader(f)}
    by_json = {r["name"]: r for r in map(json.loads, (out / "summary.jsonl").read_text()
                                         .splitlines())}
    assert by_csv.keys() == by_json.keys()
    return by_csv, by_json


def test_manifest_rows_options_and_problems(tmp_path):
    from headrecon_addon.batch_manifest import plan_heads

    (tmp_path / "sub").mkdir()
    m = _manifest(tmp_path / "sub", [
        "alice,a.json,20", "bob,../b.json,", "carol,c.json,many", ",d.json,3",
        "alice,e.json,", "dave,,"], header="Name,landmarks,components")
    heads = plan_heads([m, tmp_path / "x" / "erin.json"], tmp_path / "out")
    assert [h.name for h in heads][:3] == ["alice", "bob", "carol"]
    a, b, c, unnamed, again, dave, erin = heads
    assert a.landmarks == tmp_path / "sub" / "a.json" and a.options == {"components": 20}
    assert a.base == tmp_path / "out" / "alice" and a.error is None
    assert b.landmarks == tmp_path / "sub" / ".." / "b.json" and b.options == {}
    assert c.error == f"{m} row 4: column components: 'many' is not a whole number"
    assert unnamed.error == f"{m} row 5: column name is empty"
    assert again.error.startswith(f"{m} row 6: name 'alice' is also {m} row 2")
    assert dave.error == f"{m} row 7: column landmarks is empty"
    assert erin.name == "erin" and erin.error is None

    bad = _manifest(tmp_path, ["a,a.json,1"], header="name,landmarks,lens")
    with pytest.raises(ValueError, match=r"heads.csv: column 'lens' is unknown"):
        plan_heads([bad], tmp_path / "out")
    with pytest.raises(ValueError, match="one .blend file for 2 heads"):
        plan_heads([tmp_path / "a.json", tmp_path / "b.json"], tmp_path / "one.blend")


def test_jsonl_manifest(tmp_path):
    from headrecon_addon.batch_manifest import plan_heads

    m = tmp_path / "heads.jsonl"
    m.write_text('{"name": "a", "landmarks": "a.json", "exact": true, "method": "approach2"}\n'
                 "\n{not json\n"
                 '{"name": "b", "landmarks": "b.json", "lens": 50}\n'
                 '{"name": "c", "photos": "c_front.png;c_right.png"}\n')
    a, broken, b, c = plan_heads([m], tmp_path / "out")
    assert a.options == {"exact": True, "method": "approach2"} and a.error is None
    assert broken.error.startswith(f"{m} row 3: not JSON")
    assert b.error.startswith(f"{m} row 4: unknown key 'lens'")
    # photos instead of a landmarks file: detected by the headless script
    assert c.error is None and c.landmarks is None
    assert c.photos == (tmp_path / "c_front.png", tmp_path / "c_right.png")


def test_progress_line_counts_rate_and_time_left():
    from headrecon_addon.batch_summary import Progress

    now = [100.0]
    p = Progress(10, clock=lambda: now[0])
    p.add("skipped", fitted=False)
    p.add("failed", fitted=False)  # a broken row: counted, not in the rate
    now[0] += 60.0
    for status in ("done", "done", "failed"):
        p.add(status)
    assert p.line() == "5/10 heads, 2 failed, 1 skipped, 3.0 heads/min, 1m40s left"


def test_a_dead_worker_fails_its_head_only():
    from headrecon_addon.batch_workers import run_pool

    tasks = [{"i": i} for i in range(3)]
    got = list(run_pool(tasks, 2, lambda task, code: {"died": code},
                        command=[sys.executable, "-c", "import sys; sys.exit(3)"]))
    assert sorted(t["i"] for t, _ in got) == [0, 1, 2]
    assert all(answer == {"died": 3} for _, answer in got)


@pytest.fixture(scope="module")
def heads(model, tmp_path_factory):
    """Four synthetic cases with photos in one folder; returns the folder."""
    folder = tmp_path_factory.mktemp("heads")
    for i in range(4):
        synthetic_files(model, folder, seed=40 + i, name=f"h{i}")
    return folder


def _run_batch(args):
    return run_python(["-m", "headrecon_addon.headless", *args, "--no-texture"])


# The headless command, saying at its exit whether its own process imported bpy.
_SAYS_BPY = ("import atexit, runpy, sys; "
             "atexit.register(lambda: print('bpy imported:', 'bpy' in sys.modules)); "
             "runpy.run_module('headrecon_addon.headless', run_name='__main__')")


def test_broken_row_among_good_ones_then_resume_and_force(heads, tmp_path):
    m = _manifest(heads, ["h0,h0.json,10", "h1,h1.json,10", "broken,missing.json,10",
                          "h2,h2.json,11"])
    out = tmp_path / "out"
    proc = run_python(["-c", _SAYS_BPY, m, "--out", out, "--jobs", "2", "--no-texture"])
    assert proc.returncode == 1, proc.stderr
    assert "3 of 4 heads written" in proc.stdout
    assert "bpy imported: False" in proc.stdout  # the workers fit; this process only waits
    assert "4/4 heads, 1 failed, 0 skipped" in proc.stderr and "heads/min" in proc.stderr
    rows, jrows = _summary(out)
    assert [rows[n]["status"] for n in ("h0", "h1", "broken", "h2")] == \
        ["done", "done", "failed", "done"]
    assert rows["broken"]["error"].startswith(f"{m} row 4: landmarks ")
    assert "missing.json" in rows["broken"]["error"]
    for name in ("h0", "h1", "h2"):
        assert (out / f"{name}.blend").is_file() and (out / f"{name}.batch.json").is_file()
        assert jrows[name]["outputs"] == {"blend": str(out / f"{name}.blend")}
        assert jrows[name]["method"] in ("approach1", "approach2")
        assert jrows[name]["rms_px"] > 0 and set(jrows[name]["noise_px"]) == {"front", "right"}
        assert 0 <= jrows[name]["plausibility"] <= 100 and jrows[name]["seconds"] > 0
    assert not list(out.glob(".*"))  # no staging folder left
    stamps = {n: (out / f"{n}.blend").stat().st_mtime_ns for n in ("h0", "h1", "h2")}

    # again, one head's option changed: only that one is fitted
    m = _manifest(heads, ["h0,h0.json,10", "h1,h1.json,12", "broken,missing.json,10",
                          "h2,h2.json,11"])
    proc = _run_batch([m, "--out", out, "--jobs", "2"])
    assert proc.returncode == 1, proc.stderr
    assert "3 of 4 heads written (2 unchanged, skipped)" in proc.stdout
    rows, _ = _summary(out)
    assert [rows[n]["status"] for n in ("h0", "h1", "h2")] == ["skipped", "done", "skipped"]
    assert (out / "h0.blend").stat().st_mtime_ns == stamps["h0"]
    assert (out / "h1.blend").stat().st_mtime_ns != stamps["h1"]

    # a changed landmarks file is fitted again too; --force fits every one
    proc = _run_batch([m, "--out", out, "--jobs", "1", "--force"])
    rows, _ = _summary(out)
    assert [rows[n]["status"] for n in ("h0", "h1", "h2")] == ["done"] * 3


def test_output_choices(heads, tmp_path):
    from headrecon_addon import headless

    out = tmp_path / "out"
    code = headless.main([str(heads / "h3.json"), "--out", str(out), "--components", "10",
                          "--texture-size", "128", "--outputs", "obj,texture,report"])
    assert code == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == ["h3.batch.json", "h3.mtl", "h3.obj", "h3.report.json", "h3_texture.png",
                     "summary.csv", "summary.jsonl"]
    report = json.loads((out / "h3.report.json").read_text())
    assert report["outputs"]["texture"] == str(out / "h3_texture.png")
    assert report["options"]["outputs"] == ["obj", "texture", "report"]
    # the irises' colour read off the photos with the bake (the front looks into the eyes)
    assert len(report["iris_srgb"]) == 3 and all(0 <= c <= 1 for c in report["iris_srgb"])
    assert "h3_texture.png" in (out / "h3.mtl").read_text()
    with pytest.raises(SystemExit) as bad:
        headless.main([str(heads / "h3.json"), "--out", str(out), "--outputs", "blend,png"])
    assert bad.value.code == 2
    assert headless.main([str(heads / "h3.json"), "--out", str(out), "--outputs", "texture",
                          "--no-texture"]) == 2


def test_texture_shading_option_and_column(heads, tmp_path):
    from headrecon_addon import headless
    from headrecon_addon.batch_manifest import plan_heads

    textures = {}
    for shading in ("keep", "remove"):
        out = tmp_path / shading
        assert headless.main([str(heads / "h3.json"), "--out", str(out), "--components", "10",
                              "--texture-size", "64", "--outputs", "texture,report",
                              "--texture-shading", shading]) == 0
        report = json.loads((out / "h3.report.json").read_text())
        assert report["options"]["texture_shading"] == shading
        textures[shading] = (out / "h3_texture.png").read_bytes()
    assert textures["keep"] != textures["remove"]  # the option reached the bake
    m = _manifest(tmp_path, ["a,a.json,remove", "b,b.json,", "c,c.json,flat"],
                  header="name,landmarks,texture_shading")
    a, b, c = plan_heads([m], tmp_path / "out")
    assert a.options == {"texture_shading": "remove"} and b.options == {}
    assert c.error == f"{m} row 4: column texture_shading: 'flat' is not one of keep, remove"


def test_texture_clothes_option_and_column(model, tmp_path):
    import numpy as np
    from PIL import Image

    from headrecon_addon import headless
    from headrecon_addon.batch_manifest import plan_heads

    folder = tmp_path / "in"
    _, case, _ = synthetic_files(model, folder, seed=43, name="shirt", image_height=256)
    for name, view in case.views.items():
        w, h = view.size
        img = np.tile(np.uint8([230, 170, 140]), (h, w, 1))  # skin
        img[int(0.75 * h):] = (70, 90, 120)  # a grey-blue shirt up from the bottom edge
        Image.fromarray(img).save(case.image_path(name))
    # the command line keeps the clothes; a row leaves them out again
    m = _manifest(folder, ["kept,shirt.json,", "left,shirt.json,leave-out"],
                  header="name,landmarks,texture_clothes")
    out = tmp_path / "out"
    assert headless.main([str(m), "--out", str(out), "--jobs", "1", "--components", "10",
                          "--texture-size", "64", "--outputs", "texture,report",
                          "--texture-clothes", "keep"]) == 0
    cold = {}
    for name, clothes in (("kept", "keep"), ("left", "leave-out")):
        report = json.loads((out / f"{name}.report.json").read_text())
        assert report["options"]["texture_clothes"] == clothes
        with Image.open(out / f"{name}_texture.png") as tex:
            rgb = np.asarray(tex.convert("RGB"), dtype=np.int64)
        cold[name] = np.count_nonzero(rgb[..., 2] > rgb[..., 0])  # the shirt, never skin
    assert cold["left"] == 0 < cold["kept"], cold  # the option reached the bake
    m = _manifest(tmp_path, ["a,a.json,keep", "b,b.json,", "c,c.json,leave out"],
                  header="name,landmarks,texture_clothes")
    a, b, c = plan_heads([m], tmp_path / "out")
    assert a.options == {"texture_clothes": "keep"} and b.options == {}
    assert c.error == (f"{m} row 4: column texture_clothes: 'leave out' is not one of "
                       "leave-out, keep")
    with pytest.raises(SystemExit) as bad:
        headless.main([str(m), "--out", str(out), "--texture-clothes", "off"])
    assert bad.value.code == 2


def test_a_killed_batch_loses_only_heads_in_flight(heads, tmp_path):
    m = _manifest(heads, [f"h{i},h{i}.json,10" for i in range(4)])
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "headrecon_addon.headless", str(m),
                             "--out", str(out), "--jobs", "1", "--no-texture"], cwd=ROOT,
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    deadline = time.monotonic() + 300
    while not list(out.glob("*.batch.json")) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert list(out.glob("*.batch.json")), "no head finished"
    while not list(out.glob(".h*.partial-*")) and time.monotonic() < deadline:
        time.sleep(0.02)  # the next head is being written
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    done = {p.name[:-len(".batch.json")] for p in out.glob("*.batch.json")}
    visible = {p.name for p in out.iterdir() if not p.name.startswith(".")}
    # every visible file is complete: a finished head's, or one renamed into place
    assert all(n.endswith((".blend", ".batch.json")) or n.startswith("summary.")
               for n in visible)
    assert {f"{n}.blend" for n in done} <= visible
    proc = _run_batch([m, "--out", out, "--jobs", "1"])
    assert proc.returncode == 0, proc.stderr
    rows, _ = _summary(out)
    assert {n for n, r in rows.items() if r["status"] == "skipped"} == done
    assert not list(out.glob(".*"))  # the killed head's staging folder is gone


def test_workers_get_one_blas_thread_unless_the_environment_says(monkeypatch):
    from headrecon_addon import batch_workers

    echo = ("import json, os, sys\nprint(json.dumps({'ready': True}), flush=True)\n"
            "for line in sys.stdin:\n"
            "    print(json.dumps(os.environ.get('OPENBLAS_NUM_THREADS')), flush=True)\n")
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    got = list(batch_workers.run_pool([{}, {}], 2, None, command=[sys.executable, "-c", echo]))
    assert [answer for _, answer in got] == ["1", "1"]
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "3")  # the environment's own choice is kept
    got = list(batch_workers.run_pool([{}], 2, None, command=[sys.executable, "-c", echo]))
    assert [answer for _, answer in got] == ["3"]


def test_record_and_hash_say_when_a_head_is_done(tmp_path):
    from headrecon_addon import batch_stamp

    lm = tmp_path / "a.json"
    lm.write_text('{"views": {"front": {"image": "a_front.png"}}}')
    photo = tmp_path / "a_front.png"
    photo.write_bytes(b"one")
    settings = {"outputs": ["blend"], "components": 10}
    digest = batch_stamp.content_hash(lm, settings)
    assert batch_stamp.content_hash(lm, dict(reversed(settings.items()))) == digest
    assert batch_stamp.content_hash(lm, {**settings, "components": 11}) != digest
    photo.write_bytes(b"two")  # a retouched photo is a new input
    assert batch_stamp.content_hash(lm, settings) != digest
    photo.unlink()
    assert batch_stamp.content_hash(lm, settings) != digest

    base = tmp_path / "out" / "a"
    base.parent.mkdir()
    blend = base.with_name("a.blend")
    blend.write_bytes(b"blend")
    row = {"name": "a", "status": "done", "outputs": {"blend": str(blend)}}
    assert batch_stamp.finished_record(base, "h1") is None  # no record yet
    batch_stamp.write_record(base, "h1", row)
    assert batch_stamp.stamp_path(base) == tmp_path / "out" / "a.batch.json"
    assert batch_stamp.finished_record(base, "h1") == row
    assert batch_stamp.finished_record(base, "h2") is None  # other inputs or settings
    blend.unlink()
    assert batch_stamp.finished_record(base, "h1") is None  # an output gone


def test_a_name_with_a_dot_keeps_it_in_every_output(heads, tmp_path):
    from headrecon_addon import headless

    m = _manifest(tmp_path, [f"alice.v2,{heads / 'h3.json'},10"])
    out = tmp_path / "out"
    assert headless.main([str(m), "--out", str(out), "--no-texture", "--outputs",
                          "blend,glb"]) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "alice.v2.batch.json", "alice.v2.blend", "alice.v2.glb", "summary.csv",
        "summary.jsonl"]


def _blend_content(path):
    """What a head's .blend holds, datablock by datablock: every object's transform, mesh
    positions, shape keys (positions, value, slider range), point attributes, image pixels
    and material node count (the file's bytes differ by save time and pointers)."""
    import bpy
    import numpy as np

    bpy.ops.wm.open_mainfile(filepath=str(path))
    out = {}
    for ob in bpy.data.objects:
        out[f"object {ob.name}"] = np.array(ob.matrix_world)
        if ob.type != "MESH":
            continue
        me = ob.data
        co = np.empty(len(me.vertices) * 3, np.float32)
        me.vertices.foreach_get("co", co)
        out[f"mesh {ob.name}"] = co
        for kb in me.shape_keys.key_blocks if me.shape_keys else ():
            co = np.empty(len(kb.data) * 3, np.float32)
            kb.data.foreach_get("co", co)
            out[f"key {ob.name} {kb.name}"] = np.append(co, [kb.value, kb.slider_min,
                                                             kb.slider_max])
        for a in me.attributes:
            if a.domain == "POINT" and a.data_type in ("FLOAT", "FLOAT_COLOR"):
                per = 4 if a.data_type == "FLOAT_COLOR" else 1
                v = np.empty(len(a.data) * per, np.float32)
                a.data.foreach_get("color" if per == 4 else "value", v)
                out[f"attribute {ob.name} {a.name}"] = v
    for im in bpy.data.images:
        px = np.empty(len(im.pixels), np.float32)
        im.pixels.foreach_get(px)
        out[f"image {im.name}"] = px
    for mat in bpy.data.materials:
        out[f"material {mat.name}"] = np.array([len(mat.node_tree.nodes)])
    return out


def test_a_worker_s_second_head_is_the_head_fitted_alone(heads, tmp_path):
    """Nothing of one head leaks into the next one a worker fits (scene, images, caches,
    the freed heap): the second head's .blend holds what the head fitted alone holds."""
    import numpy as np

    opts = ["--components", "10", "--texture-size", "64", "--jobs", "1"]
    m = _manifest(heads, ["h0,h0.json,", "h1,h1.json,"], header="name,landmarks,exact")
    proc = run_python(["-m", "headrecon_addon.headless", m, "--out", tmp_path / "both", *opts])
    assert proc.returncode == 0, proc.stderr
    proc = run_python(["-m", "headrecon_addon.headless", heads / "h1.json",
                       "--out", tmp_path / "alone", *opts])
    assert proc.returncode == 0, proc.stderr
    second = _blend_content(tmp_path / "both" / "h1.blend")
    alone = _blend_content(tmp_path / "alone" / "h1.blend")
    assert second.keys() == alone.keys()
    assert any(k.startswith("key ") for k in alone) and any(k.startswith("image ") for k in alone)
    for key, value in alone.items():
        np.testing.assert_array_equal(second[key], value, err_msg=key)
    first = _blend_content(tmp_path / "both" / "h0.blend")
    assert any(not np.array_equal(first[k], v) for k, v in alone.items() if k in first)


def test_a_manifest_row_with_a_method_the_fit_has_not(tmp_path):
    from headrecon_addon.batch_manifest import plan_heads

    m = _manifest(tmp_path, ["a,a.json,approach1", "b,b.json,icp"],
                  header="name,landmarks,method")
    a, b = plan_heads([m], tmp_path / "out")
    assert a.options == {"method": "approach1"}
    assert b.error == f"{m} row 3: column method: 'icp' is not one of combined, approach1, " \
                      "approach2"
