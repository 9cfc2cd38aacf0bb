"""The expression keys by Apple's ARKit names: the mapping, and the sides on the geometry."""

import numpy as np
import pytest

from headrecon_addon import arkit


def test_apple_names_are_the_52_of_arkit():
    assert len(arkit.ARKIT_NAMES) == 52 == len(arkit.ARKIT_SET)
    assert arkit.ARKIT_NAMES[0] == "eyeBlinkLeft" and arkit.ARKIT_NAMES[-1] == "tongueOut"
    assert {"browInnerUp", "cheekPuff", "mouthClose", "jawOpen"} <= arkit.ARKIT_SET


def test_key_names_follow_one_rule():
    assert arkit.key_name("eyeBlink_L") == "eyeBlinkLeft"
    assert arkit.key_name("mouthSmile_R") == "mouthSmileRight"
    assert arkit.key_name("PupilDilate_L") == "pupilDilateLeft"
    assert arkit.key_name("jawOpen") == "jawOpen"
    assert arkit.arkit_name("EyeBlinkLeft") == "eyeBlinkLeft"
    assert arkit.arkit_name("HeadYaw") is None


def test_the_model_gives_every_arkit_shape_but_the_tongue(model):
    names = arkit.expression_key_names(model.expression_names)
    assert len(names) == len(set(names)) == 59
    assert names[:51] == [n for n in arkit.ARKIT_NAMES if n != "tongueOut"]
    assert arkit.missing_arkit_names(model.expression_names) == ("tongueOut",)
    extras = names[51:]
    assert not set(extras) & arkit.ARKIT_SET
    assert sorted(extras) == sorted([
        "pupilDilateLeft", "pupilDilateRight", "cheekRaiserLeft", "cheekRaiserRight",
        "browInnerUpLeft", "browInnerUpRight", "cheekPuffLeft", "cheekPuffRight"])
    # every model expression is in a key, none twice (the halves also in their sum)
    used = [m for _, parts in arkit.key_plan(model.expression_names) for m in parts]
    assert sorted(set(used)) == sorted(model.expression_names)


def test_combined_keys_are_the_sum_of_the_halves(model):
    keys = dict(arkit.expression_keys(model.expression_names, model.expressions))
    names = list(model.expression_names)
    for name in ("browInnerUp", "cheekPuff"):
        left = model.expressions[names.index(f"{name}_L")]
        right = model.expressions[names.index(f"{name}_R")]
        assert np.abs(keys[name] - (left + right)).max() < 1e-12
        assert np.abs(keys[f"{name}Left"] - left).max() == 0
        moved = np.linalg.norm(keys[name], axis=1) > 1e-4
        assert (model.vertices[moved, 0] > 0.01).any() and (model.vertices[moved, 0] < -0.01).any()


def _moved_x(keys, model, name):
    """Mean X (Blender axes) of the vertices a key moves most, weighted by how far."""
    w = np.linalg.norm(keys[name], axis=1)
    big = w > 0.3 * w.max()
    return float((model.vertices[big, 0] * w[big]).sum() / w[big].sum())


@pytest.mark.parametrize("left", ["eyeBlinkLeft", "mouthSmileLeft", "browOuterUpLeft",
                                  "cheekSquintLeft", "noseSneerLeft", "eyeWideLeft"])
def test_left_is_the_subjects_left_at_plus_x(model, left):
    keys = dict(arkit.expression_keys(model.expression_names, model.expressions))
    right = left[:-len("Left")] + "Right"
    assert _moved_x(keys, model, left) > 0.01 > -0.01 > _moved_x(keys, model, right)


def test_eye_blink_left_closes_the_left_eye(model):
    keys = dict(arkit.expression_keys(model.expression_names, model.expressions))
    d = keys["eyeBlinkLeft"]
    left_lid = (model.vertices[:, 0] > 0.02) & (np.linalg.norm(d, axis=1) > 0.005)
    assert left_lid.sum() > 20
    assert d[left_lid, 2].mean() < -0.003  # the upper lid comes down (Z is up)
    w = np.linalg.norm(d, axis=1)
    right_side = model.vertices[:, 0] < -0.01
    assert w[right_side].max() < 0.02 * w.max()  # the right eye stays open
