"""The Fit operator: a re-fit replaces its keys cleanly; a cancelled or failed fit leaves
the scene as it was (bpy module, background)."""

import bpy
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


def test_cancelled_or_failed_fit_leaves_scene_unchanged(files):
    from headrecon_addon import fit_job, landmarks, photos

    path, _, _ = files
    scene = imported_scene(path)
    before = snapshot()
    job = fit_job.prepare_job(scene)
    job.cancelled = True
    job.run()
    assert isinstance(job.error, fit_job.FitCancelled)
    assert snapshot() == before and scene.headrecon.head is None
    # too few landmarks: the operator is greyed out, saying why
    plane = photos.find_plane(scene, "front")
    for name in list(landmarks.landmark_objects(plane))[2:]:
        landmarks.remove_landmark(plane, name)
    before = snapshot()
    with pytest.raises(RuntimeError, match="Too few landmarks on front"):
        bpy.ops.headrecon.fit()
    assert snapshot() == before
