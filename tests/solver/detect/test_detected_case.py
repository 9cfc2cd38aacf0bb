"""Detected photos as a case (solver/detect/detected_case.py), fitted: on the rendered
sample the detected front landmarks with their uncertainty (the profile as placed by hand)
fit the true head better than the mean head and than the same points as 1-px clicks (james:
tests/bench/test_bench_detect.py)."""

import copy
import json

import numpy as np
import pytest
from PIL import Image

from solver import fit_head, load_landmarks
from solver.detect import Detector
from solver.detect.detected_case import (
    NO_PROFILE_NOTE,
    TURNED_PROFILE_NOTE,
    UNKNOWN_LENS_NOTE,
    detect_photos,
)
from solver.detect.view_guess import guess_view
from solver.fitting.depth import mirror_pairs
from solver.io.landmark_set import load_landmark_set
from solver.paths import DETECTOR_DIR
from solver.synthetic import skin_error_mm


@pytest.fixture(scope="module")
def detector():
    if not (DETECTOR_DIR / "face_landmark.tflite").is_file():
        pytest.skip(f"models missing in {DETECTOR_DIR}: run ./run detector")
    return Detector()


def _load(path):
    return np.asarray(Image.open(path).convert("RGB"))


def _both_photos(folder, detector, **options):
    """The sample's two photos as ``solver detect`` makes them a case (Auto Fit's)."""
    return detect_photos([(None, folder / "front.png"), (None, folder / "side.png")],
                         detector, _load, base_dir=folder, **options)


def _errors(model, truth, **cases):
    """Skin RMS (mm) of each labelled case's fit against the sample's true head."""
    return {label: skin_error_mm(model, fit_head(model, c).local_vertices,
                                 truth["local_vertices"]) for label, c in cases.items()}


def _mean_errors(model, truth, copies=4, **cases):
    """:func:`_errors` averaged over each case and ``copies`` - 1 copies of it with every
    point moved by 0.05 px (seeded): a photos-only fit lands in one of several nearby
    minima, and which one moves with a tenth of a pixel (0.3 mm apart on these small
    renders; docs/DECISIONS.md, "A rim of light"), so one fit is one draw of it."""
    rng = np.random.default_rng(0)
    out = {label: [] for label in cases}
    for k in range(copies):
        for label, case in cases.items():
            moved = copy.deepcopy(case)
            for v in moved.views.values() if k else ():
                if v.contour is not None:
                    v.contour = v.contour + rng.normal(0, 0.05, v.contour.shape)
                v.points = {n: tuple(np.add(p, rng.normal(0, 0.05, 2)))
                            for n, p in v.points.items()}
            out[label].append(_errors(model, truth, case=moved)["case"])
    return {label: float(np.mean(e)) for label, e in out.items()}


def test_detect_photos_names_views_and_fails_naming_the_photo(sample, detector, tmp_path):
    folder, _ = sample
    lines = []
    case = detect_photos([(None, folder / "side.png"), ("front", folder / "front.png")],
                         detector, _load, base_dir=folder, echo=lines.append)
    assert list(case.views) == ["right", "front"]
    assert case.views["right"].image == "side.png"
    assert sum(ln.startswith("note:") for ln in lines) == 1
    blank = tmp_path / "wall.png"
    Image.new("RGB", (200, 300), (90, 90, 90)).save(blank)
    with pytest.raises(ValueError, match=r"wall\.png: no face found"):
        detect_photos([(None, folder / "front.png"), (None, blank)], detector, _load)


def test_the_detected_front_with_its_uncertainty_fits_the_sample(sample, detector, model):
    folder, truth = sample
    case = load_landmarks(folder / "sample.json", known_names=model)
    auto = detect_photos([(None, folder / "front.png")], detector, _load, base_dir=folder)
    given, clicks = copy.deepcopy(case), copy.deepcopy(case)
    given.views["front"] = auto.views["front"]
    clicks.views["front"] = copy.deepcopy(auto.views["front"])
    clicks.views["front"].uncertainty = {}
    clicks.views["front"].depth = {}
    mean = skin_error_mm(model, model.vertices, truth["local_vertices"])
    err = _errors(model, truth, uncertainty=given, clicks=clicks)
    assert err["uncertainty"] < 0.6 * mean, (err, mean)
    assert err["uncertainty"] < err["clicks"], err


def test_the_detected_front_s_depth_follows_the_true_head_and_helps_its_fit(sample, detector,
                                                                          model):
    folder, truth = sample
    auto = _both_photos(folder, detector)
    front = auto.views["front"]
    assert auto.views["right"].depth == {}  # a profile's mesh is unreliable
    assert set(front.depth) == set(front.uncertainty) and len(front.depth) == 68
    cam = json.loads(str(truth["cameras"]))["front"]
    lms = load_landmark_set()
    names = sorted(front.depth)
    x = truth["world_vertices"][[lms.vertices[n] for n in names]]
    true = -cam["scale"] * x @ np.asarray(cam["rotation"])[2]  # toward the camera, px
    seen = np.array([front.depth[n] for n in names])
    assert np.corrcoef(true, seen)[0, 1] > 0.95
    # the mirror pairs' differences (how the head is turned), within 2 px
    pairs = mirror_pairs(names, [not lms.outline_in(n, "front") for n in names])
    a, b = pairs[:, 0], pairs[:, 1]
    gap = (seen[b] - seen[a]) - (true[b] - true[a])
    assert len(pairs) >= 15 and np.sqrt(np.mean(np.square(gap))) < 2.0, gap
    # the front detected without its outline (the profile as placed): the depths hold the
    # head's turn and make the fit better (1.56 against 1.69 mm on this small render, its
    # settings scaled to its size; 1.86 against 2.05 with them as given; with the front's
    # outline, which holds the turn too, 1.16 either way)
    case = load_landmarks(folder / "sample.json", known_names=model)
    given, flat = copy.deepcopy(case), copy.deepcopy(case)
    given.views["front"] = copy.deepcopy(front)
    given.views["front"].contour = None
    flat.views["front"] = copy.deepcopy(given.views["front"])
    flat.views["front"].depth = {}
    err = _errors(model, truth, depth=given, flat=flat)
    assert err["depth"] < err["flat"], err


def test_a_fit_from_the_photos_alone_started_from_its_own_head_stays_there(sample, detector,
                                                                          model):
    # Auto Fit's case. Each noise round after the first starts from the last head; begun
    # again from the landmarks alone (the staged start meant for the mean head), it left
    # that head and latched the outlines anew, so a change of 1/1000 px in the input sent
    # the rendered sample's head anywhere from 1.4 to 3.9 mm (docs/DECISIONS.md). A fit
    # from a given head also goes on with its noise and expressions: here 0.19-0.22 mm
    # away with one or two BLAS threads (0.13-0.17 before the rim of light changed a few
    # of this render's outline points: its nearby minima lie about 0.3 mm apart; 0.0 with
    # this small render's settings as given; then 0.22 staged, from the default noise
    # 0.50, the landmarks as given 0.69). On an AMD EPYC host 0.07 mm run alone and 0.27
    # in the whole suite's order (what ran before in the process changes it; not traced
    # further): the bound lies between the nearby minima and those two mistakes.
    folder, truth = sample
    auto = _both_photos(folder, detector)
    first = fit_head(model, auto)
    again = fit_head(model, auto, initial=first)
    moved = np.linalg.norm(again.local_vertices - first.local_vertices, axis=1)
    assert np.sqrt(np.mean(moved[model.skin] ** 2)) < 3.5e-4, moved.max()


def test_photos_moved_by_a_thousandth_of_a_pixel_fit_the_same_head(sample, detector, model):
    # Auto Fit's case again. With a hard cut-off on the outline rows, a point crossing it
    # switched its row on or off, and copies moved by 1/1000 px fitted to 2.16 or 2.28 mm
    # from the true head; the fading cut-off (outline.SOFT_CUT) fits them alike. What is
    # left is the outline's own choice of rim vertices: where an ICP round ends between two
    # alternating choices, a copy can settle in the neighbouring minimum (on the Intel
    # host of 2026-12-03, with this small render's settings as given, two of three copies
    # 0.34 mm from the third, 2.30 against 2.36 mm from the true head; on the AMD host
    # before, all three within 0.05 mm; with its settings scaled to its size 0.08 and
    # 0.14 mm, 1.78-1.79 mm).
    folder, truth = sample
    auto = _both_photos(folder, detector)
    heads = []
    for k in range(3):
        c = copy.deepcopy(auto)
        for v in c.views.values():
            v.points = {n: (p[0] + 1e-3 * np.sin(k * i + k), p[1])
                        for i, (n, p) in enumerate(v.points.items())}
        heads.append(fit_head(model, c).local_vertices)
    errors = [skin_error_mm(model, h, truth["local_vertices"]) for h in heads]
    assert max(errors) - min(errors) < 0.1, errors  # mm
    for h in heads[1:]:
        gap = np.sqrt(np.mean(np.sum((h - heads[0])[model.skin] ** 2, axis=1)))
        assert gap < 5e-4, gap  # 0.5 mm


def test_photos_without_a_profile_get_a_note_saying_what_it_costs(sample, detector):
    folder, _ = sample
    lines = []
    case = detect_photos([(None, folder / "front.png"), (None, folder / "front.png")],
                         detector, _load, echo=lines.append, outlines="none")
    assert list(case.views) == ["front", "front_2"]
    assert lines.count(f"note: {NO_PROFILE_NOTE}") == 1


def test_three_quarter_photos_of_unknown_lens_get_a_note_saying_what_it_costs(
        turned_sample, detector):
    folder, _ = turned_sample
    photos = [(None, folder / "front.png"), (None, folder / "side.png")]
    lines = []
    case = detect_photos(photos, detector, _load, echo=lines.append, outlines="none")
    assert all(v.camera is None for v in case.views.values())  # pinholes to calibrate
    assert sorted(ln for ln in lines if ln.endswith(UNKNOWN_LENS_NOTE)) == [
        f"note: {folder / name}: {UNKNOWN_LENS_NOTE}" for name in ("front.png", "side.png")]
    lines = []
    detect_photos(photos, detector, _load, echo=lines.append, outlines="none", lens_mm=50.0)
    assert not [ln for ln in lines if UNKNOWN_LENS_NOTE in ln]


def test_detected_outlines_become_the_views_contours(sample, detector):
    folder, _ = sample
    photos = [(None, folder / "side.png"), (None, folder / "front.png")]
    lines = []
    case = detect_photos(photos, detector, _load, echo=lines.append)
    assert len(case.views["right"].contour) > 100 and len(case.views["front"].contour) > 100
    assert sum(": outline of " in ln for ln in lines) == 2
    only = detect_photos(photos, detector, _load, outlines="profile")
    assert only.views["right"].contour is not None and only.views["front"].contour is None
    none = detect_photos(photos, detector, _load, outlines="none")
    assert all(v.contour is None for v in none.views.values())
    with pytest.raises(ValueError, match="outlines must be one of"):
        detect_photos(photos, detector, _load, outlines="front")


def test_a_photo_without_an_outline_is_one_warning_naming_it(sample, detector,
                                                            monkeypatch):
    folder, _ = sample

    def no_person(image, face):
        raise ValueError("no person found for an outline")

    monkeypatch.setattr(detector, "outline", no_person)
    lines = []
    case = detect_photos([(None, folder / "side.png")], detector, _load, echo=lines.append)
    assert case.views["right"].contour is None
    assert [ln for ln in lines if ln.startswith("warning:")] == [
        f"warning: {folder / 'side.png'}: no person found for an outline; the view gets no "
        "outline"]


def test_a_profile_s_landmarks_are_read_off_its_outline_and_fit_better(sample, detector,
                                                                       model):
    folder, truth = sample
    auto = _both_photos(folder, detector)
    right = auto.views["right"]
    exact = load_landmarks(folder / "sample.json", known_names=model).views["side"].points
    assert {"nasion", "nose_tip", "subnasale", "pogonion", "chin_bottom"} <= set(right.points)
    assert set(right.uncertainty) == set(right.points) and right.depth == {}
    size = 1.215 * np.linalg.norm(np.subtract(exact["nasion"], exact["chin_bottom"]))
    off = {n: float(np.linalg.norm(np.subtract(p, exact[n]))) for n, p in right.points.items()}
    assert max(off.values()) < 0.03 * size, (off, size)  # 3 % of the face's size
    # without its outline the profile keeps the mesh's three points, 10-20 px off
    bare = _both_photos(folder, detector, outlines="none")
    assert set(bare.views["right"].points) == {"nose_tip", "subnasale", "lip_upper_middle"}
    mesh = copy.deepcopy(auto)
    mesh.views["right"].points = bare.views["right"].points
    mesh.views["right"].uncertainty = bare.views["right"].uncertainty
    err = _mean_errors(model, truth, outline=auto, mesh=mesh)
    # On this small render, its profile half as many pixels, 1.79 against 2.27 mm (the
    # mean of the four copies; single fits 1.66-1.86 and 1.62-2.12 over six others): no
    # worse than 0.1 mm.
    assert err["outline"] < err["mesh"] + 0.1, err


def test_photos_with_their_lens_in_exif_fit_through_pinholes_of_that_lens(lens_sample,
                                                                          detector, model):
    # the sample photographed with a 50 mm lens half a metre away: each photo a pinhole of
    # its EXIF lens held near its view's direction fits the head far better than the same
    # photos taken as parallel projections, and finds the profile camera where it stood
    folder, truth = lens_sample
    photos = [(None, folder / "front.jpg"), (None, folder / "side.jpg")]
    lines = []
    auto = detect_photos(photos, detector, _load, base_dir=folder, echo=lines.append)
    assert sum("its 50 mm lens (EXIF)" in ln for ln in lines) == 2
    for name, yaw in (("front", None), ("right", 90.0)):
        view = auto.views[name]
        assert view.camera is None and view.camera_hints["kind"] == "pinhole"
        assert view.camera_hints["lens_mm"] == pytest.approx(50.0, abs=0.5)
        direction = view.camera_hints["direction_prior"]
        assert direction[0] == pytest.approx(yaw, abs=1e-9) if yaw else abs(direction[0]) < 5
    flat = detect_photos(photos, detector, _load, base_dir=folder, exif_lens=False)
    assert type(flat.views["front"].camera).__name__ == "OrthographicCamera"
    fitted = fit_head(model, auto)
    err = {"lens": skin_error_mm(model, fitted.local_vertices, truth["local_vertices"]),
           **_errors(model, truth, flat=flat),
           "mean head": skin_error_mm(model, model.vertices, truth["local_vertices"])}
    # 1.94 against 4.51 mm (the mean head 3.43) on this render (2.27 against 5.60 with
    # its settings as given)
    assert err["lens"] < 0.6 * err["flat"] and err["lens"] < 0.8 * err["mean head"], err
    true_side = json.loads(str(truth["cameras"]))["side"]
    turn = np.degrees(np.arccos(np.clip(
        np.dot(fitted.cameras["right"].rotation[2], np.asarray(true_side["rotation"])[2]),
        -1.0, 1.0)))
    assert turn < 5.0, turn


def test_photos_without_an_exif_lens_take_the_lens_given(lens_sample, detector,
                                                          monkeypatch):
    # the same photos with their EXIF gone (a messaging app's copies) and the lens given:
    # the case is the one their EXIF made; a lens their EXIF gives wins over the one given
    import solver.detect.detected_case as dc

    folder, _ = lens_sample
    photos = [(None, folder / "front.jpg"), (None, folder / "side.jpg")]
    with_exif = detect_photos(photos, detector, _load, base_dir=folder)
    lines = []
    monkeypatch.setattr(dc, "photo_lens_mm", lambda path, size: None)
    given = detect_photos(photos, detector, _load, base_dir=folder, echo=lines.append,
                          lens_mm=with_exif.views["front"].camera_hints["lens_mm"])
    assert sum("mm lens (as given)" in ln for ln in lines) == 2
    for name, view in with_exif.views.items():
        assert given.views[name].camera is None
        assert given.views[name].camera_hints == view.camera_hints
    assert all(v.camera is not None for v in detect_photos(
        photos, detector, _load, base_dir=folder).views.values())  # none given: parallel
    monkeypatch.setattr(dc, "photo_lens_mm", lambda path, size: 85.0)
    exif = detect_photos(photos, detector, _load, base_dir=folder, lens_mm=24.0)
    assert {v.camera_hints["lens_mm"] for v in exif.views.values()} == {85.0}


def test_a_profile_too_bare_to_calibrate_a_pinhole_stays_a_parallel_projection(
        sample, detector, monkeypatch):
    # both photos said to be taken with a 50 mm lens: the front gets its pinhole; the
    # profile without an outline keeps three points, too few to calibrate one, and stays
    # orthographic with a note naming it; without the EXIF rule both are orthographic
    import solver.detect.detected_case as dc

    monkeypatch.setattr(dc, "photo_lens_mm", lambda path, size: 50.0)
    folder, _ = sample
    lines = []
    case = _both_photos(folder, detector, outlines="none", echo=lines.append)
    assert case.views["front"].camera is None
    assert case.views["front"].camera_hints["lens_mm"] == 50.0
    assert case.views["right"].camera.view == "orthographic-right"
    assert [ln for ln in lines if "parallel projection" in ln] == [
        f"note: {folder / 'side.png'}: taken as a parallel projection despite its 50 mm "
        "lens: too few landmarks to calibrate its camera on"]
    flat = _both_photos(folder, detector, outlines="none", exif_lens=False)
    assert all(v.camera is not None for v in flat.views.values())


def test_an_exif_lens_no_camera_has_is_one_warning_and_no_lens(sample, detector,
                                                               monkeypatch):
    import solver.detect.detected_case as dc

    monkeypatch.setattr(dc, "photo_lens_mm", lambda path, size: 1.0)
    folder, _ = sample
    lines = []
    case = _both_photos(folder, detector, echo=lines.append)
    assert all(v.camera is not None for v in case.views.values())  # orthographic
    assert [ln for ln in lines if "EXIF" in ln] == [
        f"warning: {folder / name}: its EXIF gives a 1 mm lens (36 mm equivalent), outside "
        "2..5000 mm; the photo is used as if it gave none" for name in ("front.png",
                                                                         "side.png")]


def test_black_and_white_photos_fit_better_than_the_mean_head(sample, detector, model):
    folder, truth = sample

    def grey(path):
        return np.asarray(Image.open(path).convert("L").convert("RGB"))

    lines = []
    case = detect_photos([(None, folder / "front.png"), (None, folder / "side.png")],
                         detector, grey, base_dir=folder, echo=lines.append)
    assert sum("the photo has no colour" in ln for ln in lines) == 2
    assert all(len(v.contour) > 100 for v in case.views.values())
    err = _errors(model, truth, grey=case)["grey"]
    mean = skin_error_mm(model, model.vertices, truth["local_vertices"])
    # 2.32 against 3.43 mm (1.79 from the photos in colour); before the outline knew a
    # photo without colour, 4.82: the shirt's grey taken for skin, the profile without one
    assert err < 0.8 * mean, (err, mean)


def test_a_side_photo_short_of_a_profile_fits_nearer_with_its_camera_turned(
        turned_side_sample, detector, model):
    """The photos of a head turned 15 degrees toward the side camera, alone: with the side
    camera turned to the yaw its photo shows (``view_guess.profile_yaw_deg``) the head is
    nearer the truth than with the nominal profile's (2.40 against 2.86 mm, the mean of
    four copies; 2.5 against 3.1 mm in one fit when written)."""
    from solver import OrthographicCamera

    folder, truth = turned_side_sample
    case = _both_photos(folder, detector)
    side = case.views["right"]
    assert side.camera.rotation[2][1] > 0.1  # turned toward the front, not exactly +x
    nominal = copy.deepcopy(case)
    nominal.views["right"].camera = OrthographicCamera.nominal("orthographic-right",
                                                               side.size)
    err = _mean_errors(model, truth, turned=case, nominal=nominal)
    assert err["turned"] < 0.9 * err["nominal"], err


def _yaw(camera):
    d = camera.rotation[2]
    return float(np.degrees(np.arctan2(d[0], d[1])))


def test_photos_beside_a_side_photo_short_of_a_profile_are_placed_in_the_face_s_frame(
        sample, turned_side_sample, detector):
    """A side photo 16 degrees short of a profile has its yaw measured, so the case is
    placed in the face's frame (``view_guess.placed``): the side's camera turned to its
    yaw, a front photo's (another head's, seen from the front) to the small yaw its face
    shows, so the cameras stand as far apart as the photos say. Beside its own front
    photo, a three-quarter view 16 degrees off, that one stays a pinhole held near its
    yaw."""
    side_photo = turned_side_sample[0] / "side.png"
    side_yaw = guess_view(detector.detect(_load(side_photo))).yaw_deg
    assert side_yaw < 80.0
    front_photo = sample[0] / "front.png"
    front_yaw = guess_view(detector.detect(_load(front_photo))).yaw_deg
    case = detect_photos([(None, front_photo), (None, side_photo)], detector, _load)
    assert _yaw(case.views["right"].camera) == pytest.approx(side_yaw)
    assert _yaw(case.views["front"].camera) == pytest.approx(front_yaw) != 0.0
    case = detect_photos([(None, turned_side_sample[0] / "front.png"), (None, side_photo)],
                         detector, _load)
    quarter = case.views["three_quarter_left"]
    assert quarter.camera is None and quarter.camera_hints["kind"] == "pinhole"
    assert quarter.camera_hints["direction_prior"][0] < -15.0
    assert _yaw(case.views["right"].camera) == pytest.approx(side_yaw)


def test_a_photo_turned_gives_the_upright_photo_s_case_on_it_as_turned(model, sample,
                                                                      detector, tmp_path):
    """The front photo stored a quarter round: its points, outline and camera are the
    upright photo's, on the photo as given, one note says so, and the head is the same."""
    from solver.detect.photo_turn import to_turned

    folder, _ = sample
    front = _load(folder / "front.png")
    h, w = front.shape[:2]
    Image.fromarray(np.ascontiguousarray(np.rot90(front))).save(tmp_path / "front.png")
    lines = []
    case = detect_photos([(None, tmp_path / "front.png"), (None, folder / "side.png")],
                         detector, _load, echo=lines.append)
    upright = _both_photos(folder, detector)
    view, was = case.views["front"], upright.views["front"]
    assert view.size == (h, w) and set(view.points) == set(was.points)
    names = sorted(was.points)
    assert np.allclose([view.points[n] for n in names],
                       to_turned([was.points[n] for n in names], 1, (w, h)))
    assert np.allclose(view.contour, to_turned(was.contour, 1, (w, h)))
    assert view.uncertainty == was.uncertainty
    somewhere = np.random.default_rng(0).normal(0.0, 0.1, (10, 3))
    assert np.allclose(view.camera.project(somewhere),
                       to_turned(was.camera.project(somewhere), 1, (w, h)))
    turned = [ln for ln in lines if "in the photo: detected on the photo turned" in ln]
    assert len(turned) == 1 and turned[0].startswith(f"note: {tmp_path / 'front.png'}: ")
    assert "a quarter round anticlockwise" in turned[0]
    # the profile beside it: its turn is not told, so the user is asked to check it
    warned = [ln for ln in lines if ln.startswith("warning:")]
    assert warned == [f"warning: {folder / 'side.png'}: {TURNED_PROFILE_NOTE} "
                      f"({tmp_path / 'front.png'})"]
    heads = [fit_head(model, c).local_vertices for c in (case, upright)]
    assert skin_error_mm(model, *heads) < 0.05
