"""Large and small photos: heads fitted from their photos alone (detected, as Auto Fit
takes them) at the size they were rendered (1024 px high) and with the same photos
resized (a phone's 12-megapixel photo is 4032 px on its long side, ``--scale 4``; a
webcam's or a web page's photo 512 px or less, ``--scale 0.5``), with the fit's pixel
settings scaled to the head's size in the photos (the default, ``FitOptions.pixel_scale``
None) and as given (``pixel_scale=1``).

    python -m bench.bench_photo_size [--scale K ...] [--heads DIR ...] [--render SEED ...]

Heads: the sample (``./run sample``) and ``generated/bench_heads/seed<N>`` for each
``--render`` seed (rendered there first when missing, ``tools.make_sample``, about 45 s a
head); the resized photos (bicubic up, Lanczos down) are written to a temporary folder.
Scores: skin RMS against the true head after a similarity (``skin_error_mm``), mm, and
each fit's wall time, s.
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

from bench.common import machine_description
from bench.rendered_heads import add_head_options, chosen_folders, photo_path
from solver import FitOptions, fit_head, load_model
from solver.cli import load_photo
from solver.detect import Detector
from solver.detect.detected_case import detect_photos
from solver.fitting.views import photo_scale
from solver.synthetic import skin_error_mm


def resized(folder, scale, into):
    """The head's two photos ``scale`` times the size (bicubic up, Lanczos down), written
    into ``into``."""
    into.mkdir(parents=True, exist_ok=True)
    for view in ("front", "side"):
        image = Image.open(folder / f"{view}.png").convert("RGB")
        size = (round(image.width * scale), round(image.height * scale))
        image.resize(size, Image.BICUBIC if scale > 1 else Image.LANCZOS) \
            .save(into / f"{view}.png")
    return into


def photos_case(folder, detector):
    """The case ``solver detect`` makes of a folder's front and side photos
    (``rendered_heads.photo_path``: a JPEG's EXIF lens makes its camera a pinhole), read
    as it reads them (``cli.load_photo``: a cut-out keeps its alpha)."""
    return detect_photos([(None, photo_path(folder, "front")),
                          (None, photo_path(folder, "side"))],
                         detector, load_photo, base_dir=folder)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scale", nargs="*", type=float, default=[4.0],
                    help="how many times the photos' size they are made (default 4; 0.5: "
                         "half)")
    add_head_options(ap)
    args = ap.parse_args(argv)
    print(f"machine: {machine_description()}")
    folders = chosen_folders(args)
    model, detector = load_model(), Detector()
    columns = ["as rendered"] + [f"x{k:g} {label}" for k in args.scale
                                 for label in ("scaled", "as given")]
    print("skin RMS vs the true head, mm (fit wall time, s); photo_scale of the last size")
    print(f"  {'head':<10}" + "".join(f"{c:>18}" for c in columns))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for folder in folders:
            truth = np.load(folder / "truth.npz", allow_pickle=True)["local_vertices"]
            runs = [(photos_case(folder, detector), None)]
            for k in args.scale:
                case = photos_case(resized(folder, k, Path(tmp) / f"{folder.name}_x{k:g}"),
                                   detector)
                runs += [(case, None), (case, FitOptions(pixel_scale=1.0))]
            row, cells = [], []
            for case, opts in runs:
                t0 = time.perf_counter()
                res = fit_head(model, case, opts)
                wall = time.perf_counter() - t0
                row.append(skin_error_mm(model, res.local_vertices, truth))
                cells.append(f"{row[-1]:.2f} ({wall:.1f})")
            rows.append(row)
            print(f"  {folder.name:<10}" + "".join(f"{c:>18}" for c in cells)
                  + f"   {photo_scale(model, runs[-1][0]):.2f}", flush=True)
    a = np.array(rows)
    print(f"  {'mean':<10}" + "".join(f"{v:>18.2f}" for v in a.mean(axis=0)))
    print(f"  {'worst':<10}" + "".join(f"{v:>18.2f}" for v in a.max(axis=0)))


if __name__ == "__main__":
    main()
