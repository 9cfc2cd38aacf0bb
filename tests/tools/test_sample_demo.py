"""The sample case (tools/make_sample.py) and the demo (tools/demo.py).

Both run once per session at a reduced size (384x512 photos, 4 samples per pixel) in
subprocesses, so Blender's global state never mixes with other tests (the sample is the
session fixture ``sample`` of tests/conftest.py).
"""

import json
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image
from scipy import ndimage

from solver import camera_from_dict, load_landmarks
from solver.io.obj import read_obj
from tests import ROOT, SAMPLE_ARGS, SAMPLE_SIZE
from tools.make_sample import EXPRESSIONS, LIGHTS, make_sample, sample_head

SIZE, ARGS = SAMPLE_SIZE, SAMPLE_ARGS
# The fitted head's RMS distance to the true one over the skin (after similarity
# alignment) must stay under this, and well under the mean head's distance.
MAX_RMS_MM = 2.0
MAX_SHARE_OF_MEAN_HEAD = 0.6


def _run(module, *args):
    proc = subprocess.run([sys.executable, "-m", module, *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, f"{module} failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return proc.stdout


@pytest.fixture(scope="module")
def demo(sample, tmp_path_factory):
    folder, _ = sample
    out = tmp_path_factory.mktemp("demo") / "demo"
    stdout = _run("tools.demo", "--out", str(out), "--sample", str(folder), *ARGS,
                  "--panel-height", "256")
    return out, json.loads((out / "report.json").read_text()), stdout


def test_sample_is_a_valid_landmarks_file(sample, model):
    folder, truth = sample
    case = load_landmarks(folder / "sample.json", known_names=model)
    views = case.views
    assert set(views) == {"front", "side"}
    assert views["front"].camera.view == "orthographic-front"
    assert views["side"].camera.view == "orthographic-right"
    for name, v in views.items():
        assert v.size == SIZE
        with Image.open(case.image_path(name)) as im:
            assert im.size == SIZE and im.mode == "RGB"
        assert len(v.points) >= 30, name
        assert set(v.points) == set(json.loads(str(truth["landmark_names"]))[name])
    assert views["front"].contour is None
    assert 100 <= len(views["side"].contour) <= 150
    # side landmarks are the subject's right side and the midline, never the left side
    assert not [n for n in views["side"].points if n.endswith("_left")]


def test_detected_landmarks_on_the_front_photo(sample, tmp_path):
    """``python -m solver detect`` on the rendered front photo: a landmarks file the fit
    reads, its iBUG-68 points near the exact ones (bench/bench_detect.py measures the
    full-size photo: 2.5 % of the eye-to-mouth distance, median)."""
    folder, truth = sample
    out = tmp_path / "detected.json"
    _run("solver", "detect", str(folder / "front.png"), "--out", str(out), "-q")
    case = load_landmarks(out, for_fit=False)
    points = case.views["front"].points
    assert len(points) == 68
    assert case.image_path("front").resolve() == (folder / "front.png").resolve()
    names = json.loads(str(truth["landmark_names"]))["front"]
    exact = dict(zip(names, truth["exact_front"], strict=True))
    err = np.array([np.linalg.norm(np.subtract(points[n], exact[n])) for n in points])
    eyes = np.mean([exact[n] for n in ("eye_outer_right", "eye_inner_right",
                                       "eye_inner_left", "eye_outer_left")], axis=0)
    mouth = np.mean([exact["mouth_corner_right"], exact["mouth_corner_left"]], axis=0)
    scale = np.linalg.norm(eyes - mouth)
    assert np.median(err) < 0.045 * scale, (np.median(err), scale)
    assert np.percentile(err, 90) < 0.12 * scale, (np.percentile(err, 90), scale)


def test_truth_is_consistent(sample, model):
    _, t = sample
    local = model.identity.instance(t["identity_coeffs"])
    np.testing.assert_allclose(t["local_vertices"], local, atol=1e-9)
    r = t["rotation"]
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0)
    assert np.degrees(np.arccos((np.trace(r) - 1) / 2)) < 6.0  # a few degrees of tilt
    np.testing.assert_allclose(t["world_vertices"], local @ r.T + t["translation"], atol=1e-12)
    assert not np.allclose(t["identity_coeffs"], 0.0)


def test_points_are_the_projected_landmarks(sample, model):
    folder, t = sample
    case = load_landmarks(folder / "sample.json", known_names=model)
    cams = {k: camera_from_dict(d) for k, d in json.loads(str(t["cameras"])).items()}
    for name, v in case.views.items():
        names, vertices, placed = v.arrays(model)
        exact = t[f"exact_{name}"]
        # the stored camera reproduces Blender's projection (checked at render time too)
        np.testing.assert_allclose(cams[name].project(t["world_vertices"][vertices]), exact,
                                   atol=0.05)
        noise = placed - exact
        assert 0.2 < noise.std() < 1.0  # ~1 px at 1024 px height, scaled to 512
        assert np.abs(noise).max() < 3.0
        # landmarks sit on the head in the render (within 2 px of its silhouette)
        mask = t[f"head_alpha_{name}"] >= 128
        grown = ndimage.binary_dilation(mask, iterations=2)
        col = np.clip(exact[:, 0].astype(int), 0, SIZE[0] - 1)
        row = np.clip(exact[:, 1].astype(int), 0, SIZE[1] - 1)
        assert grown[row, col].all(), [n for n, ok in zip(names, grown[row, col],
                                                          strict=True) if not ok]
    # the nose tip is well inside the front view's head (in the side view it is on the
    # outline: see the contour test)
    names, _, _ = case.views["front"].arrays(model)
    u, v = t["exact_front"][names.index("nose_tip")].astype(int)
    assert ndimage.binary_erosion(t["head_alpha_front"] >= 128, iterations=10)[v, u]


def test_a_lens_sample_is_photographed_by_pinholes_of_its_lens(lens_sample, model):
    # --lens 50: pinhole cameras standing where they frame the head as the orthographic
    # sample does, JPEGs whose EXIF gives the lens, views whose cameras the fit computes
    from solver.io.exif import photo_lens_mm

    folder, t = lens_sample
    assert not (folder / "front.png").exists()
    case = load_landmarks(folder / "sample.json", known_names=model)
    cams = {k: camera_from_dict(d) for k, d in json.loads(str(t["cameras"])).items()}
    for name, v in case.views.items():
        cam = cams[name]
        assert cam.perspective and cam.lens_mm == pytest.approx(50.0)
        assert v.camera is None and v.camera_hints == {"kind": "pinhole", "lens_mm": 50.0}
        assert photo_lens_mm(folder / v.image, v.size) == pytest.approx(50.0, abs=0.5)
        names, vertices, _ = v.arrays(model)
        np.testing.assert_allclose(cam.project(t["world_vertices"][vertices]),
                                   t[f"exact_{name}"], atol=0.05)
        # about half a metre away, the head's middle as large as in the orthographic photo
        distance = np.linalg.norm(cam.centre - t["world_vertices"][model.skin].mean(axis=0))
        assert 0.4 < distance < 0.8, distance
        px = cam.project(t["world_vertices"][model.skin])
        assert px.min() >= 0 and (px <= SIZE).all()


def test_a_sample_with_an_expression_shows_it_and_keeps_the_neutral_head_as_truth(
        open_mouth_sample, sample, model):
    folder, t = open_mouth_sample
    weights = json.loads(str(t["expression"]))
    assert weights == EXPRESSIONS["jaw_open"] == {"jawOpen": 0.2}
    local = model.identity.instance(t["identity_coeffs"])
    np.testing.assert_allclose(t["local_vertices"], local, atol=1e-9)  # what a fit should find
    shown = local + 0.2 * model.expressions[model.expression_names.index("jawOpen")]
    np.testing.assert_allclose(t["world_vertices"], shown @ t["rotation"].T + t["translation"],
                               atol=1e-12)
    # the points are the open mouth's: the chin lower and the lips apart, in both photos
    case = load_landmarks(folder / "sample.json", known_names=model)
    cams = {k: camera_from_dict(d) for k, d in json.loads(str(t["cameras"])).items()}
    neutral = local @ t["rotation"].T + t["translation"]
    for name, v in case.views.items():
        names, vertices, _ = v.arrays(model)
        np.testing.assert_allclose(cams[name].project(t["world_vertices"][vertices]),
                                   t[f"exact_{name}"], atol=0.05)
        drop = t[f"exact_{name}"][:, 1] - cams[name].project(neutral[vertices])[:, 1]
        assert drop[names.index("chin_bottom")] > 3.0
        assert abs(drop[names.index("nose_tip")]) < 0.2
    def lips_apart(points, truth):  # the inner lips' gap on the front photo's midline, px
        px = dict(zip(points.views["front"].arrays(model)[0], truth["exact_front"],
                      strict=True))
        return px["lip_lower_inner_middle"][1] - px["mouth_middle"][1]

    plain = load_landmarks(sample[0] / "sample.json", known_names=model)
    assert lips_apart(case, t) > lips_apart(plain, sample[1]) + 3.0


def test_side_contour_traces_the_head_outline(sample, model):
    folder, t = sample
    case = load_landmarks(folder / "sample.json", known_names=model)
    contour = case.views["side"].contour
    mask = t["head_alpha_side"] >= 128
    outline = mask & ~ndimage.binary_erosion(mask)
    dist = ndimage.distance_transform_edt(~outline)
    col = np.clip(contour[:, 0].astype(int), 0, SIZE[0] - 1)
    row = np.clip(contour[:, 1].astype(int), 0, SIZE[1] - 1)
    assert dist[row, col].max() <= 2.0
    # drawing order: from the front of the neck over the face and skull to the back
    assert contour[0, 0] > contour[-1, 0]
    step = np.linalg.norm(np.diff(contour, axis=0), axis=1)
    assert step.max() < 1.5 * np.median(step)
    top = contour[:, 1].argmin()
    assert 0 < top < len(contour) - 1  # the skull top lies between the two neck ends
    # the nose tip is on the profile outline
    names, _, _ = case.views["side"].arrays(model)
    nose = t["exact_side"][names.index("nose_tip")]
    assert np.linalg.norm(contour - nose, axis=1).min() < 4.0


def test_sample_is_reused_when_up_to_date(sample, model):
    folder, _ = sample
    before = {p.name: p.stat().st_mtime_ns for p in folder.iterdir()}
    messages = []
    make_sample(folder, size=SIZE, samples=4, model=model, log=messages.append)
    assert messages == [f"sample up to date: {folder}"]
    assert {p.name: p.stat().st_mtime_ns for p in folder.iterdir()} == before


def test_demo_writes_everything_and_fits_the_truth(demo, model):
    out, report, stdout = demo
    for name in ("head.blend", "head.obj", "head.mtl", "head_texture.png", "preview.png",
                 "report.json"):
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    assert report["requested_method"] == "combined"
    err = report["vertex_error"]
    assert err["rms_mm"] < MAX_RMS_MM
    assert err["rms_mm"] < MAX_SHARE_OF_MEAN_HEAD * report["mean_head_error_mm"]
    assert report["residual_rms_px"] < 3.0
    assert "vertex error" in stdout and "landmark residual" in stdout
    # where its landmarks come from, and why not from the detector; its outlines detected
    assert report["landmarks_source"] in stdout and "not detected" in stdout
    assert "outlines detected on front" in stdout and report["timings"]["outline_s"] > 0
    with Image.open(out / "preview.png") as im:
        assert im.width == 3 * 192 and im.height > 2 * 256  # 3 columns, 2 rows + caption
    with Image.open(out / "head_texture.png") as im:
        assert im.size == (2048, 1024)  # two UDIM tiles side by side
    obj = read_obj(out / "head.obj")
    assert obj.positions.shape == (model.n_vertices, 3)
    assert "map_Kd head_texture.png" in (out / "head.mtl").read_text()


def test_demo_refuses_without_a_fit(monkeypatch):
    import tools.demo as demo_mod

    monkeypatch.setitem(sys.modules, "solver.fitting.fit", None)  # import fails like a missing fit
    with pytest.raises(demo_mod.DemoError, match="fit is not available"):
        demo_mod._fit_api()


def test_make_sample_rejects_bad_settings(tmp_path, model):
    with pytest.raises(ValueError, match="samples"):
        make_sample(tmp_path / "s", samples=0, model=model)
    with pytest.raises(ValueError, match="size"):
        make_sample(tmp_path / "s", size=(32, 1024), model=model)
    with pytest.raises(ValueError, match="lens_mm"):
        make_sample(tmp_path / "s", lens_mm=2.0, model=model)
    with pytest.raises(ValueError, match="yaw_deg"):
        make_sample(tmp_path / "s", yaw_deg=90.0, model=model)
    with pytest.raises(ValueError, match="pitch_deg"):
        make_sample(tmp_path / "s", pitch_deg=-35.0, model=model)
    with pytest.raises(ValueError, match="side_deg"):
        make_sample(tmp_path / "s", side_deg=30.0, model=model)
    with pytest.raises(ValueError, match="skin_tone: one of light, medium, dark"):
        make_sample(tmp_path / "s", skin_tone="olive", model=model)
    with pytest.raises(ValueError, match="expression: one of smile, eyes_closed, jaw_open"):
        make_sample(tmp_path / "s", expression="grin", model=model)
    with pytest.raises(ValueError, match="light: one of studio, window"):
        make_sample(tmp_path / "s", light="neon", model=model)
    assert not (tmp_path / "s").exists()


def test_the_lights_a_sample_takes_are_those_the_renderer_draws():
    from tools.render_util import LIGHTINGS

    assert LIGHTS == tuple(LIGHTINGS) and LIGHTS[0] == "studio"


def test_a_side_camera_short_of_a_profile_frames_the_head_from_its_direction(model):
    """``side_deg`` stands the side camera that many degrees from the front camera (90:
    the nominal profile), framing the head as the profile's does; ``sample.json`` gives
    that view the turned camera."""
    from solver import OrthographicCamera
    from tools.make_sample import frame_cameras, view_camera

    _, local, rotation, translation = sample_head(model, 5)
    world = local @ rotation.T + translation
    size = (300, 400)
    square = frame_cameras(world, -0.1, size, 5)
    short = frame_cameras(world, -0.1, size, 5, side_deg=72.0)
    d = short["side"].rotation[2]
    assert np.degrees(np.arctan2(d[0], d[1])) == pytest.approx(72.0)
    np.testing.assert_allclose(short["front"].rotation, square["front"].rotation)
    np.testing.assert_allclose(square["side"].rotation,
                               OrthographicCamera.nominal("orthographic-right", size).rotation)
    u = short["side"].project(world[world[:, 2] > -0.1])[:, 0]
    assert u.min() > 0 and u.max() < size[0]  # the head across the photo
    assert view_camera("side", size, 72.0).rotation == pytest.approx(short["side"].rotation)
    assert view_camera("side", size).to_dict() == \
        OrthographicCamera.nominal("orthographic-right", size).to_dict()


def test_sample_head_turned_by_the_yaw_given(model):
    """``yaw_deg`` turns the seeded head about the vertical on top of its own small turn
    (negative: the face toward the subject's right, where the side camera stands)."""
    _, local, rotation, translation = sample_head(model, 5)
    _, local_t, turned, translation_t = sample_head(model, 5, yaw_deg=-45.0)
    np.testing.assert_array_equal(local_t, local)
    np.testing.assert_array_equal(translation_t, translation)
    forward = rotation @ [0.0, -1.0, 0.0]  # the face looks toward -Y
    forward_t = turned @ [0.0, -1.0, 0.0]
    angle = np.degrees(np.arctan2(np.cross(forward[:2], forward_t[:2]),
                                  forward[:2] @ forward_t[:2]))
    assert abs(abs(angle) - 45.0) < 1e-6
    assert forward_t[0] < forward[0]  # toward -X: the subject's right


def test_sample_head_nodded_by_the_pitch_given(model):
    """``pitch_deg`` nods the seeded head about the left-right axis on top of its own small
    turn (positive: the face down), the identity and the head's place unchanged."""
    _, local, rotation, translation = sample_head(model, 5)
    for pitch in (12.0, -12.0):
        _, local_n, nodded, translation_n = sample_head(model, 5, pitch_deg=pitch)
        np.testing.assert_array_equal(local_n, local)
        np.testing.assert_array_equal(translation_n, translation)
        forward = rotation @ [0.0, -1.0, 0.0]  # the face looks toward -Y
        forward_n = nodded @ [0.0, -1.0, 0.0]
        # the face's direction leaves the level by the pitch, down for a positive one
        down = np.degrees(np.arcsin(forward[2]) - np.arcsin(forward_n[2]))
        assert down == pytest.approx(pitch, abs=0.5)
