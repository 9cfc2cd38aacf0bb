"""What the photos-only fit loses to its detected landmarks and to its detected outlines:
each rendered head fitted from the case ``solver detect`` makes of its two photos, then
from the same case with the front photo's landmarks at their exact pixels (the detector's
uncertainty kept, and as exact clicks without it), with every outline point moved onto the
true silhouette (the nearest point of the head's render alpha at 0.5: the outline's
extent and order as detected, its error taken out), and with both.

    python -m bench.bench_attribution [--heads DIR ...] [--render SEED ...] [--skin TONE]
                                      [--expression NAME] [--copies N] [--copy-px PX]
                                      [--only LABEL ...] [--regions]

Heads: as ``bench.bench_photo_variants`` (the sample and ``generated/bench_heads/seed<N>``,
rendered when missing; ``--skin`` and ``--expression`` as ``bench.rendered_heads`` takes
them: with an expression the photos show it and the head is scored against the neutral
one), or given folders: ``bench_lens``'s too (``--render --heads
generated/bench_heads/seed7_lens85``, ``--render`` with no seed so that only the folders
given run: JPEG photos whose EXIF lens makes each camera a pinhole; with its ``--yaw`` the
front photo a three-quarter view, scored as the front).
Scores: skin RMS against the true head after a similarity
(``solver.synthetic.skin_error_mm``), mm; a head whose photos are not detected as a front
(or three-quarter view) and a profile is said and left out. A photos-only fit lands in
one of several nearby minima, and which one moves with a tenth of a pixel: ``--copies N``
fits each case and N - 1 copies of it with every point moved by ``COPY_PX`` (seeded) and
prints their mean, and the spread of a head's copies (their largest less their smallest,
mean over the heads);
``--copy-px`` moves them further (0.3 px shows the far minima a change to the fit may fall
into, which one fit per head hides: docs/DECISIONS.md), and ``--only`` fits the columns
named (``--only detected``: the default fit alone, a fifth of the time). ``--regions``
prints under each head its error over each region of the skin (``bench.head_regions``: the
face, the ears, the back of the head, the rest; the same similarity as the whole skin's):
the spread of a photos-only fit's copies lies at the ears and the back, which no photo
shows (docs/DECISIONS.md).
"""

import argparse
import copy
import json

import numpy as np
from scipy.spatial import cKDTree

from bench.bench_photo_size import photos_case
from bench.common import machine_description
from bench.head_regions import region_errors, skin_regions
from bench.rendered_heads import add_head_options, chosen_folders
from solver import fit_head, load_model
from solver.detect import Detector
from solver.detect.iso_line import iso_lines
from solver.synthetic import skin_error_mm

#: The true silhouette is sampled this often along its iso-line (pixels): a point moved
#: onto it lands within half of it of the line.
SILHOUETTE_STEP_PX = 0.1

#: How far (standard deviation, px) ``--copies`` moves every point of a copy of a case.
COPY_PX = 0.05

#: The view names ``solver detect`` gives a profile photo.
PROFILE_VIEWS = ("right", "left")

#: The fits of each head, in the table's order: label -> (front's landmarks exact, their
#: uncertainty dropped, outlines moved onto the true silhouette).
ATTRIBUTIONS = {
    "detected": (False, False, False),
    "front exact": (True, False, False),
    "front exact clicks": (True, True, False),
    "true outlines": (False, False, True),
    "both": (True, False, True),
}


def true_silhouette(alpha, step=SILHOUETTE_STEP_PX):
    """Points every ``step`` px along the 0.5 iso-lines of a render's ``alpha`` (H, W) in
    [0, 1] or [0, 255] uint8, (k, 2) photo pixels (pixel (r, c) covers [c, c + 1) x
    [r, r + 1))."""
    a = np.asarray(alpha, dtype=np.float64)
    if np.asarray(alpha).dtype == np.uint8:
        a = a / 255.0
    parts = []
    for line in iso_lines(a):
        closed = np.vstack([line, line[:1]]) + 0.5
        seg = np.diff(closed, axis=0)
        n = np.maximum(np.ceil(np.linalg.norm(seg, axis=1) / step).astype(int), 1)
        t = np.concatenate([np.arange(k) / k for k in n])
        start = np.repeat(closed[:-1], n, axis=0)
        parts.append(start + t[:, None] * np.repeat(seg, n, axis=0))
    if not parts:
        raise ValueError("the alpha has no silhouette")
    return np.concatenate(parts)


def onto_silhouette(points, silhouette):
    """Each point (n, 2) moved to its nearest point of ``silhouette`` (k, 2), (n, 2)."""
    _, i = cKDTree(silhouette).query(np.asarray(points, dtype=np.float64).reshape(-1, 2))
    return np.asarray(silhouette, dtype=np.float64)[i]


def attributed(case, truth):
    """The photos-only ``case`` of a rendered head as each of ``ATTRIBUTIONS`` changes it,
    label -> case; ``truth``: the head's ``truth.npz`` (``landmark_names``,
    ``exact_front``, ``head_alpha_front`` and ``_side``). The case's views must be one
    profile ("right" or "left": its side photo) and one other, its front photo (a "front",
    or a three-quarter view where the head is turned, ``bench_lens --yaw``)."""
    sides = [v for v in case.views if v in PROFILE_VIEWS]
    if len(case.views) != 2 or len(sides) != 1:
        raise ValueError(f"the photos were detected as {sorted(case.views)}, not a front "
                         "(or a three-quarter view) and a profile")
    front_view = next(v for v in case.views if v != sides[0])
    photo = {front_view: "front", sides[0]: "side"}
    names = json.loads(str(truth["landmark_names"]))["front"]
    exact = dict(zip(names, np.asarray(truth["exact_front"], dtype=np.float64), strict=True))
    silhouettes = {v: true_silhouette(truth[f"head_alpha_{photo[v]}"]) for v in case.views}
    out = {}
    for label, (exact_front, clicks, outlines) in ATTRIBUTIONS.items():
        c = copy.deepcopy(case)
        front = c.views[front_view]
        if exact_front:
            front.points = {n: tuple(exact[n]) if n in exact else p
                            for n, p in front.points.items()}
        if clicks:
            front.uncertainty = {}
        if outlines:
            for name, view in c.views.items():
                if view.contour is not None:
                    view.contour = onto_silhouette(view.contour, silhouettes[name])
        out[label] = c
    return out


def moved_copy(case, rng, px=COPY_PX):
    """A copy of ``case`` with every landmark and outline point moved by a normal draw of
    ``px`` (standard deviation, pixels) from ``rng``."""
    out = copy.deepcopy(case)
    for view in out.views.values():
        if view.contour is not None:
            view.contour = view.contour + rng.normal(0.0, px, view.contour.shape)
        view.points = {n: tuple(np.add(p, rng.normal(0.0, px, 2)))
                       for n, p in view.points.items()}
    return out


def copies_error(model, case, true_head, copies, rng, px=COPY_PX, regions=None):
    """The errors (mm) of the fits of ``case`` and ``copies`` - 1 copies of it moved by
    ``px`` (:func:`moved_copy`): name -> (copies,), the skin RMS under "skin" and, with
    ``regions`` (``head_regions.skin_regions``), each region's
    (``head_regions.region_errors``)."""
    cases = [case] + [moved_copy(case, rng, px) for _ in range(copies - 1)]
    heads = [fit_head(model, c).local_vertices for c in cases]
    parts = [region_errors(model, h, true_head, regions) if regions else {} for h in heads]
    return {"skin": np.array([skin_error_mm(model, h, true_head) for h in heads]),
            **{name: np.array([p[name] for p in parts]) for name in regions or ()}}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--copies", type=int, default=1,
                    help="fit each case and this many - 1 copies moved by --copy-px: their "
                         "mean, and the spread of a head's copies (default 1)")
    ap.add_argument("--copy-px", type=float, default=COPY_PX,
                    help=f"standard deviation a copy's points are moved by, px (default "
                         f"{COPY_PX:g})")
    ap.add_argument("--only", nargs="+", choices=list(ATTRIBUTIONS), metavar="LABEL",
                    help="fit only these columns: " + ", ".join(ATTRIBUTIONS))
    ap.add_argument("--regions", action="store_true",
                    help="also each head's error over the face, the ears, the back of the "
                         "head and the rest of the skin")
    add_head_options(ap)
    args = ap.parse_args(argv)
    if args.copies < 1:
        ap.error(f"--copies: at least 1, got {args.copies}")
    if not args.copy_px > 0:
        ap.error(f"--copy-px: a positive number of pixels, got {args.copy_px:g}")
    chosen = [a for a in ATTRIBUTIONS if args.only is None or a in args.only]
    print(f"machine: {machine_description()}")
    folders = chosen_folders(args)
    detector = Detector()
    model = load_model()
    columns = ["mean head", *chosen]
    print("skin RMS vs the true head, mm, from the photos alone: the case solver detect "
          "makes, with the front's landmarks exact (their uncertainty kept; as clicks), the "
          "outlines on the true silhouette, both")
    if args.copies > 1:
        print(f"each the mean of {args.copies} fits: the case and copies of it with every "
              f"point moved by {args.copy_px:g} px")
    print(f"  {'head':<14}" + "".join(f"{c:>20}" for c in columns))
    rows, spreads, region_rows = [], [], []
    regions = skin_regions(model) if args.regions else None
    rng = np.random.default_rng(0)
    for folder in folders:
        truth = np.load(folder / "truth.npz", allow_pickle=True)
        true_head = truth["local_vertices"]
        try:
            cases = {k: c for k, c in attributed(photos_case(folder, detector), truth).items()
                     if k in chosen}
        except ValueError as err:
            print(f"  {folder.name}: {err}")
            continue
        results = [copies_error(model, c, true_head, args.copies, rng, args.copy_px,
                                regions) for c in cases.values()]
        errors = [r["skin"] for r in results]
        row = [skin_error_mm(model, model.vertices, true_head)] + [e.mean() for e in errors]
        rows.append(row)
        spreads.append([e.max() - e.min() for e in errors])
        print(f"  {folder.name:<14}" + "".join(f"{v:>20.2f}" for v in row), flush=True)
        if regions is not None:
            mean_head = region_errors(model, model.vertices, true_head, regions)
            region_rows.append([[mean_head[n]] + [r[n].mean() for r in results]
                                for n in regions])
            _print_regions(regions, region_rows[-1])
    if rows:
        print(f"  {'mean':<14}" + "".join(f"{v:>20.2f}" for v in np.mean(rows, axis=0)))
    if region_rows:
        _print_regions(regions, np.mean(region_rows, axis=0))
    if rows and args.copies > 1:
        print(f"  {'spread':<14}" + " " * 20
              + "".join(f"{v:>20.2f}" for v in np.mean(spreads, axis=0)))


def _print_regions(regions, values):
    """One line per region under a head's (or the mean's) line: its error in each column."""
    for name, row in zip(regions, values, strict=True):
        print(f"    {name:<12}" + "".join(f"{v:>20.2f}" for v in row), flush=True)


if __name__ == "__main__":
    main()
