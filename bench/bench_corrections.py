"""The artist's corrections: heads fitted from their photos alone (both photos detected, as
Auto Fit takes them), then with each group of the front photo's detected iBUG points
replaced by the exact ones, as an artist correcting the detection would place them (a
moved landmark forgets the detector's uncertainty and depth, as in Blender).
A correction should never make the head much worse; a fit left in a wrong minimum does.

    python -m bench.bench_corrections [--heads DIR ...] [--render SEED ...] [--always]
                                      [--variant VARIANT] [--from-photos]

Heads: rendered sample folders (``python -m tools.make_sample --seed N --out DIR``: the
front and profile photos, ``sample.json`` with the exact landmarks, ``truth.npz`` with the
true head); default the sample (``./run sample``) and ``generated/bench_heads/seed<N>``
for each ``--render`` seed, rendered there first when missing (about 45 s a head).
Scores: skin RMS against the true head after a similarity (``skin_error_mm``), mm, for the
photos alone, each group exact (jaw 1-17, brows 18-27, nose 28-36, eyes 37-48, mouth
49-68), all 68 exact, the profile's four ear points added by hand (the detector finds no
ear), and every landmark of both photos exact (``sample.json``). Each fit is scored as
the fit is ("fit") and with no second start ("once": run again with
``fit.MISSED_OUTLINE`` beyond reach where a second start ran, else the same fit); "*"
marks a fit whose second start was kept.
The last lines give the mean and the worst of each column, and how many fits end more
than 1.5 x the photos-only error of their head. ``--always`` runs the second start on
every fit ("fit" column; ``fit.MISSED_OUTLINE`` below 0): what the rule leaves untried.
``--variant`` detects each head's photos as one of ``bench_photo_variants``' variants show
them (``hair``: as most people come), the exact landmarks placed as before.
``--from-photos`` scores each correction also from the photos-only fit (as scored), as
Blender gives it to the artist: "live" the live refit while the points are moved
(``refit_landmarks``: that fit's cameras and outline kept), "continued" a fit from that
fit's head (``fit_head(initial=...)``); the usual fits start from the mean head.
"""

import argparse
import copy
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

from bench.bench_photo_variants import VARIANTS, changed
from bench.common import machine_description
from bench.realistic_cases import FACE_PARTS
from bench.rendered_heads import add_head_options, chosen_folders
from solver import fit_head, load_landmarks, load_model
from solver.detect import Detector
from solver.detect.detected_case import detect_photos
from solver.fitting import fit
from solver.fitting.fit import refit_landmarks
from solver.io.landmark_set import load_landmark_set
from solver.synthetic import skin_error_mm

GROUPS = {**FACE_PARTS, "all 68": range(1, 69)}
#: A fit this many times its head's photos-only error counts as made worse by a correction.
WORSE = 1.5


def corrected_cases(folder, model, detector, photos=None):
    """(label, case) of one head: the photos-only case and its corrections, and the case of
    every exact landmark; None when the photos were not detected as front and profile.
    ``photos``: the folder whose front.png and side.png are detected (default ``folder``;
    the exact landmarks are always ``folder``'s)."""
    photos = folder if photos is None else photos
    exact = load_landmarks(folder / "sample.json", known_names=model)
    auto = detect_photos([(None, photos / "front.png"), (None, photos / "side.png")],
                         detector, lambda p: np.asarray(Image.open(p).convert("RGB")),
                         base_dir=photos)
    if set(auto.views) != {"front", "right"}:
        return None
    names = load_landmark_set().ibug
    placed = exact.views["front"].points
    out = [("photos", auto)]
    for group, numbers in GROUPS.items():
        case = copy.deepcopy(auto)
        front = case.views["front"]
        for n in (names.get(i) for i in numbers):
            if n in front.points and n in placed:
                front.points[n] = placed[n]  # hand-placed: no uncertainty, no depth
                front.uncertainty.pop(n, None)
                front.depth.pop(n, None)
        out.append((group, case))
    case = copy.deepcopy(auto)  # the profile's ear points added by hand
    side = exact.views["side"].points
    case.views["right"].points.update({n: p for n, p in side.items() if n.startswith("ear_")})
    out.append(("profile ears", case))
    out.append(("every exact", exact))
    return out


def fit_errors(model, case, truth, always=False):
    """(skin RMS mm as the fit is, whether its second start's head was kept, skin RMS mm
    with no second start, the fit as it is). Without a second start the two fits are
    one."""
    missed = fit.MISSED_OUTLINE
    fit.MISSED_OUTLINE = -1.0 if always else missed
    try:
        res = fit_head(model, case)
        starts = res.info.get("starts")
        err = skin_error_mm(model, res.local_vertices, truth)
        if starts is None:
            return err, False, err, res
        fit.MISSED_OUTLINE = float("inf")
        once = fit_head(model, case)
    finally:
        fit.MISSED_OUTLINE = missed
    return err, starts["kept"] != "continued", skin_error_mm(model, once.local_vertices,
                                                             truth), res


def from_photos_errors(model, case, photos_fit, truth):
    """(skin RMS mm of the live refit of ``case`` from ``photos_fit``, of the fit continued
    from it): the two heads Blender gives an artist who corrects the photos-only fit. NaN
    for a case of other views (``sample.json``'s every exact landmark)."""
    if set(case.views) != set(photos_fit.cameras):
        return float("nan"), float("nan")
    live = refit_landmarks(model, case, photos_fit)
    continued = fit_head(model, case, initial=photos_fit)
    return (skin_error_mm(model, live.local_vertices, truth),
            skin_error_mm(model, continued.local_vertices, truth))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    add_head_options(ap, render=[])
    ap.add_argument("--always", action="store_true",
                    help="run the second start on every fit, not only on heads that miss "
                         "their outline")
    ap.add_argument("--variant", choices=list(VARIANTS), default=None,
                    help="detect the photos changed as bench_photo_variants changes them")
    ap.add_argument("--from-photos", action="store_true",
                    help="also score each correction from the photos-only fit: its live "
                         "refit and a fit continued from its head")
    args = ap.parse_args(argv)
    print(f"machine: {machine_description()}")
    folders = chosen_folders(args)
    model, detector = load_model(), Detector()
    columns = ["photos", *GROUPS, "profile ears", "every exact"]
    print("skin RMS vs the true head, mm: fit / once (no second start); * second start kept"
          + (" (run on every fit)" if args.always else "")
          + (f"; photos: {args.variant}" if args.variant else ""))
    print(f"  {'head':<16}" + "".join(f"{c:>16}" for c in columns))
    table = {"fit": [], "once": []}
    if args.from_photos:
        table.update({"live": [], "continued": []})
    with tempfile.TemporaryDirectory() as tmp:
        for folder in folders:
            if not (folder / "truth.npz").is_file():
                print(f"  {folder}: no truth.npz; skipped")
                continue
            photos = None if args.variant is None else changed(
                folder, args.variant, Path(tmp) / folder.name, detector)
            cases = corrected_cases(folder, model, detector, photos)
            if cases is None:
                print(f"  {folder}: the photos were not detected as front and right; skipped")
                continue
            truth = np.load(folder / "truth.npz", allow_pickle=True)["local_vertices"]
            row = {k: [] for k in table}
            cells = []
            photos_fit = None  # the first case's fit (the photos alone) as scored
            for _, case in cases:
                e, kept, once, res = fit_errors(model, case, truth, args.always)
                row["fit"].append(e)
                row["once"].append(once)
                cells.append(f"{e:.2f}{'*' if kept else ' '}/{once:.2f}")
                if args.from_photos:
                    photos_fit = photos_fit or res
                    live, continued = from_photos_errors(model, case, photos_fit, truth)
                    row["live"].append(live)
                    row["continued"].append(continued)
            for k in table:
                table[k].append(row[k])
            print(f"  {folder.name:<16}" + "".join(f"{c:>16}" for c in cells), flush=True)
            if args.from_photos:
                print(f"  {'  live/cont.':<16}" + "".join(
                    f"{_mm(a):>11}/{_mm(b):<4}" for a, b in zip(row["live"], row["continued"],
                                                             strict=True)), flush=True)
    if not table["fit"]:
        return
    for k, rows in table.items():
        a = np.array(rows)
        worse = int((a[:, 1:-1] > WORSE * a[:, :1]).sum())
        print(f"  {'mean ' + k:<16}" + "".join(f"{_mm(v):>16}" for v in a.mean(axis=0)))
        print(f"  {'worst ' + k:<16}" + "".join(f"{_mm(v):>16}" for v in a.max(axis=0)))
        print(f"  {k}: {worse} of {a[:, 1:-1].size} corrected fits worse than {WORSE} x "
              "their head's photos-only error")


def _mm(value):
    """A table cell: millimetres to two decimals, "-" for none (NaN)."""
    return "-" if np.isnan(value) else f"{value:.2f}"


if __name__ == "__main__":
    main()
