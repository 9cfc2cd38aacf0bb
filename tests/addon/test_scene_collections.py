"""Everything the add-on makes goes into the "HeadRecon" collection and its "Photos",
"Landmarks" and "Cameras" sub-collections; scenes of older versions (objects anywhere)
still work (bpy module, background)."""

import bpy
import numpy as np
import pytest

from tests.addon.support import imported_scene, snapshot, write_photo

FILES_SEED = 5  # the head of the ``files`` fixture (tests/addon/conftest.py)


def _names(coll):
    return {o.name for o in coll.objects}


def test_objects_go_into_the_headrecon_collections(files, tmp_path):
    from headrecon_addon import landmarks, photos, scene_collections

    path, case, _ = files
    scene = imported_scene(path)
    root = scene_collections.root_collection(scene, create=False)
    assert root is not None and root.name == "HeadRecon"
    assert root.name in {c.name for c in scene.collection.children}
    subs = {c.name: c for c in root.children}
    assert set(subs) == {"Photos", "Landmarks"}
    planes = photos.photo_planes(scene)
    assert _names(subs["Photos"]) == {p.name for p in planes}
    markers = {o.name for p in planes for o in p.children}
    assert markers and _names(subs["Landmarks"]) == markers
    assert any(o.headrecon.role == "CONTOUR" for o in subs["Landmarks"].objects)
    assert not scene.collection.objects  # nothing loose in the scene's own collection
    # a landmark placed later joins the landmarks
    plane = photos.find_plane(scene, "front")
    obj = landmarks.place_landmark(plane, "nose_tip_extra_test", (10.0, 10.0))
    assert obj.users_collection == (subs["Landmarks"],)
    # a perspective photo's camera goes to "Cameras", its plane to "Photos"
    photo = write_photo(tmp_path / "three_quarter.png", (300, 400))
    assert bpy.ops.headrecon.load_photo(filepath=str(photo), projection="PERSPECTIVE",
                                        view="tq") == {"FINISHED"}
    plane = photos.find_plane(scene, "tq")
    cameras = scene_collections.collection_for(scene, "CAMERA", create=False)
    assert cameras is not None and cameras.name == "Cameras"
    assert plane.users_collection == (subs["Photos"],)
    assert photos.camera_object(plane).users_collection == (cameras,)
    # the head
    assert bpy.ops.headrecon.add_head() == {"FINISHED"}
    assert scene.headrecon.head.users_collection == (root,)


def test_collections_are_found_renamed_and_a_failed_load_makes_none(scene, tmp_path):
    from headrecon_addon import scene_collections

    before = snapshot()
    with pytest.raises(RuntimeError, match="missing.png: photo not found"):
        bpy.ops.headrecon.load_photo(filepath=str(tmp_path / "missing.png"), view="front")
    assert snapshot() == before  # no "HeadRecon" collection left behind
    photo = write_photo(tmp_path / "front.png", (300, 400))
    assert bpy.ops.headrecon.load_photo(filepath=str(photo), view="front") == {"FINISHED"}
    root = scene_collections.root_collection(scene, create=False)
    photos_coll = scene_collections.collection_for(scene, "PHOTO", create=False)
    root.name, photos_coll.name = "Reference", "Pictures"  # the artist's names
    photo2 = write_photo(tmp_path / "side.png", (300, 400))
    assert bpy.ops.headrecon.load_photo(filepath=str(photo2), view="side",
                                        camera_view="orthographic-right") == {"FINISHED"}
    assert len(bpy.data.collections) == 2
    assert len(photos_coll.objects) == 2


def test_a_scene_of_an_older_version_still_fits(files):
    from headrecon_addon import photos, scene_collections

    path, case, _ = files
    scene = imported_scene(path)
    # as older versions made it: everything in the scene's own collection
    root = scene_collections.root_collection(scene, create=False)
    objects = list(scene.objects)
    for obj in objects:
        scene.collection.objects.link(obj)
    for coll in [*root.children, root]:
        bpy.data.collections.remove(coll)
    assert not bpy.data.collections and set(scene.collection.objects) == set(objects)
    assert {p.headrecon.view for p in photos.photo_planes(scene)} == set(case.views)
    scene.headrecon.bake_texture = False
    scene.headrecon.n_identity = 10
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    head = scene.headrecon.head
    assert head.users_collection == (scene_collections.root_collection(scene, create=False),)
    assert head.data.shape_keys is not None
    assert np.isfinite(head.headrecon.fit_rms_px)
    # the old objects stay where they were
    assert all(o.users_collection == (scene.collection,) for o in objects)
