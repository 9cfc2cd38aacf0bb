"""The Fit operator: a re-fit replaces its keys cleanly; a cancelled or failed fit leaves
the scene as it was (bpy module, background)."""

import bpy
import numpy as np
import pytest

from tests.addon.support import imported_scene, key_blocks, snapshot

FILES_SEED = 5  # the head of the ``files`` fixture (tests/addon/conftest.py)


def test_refit_replaces_keys_cleanly(model, files):
    from headrecon_addon.live_refit import LIVE

    path, _, _ = files
    scene = imported_scene(path)
    props = scene.headrecon
    props.bake_texture = False
    props.n_identity = 20
    props.n_regional = 2
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    head = props.head
    head.shape_key_add(name="artist_key", from_mix=False)
    result = LIVE.result
    assert len(result.regional_names) == 2 * len(model.region_names)
    assert all(n in key_blocks(head) for n in result.regional_names)
    objects = snapshot()["objects"]
    props.n_regional = 0
    props.n_identity = 10
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    names = [kb.name for kb in key_blocks(head)]
    assert len(names) == len(set(names))
    assert "artist_key" in names
    assert not any(n.startswith(model.region_names[0] + "_") for n in names)
    assert sum(n.startswith("identity_") for n in names) == 10
    assert snapshot()["objects"] == objects  # the same head, no second one


def _offset(head, name):
    from headrecon_addon.shape_keys import get_key_co

    blocks = key_blocks(head)
    return get_key_co(blocks[name]) - get_key_co(blocks[name].relative_key)


def test_refit_keeps_the_artists_expressions_and_own_keys(files):
    path, _, _ = files
    scene = imported_scene(path)
    props = scene.headrecon
    props.bake_texture = False
    props.n_identity = 10
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    head = props.head
    blocks = key_blocks(head)
    blocks["jawOpen"].value = 0.7
    blocks["mouthSmileLeft"].slider_max = 2.0
    blocks["mouthSmileLeft"].value = 1.5
    blocks["eyeBlinkLeft"].mute = True
    smirk = head.shape_key_add(name="smirk", from_mix=False)
    rng = np.random.default_rng(0)
    from headrecon_addon.shape_keys import get_key_co, set_key_co

    set_key_co(smirk, get_key_co(smirk) + rng.normal(0.0, 1e-3, (len(smirk.data), 3)))
    smirk.value = 0.4
    smirk.relative_key = blocks["jawOpen"]  # relative to a key the fit rewrites
    smirk_offset = _offset(head, "smirk")
    identity_before = blocks["identity_000"].value
    props.n_identity = 12
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    blocks = key_blocks(head)
    assert blocks["jawOpen"].value == pytest.approx(0.7)
    assert blocks["mouthSmileLeft"].value == pytest.approx(1.5)
    assert blocks["mouthSmileLeft"].slider_max == pytest.approx(2.0)
    assert blocks["eyeBlinkLeft"].mute and not blocks["eyeBlinkRight"].mute
    assert blocks["jawOpen"].relative_key == blocks["Basis"]
    assert blocks["smirk"].value == pytest.approx(0.4)
    assert blocks["smirk"].relative_key == blocks["jawOpen"]
    np.testing.assert_allclose(_offset(head, "smirk"), smirk_offset, atol=1e-7)
    # the fit's own values are the new fit's (identity), not kept
    assert sum(n.startswith("identity_") for n in blocks.keys()) == 12
    assert blocks["identity_000"].value != pytest.approx(identity_before, abs=0.0)


def test_refit_after_apply_identity_keeps_an_artists_key_shape(files):
    path, _, _ = files
    scene = imported_scene(path)
    props = scene.headrecon
    props.bake_texture = False
    props.n_identity = 10
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    head = props.head
    from headrecon_addon.shape_keys import get_key_co, set_key_co

    own = head.shape_key_add(name="brow_raise", from_mix=False)
    co = get_key_co(own)
    co[:, 2] += 0.002
    set_key_co(own, co)
    assert bpy.ops.headrecon.apply_identity() == {"FINISHED"}
    offset = _offset(head, "brow_raise")
    assert np.allclose(offset[:, 2], 0.002, atol=1e-6)
    assert bpy.ops.headrecon.fit() == {"FINISHED"}  # the Basis is the mean head again
    np.testing.assert_allclose(_offset(head, "brow_raise"), offset, atol=1e-6)


def test_cancelled_or_failed_fit_leaves_scene_unchanged(files):
    from headrecon_addon import fit_job, landmarks, photos
    from headrecon_addon.job_progress import JobCancelled

    path, _, _ = files
    scene = imported_scene(path)
    before = snapshot()
    job = fit_job.prepare_job(scene)
    job.cancelled = True
    job.run()
    assert isinstance(job.error, JobCancelled)
    assert snapshot() == before and scene.headrecon.head is None
    # too few landmarks: the operator is greyed out, saying why
    plane = photos.find_plane(scene, "front")
    for name in list(landmarks.landmark_objects(plane))[2:]:
        landmarks.remove_landmark(plane, name)
    before = snapshot()
    with pytest.raises(RuntimeError, match="Too few landmarks on front"):
        bpy.ops.headrecon.fit()
    assert snapshot() == before


def test_reset_to_defaults_resets_the_advanced_settings_only(scene):
    import dataclasses

    from headrecon_addon.properties import ADVANCED_FIT_SETTINGS
    from solver import FitOptions

    props = scene.headrecon
    defaults = FitOptions()
    changed = {"n_identity": 7, "n_regional": 3, "lambda1": 42.0, "lambda2": 0.125,
               "prior": "identity" if defaults.prior != "identity" else "eigen",
               "landmark_weight": 9.5, "exact_landmarks": not defaults.exact_landmarks}
    assert set(changed) == set(ADVANCED_FIT_SETTINGS)
    for name, value in changed.items():
        setattr(props, name, value)
    props.method = "approach2"  # up front, not an Advanced setting
    props.texture_size = "256"
    assert bpy.ops.headrecon.reset_fit_settings() == {"FINISHED"}
    for name in ADVANCED_FIT_SETTINGS:
        want = getattr(defaults, name)
        assert getattr(props, name) == pytest.approx(want), name
        assert dataclasses.asdict(defaults)[name] != changed[name]
    assert props.method == "approach2" and props.texture_size == "256"


def test_a_side_photo_short_of_a_profile_placed_by_hand_turns_its_plane(model, tmp_path):
    # landmarks placed by hand on a front photo and on a side photo taken 72 degrees from
    # it, both planes loaded with their nominal cameras: the fit turns the side's camera to
    # the yaw its landmarks show, and the plane stands where the photo was taken
    from solver.synthetic import make_hand_placed_case
    from tests.addon.support import save_case

    case, _ = make_hand_placed_case(model, 3, side_deg=72.0, noise_px=0.7, size=(384, 512))
    path, _ = save_case(case, tmp_path, "turned")
    scene = imported_scene(path)
    scene.headrecon.bake_texture = False
    side = next(o for o in scene.objects if o.name == "HeadRecon Photo side")
    before = side.matrix_world.to_euler().z
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    turned = np.degrees(side.matrix_world.to_euler().z - before)
    assert 13.0 < abs(turned) < 23.0, turned  # 18 degrees short of the nominal profile
