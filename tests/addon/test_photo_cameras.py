"""Photos from any camera in the add-on: a Blender camera per perspective photo (pinhole,
DLT, mirrored), its photo plane inside the frustum, version-2 import/export, a fit on a
perspective case updating the cameras, passpoint residuals (bpy module, background)."""

import json
import types

import bpy
import numpy as np
import pytest
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

from tests.addon.support import add_passpoints, addon, empty_scene, save_case, snapshot, write_photo


@pytest.fixture(scope="module")
def mirror_file(model, tmp_path_factory):
    """Version 2: "front" seen by a DLT camera with non-square pixels and an off-centre
    principal point, "mirror" (mirror_of front) by the mirrored pinhole camera, "side" by a
    calibrated pinhole; all cameras given. Returns (path, case, head points (n, 3))."""
    from solver import synthetic
    from solver.cameras.dlt import DLTCamera

    addon()
    case, truth = synthetic.make_mirror_case(model, 2, calibrated=True, head_px=300.0)
    pin = truth.cameras["front"]
    k, r, c = pin.decompose()
    k[1, 1] *= 1.02
    k[:2, 2] += (30.0, -20.0)
    case.views["front"].camera = DLTCamera.from_krc(k, r, c, pin.size)
    case.views["mirror"].camera = truth.cameras["mirror"]
    case.views["mirror"].calibrated = True
    side, side_truth = synthetic.make_perspective_case(model, 4, n_views=1, calibrated=True,
                                                       head_px=(300.0, 320.0))
    case.views["side"] = side.views["photo0"]
    case.views["side"].name = "side"
    path, case = save_case(case, tmp_path_factory.mktemp("cams"), "mirror")
    points = np.vstack([truth.world_vertices[model.skin[::997]],
                        side_truth.world_vertices[model.skin[::997]]])
    return path, case, points


def _photo_pixels(scene, cam_obj, plane, world):
    """Pixels of world points through a Blender camera (``world_to_camera_view``), in the
    photo's convention (top-left origin; a flipped camera's pixels flipped back)."""
    from headrecon_addon import photo_cameras, photos

    (w, h), _ = photos.plane_size(plane)
    photo_cameras.look_through(scene, cam_obj, (w, h))
    ndc = np.array([world_to_camera_view(scene, cam_obj, Vector(x)) for x in world])
    u, v = ndc[:, 0] * w, (1.0 - ndc[:, 1]) * h
    return np.column_stack([w - u if cam_obj.headrecon.flip_x else u, v])


def _plane_world(plane, uv):
    """World points of pixels on a plane (its surface, z = 0)."""
    from headrecon_addon import photos

    m = plane.matrix_world
    return np.array([m @ Vector((x, y, 0.0)) for x, y in photos.local_from_pixels(plane, uv)])


def test_cameras_match_the_solver(mirror_file):
    from headrecon_addon import landmarks, photos

    path, case, points = mirror_file
    scene = empty_scene()
    assert bpy.ops.headrecon.import_landmarks(filepath=str(path)) == {"FINISHED"}
    bpy.context.view_layer.update()
    for name, view in case.views.items():
        plane = photos.find_plane(scene, name)
        cam_obj = photos.camera_object(plane)
        assert cam_obj is not None and cam_obj.type == "CAMERA", name
        assert cam_obj.name in scene.objects and cam_obj.data.type == "PERSP"
        assert photos.view_root(plane) == cam_obj and plane.parent == cam_obj
        # the photo is the camera's background (flipped for the mirrored camera)
        bg = cam_obj.data.background_images[0]
        assert cam_obj.data.show_background_images and bg.image == plane.headrecon.image
        assert bg.use_flip_x == cam_obj.headrecon.flip_x == (name == "mirror")
        # Blender's projection of head points = the solver camera's
        cam = view.camera
        got = _photo_pixels(scene, cam_obj, plane, points)
        assert np.abs(got - cam.project(points)).max() < 0.05, name
        # the plane fills the view: a pixel of the photo on the plane is that pixel
        w, h = view.size
        uv = np.array([[0.0, 0.0], [w, h], [w, 0.0], [0.3 * w, 0.7 * h]])
        on_plane = _plane_world(plane, uv)
        assert np.abs(_photo_pixels(scene, cam_obj, plane, on_plane) - uv).max() < 0.05
        assert np.abs(cam.project(on_plane) - uv).max() < 0.05, name
        # ... and it stands behind the head, seen from the camera
        depth = -(cam_obj.matrix_world.inverted() @ Vector(points.mean(axis=0))).z
        assert -plane.matrix_basis.translation.z > depth + 0.2
        # the imported landmarks sit on their pixels
        px = landmarks.landmark_pixels(plane)
        assert list(px) == list(view.points)
        assert np.allclose(list(px.values()), list(view.points.values()), atol=1e-3)
    # View Photo looks through the photo's camera, in the photo's frame
    plane = photos.find_plane(scene, "front")
    rv3d = types.SimpleNamespace()
    photos.look_through(types.SimpleNamespace(scene=scene, space_data=types.SimpleNamespace(
        region_3d=rv3d)), plane)
    assert rv3d.view_perspective == "CAMERA" and scene.camera == photos.camera_object(plane)
    render = scene.render
    assert (render.resolution_x, render.resolution_y) == case.views["front"].size
    assert render.pixel_aspect_x == pytest.approx(1.02, rel=1e-6)
    # importing again replaces views with their cameras (no second camera)
    assert bpy.ops.headrecon.import_landmarks(filepath=str(path)) == {"FINISHED"}
    assert len(bpy.data.cameras) == len(case.views)
    assert sum(o.type == "CAMERA" for o in scene.objects) == len(case.views)


def test_click_through_camera_places_pixel(mirror_file, tmp_path):
    # a click = a ray from the camera through the photo: the landmark lands on the pixel
    # under the mouse, and the export says so
    from headrecon_addon import case_to_scene, landmark_ops, landmarks, photos, scene_to_case
    from solver.io import landmarks_file

    path, case, _ = mirror_file
    scene = empty_scene()
    case_to_scene.import_landmarks(bpy.context, path)
    plane = photos.find_plane(scene, "mirror")
    cam_obj = photos.camera_object(plane)
    for name in list(landmarks.landmark_objects(plane)):
        landmarks.remove_landmark(plane, name)
    session = landmark_ops.PlacementSession(plane)
    first = session.current["name"]
    uv = (123.25, 201.5)
    target = Vector(_plane_world(plane, [uv])[0])
    origin = cam_obj.matrix_world.translation
    assert session.click(origin, (target - origin).normalized())
    assert np.allclose(landmarks.landmark_pixels(plane)[first], uv, atol=1e-3)
    out = tmp_path / "clicked.json"
    scene_to_case.export_landmarks(scene, out)
    assert np.allclose(landmarks_file.load_landmarks(out, for_fit=False)
                       .views["mirror"].points[first], uv, atol=1e-3)


def test_v2_round_trip(model, mirror_file, tmp_path):
    from headrecon_addon import (
        calibration_object,
        case_to_scene,
        landmark_ops,
        landmarks,
        photo_cameras,
        photos,
    )
    from solver import synthetic
    from solver.io import landmarks_file

    path, _, _ = mirror_file
    data = json.loads(path.read_text())
    # a passpoint view (its camera to compute) next to the given cameras
    case, truth = synthetic.make_perspective_case(model, 1, n_views=1, head_px=(300.0, 320.0))
    names = add_passpoints(case, truth, "photo0", np.random.default_rng(0))
    pp_path, _ = save_case(case, path.parent, "passpoints")
    pp = json.loads(pp_path.read_text())
    data["views"]["calib"] = pp["views"]["photo0"]
    data["passpoints"] = pp["passpoints"]
    path = path.parent / "round_trip.json"
    path.write_text(json.dumps(data))
    case = landmarks_file.load_landmarks(path)
    scene = empty_scene()
    assert bpy.ops.headrecon.import_landmarks(filepath=str(path)) == {"FINISHED"}
    plane = photos.find_plane(scene, "calib")
    markers = landmarks.passpoint_objects(plane)
    assert sorted(markers) == sorted(names)
    assert all("Passpoint" in o.material_slots[0].material.name for o in markers.values())
    # the camera to compute is shown as the passpoints' DLT until a fit (less its skew,
    # which Blender has not)
    cam = case_to_scene.passpoint_camera(case, "calib")
    skew = photo_cameras.blender_settings(cam)["dropped_skew_px"]
    pts = truth.world_vertices[::4000]
    got = _photo_pixels(scene, photos.camera_object(plane), plane, pts)
    assert np.abs(got - cam.project(pts)).max() < skew + 0.01
    # passpoints are placed with the landmark tool's session: a click through the camera
    cam_obj = photos.camera_object(plane)
    xyz = calibration_object.case_passpoints(scene)
    assert list(xyz) == list(case.passpoints)
    assert landmark_ops.PlacementSession(plane, role="PASSPOINT", passpoints=xyz).done
    assert landmarks.remove_landmark(plane, names[1], "PASSPOINT")
    session = landmark_ops.PlacementSession(plane, role="PASSPOINT", passpoints=xyz)
    assert session.current["name"] == names[1]
    assert session.header().startswith("Passpoint 2/") and ") m" in session.header()
    target = Vector(_plane_world(plane, [case.views["calib"].passpoints[names[1]]])[0])
    origin = cam_obj.matrix_world.translation
    assert session.click(origin, (target - origin).normalized())
    assert landmarks.passpoint_objects(plane)[names[1]].headrecon.role == "PASSPOINT"
    # a passpoint moved by hand is exported where it now is
    moved = markers[names[0]]
    moved.location.x += 0.01 * plane.headrecon.plane_height
    out = tmp_path / "again.json"
    assert bpy.ops.headrecon.export_landmarks(filepath=str(out)) == {"FINISHED"}
    again = landmarks_file.load_landmarks(out)
    assert json.loads(out.read_text())["version"] == 2
    for name, view in case.views.items():
        a = again.views[name]
        assert a.calibrated == view.calibrated and a.mirror_of == view.mirror_of, name
        assert a.camera_hints == view.camera_hints, name
        if view.camera is None:
            assert a.camera is None
        else:
            assert a.camera.to_dict() == view.camera.to_dict(), name
    assert again.views["mirror"].mirror_of == "front"
    assert again.views["mirror"].camera.is_mirrored
    assert list(again.passpoints) == list(case.passpoints)
    assert all(np.array_equal(again.passpoints[k], case.passpoints[k])
               for k in case.passpoints)
    pa, pb = again.views["calib"].passpoints, case.views["calib"].passpoints
    assert sorted(pa) == sorted(pb)
    du = pa[names[0]][0] - pb[names[0]][0]
    assert du == pytest.approx(0.01 * case.views["calib"].size[1], abs=0.01)
    assert all(np.allclose(pa[k], pb[k], atol=1e-3) for k in names[1:])


def test_fit_updates_cameras_and_lists_calibration(model, tmp_path):
    from headrecon_addon import landmarks, photo_cameras, photos
    from headrecon_addon.live_refit import LIVE
    from solver import synthetic

    addon()
    case, truth = synthetic.make_perspective_case(model, 0, n_views=3, head_px=(300.0, 320.0))
    names = add_passpoints(case, truth, "photo0", np.random.default_rng(1), misplace=(3, 12.0))
    path, case = save_case(case, tmp_path, "persp", photos=False)
    scene = empty_scene()
    assert bpy.ops.headrecon.import_landmarks(filepath=str(path)) == {"FINISHED"}
    before = {v: photos.camera_object(photos.find_plane(scene, v)).matrix_world.copy()
              for v in case.views}
    scene.headrecon.bake_texture = False
    scene.headrecon.n_identity = 20
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    result = LIVE.result
    head = scene.headrecon.head
    keys = head.data.shape_keys.key_blocks
    assert keys["identity_000"].value == pytest.approx(result.identity_coeffs[0], abs=1e-6)
    # every photo's Blender camera is its fitted camera; the self-calibrated ones moved
    # toward where the photos were taken
    for v in case.views:
        plane = photos.find_plane(scene, v)
        cam_obj = photos.camera_object(plane)
        want = photo_cameras.blender_settings(result.cameras[v])
        assert cam_obj.data.lens == pytest.approx(want["lens"], rel=1e-5)
        assert np.allclose(np.array(cam_obj.matrix_world), want["matrix_world"], atol=1e-5)
        pts = result.world_vertices[model.skin[::500]]
        got = _photo_pixels(scene, cam_obj, plane, pts)  # (a DLT's skew is dropped)
        assert np.abs(got - result.cameras[v].project(pts)).max() < \
            want["dropped_skew_px"] + 0.05, v
        if v != "photo0":
            true_c = truth.cameras[v].centre
            assert np.linalg.norm(np.array(cam_obj.matrix_world.translation) - true_c) < \
                np.linalg.norm(np.array(before[v].translation) - true_c), v
    # the passpoints' residuals are in the list, the misplaced one first and flagged
    items = list(scene.headrecon.residuals)
    pp = [it for it in items if it.kind == "PASSPOINT"]
    assert sorted(it.landmark for it in pp) == sorted(names)
    assert all(it.view == "photo0" for it in pp)
    assert (items[0].kind, items[0].landmark, items[0].flagged) == ("PASSPOINT", names[3], True)
    assert "misplaced" in items[0].message
    assert sum(it.flagged for it in pp) == 1
    n_lm = sum(len(r.names) for r in result.residuals.values())
    assert len(items) == n_lm + len(names)
    flags = [it.flagged for it in items]
    assert flags == sorted(flags, reverse=True)
    marker = landmarks.passpoint_objects(photos.find_plane(scene, "photo0"))[names[3]]
    assert marker.headrecon.flagged and "Flagged" in marker.material_slots[0].material.name
    assert "1 passpoint suspect" in scene.headrecon.status
    # clicking the row selects the passpoint
    scene.headrecon.residual_index = 0
    assert bpy.context.view_layer.objects.active == marker
    # a live refit keeps the cameras and the passpoint rows
    obj = next(iter(landmarks.landmark_objects(photos.find_plane(scene, "photo1")).values()))
    obj.location.x += 0.002
    live = LIVE.step(scene, force=True, drag=False)
    assert live is not None and LIVE.stats()["error"] == ""
    assert live.cameras["photo1"] is result.cameras["photo1"]
    assert [it.landmark for it in scene.headrecon.residuals if it.kind == "PASSPOINT"][0] \
        == names[3]


def test_load_photo_with_any_camera(tmp_path):
    from headrecon_addon import landmarks, photos, scene_to_case

    scene = empty_scene()
    img = write_photo(tmp_path / "three_quarter.png", (300, 400))
    assert bpy.ops.headrecon.load_photo(filepath=str(img), projection="PERSPECTIVE",
                                        lens_mm=85.0) == {"FINISHED"}
    plane = photos.find_plane(scene, "photo")
    cam_obj = photos.camera_object(plane)
    assert photos.is_perspective(plane) and cam_obj.name in scene.objects
    assert cam_obj.data.lens == pytest.approx(85.0, rel=1e-5)  # 36 mm equivalent
    assert "Pinhole 85 mm, to compute" in photos.camera_label(plane)
    landmarks.place_landmark(plane, "nose_tip", (150.0, 220.0))
    doc = scene_to_case.case_dict_from_scene(scene)
    assert doc["views"]["photo"]["camera"] == {"kind": "pinhole", "lens_mm": 85.0}
    # turning a camera still to compute turns its stand-in camera (here: to the left side)
    plane.headrecon.camera_view = "orthographic-left"
    axis = -np.array(cam_obj.matrix_world.to_3x3())[:, 2]  # Blender cameras look down -Z
    assert np.allclose(axis, (-1.0, 0.0, 0.0), atol=1e-6)
    # a second photo gets its own view; an orthographic one stands in the world
    assert bpy.ops.headrecon.load_photo(filepath=str(img)) == {"FINISHED"}
    front = photos.find_plane(scene, "front")
    assert front is not None and photos.camera_object(front) is None and front.parent is None
    # the same view made orthographic: its camera goes, its landmark stays
    n_cameras = len(bpy.data.cameras)
    assert bpy.ops.headrecon.load_photo(filepath=str(img), view="photo",
                                        camera_view="orthographic-left") == {"FINISHED"}
    assert photos.camera_object(plane) is None and len(bpy.data.cameras) == n_cameras - 1
    assert plane.headrecon.camera_view == "orthographic-left"
    assert scene_to_case.case_dict_from_scene(scene)["views"]["photo"]["camera"] == \
        "orthographic-left"
    assert np.allclose(landmarks.landmark_pixels(plane)["nose_tip"], (150.0, 220.0),
                       atol=1e-3)


def _broken(path, how):
    data = json.loads(path.read_text())
    cam = data["views"]["side"]["camera"]
    if how == "rotation":
        cam["rotation"][0] = [2.0, 0.0, 0.0]
    elif how == "dlt":
        data["views"]["front"]["camera"]["parameters"] = [1.0, 2.0]
    elif how == "mirror":
        data["views"]["mirror"]["mirror_of"] = "nowhere"
    elif how == "photo":  # found only while building: cameras of earlier views exist then
        w, h = data["views"]["side"]["size"]
        write_photo(path.parent / "other_size.png", (w + 4, h))
        data["views"]["side"]["image"] = "other_size.png"
    out = path.parent / f"broken_{how}.json"
    out.write_text(json.dumps(data))
    return out


@pytest.mark.parametrize("how, words", [("rotation", "views.side.camera"),
                                        ("dlt", "views.front.camera"),
                                        ("mirror", "nowhere"),
                                        ("photo", "other_size.png")])
def test_broken_camera_leaves_scene_unchanged(mirror_file, how, words):
    from headrecon_addon import case_to_scene

    path, _, _ = mirror_file
    scene = empty_scene()
    case_to_scene.import_landmarks(bpy.context, path)
    cam_names = sorted(o.name for o in scene.objects if o.type == "CAMERA")
    before = snapshot()
    bad = _broken(path, how)
    with pytest.raises(ValueError) as err:
        case_to_scene.import_landmarks(bpy.context, bad)
    assert words in str(err.value)
    assert snapshot() == before
    with pytest.raises(RuntimeError, match="Error"):
        bpy.ops.headrecon.import_landmarks(filepath=str(bad))
    assert snapshot() == before
    assert sorted(o.name for o in scene.objects if o.type == "CAMERA") == cam_names


def test_fit_places_the_mirror_view_camera(model, tmp_path):
    # one photo with a mirror beside the head: the mirror view's fitted camera is mirrored,
    # shown as the real camera seeing the flipped photo
    from headrecon_addon import photos
    from headrecon_addon.live_refit import LIVE
    from solver import synthetic

    addon()
    case, truth = synthetic.make_mirror_case(model, 2, head_px=300.0)
    path, case = save_case(case, tmp_path, "mirror_fit")
    scene = empty_scene()
    assert bpy.ops.headrecon.import_landmarks(filepath=str(path)) == {"FINISHED"}
    plane = photos.find_plane(scene, "mirror")
    assert "mirror of front" in photos.camera_label(plane)
    assert plane.headrecon.image == photos.find_plane(scene, "front").headrecon.image
    scene.headrecon.bake_texture = False
    scene.headrecon.n_identity = 10
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    result = LIVE.result
    cam = result.cameras["mirror"]
    assert cam.is_mirrored
    cam_obj = photos.camera_object(plane)
    assert cam_obj.headrecon.flip_x and cam_obj.data.background_images[0].use_flip_x
    pts = result.world_vertices[model.skin[::700]]
    got = _photo_pixels(scene, cam_obj, plane, pts)
    assert np.abs(got - cam.project(pts)).max() < 0.05


def _camera_pixels(scene, view, pts):
    from headrecon_addon import photos

    plane = photos.find_plane(scene, view)
    return _photo_pixels(scene, photos.camera_object(plane), plane, pts)


def test_export_after_fit_writes_the_fitted_cameras(model, tmp_path, monkeypatch):
    from headrecon_addon import fit_job, photos
    from headrecon_addon.live_refit import LIVE
    from solver import synthetic
    from solver.io import landmarks_file

    addon()
    case, truth = synthetic.make_perspective_case(model, 5, n_views=2, head_px=(300.0, 320.0))
    path, case = save_case(case, tmp_path, "self_calib")
    assert all(v.camera is None for v in case.views.values())
    scene = empty_scene()
    assert bpy.ops.headrecon.import_landmarks(filepath=str(path)) == {"FINISHED"}
    scene.headrecon.bake_texture = False
    scene.headrecon.n_identity = 10
    stored = {v: photos.find_plane(scene, v).headrecon.camera_json for v in case.views}
    assert stored == {v: "" for v in case.views}
    # a failed fit changes no stored camera
    monkeypatch.setattr(fit_job, "fit_head", lambda *a, **k: (_ for _ in ()).throw(
        ValueError("no fit today")))
    with pytest.raises(RuntimeError, match="no fit today"):
        bpy.ops.headrecon.fit()
    assert {v: photos.find_plane(scene, v).headrecon.camera_json for v in case.views} == stored
    monkeypatch.undo()
    assert bpy.ops.headrecon.fit() == {"FINISHED"}
    result = LIVE.result
    pts = result.world_vertices[model.skin[::700]]
    shown = {v: _camera_pixels(scene, v, pts) for v in case.views}
    out = tmp_path / "after_fit.json"
    assert bpy.ops.headrecon.export_landmarks(filepath=str(out)) == {"FINISHED"}
    doc = json.loads(out.read_text())
    again = landmarks_file.load_landmarks(out)
    for v in case.views:
        cam = result.cameras[v]
        assert doc["views"][v]["camera"]["kind"] == cam.kind
        assert again.views[v].camera is not None, v
        assert not again.views[v].camera_fixed, v  # a starting guess, still refined
        assert np.allclose(again.views[v].camera.project(pts), cam.project(pts), atol=1e-6)
    # re-importing the export gives the same Blender cameras
    scene = empty_scene()
    assert bpy.ops.headrecon.import_landmarks(filepath=str(out)) == {"FINISHED"}
    for v in case.views:
        assert np.abs(_camera_pixels(scene, v, pts) - shown[v]).max() < 0.05, v


def test_mirror_of_and_passpoints_from_the_ui(tmp_path):
    from headrecon_addon import landmarks, photos, properties
    from solver.io import landmarks_file

    scene = empty_scene()
    img = write_photo(tmp_path / "mirror.png", (400, 300))
    assert bpy.ops.headrecon.load_photo(filepath=str(img), view="front", projection="PERSPECTIVE",
                                        lens_mm=50.0) == {"FINISHED"}
    assert bpy.ops.headrecon.load_photo(filepath=str(img), view="mirror",
                                        projection="PERSPECTIVE", lens_mm=50.0) == {"FINISHED"}
    front, mirror = photos.find_plane(scene, "front"), photos.find_plane(scene, "mirror")
    props = mirror.headrecon
    items = [i[0] for i in properties._mirror_items(props, bpy.context)]
    assert items == [properties.NO_MIRROR, "front"]
    assert props.mirror_of == properties.NO_MIRROR
    props.mirror_of = "front"
    assert props.mirror_of == "front" and photos.mirror_of(mirror) == "front"
    assert "mirror of front" in photos.camera_label(mirror)
    # passpoints of the calibration object: added, moved, removed through the operator
    op = bpy.ops.headrecon.edit_passpoint
    assert op(name="A", location=(0.1, 0.0, 0.0)) == {"FINISHED"}
    assert op(name="B", location=(0.0, 0.2, 0.0)) == {"FINISHED"}
    assert op(name="A", location=(0.1, 0.0, 0.05)) == {"FINISHED"}
    assert op(name="C", location=(0.0, 0.0, 0.3)) == {"FINISHED"}
    assert op(name="C", remove=True) == {"FINISHED"}
    with pytest.raises(RuntimeError, match="give it a name"):
        op(name="  ", location=(0.0, 0.0, 0.0))
    landmarks.place_landmark(front, "nose_tip", (200.0, 150.0))
    landmarks.place_landmark(mirror, "nose_tip", (120.0, 150.0))
    landmarks.place_landmark(front, "A", (50.0, 60.0), "PASSPOINT")
    with pytest.raises(RuntimeError, match="still placed on view"):
        op(name="A", remove=True)
    out = tmp_path / "ui.json"
    assert bpy.ops.headrecon.export_landmarks(filepath=str(out)) == {"FINISHED"}
    doc = json.loads(out.read_text())
    assert doc["views"]["mirror"]["mirror_of"] == "front"
    assert "mirror_of" not in doc["views"]["front"]
    assert list(doc["passpoints"]) == ["A", "B"]
    assert np.allclose([doc["passpoints"]["A"], doc["passpoints"]["B"]],
                       [[0.1, 0.0, 0.05], [0.0, 0.2, 0.0]], atol=1e-7)
    assert doc["views"]["front"]["passpoints"] == {"A": [50.0, 60.0]}
    again = landmarks_file.load_landmarks(out, for_fit=False)
    assert again.views["mirror"].mirror_of == "front"
    assert np.allclose(again.passpoints["A"], (0.1, 0.0, 0.05))
    # a mirror of a view that is itself a mirror is refused on export, naming the field
    front.headrecon.mirror_of = "mirror"
    with pytest.raises(RuntimeError, match="mirror_of"):
        bpy.ops.headrecon.export_landmarks(filepath=str(tmp_path / "bad.json"))
    front.headrecon.mirror_of = properties.NO_MIRROR
    assert photos.mirror_of(front) is None
