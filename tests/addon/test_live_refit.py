"""The live refit follows a moved landmark; Quick Refit writes the settled form (bpy
module, background)."""

import bpy
import numpy as np
import pytest

from tests.addon.support import imported_scene, key_blocks

FILES_SEED = 5  # the head of the ``files`` fixture (tests/addon/conftest.py)


def test_live_refit_follows_a_moved_landmark(model, files):
    from headrecon_addon import landmarks, photos, shape_keys
    from headrecon_addon.live_refit import LIVE

    path, _, _ = files
    scene = imported_scene(path)
    scene.headrecon.bake_texture = False
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    head = scene.headrecon.head
    base = LIVE.result
    assert LIVE.stats()["ready"] and not LIVE.stats()["moved"]
    scene.headrecon.live_refit = True
    bpy.context.view_layer.update()  # records the positions; nothing moved yet
    plane = photos.find_plane(scene, "front")
    obj = landmarks.landmark_objects(plane)["nose_tip"]
    obj.location.x += 0.004  # about 10 px to the side
    bpy.context.view_layer.update()  # depsgraph handler -> refit_landmarks
    live = LIVE.stats()
    assert live["error"] == "" and live["ms"] > 0
    assert live["moved"]  # the panel asks for a Fit to take the move in fully
    result = LIVE.result
    assert result is not base
    assert not np.allclose(result.identity_coeffs, base.identity_coeffs)
    assert key_blocks(head)["identity_000"].value == pytest.approx(result.identity_coeffs[0],
                                                               abs=1e-6)
    # while dragging, the coefficient keys are muted and the detail key shows the shape
    assert key_blocks(head)["identity_000"].mute and shape_keys.in_live_shape(head)
    local = shape_keys.evaluated_vertices(head, bpy.context.evaluated_depsgraph_get())
    assert np.abs(local - result.local_vertices).max() < 1e-5
    # nothing moved: no refit
    assert LIVE.step(scene) is None
    # the drag ends (the timer does this in the UI): keys back to coefficients + detail
    assert LIVE.finish_drag()
    assert not key_blocks(head)["identity_000"].mute and not shape_keys.in_live_shape(head)
    local = shape_keys.evaluated_vertices(head, bpy.context.evaluated_depsgraph_get())
    assert np.abs(local - result.local_vertices).max() < 1e-5
    detail = shape_keys.get_key_co(key_blocks(head)["fit_detail"])
    assert np.abs(detail - (model.vertices + result.detail)).max() < 1e-5
    # Quick Refit writes the settled form directly
    obj.location.x -= 0.004
    assert bpy.ops.headrecon.refit_landmarks() == {"FINISHED"}
    assert not shape_keys.in_live_shape(head) and LIVE.stats()["moved"]
    local = shape_keys.evaluated_vertices(head, bpy.context.evaluated_depsgraph_get())
    assert np.abs(local - LIVE.result.local_vertices).max() < 1e-5
    scene.headrecon.live_refit = False
