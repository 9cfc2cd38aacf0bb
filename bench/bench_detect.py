"""Automatic landmarks: time per photo, and detected vs true iBUG-68 landmarks in pixels
(median, 90th percentile, per group; also as % of the eye-to-mouth distance).

    python -m bench.bench_detect [--sample generated/sample] [--james FOLDER] [--fit]

Photos: the rendered sample's front photo (``./run sample``; truth: the exact landmark
pixels in ``truth.npz``) and the two real photos of the scan "james" (its texture's
halves, cut and calibrated as ``bench.realistic_cases`` does; truth: the scan's 68
landmarks projected through each photo's DLT, those the photo shows). A missing photo
set is reported and skipped. ``--fit`` also fits the sample with the front photo's
landmarks detected (the profile's still as placed) and compares with the exact ones
(skin RMS in mm against the true head, ``solver.synthetic.skin_error_mm``).
"""

import argparse
import copy
import json
from pathlib import Path

import numpy as np
from PIL import Image

from bench.common import machine_description, median_time
from bench.realistic_cases import calibrate, james_folder, load_scan, scan_landmarks
from solver.detect import Detector
from solver.io.landmark_set import load_landmark_set

ROOT = Path(__file__).resolve().parent.parent
GROUPS = {"jaw": range(1, 18), "brows": range(18, 28), "nose": range(28, 37),
          "eyes": range(37, 49), "mouth": range(49, 69)}


def sample_truth(folder):
    """(photo uint8 (H, W, 3), {iBUG number: (u, v)}) of the sample's front photo."""
    folder = Path(folder)
    truth = np.load(folder / "truth.npz", allow_pickle=True)
    names = json.loads(str(truth["landmark_names"]))["front"]
    number = {n: i for i, n in load_landmark_set().ibug.items()}
    pts = {number[n]: p for n, p in zip(names, truth["exact_front"], strict=True) if n in number}
    return np.asarray(Image.open(folder / "front.png").convert("RGB")), pts


def james_truth(folder):
    """[(name, photo, {iBUG number: (u, v)})] of the scan's two real photos."""
    scan = load_scan(folder)
    image = np.asarray(Image.open(Path(folder) / "james.jpg").convert("RGB"))
    half = image.shape[1] // 2
    out = []
    for photo, x0 in (("photo_a", 0), ("photo_b", half)):
        numbers, px = scan_landmarks(scan, calibrate(scan, photo).camera)
        out.append((f"james {photo}", image[:, x0:x0 + half], dict(zip(numbers, px, strict=True))))
    return out


def eye_to_mouth(pts):
    eyes = np.mean([pts[i] for i in range(37, 49) if i in pts], axis=0)
    mouth = np.mean([pts[i] for i in (49, 55) if i in pts], axis=0)
    return float(np.linalg.norm(eyes - mouth))


def report(name, detector, image, truth):
    t = median_time(lambda: detector.detect(image), repeats=5, warmup=1)
    face = t.result
    h, w = image.shape[:2]
    print(f"{name}: {w}x{h} px, detect median {t.median:.3f} s (min {t.min:.3f}, "
          f"CPU {t.cpu_median:.3f} s)")
    if face is None or not face.is_face:
        print("  no face found" if face is None else
              f"  a face (score {face.score:.2f}) the mesh does not see "
              f"(presence {face.presence:.2f})")
        return
    scale = eye_to_mouth(truth)
    err = {i: float(np.linalg.norm(face.ibug[i - 1] - truth[i])) for i in truth}
    rows = [("all", list(err))] + [(g, [i for i in r if i in err]) for g, r in GROUPS.items()]
    print(f"  eye-to-mouth {scale:.0f} px; error px median / p90 (median % of eye-to-mouth)")
    for g, ids in rows:
        if ids:
            e = np.array([err[i] for i in ids])
            print(f"  {g:<6} n={len(ids):2d}  {np.median(e):5.1f} / {np.percentile(e, 90):5.1f}"
                  f"  ({100 * np.median(e) / scale:.1f} %)")


def fit_errors(folder, detector):
    """Skin RMS (mm) of the sample's fit: mean head, every exact landmark, the front's 68
    iBUG points detected or exact (the profile as placed, with its outline, in both)."""
    from solver import fit_head, load_landmarks, load_model
    from solver.synthetic import skin_error_mm

    model = load_model()
    folder = Path(folder)
    case = load_landmarks(folder / "sample.json", known_names=model)
    truth = np.load(folder / "truth.npz", allow_pickle=True)["local_vertices"]
    print(f"fit, skin RMS vs the true head: mean head "
          f"{skin_error_mm(model, model.vertices, truth):.2f} mm")
    names = load_landmark_set().ibug
    image = np.asarray(Image.open(folder / "front.png").convert("RGB"))
    face = detector.detect(image)
    if face is None or not face.is_face:
        print("  no face found in the front photo")
        return
    detected, exact68 = copy.deepcopy(case), copy.deepcopy(case)
    detected.views["front"].points = {names[i]: tuple(face.ibug[i - 1]) for i in names}
    exact68.views["front"].points = {n: p for n, p in case.views["front"].points.items()
                                     if n in set(names.values())}
    for label, c in (("every exact landmark", case), ("front: 68 exact", exact68),
                     ("front: 68 detected", detected)):
        r = fit_head(model, c)
        print(f"  {label:<22} {skin_error_mm(model, r.local_vertices, truth):.2f} mm")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sample", default=str(ROOT / "generated" / "sample"))
    ap.add_argument("--james", default=None)
    ap.add_argument("--fit", action="store_true",
                    help="also fit the sample from detected front landmarks")
    args = ap.parse_args(argv)
    print(f"machine: {machine_description()}")
    detector = Detector()
    if (Path(args.sample) / "truth.npz").is_file():
        report("sample front", detector, *sample_truth(args.sample))
        if args.fit:
            fit_errors(args.sample, detector)
    else:
        print(f"sample: {args.sample} has no truth.npz (./run sample); skipped")
    folder = Path(args.james) if args.james else james_folder(ROOT)
    if (folder / "james.obj").is_file():
        for name, image, truth in james_truth(folder):
            report(name, detector, image, truth)
    else:
        print(f"james: {folder} not found; skipped")


if __name__ == "__main__":
    main()
