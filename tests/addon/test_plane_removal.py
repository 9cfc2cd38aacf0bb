"""A photo leaving the scene (bpy module, background): Remove Photo takes its plane,
markers and camera in one undoable step; a plane deleted by other means leaves no marker a
fit reads or the artist sees, and a photo loaded into its view takes them back; the Fit's
report names what it left out."""

import bpy
import numpy as np
import pytest

from tests.addon.support import DATA_KINDS, imported_scene, snapshot

FILES_SEED = 4


def _markers(view):
    return sorted(o.name for o in bpy.data.objects
                  if o.headrecon.role in ("LANDMARK", "PASSPOINT", "CONTOUR")
                  and o.headrecon.view == view)


def _view_names(scene, view):
    from headrecon_addon import photos

    return sorted(o.name for o in photos.view_objects(photos.find_plane(scene, view)))


def _pixels(scene):
    from headrecon_addon import scene_to_case

    case = scene_to_case.case_from_scene(scene)
    return {n: dict(v.points) for n, v in case.views.items()}, \
        {n: None if v.contour is None else np.asarray(v.contour) for n, v in case.views.items()}


def test_deleting_a_plane_parks_its_landmarks_and_a_new_photo_takes_them_back(files):
    from headrecon_addon import photos, plane_removal

    path, case, _ = files
    scene = imported_scene(path)
    points, contours = _pixels(scene)
    right = photos.find_plane(scene, "right")
    markers = _markers("right")
    assert len(markers) > 10 and any("contour" in n for n in markers)
    bpy.data.objects.remove(right, do_unlink=True)
    bpy.context.view_layer.update()  # the depsgraph handler runs
    # the markers are hidden, parented to nothing, and not read by the next fit
    assert _markers("right") == markers
    for name in markers:
        obj = bpy.data.objects[name]
        assert obj.parent is None and obj.hide_viewport and obj.hide_select
    after, _ = _pixels(scene)
    assert list(after) == ["front"] and after["front"] == points["front"]
    assert plane_removal.orphan_notes(scene) == [
        f"view 'right': its photo plane was deleted; {len(markers) - 1} landmarks and the "
        "contour kept hidden, not fitted (load a photo into 'right' to get them back, or "
        "Remove Photo)"]
    # the same photo loaded into that view again: its landmarks come back where they were
    assert bpy.ops.headrecon.load_photo(filepath=str(case.image_path("right")), view="right",
                                        camera_view="orthographic-right") == {"FINISHED"}
    bpy.context.view_layer.update()
    plane = photos.find_plane(scene, "right")
    assert not plane_removal.orphan_markers(scene)
    for name in markers:
        obj = bpy.data.objects[name]
        assert obj.parent == plane and not obj.hide_viewport and not obj.hide_select
    again, contours_again = _pixels(scene)
    assert set(again["right"]) == set(points["right"])
    for name, uv in points["right"].items():
        assert np.allclose(again["right"][name], uv, atol=2e-3), name
    np.testing.assert_allclose(contours_again["right"], contours["right"], atol=2e-3)


def test_deleting_a_plane_is_undone_with_its_landmarks(files):
    from headrecon_addon import photos

    path, _, _ = files
    scene = imported_scene(path)
    markers = _markers("front")
    bpy.ops.ed.undo_push(message="before")
    bpy.data.objects.remove(photos.find_plane(scene, "front"), do_unlink=True)
    bpy.context.view_layer.update()
    bpy.ops.ed.undo_push(message="deleted")
    assert bpy.data.objects[markers[0]].hide_viewport
    bpy.ops.ed.undo()
    scene = bpy.context.scene
    plane = photos.find_plane(scene, "front")
    assert plane is not None and _markers("front") == markers
    assert all(bpy.data.objects[n].parent == plane and not bpy.data.objects[n].hide_viewport
               for n in markers)


def test_remove_photo_removes_its_view_and_nothing_else(files, tmp_path):
    from headrecon_addon import landmarks, photos

    path, case, _ = files
    scene = imported_scene(path)
    before = snapshot()
    points, contours = _pixels(scene)
    # a perspective photo with a camera, landmarks, a passpoint and a contour
    assert bpy.ops.headrecon.load_photo(filepath=str(case.image_path("front")), view="extra",
                                        projection="PERSPECTIVE", lens_mm=50.0) == {"FINISHED"}
    plane = photos.find_plane(scene, "extra")
    camera = photos.camera_object(plane)
    assert camera is not None
    for i, name in enumerate(list(points["front"])[:8]):
        landmarks.place_landmark(plane, name, (100.0 + 20 * i, 200.0 + 10 * i))
    landmarks.place_landmark(plane, "pp00", (50.0, 60.0), role="PASSPOINT")
    landmarks.set_contour(plane, [(10.0, 10.0), (40.0, 50.0), (80.0, 90.0)])
    removed = _view_names(scene, "extra")
    assert len(removed) == 12  # camera, plane, 8 landmarks, a passpoint, the contour
    assert bpy.ops.headrecon.remove_photo(view="extra") == {"FINISHED"}
    assert photos.find_plane(scene, "extra") is None
    assert not any(n in bpy.data.objects for n in removed)
    after = snapshot()
    # nothing else went, nothing stayed (but the passpoints' colour, made for the first)
    after["materials"].remove("HeadRecon Landmark Passpoint")
    for kind in ("objects", "meshes", "curves", "cameras", "materials"):
        assert after[kind] == before[kind], kind
    again, contours_again = _pixels(scene)
    assert again == points
    for view in contours:
        np.testing.assert_array_equal(contours_again[view], contours[view])


def test_remove_photo_is_undoable(files):
    from headrecon_addon import photos, plane_removal

    assert {"REGISTER", "UNDO"} <= plane_removal.HEADRECON_OT_remove_photo.bl_options
    path, _, _ = files
    scene = imported_scene(path)
    names = _view_names(scene, "right")
    points, _ = _pixels(scene)
    bpy.ops.ed.undo_push(message="imported")
    assert bpy.ops.headrecon.remove_photo(view="right") == {"FINISHED"}
    # (in the background an operator called from Python pushes no undo step: pushed here as
    # Blender's window manager does after an UNDO operator)
    bpy.ops.ed.undo_push(message="Remove Photo")
    assert not any(n in bpy.data.objects for n in names)
    bpy.ops.ed.undo()
    scene = bpy.context.scene
    assert _view_names(scene, "right") == names
    assert _pixels(scene)[0] == points
    bpy.ops.ed.redo()
    assert photos.find_plane(bpy.context.scene, "right") is None


def test_a_failed_remove_photo_leaves_the_scene_unchanged(files):
    path, _, _ = files
    scene = imported_scene(path)
    before = snapshot()
    points, _ = _pixels(scene)
    with pytest.raises(RuntimeError, match="No photo for view 'nope'"):
        bpy.ops.headrecon.remove_photo(view="nope")
    assert snapshot() == before and _pixels(scene)[0] == points
    assert set(DATA_KINDS) <= set(before)


def test_remove_photo_of_a_mirrored_view_makes_the_mirror_direct(files):
    from headrecon_addon import photos

    path, _, _ = files
    scene = imported_scene(path)
    photos.set_mirror_of(photos.find_plane(scene, "right"), "front")
    assert bpy.ops.headrecon.remove_photo(view="front") == {"FINISHED"}
    assert photos.mirror_of(photos.find_plane(scene, "right")) is None


def test_the_fit_report_names_skipped_and_deleted_views(files, capfd):
    from headrecon_addon import landmarks, photos

    path, _, truth = files
    scene = imported_scene(path)
    scene.headrecon.bake_texture = False
    scene.headrecon.n_identity = 10
    right = photos.find_plane(scene, "right")
    # a profile with its camera known and kept, and no landmark or outline: the fit skips it
    photos.set_plane_camera(right, truth.cameras["right"])
    right.headrecon.view_json = '{"calibrated": true}'
    for obj in list(right.children):
        photos.remove_objects([obj])
    capfd.readouterr()
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    out = capfd.readouterr().out
    line = next(ln for ln in out.splitlines() if "Fitted" in ln)
    assert line.startswith("Warning") and "view 'right' skipped (no usable landmark)" in line
    # a front photo's outline point on the profile: left out, and said so
    scene = imported_scene(path)
    scene.headrecon.bake_texture = False
    scene.headrecon.n_identity = 10
    right = photos.find_plane(scene, "right")
    landmarks.place_landmark(right, "jaw_1_right", (300.0, 700.0))
    capfd.readouterr()
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    line = next(ln for ln in capfd.readouterr().out.splitlines() if "Fitted" in ln)
    assert line.startswith("Warning") and "view 'right': jaw_1_right left out" in line
    # a photo plane deleted: the report says its view was not fitted
    n = len(landmarks.landmark_objects(right))
    bpy.data.objects.remove(right, do_unlink=True)
    bpy.context.view_layer.update()
    capfd.readouterr()
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    out = capfd.readouterr().out
    line = next(ln for ln in out.splitlines() if "Fitted" in ln)
    assert "view 'right' not fitted (its photo plane was deleted)" in line
    assert f"view 'right': its photo plane was deleted; {n} landmarks and the contour kept " \
        "hidden, not fitted" in out


def test_a_file_imported_after_a_deletion_keeps_its_own_landmarks(files):
    from headrecon_addon import landmarks, photos, plane_removal

    path, _, _ = files
    scene = imported_scene(path)
    points, _ = _pixels(scene)
    bpy.data.objects.remove(photos.find_plane(scene, "right"), do_unlink=True)
    bpy.context.view_layer.update()
    parked = _markers("right")
    assert bpy.ops.headrecon.import_landmarks(filepath=str(path)) == {"FINISHED"}
    bpy.context.view_layer.update()
    plane = photos.find_plane(scene, "right")
    # the file's landmarks on the new plane; the old ones stay hidden, said so, and go with
    # Remove Photo
    assert _pixels(scene)[0] == points
    assert not set(parked) & {o.name for o in plane.children}
    assert all(bpy.data.objects[n].hide_viewport for n in parked)
    assert plane_removal.deleted_views(scene) == []
    n = len(landmarks.landmark_objects(plane))
    assert plane_removal.orphan_notes(scene) == [
        f"view 'right': {n} landmarks and the contour of a deleted photo plane kept hidden, "
        "not fitted (its photo has its own; Remove Photo removes both)"]
    assert bpy.ops.headrecon.remove_photo(view="right") == {"FINISHED"}
    assert _markers("right") == [] and not plane_removal.orphan_markers(scene)


def test_deleting_a_photos_camera_alone_makes_it_again_from_the_view(files):
    """The camera object only shows the camera the view keeps (the fit reads that one):
    deleted alone it comes back as it was, and the plane and its landmarks stay in place
    (before, the plane took its camera-space transform as its world one)."""
    from headrecon_addon import landmarks, photo_cameras, photos
    from solver import PinholeCamera

    path, case, _ = files
    scene = imported_scene(path)
    assert bpy.ops.headrecon.load_photo(filepath=str(case.image_path("front")), view="extra",
                                        projection="PERSPECTIVE", lens_mm=50.0) == {"FINISHED"}
    plane = photos.find_plane(scene, "extra")
    names = list(_pixels(scene)[0]["front"])[:8]
    for i, name in enumerate(names):
        landmarks.place_landmark(plane, name, (100.0 + 20 * i, 200.0 + 10 * i))
    (w, h), _ = photos.plane_size(plane)
    # the view's camera as a fit leaves it (stored, and shown)
    fitted = PinholeCamera.look_at([0.2, -0.9, 0.05], [0, 0, 0], (w, h), lens_mm=70)
    photos.store_fitted_camera(plane, fitted)
    photos.place_plane(plane, fitted)
    bpy.context.view_layer.update()
    points, _ = _pixels(scene)
    shown = photo_cameras.settings_of(photos.camera_object(plane), (w, h))
    world = {o.name: np.array(o.matrix_world) for o in [plane, *plane.children]}
    for _ in range(2):  # a provisional camera too, then the fitted one
        bpy.data.objects.remove(photos.camera_object(plane), do_unlink=True)
        bpy.context.view_layer.update()  # the depsgraph handler runs
        bpy.context.view_layer.update()  # and the world matrices follow what it did
        camera = photos.camera_object(plane)
        assert camera is not None and camera.name in scene.objects
        assert camera.data.background_images[0].image == plane.headrecon.image
        again = photo_cameras.settings_of(camera, (w, h))
        for key in ("lens", "sensor_width", "shift_x", "shift_y"):
            assert again[key] == pytest.approx(shown[key]), key
        np.testing.assert_allclose(again["matrix_world"], shown["matrix_world"], atol=1e-6)
        for name, m in world.items():
            np.testing.assert_allclose(np.array(bpy.data.objects[name].matrix_world), m,
                                       atol=1e-5, err_msg=name)
        assert _pixels(scene)[0] == points
        if not photos.plane_camera(plane):
            break
        # a camera still to compute: its provisional camera comes back
        photos.set_camera_hints(plane, {"kind": "pinhole", "lens_mm": 50.0})
        photos.place_plane(plane)
        bpy.context.view_layer.update()
        shown = photo_cameras.settings_of(photos.camera_object(plane), (w, h))
        world = {o.name: np.array(o.matrix_world) for o in [plane, *plane.children]}
    assert photos.plane_camera(plane) is None  # both rounds ran
    assert len([o for o in scene.objects if photo_cameras.is_camera_object(o)]) == 1
