"""Import ARKit Animation: a Live Link Face CSV (a small hand-written one in
tests/addon/data/) becomes an action on the head's ARKit keys; a bad file is refused with
one line naming it, the line and the column, and the scene is left as it was."""

from pathlib import Path

import bpy
import numpy as np
import pytest

from tests.addon.support import empty_scene, key_blocks, snapshot, synthetic_files

CSV = Path(__file__).parent / "data" / "live_link_face_5_frames.csv"


@pytest.fixture(scope="module")
def fit(model, tmp_path_factory):
    from solver import FitOptions, fit_head

    _, case, _ = synthetic_files(model, tmp_path_factory.mktemp("anim"), seed=9, photos=False)
    return case, fit_head(model, case, FitOptions(n_identity=10))


@pytest.fixture
def head(model, fit):
    from headrecon_addon import head_scene

    scene = empty_scene()
    scene.render.fps, scene.render.fps_base = 30, 1.0
    scene.frame_start, scene.frame_end = 1, 2
    case, result = fit
    head = head_scene.build_scene_from_fit(model, case, result, bake=False)
    scene.headrecon.head = head
    return head


def test_reads_the_live_link_face_csv():
    from headrecon_addon import arkit, arkit_animation

    take = arkit_animation.read_live_link_csv(CSV, timecode_fps=60)
    assert sorted(take.names) == sorted(arkit.ARKIT_NAMES)  # the rotations are not shapes
    assert take.values.shape == (5, 52)
    assert np.allclose(take.times, np.arange(5) / 60.0)
    blink = take.values[:, take.names.index("eyeBlinkLeft")]
    assert blink.tolist() == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert np.allclose(arkit_animation.read_live_link_csv(CSV, 30).times, np.arange(5) / 30)


def test_timecodes():
    from headrecon_addon.arkit_animation import parse_timecode

    assert parse_timecode("01:02:03:04", 30) == pytest.approx(3723 + 4 / 30)
    assert parse_timecode("00:00:01:29.500", 30) == pytest.approx(1 + 29.5 / 30)
    assert parse_timecode("00:00:01:30", 30) is None  # no frame 30 at 30 fps
    assert parse_timecode("00:61:00:00", 30) is None
    assert parse_timecode("12.5", 30) is None


def _value_at(head, name, frame, subframe=0.0):
    bpy.context.scene.frame_set(frame, subframe=subframe)
    return key_blocks(head)[name].value


def test_the_capture_plays_on_the_keys(model, head):
    from headrecon_addon import arkit_animation, shape_keys

    scene = bpy.context.scene
    take = arkit_animation.read_live_link_csv(CSV, timecode_fps=60)
    action, skipped = arkit_animation.apply_take(head, take, scene)
    assert skipped == ["tongueOut"]  # the model has no tongue: reported, not invented
    assert head.data.shape_keys.animation_data.action == action
    # 60 fps capture on a 30 fps scene from frame 1: rows at frames 1, 1.5, 2, 2.5, 3
    assert tuple(action.frame_range) == pytest.approx((1.0, 3.0))
    assert scene.frame_end == 3
    assert _value_at(head, "eyeBlinkLeft", 1) == pytest.approx(0.0)
    assert _value_at(head, "eyeBlinkLeft", 2) == pytest.approx(0.5)
    assert _value_at(head, "eyeBlinkLeft", 1, 0.25) == pytest.approx(0.125)  # linear
    assert _value_at(head, "cheekPuff", 2, 0.5) == pytest.approx(0.8)
    assert _value_at(head, "jawOpen", 3) == pytest.approx(0.3)
    assert _value_at(head, "mouthSmileRight", 2) == pytest.approx(0.05)
    assert _value_at(head, "eyeBlinkRight", 3) == 0.0
    # the left eye is closed on the head at the last frame
    scene.frame_set(3)
    closed = shape_keys.evaluated_vertices(head, bpy.context.evaluated_depsgraph_get())
    scene.frame_set(1)
    start = shape_keys.evaluated_vertices(head, bpy.context.evaluated_depsgraph_get())
    moved = np.linalg.norm(closed - start, axis=1) > 1e-3
    assert moved.any() and (model.vertices[moved, 0] > 0).mean() > 0.5


def test_the_operator(head):
    assert bpy.ops.headrecon.import_arkit_animation(filepath=str(CSV),
                                                    timecode_fps="60") == {"FINISHED"}
    assert head.data.shape_keys.animation_data.action is not None


def _bad(tmp_path, edit):
    lines = CSV.read_text().splitlines()
    lines = edit(lines)
    path = tmp_path / "take.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


def _cell(lines, line, column, value):
    header = lines[0].split(",")
    row = lines[line - 1].split(",")
    row[header.index(column)] = value
    return lines[:line - 1] + [",".join(row)] + lines[line:]


BAD = [
    (lambda ls: _cell(ls, 3, "JawOpen", "abc"), r"take\.csv: line 3, column JawOpen: 'abc' is "
                                                r"not a number"),
    (lambda ls: _cell(ls, 4, "EyeBlinkLeft", "nan"), r"line 4, column EyeBlinkLeft"),
    (lambda ls: ls[:4] + [ls[4].rsplit(",", 3)[0]] + ls[5:], r"line 5: 60 columns, the header "
                                                             r"has 63"),
    (lambda ls: _cell(ls, 2, "Timecode", "9:41"), r"line 2, column Timecode: '9:41' is not a "
                                                  r"timecode"),
    (lambda ls: ls[:1] + [ls[2], ls[1]] + ls[3:], r"line 3, column Timecode: .* is not after"),
    (lambda ls: ["Frame," + ls[0]] + ls[1:], r"take\.csv: line 1: expected a Live Link Face "
                                             r"header"),
    (lambda ls: ls[:1], r"take\.csv: no data rows"),
    (lambda ls: [], r"take\.csv: line 1: expected .* got an empty line"),
]


@pytest.mark.parametrize("edit, message", BAD)
def test_a_bad_file_is_refused_and_the_scene_stays(head, tmp_path, edit, message):
    from headrecon_addon import arkit_animation

    path = _bad(tmp_path, edit)
    with pytest.raises(ValueError, match=message):
        arkit_animation.read_live_link_csv(path)
    before, actions = snapshot(), len(bpy.data.actions)
    with pytest.raises(RuntimeError, match=message):
        bpy.ops.headrecon.import_arkit_animation(filepath=str(path))
    assert snapshot() == before and len(bpy.data.actions) == actions
    assert head.data.shape_keys.animation_data is None


def test_a_missing_file_names_it(head, tmp_path):
    with pytest.raises(RuntimeError, match=r"nothere\.csv: cannot read the file"):
        bpy.ops.headrecon.import_arkit_animation(filepath=str(tmp_path / "nothere.csv"))
