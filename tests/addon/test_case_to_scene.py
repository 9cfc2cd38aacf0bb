"""Importing a landmarks file: a bad file leaves the scene as it was (bpy module,
background)."""

import json

import bpy
import pytest

from tests.addon.support import snapshot


def _bad_files(folder, good):
    data = json.loads(good.read_text())
    out = {}
    (folder / "bad_json.json").write_text("{ nope")
    out["not_json"] = (folder / "bad_json.json", "not valid JSON")
    d = json.loads(json.dumps(data))
    first = next(iter(d["views"]))
    d["views"][first]["points"]["nose_tipp"] = [10, 10]
    (folder / "bad_unknown.json").write_text(json.dumps(d))
    out["unknown"] = (folder / "bad_unknown.json", "nose_tipp")
    d = json.loads(json.dumps(data))
    last = list(d["views"])[-1]
    d["views"][last]["image"] = "missing_photo.png"
    (folder / "bad_missing.json").write_text(json.dumps(d))
    out["missing"] = (folder / "bad_missing.json", "missing_photo.png")
    d = json.loads(json.dumps(data))
    w, h = d["views"][last]["size"]
    d["views"][last]["size"] = [w + 2, h + 2]
    (folder / "bad_size.json").write_text(json.dumps(d))
    out["size"] = (folder / "bad_size.json", "pixels")
    out["absent"] = (folder / "bad_absent.json", "no such file")
    return out


def test_bad_landmarks_file_leaves_scene_unchanged(files, scene):
    from headrecon_addon import case_to_scene

    path, _, _ = files
    bpy.ops.headrecon.import_landmarks(filepath=str(path))  # a scene with work in it
    before = snapshot()
    # next to the good file, so its photos' relative paths resolve
    for key, (bad, words) in _bad_files(path.parent, path).items():
        with pytest.raises((ValueError, OSError)) as err:
            case_to_scene.import_landmarks(bpy.context, bad)
        assert words in str(err.value), key
        assert snapshot() == before, key
        # the operator reports the error and cancels, also leaving everything as it was
        with pytest.raises(RuntimeError, match="Error"):
            bpy.ops.headrecon.import_landmarks(filepath=str(bad))
        assert snapshot() == before, key
