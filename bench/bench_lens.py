"""Photos taken with a known lens: heads photographed by pinhole cameras (a front and a
right profile, as close as the lens frames the head: 50 mm about half a metre, 85 mm
about a metre) and fitted from the photos alone, as Auto Fit and ``solver detect`` take
them: each photo's camera a pinhole of the lens its EXIF gives, held near the view's
direction (the default), against the same photos taken as parallel projections (what
photos without EXIF get), and the fit from every exact landmark (``sample.json``, its
cameras self-calibrated with the lens).

    python -m bench.bench_lens [--lens MM ...] [--render SEED ...] [--heads DIR ...]
                               [--direction-sigma DEG ...] [--given-lens MM ...] [--yaw DEG]

Heads: ``generated/bench_heads/seed<N>_lens<MM>`` for each ``--render`` seed and
``--lens``, rendered there first when missing (``tools.make_sample --lens``, about 45 s a
head: JPEG photos with the lens in their EXIF), or given folders; with ``--yaw`` the head
turned by that much more (``..._yaw<DEG>``; -45: two three-quarter photos, -30: a
three-quarter front photo and a side photo 60 degrees from the front). Scores: skin RMS
against the true head after a similarity (``skin_error_mm``), mm, and each fit's wall
time; the mean head's beside them.
``--direction-sigma`` adds a column per value: the EXIF-lens fit with that standard
deviation of the cameras' direction prior instead of ``photo_lens.DIRECTION_SIGMA_DEG``.
``--given-lens`` adds a column per value: the photos as if their EXIF were gone (a
messaging app's copies) and that lens given (``solver detect --lens``), right or not.
"""

import argparse
import copy
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image

from bench.common import machine_description
from bench.rendered_heads import photo_path
from solver import fit_head, load_landmarks, load_model
from solver.detect import Detector
from solver.detect.detected_case import detect_photos
from solver.io import photo_lens
from solver.synthetic import skin_error_mm

ROOT = Path(__file__).resolve().parent.parent
COLUMNS = ("EXIF lens", "orthographic", "every exact")


def render_head(seed, lens, folder, yaw=0.0):
    """Render a model head's perspective photos into ``folder`` unless they are there
    (the head turned ``yaw`` degrees more, ``tools.make_sample --yaw``)."""
    if (folder / "truth.npz").is_file():
        return
    print(f"rendering seed {seed} with a {lens:g} mm lens into {folder} ...", flush=True)
    subprocess.run([sys.executable, "-m", "tools.make_sample", "--seed", str(seed),
                    "--lens", str(lens), "--yaw", str(yaw), "--out", str(folder)], cwd=ROOT,
                   check=True, stdout=subprocess.DEVNULL)


def head_cases(folder, model, detector, sigmas=(), given=()):
    """(label, case) of one head: the photos detected with their EXIF lens, the same taken
    as orthographic, every exact landmark, the EXIF-lens case with each of ``sigmas``
    (degrees) as its cameras' direction prior, and the photos without their EXIF with
    each of ``given`` (mm) as their lens."""
    photos = [(None, photo_path(folder, name)) for name in ("front", "side")]

    def load(path):
        return np.asarray(Image.open(path).convert("RGB"))

    lens = detect_photos(photos, detector, load, base_dir=folder)
    out = [(COLUMNS[0], lens),
           (COLUMNS[1], detect_photos(photos, detector, load, base_dir=folder,
                                      exif_lens=False)),
           (COLUMNS[2], load_landmarks(folder / "sample.json", known_names=model))]
    for sigma in sigmas:
        case = copy.deepcopy(lens)
        for view in case.views.values():
            if "direction_prior" in view.camera_hints:
                view.camera_hints["direction_prior"][1] = float(sigma)
        out.append((f"sigma {sigma:g} deg", case))
    for lens_mm in given:
        out.append((f"given {lens_mm:g} mm", detect_photos(
            photos, detector, load, base_dir=folder, exif_lens=False, lens_mm=lens_mm)))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lens", nargs="*", type=float, default=[50.0, 85.0],
                    help="lenses (mm, 36 mm equivalent) of the rendered heads "
                         "(default: 50 85)")
    ap.add_argument("--render", nargs="*", type=int, default=[7, 201, 202, 203],
                    help="model seeds rendered into generated/bench_heads/seed<N>_lens<MM> "
                         "if missing (default: 7 201 202 203)")
    ap.add_argument("--heads", nargs="*", default=[],
                    help="more rendered folders with front and side photos (.jpg or "
                         ".png: a PNG has no EXIF, as a parallel render by "
                         "tools.make_sample)")
    ap.add_argument("--direction-sigma", nargs="*", type=float, default=[],
                    help="also fit with these standard deviations (degrees) of the cameras' "
                         f"direction prior (default {photo_lens.DIRECTION_SIGMA_DEG:g})")
    ap.add_argument("--given-lens", nargs="*", type=float, default=[],
                    help="also fit the photos without their EXIF, each of these lenses (mm) "
                         "given instead")
    ap.add_argument("--yaw", type=float, default=0.0,
                    help="the rendered heads turned by this much more, degrees (negative: "
                         "toward the side camera; default 0)")
    args = ap.parse_args(argv)
    print(f"machine: {machine_description()}")
    folders = [Path(h) for h in args.heads]
    turned = f"_yaw{args.yaw:g}" if args.yaw else ""
    for lens in args.lens:
        for seed in args.render:
            folder = ROOT / "generated" / "bench_heads" / f"seed{seed}_lens{lens:g}{turned}"
            render_head(seed, lens, folder, args.yaw)
            folders.append(folder)
    model, detector = load_model(), Detector()
    print("skin RMS vs the true head, mm (fit wall time, s)")
    columns = ["mean head", *COLUMNS, *(f"sigma {s:g} deg" for s in args.direction_sigma),
               *(f"given {g:g} mm" for g in args.given_lens)]
    print(f"  {'head':<18}" + "".join(f"{c:>20}" for c in columns))
    errors = []
    for folder in folders:
        truth = np.load(folder / "truth.npz", allow_pickle=True)["local_vertices"]
        row = [skin_error_mm(model, model.vertices, truth)]
        cells = [f"{row[0]:.2f}"]
        for _, case in head_cases(folder, model, detector, args.direction_sigma,
                                  args.given_lens):
            t0 = time.perf_counter()
            res = fit_head(model, case)
            wall = time.perf_counter() - t0
            row.append(skin_error_mm(model, res.local_vertices, truth))
            cells.append(f"{row[-1]:.2f} ({wall:.1f})")
        errors.append(row)
        print(f"  {folder.name:<18}" + "".join(f"{c:>20}" for c in cells), flush=True)
    if errors:
        a = np.array(errors)
        print(f"  {'mean':<18}" + "".join(f"{v:>20.2f}" for v in a.mean(axis=0)))
        print(f"  {'worst':<18}" + "".join(f"{v:>20.2f}" for v in a.max(axis=0)))
        beats = (a[:, 1:] < a[:, :1]).sum(axis=0)
        print(f"  {'beat mean':<18}" + " " * 20
              + "".join(f"{f'{b} of {len(a)}':>20}" for b in beats))


if __name__ == "__main__":
    main()
