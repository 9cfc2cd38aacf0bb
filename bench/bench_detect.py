"""Automatic landmarks: time per photo (the face alone; and the face, its outline and the
landmarks kept, as Auto Fit detects a photo), the view guessed (front, profile,
three-quarter, with the yaw), and detected vs true iBUG-68 landmarks in pixels (median,
90th percentile, per group; also as % of the eye-to-mouth distance).

    python -m bench.bench_detect [--sample generated/sample] [--james FOLDER] [--fit]
                                 [--uncertainty] [--profile-line] [--small-faces] [--bias]
                                 [--second-face]

Photos: the rendered sample's front photo (``./run sample``; truth: the exact landmark
pixels in ``truth.npz``) and the two real photos of the scan "james" (its texture's
halves, cut and calibrated as ``bench.realistic_cases`` does; truth: the scan's 68
landmarks projected through each photo's DLT, those the photo shows). A missing photo
set is reported and skipped. The sample's profile photo is measured as it is (a right
profile) and mirrored (a left one), on the points the detector keeps there
(``solver.detect.view_guess``). ``--uncertainty`` prints each group's median error as a
fraction of the detector box's width, pooled over the photos (front: the sample's front
and james' two; profile: per kept point, both sides): the table of
``assets/mediapipe_ibug68.json`` "uncertainty". The detected outline of the sample's
profile and of james rendered as ``bench_realistic`` renders him (right profile) is
measured against the true silhouette (median px). ``--fit`` also fits the sample from
detected landmarks (``fit_errors``: with and without their uncertainty, and the case
``solver detect`` writes) and compares with the exact ones (skin RMS in mm against the
true head, ``solver.synthetic.skin_error_mm``), and james from its two photos' detected
landmarks against its 68 projected exactly (face RMS against the scan, as
``bench.bench_realistic`` scores it). The profile line's points read off the outline
(``solver.detect.profile_line``) are measured on the sample's and james' profiles against
their true landmarks, and with ``--profile-line`` on 40 profiles of model heads (the
table of its ``MEDIAN_ERROR`` and ``ARC_SHIFT``). ``--small-faces`` detects each front
photo placed in the middle of one 2-6 times its size (the face as small as in a photo
from further away) and a grey 12-megapixel photo with no face.
"""

import argparse
import copy
import json
from pathlib import Path

import numpy as np
from PIL import Image

from bench.common import machine_description, median_time
from bench.realistic_cases import (
    FACE_PARTS,
    calibrate,
    james_folder,
    load_scan,
    scan_landmarks,
    scan_photo_halves,
)
from solver.detect import Detector
from solver.detect.view_guess import guess_view, point_uncertainty
from solver.io.landmark_set import load_landmark_set

ROOT = Path(__file__).resolve().parent.parent
GROUPS = FACE_PARTS


def sample_truth(folder, view="front"):
    """(photo uint8 (H, W, 3), {iBUG number: (u, v)}) of the sample's front (or "side")
    photo."""
    folder = Path(folder)
    truth = np.load(folder / "truth.npz", allow_pickle=True)
    names = json.loads(str(truth["landmark_names"]))[view]
    number = {n: i for i, n in load_landmark_set().ibug.items()}
    pts = {number[n]: p for n, p in zip(names, truth[f"exact_{view}"], strict=True)
           if n in number}
    return np.asarray(Image.open(folder / f"{view}.png").convert("RGB")), pts


def mirrored(image, truth):
    """The photo mirrored left to right, and its true points with it."""
    w = image.shape[1]
    return image[:, ::-1].copy(), {i: (w - p[0], p[1]) for i, p in truth.items()}


def james_truth(folder):
    """[(name, photo, {iBUG number: (u, v)})] of the scan's two real photos."""
    scan = load_scan(folder)
    out = []
    for photo, image in scan_photo_halves(folder).items():
        numbers, px = scan_landmarks(scan, calibrate(scan, photo).camera)
        out.append((f"james {photo}", image, dict(zip(numbers, px, strict=True))))
    return out


def face_frame_errors(detected, truth):
    """Signed errors of ``detected`` (68, 2) px (row i - 1: iBUG point i) against
    ``truth`` ({iBUG number: (u, v)}, at least both eyes and mouth corners) in the face's
    frame, % of the eye-to-mouth distance: {number: (across, down)}, across along the
    line from the subject's right eye's centre to the left eye's, down at right angles
    to it (toward the mouth)."""
    eyes = [np.mean([truth[i] for i in r if i in truth], axis=0)
            for r in (range(37, 43), range(43, 49))]
    across = (eyes[1] - eyes[0]) / np.linalg.norm(eyes[1] - eyes[0])
    frame = np.array([across, [-across[1], across[0]]])  # rows: across, down
    scale = eye_to_mouth(truth)
    return {i: 100.0 * frame @ (np.asarray(detected[i - 1], float) - np.asarray(p, float))
            / scale for i, p in truth.items()}


def landmark_bias(detector, groups):
    """Print each iBUG point's mean signed error per group of front photos ({label:
    [(image, truth)]}, truth as :func:`face_frame_errors` takes it), sorted by the
    largest mean over the groups; photos with no face are said and left out."""
    names = load_landmark_set().ibug
    errors = {label: {} for label in groups}
    used = dict.fromkeys(groups, 0)
    for label, photos in groups.items():
        for image, truth in photos:
            face = detector.detect(image)
            if face is None or not face.is_face:
                print(f"  {label}: a photo without a front face, left out")
                continue
            used[label] += 1
            for i, e in face_frame_errors(face.ibug, truth).items():
                errors[label].setdefault(i, []).append(e)
    means = {label: {i: np.mean(e, axis=0) for i, e in errs.items()}
             for label, errs in errors.items()}
    order = sorted(names, key=lambda i: -max(
        (float(np.linalg.norm(m[i])) for m in means.values() if i in m), default=0.0))
    print("landmark bias: mean signed error (across, down), % of eye-to-mouth, over "
          + ", ".join(f"{label} ({n} photos)" for label, n in used.items()))
    for i in order:
        cells = [f"{label} " + (f"({means[label][i][0]:+5.1f} {means[label][i][1]:+5.1f})"
                                if i in means[label] else "(  -     -  )")
                 for label in groups]
        print(f"  {i:2d} {names[i]:<26} " + "   ".join(cells))
    return means


def eye_to_mouth(pts):
    eyes = np.mean([pts[i] for i in range(37, 49) if i in pts], axis=0)
    mouth = np.mean([pts[i] for i in (49, 55) if i in pts], axis=0)
    return float(np.linalg.norm(eyes - mouth))


def report(name, detector, image, truth):
    """Print the photo's timing, view and errors; returns (kind "front"/"profile", {iBUG
    number: error / detector box width}) of the points kept, or None."""
    t = median_time(lambda: detector.detect(image), repeats=5, warmup=1)
    face = t.result
    h, w = image.shape[:2]
    print(f"{name}: {w}x{h} px, detect median {t.median:.3f} s (min {t.min:.3f}, "
          f"CPU {t.cpu_median:.3f} s)")
    guess = None if face is None else guess_view(face)
    if guess is None:
        print("  no face found" if face is None else
              f"  a face (score {face.score:.2f}) whose direction is not told "
              f"(presence {face.presence:.2f})")
        return None
    print(f"  {guess.describe()}; mesh presence {face.presence:.2f}, face box "
          f"{face.face_size:.0f} px")
    kept = point_uncertainty(face)
    scale = eye_to_mouth(truth)
    err = {i: float(np.linalg.norm(face.ibug[i - 1] - truth[i])) for i in truth if i in kept}
    if guess.profile:
        print(f"  profile: {len(err)} points kept ({sorted(kept)}), all the mesh's: median "
              f"{np.median([np.linalg.norm(face.ibug[i - 1] - truth[i]) for i in truth]):.1f}"
              " px")
    rows = [("all", list(err))] + [(g, [i for i in r if i in err]) for g, r in GROUPS.items()]
    print(f"  eye-to-mouth {scale:.0f} px; error px median / p90 (median % of eye-to-mouth)")
    for g, ids in rows:
        if ids:
            e = np.array([err[i] for i in ids])
            print(f"  {g:<6} n={len(ids):2d}  {np.median(e):5.1f} / {np.percentile(e, 90):5.1f}"
                  f"  ({100 * np.median(e) / scale:.1f} %)")
    return ("profile" if guess.profile else "front",
            {i: e / face.face_size for i, e in err.items()})


def uncertainty_table(measured):
    """{"front": {iBUG: fraction}, "profile": {...}} from the photos' relative errors:
    front, each group's median over every front photo's points of that group; profile,
    each kept point's median over the profile photos."""
    out = {"front": {}, "profile": {}}
    fronts = [m for kind, m in measured if kind == "front"]
    for ids in GROUPS.values():
        e = [m[i] for m in fronts for i in ids if i in m]
        for i in ids:
            out["front"][i] = round(float(np.median(e)), 4) if e else None
    profiles = [m for kind, m in measured if kind == "profile"]
    for i in sorted({i for m in profiles for i in m}):
        out["profile"][i] = round(float(np.median([m[i] for m in profiles if i in m])), 4)
    return out


def outline_error(name, detector, image, truth):
    """Print and return the median and 90th percentile distance (px) of the detected
    outline's points to the true outline ``truth`` (m, 2) (points beyond its ends left
    out, and counted), the share of the truth within 3 px of the outline, and the time."""
    t = median_time(lambda: detector.outline(image, detector.detect(image)), repeats=3,
                    warmup=1)
    pts = t.result.points
    d, beyond = _distance_to_polyline(pts, truth)
    covered, _ = _distance_to_polyline(truth, pts)
    out = (float(np.median(d[~beyond])), float(np.percentile(d[~beyond], 90)),
           float(np.mean(covered < 3)))
    print(f"{name} outline: {len(pts)} points, {t.median:.2f} s (detect + outline); to the "
          f"true silhouette median {out[0]:.2f} px, p90 {out[1]:.2f} px; {int(beyond.sum())} "
          f"beyond its ends; {100 * out[2]:.0f} % of the truth within 3 px "
          f"({'; '.join(t.result.notes)})")
    return out


def photo_time(name, detector, image):
    """Print and return the median seconds of everything a photo gets (Auto Fit's
    detection of it): the face, its outline and the landmarks kept (a profile's read off
    the outline)."""
    from solver.detect.detected_case import face_landmarks

    def run():
        face = detector.detect(image)
        guess = guess_view(face)
        outline = detector.outline(image, face)
        return face_landmarks(face, image.shape[1::-1], guess.side if guess else None,
                              outline.points)

    t = median_time(run, repeats=5, warmup=1)
    print(f"{name}: face, outline and landmarks {t.median:.3f} s median "
          f"({len(t.result[0])} landmarks; target <= 0.3 s a photo)")
    return t.median


def _distance_to_polyline(points, line):
    a, b = line[:-1], line[1:]
    ab = b - a
    t = np.clip(((points[:, None] - a[None]) * ab[None]).sum(2)
                / np.maximum((ab * ab).sum(1), 1e-12), 0, 1)
    d = np.linalg.norm(points[:, None] - (a[None] + t[..., None] * ab[None]), axis=2)
    i = d.argmin(1)
    tt = t[np.arange(len(points)), i]
    beyond = ((i == 0) & (tt == 0)) | ((i == len(a) - 1) & (tt == 1))
    return d.min(1), beyond


PROFILE_LINE = ("nasion", "nose_tip", "subnasale", "lip_upper_middle", "mouth_middle",
                "lip_lower_middle", "pogonion", "chin_bottom")
#: The detector box's width over the nasion-to-menton distance on the rendered sample's
#: profile: the face's size the synthetic profiles are read with.
FACE_PER_HEIGHT = 1.215


def profile_line_errors(heads=20, seed=2000):
    """The profile line's points read off outlines (``solver.detect.profile_line``) of
    heads drawn from the model (``heads`` each in a right and a left profile, turned up to
    5 degrees, silhouettes traced with 1 px noise, a point every 3 px), against their
    landmark vertices' projections: per point the median and 90th percentile error (% of
    the face's size), how often it was not found, and the mean offset along the outline
    (% of the face's size, + away from the nose tip; the nose tip's + upward): what
    ``MEDIAN_ERROR`` and ``ARC_SHIFT`` say. Seeds from ``seed`` (``ARC_SHIFT`` was measured
    on 1000-1019, these are others)."""
    from solver import load_model
    from solver.detect.profile_line import profile_line_points
    from solver.synthetic import make_case, resample_polyline

    model = load_model()
    errors = {n: [] for n in PROFILE_LINE}
    along = {n: [] for n in PROFILE_LINE}
    heights = {n: [] for n in ("lip_upper_middle", "mouth_middle", "lip_lower_middle")}
    for k in range(heads):
        for view in ("right", "left"):
            _, truth = make_case(model, np.random.default_rng(seed + k), noise_px=0.0,
                                 views=(view,))
            traced = np.asarray(truth.contour[view])
            n = int(np.sum(np.linalg.norm(np.diff(traced, axis=0), axis=1)) / 3.0)
            rng = np.random.default_rng(seed + 500 + k)
            outline = resample_polyline(traced, n) + rng.normal(size=(n, 2))
            exact = truth.pixels[view]
            size = FACE_PER_HEIGHT * np.linalg.norm(exact["nasion"] - exact["chin_bottom"])
            top, bottom = exact["nasion"][1], exact["chin_bottom"][1]
            for name in heights:
                heights[name].append((exact[name][1] - top) / (bottom - top))
            points, _ = profile_line_points(outline, view, size,
                                            exact["nose_tip"] + rng.normal(0, 0.04 * size, 2))
            arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(outline, axis=0),
                                                                  axis=1))])
            tip = _arc_at(outline, arc, exact["nose_tip"])
            for name, p in points.items():
                errors[name].append(np.linalg.norm(np.subtract(p, exact[name])) / size)
                if name == "nose_tip":
                    up = np.sign(p[1] - exact[name][1])
                    along[name].append(up * abs(_arc_at(outline, arc, p) - tip) / size)
                else:
                    along[name].append((abs(_arc_at(outline, arc, exact[name]) - tip)
                                        - abs(_arc_at(outline, arc, p) - tip)) / size)
    print(f"profile line read off the outline ({2 * heads} profiles of model heads, 1 px "
          "outline noise), % of the face's size:")
    print("  point               median    p90  missing  along the outline (mean)")
    for name in PROFILE_LINE:
        e = 100 * np.asarray(errors[name])
        print(f"  {name:<18} {np.median(e):7.2f} {np.percentile(e, 90):6.2f} "
              f"{2 * heads - len(e):8d} {100 * np.mean(along[name]):+10.2f}")
    print("  the lips' heights (nasion 0, menton 1; the landmark vertices), mean +- sd: "
          + ", ".join(f"{n} {np.mean(h):.3f} +- {np.std(h):.3f}" for n, h in heights.items()))
    return errors


def _arc_at(outline, arc, point):
    return arc[int(np.argmin(np.linalg.norm(outline - np.asarray(point), axis=1)))]


def read_profile_line(detector, image, truth):
    """The profile line's points of a profile photo (H, W, 3) as the detection reads them
    off its detected outline: (px error by name against ``truth`` ({landmark name: (u,
    v)}, those it has), the points read, the face's size px, whether they were read off
    the outline)."""
    from solver.detect.detected_case import face_landmarks
    from solver.detect.view_guess import guess_view as guess

    face = detector.detect(image)
    side = guess(face).side if face is not None and guess(face) else None
    contour = detector.outline(image, face).points if side else None
    h, w = image.shape[:2]
    points, _, _, off = face_landmarks(face, (w, h), side, contour) if side else ({}, 0, 0, 0)
    err = {n: float(np.linalg.norm(np.subtract(p, truth[n]))) for n, p in points.items()
           if n in truth}
    size = face.face_size if face is not None else float("nan")
    return err, points, size, off


def profile_line_photo(name, detector, image, truth):
    """Print the px error of each profile line point read off a profile photo's detected
    outline against ``truth`` ({landmark name: (u, v)}, those it has)."""
    err, points, size, off = read_profile_line(detector, image, truth)
    print(f"{name}: profile line off its detected outline ({off and 'read' or 'not read'}; "
          f"face {size:.0f} px): " + ", ".join(f"{n} {e:.1f}" for n, e in err.items())
          + f" px; not found: {', '.join(n for n in PROFILE_LINE if n not in points) or '-'}")
    return err


def james_profile(folder):
    """james rendered as ``bench_realistic`` renders him: the right profile photo (uint8),
    its true outline (the scan's silhouette, its cut edges left out) and the scan's
    landmarks it shows, projected ({landmark name: (u, v)})."""
    from bench.realistic_cases import render_scan, scan_render_cases

    cases, moved, _, cams = scan_render_cases(load_scan(folder))
    photo = (render_scan(moved, cams["right"]) * 255).astype(np.uint8)
    view = cases["front + profile, projected"].views["right"]
    names = load_landmark_set().ibug
    truth = {names[int(k[4:])]: p for k, p in view.points.items()}
    return photo, view.contour, truth


def fit_errors(folder, detector):
    """Skin RMS (mm) of the sample's fit against the true head: the mean head; every exact
    landmark; the front's 68 iBUG points exact, detected as 1-px clicks, detected with
    their uncertainty (the profile as placed, with its outline, in these); and from the
    photos alone (``python -m solver detect front.png side.png``): the detected points
    without outlines, with the profile's traced outline, with its detected outline, and
    the case as written (both photos' detected outlines), also with its front's or its
    profile's points exact, and with the profile's points from the face mesh instead of
    its outline."""
    from solver import fit_head, load_landmarks, load_model
    from solver.detect.detected_case import detect_photos
    from solver.synthetic import skin_error_mm

    model = load_model()
    folder = Path(folder)
    case = load_landmarks(folder / "sample.json", known_names=model)
    truth = np.load(folder / "truth.npz", allow_pickle=True)["local_vertices"]
    print(f"fit, skin RMS vs the true head: mean head "
          f"{skin_error_mm(model, model.vertices, truth):.2f} mm")
    names = load_landmark_set().ibug

    def load(path):
        return np.asarray(Image.open(path).convert("RGB"))

    auto = detect_photos([(None, folder / "front.png"), (None, folder / "side.png")],
                         detector, load, base_dir=folder)
    if set(auto.views) != {"front", "right"}:
        print(f"  the photos were detected as {sorted(auto.views)}, not front and right")
        return
    detected, clicks, exact68 = (copy.deepcopy(case) for _ in range(3))
    detected.views["front"] = auto.views["front"]
    clicks.views["front"] = copy.deepcopy(auto.views["front"])
    clicks.views["front"].uncertainty = {}
    exact68.views["front"].points = {n: p for n, p in case.views["front"].points.items()
                                     if n in set(names.values())}
    bare = copy.deepcopy(auto)
    for v in bare.views.values():
        v.contour = None
    outlined = copy.deepcopy(bare)
    outlined.views["right"].contour = case.views["side"].contour
    profile_only = copy.deepcopy(auto)
    profile_only.views["front"].contour = None
    # the sample's own landmarks with the outlines detected (what the demo could use)
    own_profile = copy.deepcopy(case)
    own_profile.views["side"].contour = auto.views["right"].contour
    own_both = copy.deepcopy(own_profile)
    own_both.views["front"].contour = auto.views["front"].contour
    # the photos-only case with the front's points exact: what the detection's error costs
    exact_front68, exact_front = copy.deepcopy(auto), copy.deepcopy(auto)
    exact_front68.views["front"].points = dict(exact68.views["front"].points)
    exact_front.views["front"].points = dict(case.views["front"].points)
    for c in (exact_front68, exact_front):
        c.views["front"].uncertainty = {}
    # the profile's points read off its outline, exact instead (their uncertainty kept)
    exact_profile = copy.deepcopy(auto)
    side = case.views["side"].points
    exact_profile.views["right"].points = {n: side[n] for n in auto.views["right"].points
                                           if n in side}
    # the profile's points from the face mesh (its outline not read for them)
    mesh_profile = copy.deepcopy(auto)
    mesh_only = detect_photos([(None, folder / "front.png"), (None, folder / "side.png")],
                              detector, load, base_dir=folder, outlines="none")
    mesh_profile.views["right"].points = mesh_only.views["right"].points
    mesh_profile.views["right"].uncertainty = mesh_only.views["right"].uncertainty
    for label, c in (("every exact landmark", case),
                     ("  its profile outline detected", own_profile),
                     ("  both photos' outlines detected", own_both),
                     ("front: 68 exact", exact68),
                     ("front: 68 detected as clicks", clicks),
                     ("front: 68 detected, uncertainty", detected),
                     ("detected points, no outline", bare),
                     ("  + the traced profile outline", outlined),
                     ("  + the detected profile outline", profile_only),
                     ("solver detect's case (+ front outline)", auto),
                     ("  its front's 68 points exact", exact_front68),
                     ("  every front landmark exact", exact_front),
                     ("  its profile's points exact", exact_profile),
                     ("  its profile's points off the face mesh", mesh_profile)):
        r = fit_head(model, c)
        print(f"  {label:<32} {skin_error_mm(model, r.local_vertices, truth):.2f} mm")


def james_fit_errors(folder, detector, samples=4000):
    """Face RMS (mm) against the scan james (``bench_realistic``'s scoring): the mean head,
    the fit from its 68 landmarks projected exactly (self-calibrated pinholes), and from
    the case ``solver detect`` writes for its two photos (three-quarter views, pinholes).
    Returns those errors by label ("mean head", "68 projected exactly", "solver detect's
    case")."""
    from bench.bench_realistic import SCAN_SEED, scan_truth
    from bench.realistic_cases import scan_cases
    from solver import fit_head, load_model
    from solver.detect.detected_case import detect_photos

    model = load_model()
    scan = load_scan(folder)
    halves = scan_photo_halves(folder)
    auto = detect_photos([(None, p) for p in halves], detector, halves.__getitem__)
    cams = {p: calibrate(scan, p).camera for p in scan.photos}
    exact = scan_cases(scan, cams)[0]["pinhole, projected"]
    truth = scan_truth(model, scan, samples, np.random.default_rng(SCAN_SEED))
    out = {"mean head": truth.score(model.vertices)["face"]}
    print(f"james fit, face RMS vs the scan: mean head {out['mean head']:.2f} mm; views "
          f"detected: {', '.join(sorted(auto.views))}")
    for label, c in (("68 projected exactly", exact), ("solver detect's case", auto)):
        out[label] = truth.score(fit_head(model, c).local_vertices)["face"]
        print(f"  {label:<32} {out[label]:.2f} mm")
    return out


def padded(image, truth, factor):
    """``image`` in the middle of a photo ``factor`` times its size (its corner's colour
    around it), and its true points moved with it: a face as small as a photo taken from
    further away shows it."""
    h, w = image.shape[:2]
    big = np.empty((int(factor * h), int(factor * w), 3), np.uint8)
    big[:] = image[2, 2]
    at = np.array([(big.shape[1] - w) // 2, (big.shape[0] - h) // 3])
    big[at[1]:at[1] + h, at[0]:at[0] + w] = image
    return big, {i: np.asarray(p, float) + at for i, p in truth.items()}


def small_faces(name, detector, image, truth, factors=(1, 2, 3, 4, 6)):
    """Each photo's face made small (:func:`padded`): found or not, its box, the median
    landmark error (% of the eye-to-mouth distance) and the time."""
    scale = eye_to_mouth(truth)
    for factor in factors:
        big, moved = padded(image, truth, factor)
        t = median_time(lambda b=big: detector.detect(b), repeats=1, warmup=0)
        face = t.result
        size = f"{big.shape[1]}x{big.shape[0]}"
        if face is None:
            print(f"  {name} x{factor} ({size}): no face found ({t.median:.2f} s)")
            continue
        err = np.median([np.linalg.norm(face.ibug[i - 1] - p) for i, p in moved.items()])
        print(f"  {name} x{factor} ({size}): face box {face.face_size:.0f} px "
              f"({face.face_size / max(big.shape[:2]):.2f} of the longer side), median "
              f"error {err:.1f} px ({100 * err / scale:.1f} %), {t.median:.2f} s")


def second_face(detector, folder, scales=(0.3, 0.45, 0.6)):
    """The sample's two photos with a smaller copy of its front face pasted in a top
    corner (someone further back): which face is taken (the subject's, by its box's
    overlap with the face found on the photo alone), and how many others are reported."""
    from PIL import Image

    front = Image.open(Path(folder) / "front.png").convert("RGB")
    u0, v0, u1, v1 = detector.detect(np.asarray(front)).box
    m = 0.2 * (u1 - u0)
    face = front.crop((int(u0 - m), int(v0 - m), int(u1 + m), int(v1 + 2 * m)))
    for view in ("front", "side"):
        photo = Image.open(Path(folder) / f"{view}.png").convert("RGB")
        alone = detector.detect(np.asarray(photo)).box
        for scale in scales:
            small = face.resize((int(face.width * scale), int(face.height * scale)))
            both = photo.copy()
            both.paste(small, (photo.width - small.width - 2 if view == "front" else 2, 2))
            found = detector.detect(np.asarray(both))
            subject = np.abs(found.box - alone).max() < 0.1 * (alone[2] - alone[0])
            print(f"  sample {view} with a face {scale:.2f} of its size in a corner: "
                  f"{'the subject' if subject else 'the other face'} taken "
                  f"(score {found.score:.2f}), {found.others} other(s) reported")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sample", default=str(ROOT / "generated" / "sample"))
    ap.add_argument("--james", default=None)
    ap.add_argument("--fit", action="store_true",
                    help="also fit the sample from detected front landmarks")
    ap.add_argument("--profile-line", action="store_true",
                    help="also measure the profile line read off outlines of model heads")
    ap.add_argument("--small-faces", action="store_true",
                    help="also detect each front photo placed in a 2-6 times larger one")
    ap.add_argument("--uncertainty", action="store_true",
                    help="print the per-group relative errors (the uncertainty table)")
    ap.add_argument("--second-face", action="store_true",
                    help="also detect the sample's photos with a smaller face pasted in")
    ap.add_argument("--bias", action="store_true",
                    help="print each landmark's mean signed error on the ten rendered heads "
                         "and on james' photos")
    args = ap.parse_args(argv)
    print(f"machine: {machine_description()}")
    detector = Detector()
    measured = []
    if (Path(args.sample) / "truth.npz").is_file():
        front = sample_truth(args.sample)
        measured.append(report("sample front", detector, *front))
        photo_time("sample front", detector, front[0])
        side = sample_truth(args.sample, "side")
        photo_time("sample side", detector, side[0])
        measured.append(report("sample side (right profile)", detector, *side))
        measured.append(report("sample side mirrored (left profile)", detector,
                               *mirrored(*side)))
        contour = json.loads((Path(args.sample) / "sample.json").read_text())
        outline_error("sample side", detector, side[0],
                      np.asarray(contour["views"]["side"]["contour"], float))
        truth = np.load(Path(args.sample) / "truth.npz", allow_pickle=True)
        names = json.loads(str(truth["landmark_names"]))["side"]
        profile_line_photo("sample side", detector, side[0],
                           dict(zip(names, truth["exact_side"], strict=True)))
        if args.fit:
            fit_errors(args.sample, detector)
    else:
        print(f"sample: {args.sample} has no truth.npz (./run sample); skipped")
    folder = Path(args.james) if args.james else james_folder(ROOT)
    if (folder / "james.obj").is_file():
        for name, image, truth in james_truth(folder):
            measured.append(report(name, detector, image, truth))
        photo, silhouette, truth = james_profile(folder)
        outline_error("james rendered profile", detector, photo, silhouette)
        profile_line_photo("james rendered profile", detector, photo, truth)
        if args.fit:
            james_fit_errors(folder, detector)
    else:
        print(f"james: {folder} not found; skipped")
    if args.small_faces:
        print("small faces (each photo in the middle of a larger one; one run each):")
        if (Path(args.sample) / "truth.npz").is_file():
            small_faces("sample front", detector, *sample_truth(args.sample))
        if (folder / "james.obj").is_file():
            for name, image, truth in james_truth(folder):
                small_faces(name, detector, image, truth)
        grey = np.full((4032, 3024, 3), 128, np.uint8)
        t = median_time(lambda: detector.detect(grey), repeats=1, warmup=0)
        print(f"  a grey 3024x4032 photo: {'no face' if t.result is None else 'a face'} "
              f"in {t.median:.2f} s")
    if args.second_face and (Path(args.sample) / "front.png").is_file():
        print("a second face (the sample's front face, smaller, pasted in a top corner):")
        second_face(detector, args.sample)
    if args.profile_line:
        profile_line_errors()
    if args.bias:
        from bench.rendered_heads import TEN_HEADS, head_folders

        groups = {"rendered": [sample_truth(f) for f in head_folders(None, TEN_HEADS)]}
        if (folder / "james.obj").is_file():
            groups["james"] = [(image, truth) for _, image, truth in james_truth(folder)]
        landmark_bias(detector, groups)
    if args.uncertainty:
        table = uncertainty_table([m for m in measured if m is not None])
        print("uncertainty (median error / detector box width):")
        print(json.dumps({k: {str(i): f for i, f in v.items()} for k, v in table.items()}))


if __name__ == "__main__":
    main()
