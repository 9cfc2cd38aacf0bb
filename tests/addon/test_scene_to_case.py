"""The scene read back as a landmarks file (an export keeps what the import brought) and
whether it has the landmarks a fit needs (bpy module, background)."""

import json

import bpy
import numpy as np

from tests.addon.support import write_photo


def test_import_export_round_trip(files, scene, tmp_path):
    from solver.io import landmarks_file

    path, case, _ = files
    # keys the add-on does not edit travel through the scene untouched
    data = json.loads(path.read_text())
    data["version"] = 2
    data["x-tool"] = {"made by": "test"}
    data["views"]["front"]["calibrated"] = False
    data["views"]["front"]["x-note"] = "kept"
    path = path.parent / "case_v2.json"
    path.write_text(json.dumps(data))
    case = landmarks_file.load_landmarks(path)
    assert bpy.ops.headrecon.import_landmarks(filepath=str(path)) == {"FINISHED"}
    planes = [o for o in scene.objects if o.headrecon.role == "PHOTO"]
    assert sorted(p.headrecon.view for p in planes) == sorted(case.views)
    n_lm = sum(1 for o in scene.objects if o.headrecon.role == "LANDMARK")
    assert n_lm == case.n_points
    out = tmp_path / "sub" / "exported.json"
    out.parent.mkdir()
    assert bpy.ops.headrecon.export_landmarks(filepath=str(out)) == {"FINISHED"}
    again = landmarks_file.load_landmarks(out)
    assert _same(again, case)
    assert again.extra == {"x-tool": {"made by": "test"}}
    assert again.views["front"].calibrated is False
    assert again.views["front"].extra == {"x-note": "kept"}
    # image paths are rewritten relative to the new file and still find the photos
    for v in case.views:
        assert again.image_path(v).resolve() == case.image_path(v).resolve()
    # importing the export again replaces the planes (no duplicates) and keeps the points
    assert bpy.ops.headrecon.import_landmarks(filepath=str(out)) == {"FINISHED"}
    assert sum(1 for o in scene.objects if o.headrecon.role == "PHOTO") == len(case.views)
    assert sum(1 for o in scene.objects if o.headrecon.role == "LANDMARK") == n_lm


def _same(a, b):
    for v in b.views:
        pa, pb = a.views[v].points, b.views[v].points
        assert list(pa) == list(pb)
        assert np.allclose([pa[k] for k in pa], [pb[k] for k in pb], atol=1e-3)
        if b.views[v].contour is not None:
            assert np.allclose(a.views[v].contour, b.views[v].contour, atol=1e-3)
        assert a.views[v].camera.to_dict() == b.views[v].camera.to_dict()
    return True


def test_fit_problem_follows_the_solver_count_rule(scene, tmp_path):
    # the Fit button asks the solver's rule: an orthographic photo needs 3 landmarks, a
    # pinhole camera still to compute 4 (what refitting it needs)
    from headrecon_addon import landmarks, photos, scene_to_case

    img = write_photo(tmp_path / "photo.png", (300, 400))
    assert bpy.ops.headrecon.load_photo(filepath=str(img), view="front") == {"FINISHED"}
    assert bpy.ops.headrecon.load_photo(filepath=str(img), view="photo",
                                        projection="PERSPECTIVE") == {"FINISHED"}
    front, photo = photos.find_plane(scene, "front"), photos.find_plane(scene, "photo")
    names = [d["name"] for d in landmarks.landmark_definitions("front")]
    for i, name in enumerate(names[:2]):
        landmarks.place_landmark(front, name, (100.0 + 10 * i, 150.0))
    for i, name in enumerate(names[:3]):
        landmarks.place_landmark(photo, name, (100.0 + 10 * i, 150.0))
    assert scene_to_case.fit_problem(scene) == \
        "Too few landmarks on front (2), photo (3): place at least 3 on front, 4 on photo"
    landmarks.place_landmark(front, names[2], (130.0, 150.0))
    assert scene_to_case.fit_problem(scene) == \
        "Too few landmarks on photo (3): place at least 4 per photo"
    landmarks.place_landmark(photo, names[3], (130.0, 150.0))
    assert scene_to_case.fit_problem(scene) is None


def test_a_profile_with_only_its_outline_can_be_fitted(scene, tmp_path):
    # a profile photo with a traced outline needs no landmark (the solver's rule: the
    # outline places its camera); without the outline it needs 3
    from headrecon_addon import landmarks, photos, scene_to_case

    img = write_photo(tmp_path / "photo.png", (300, 400))
    for view in ("front", "right"):
        assert bpy.ops.headrecon.load_photo(filepath=str(img), view=view,
                                            camera_view=f"orthographic-{view}") == {"FINISHED"}
    front, side = photos.find_plane(scene, "front"), photos.find_plane(scene, "right")
    for i, name in enumerate(d["name"] for d in landmarks.landmark_definitions("front")):
        if i == 6:
            break
        landmarks.place_landmark(front, name, (100.0 + 10 * i, 150.0))
    assert scene_to_case.fit_problem(scene) == \
        "Too few landmarks on right (0): place at least 3 per photo"
    landmarks.set_contour(side, np.array([[150.0, 50.0], [170.0, 200.0],
                                          [160.0, 350.0]]))
    assert scene_to_case.fit_problem(scene) is None
