"""The rendered model heads the photos-only benchmarks fit (``bench_attribution``,
``bench_corrections``, ``bench_photo_size``, ``bench_photo_variants``): the sample and
``TEN_HEADS`` more, each folder holding its front and profile photos, ``sample.json`` (the
exact landmarks) and ``truth.npz`` (the true head), rendered by ``tools.make_sample`` when
missing; with ``--skin`` of another complexion (``tools.make_sample.SKIN_TONES``) or
``--expression`` (``tools.make_sample.EXPRESSIONS``: the face in the photos shows it, the
truth is the neutral head) or ``--pitch`` (the head nodded in both photos) or ``--light``
(``tools.make_sample.LIGHTS``), the sample's seed and the others rendered so."""

import subprocess
import sys
from pathlib import Path

from tools.make_sample import DEFAULT_SEED, EXPRESSIONS, LIGHTS, SKIN_TONES

ROOT = Path(__file__).resolve().parent.parent


def render_head(seed, folder, skin_tone="light", expression=None, pitch=0.0, light="studio"):
    """Render a model head's sample photos (its skin ``skin_tone``, its face showing
    ``expression`` or neutral, nodded ``pitch`` degrees, lit by ``light``) into ``folder``
    unless they are there."""
    if (folder / "truth.npz").is_file():
        return
    print(f"rendering seed {seed} into {folder} ...", flush=True)
    more = ([] if expression is None else ["--expression", expression]) + \
        ([] if not pitch else ["--pitch", f"{pitch:g}"]) + \
        ([] if light == "studio" else ["--light", light])
    subprocess.run([sys.executable, "-m", "tools.make_sample", "--seed", str(seed),
                    "--out", str(folder), "--skin", skin_tone, *more], cwd=ROOT, check=True,
                   stdout=subprocess.DEVNULL)


#: The model heads the photos-only benchmarks render and fit besides the sample.
TEN_HEADS = [101, 201, 202, 203, 204, 205, 206, 207, 208]


def add_head_options(parser, render=None):
    """``--heads`` (rendered sample folders; default the sample), ``--render`` (model
    seeds; default ``render``, else ``TEN_HEADS``), ``--skin`` and ``--expression``, as
    :func:`chosen_folders` takes them."""
    parser.add_argument("--heads", nargs="*", default=None,
                        help="rendered sample folders (default: the sample and the --render "
                             "ones)")
    parser.add_argument("--render", nargs="*", type=int,
                        default=TEN_HEADS if render is None else render,
                        help="model seeds rendered into generated/bench_heads/seed<N> if "
                             "missing")
    parser.add_argument("--skin", default="light", choices=list(SKIN_TONES),
                        help="the heads' skin tone (default light: the sample and its "
                             "seeds; else the sample's seed too, rendered into "
                             "generated/bench_heads/seed<N>_<tone>)")
    parser.add_argument("--expression", default=None, choices=list(EXPRESSIONS),
                        help="the heads' faces show this expression in both photos (default "
                             "neutral; else the sample's seed too, rendered into "
                             "generated/bench_heads/seed<N>[_<tone>]_<expression>); the "
                             "truth stays the neutral head")
    parser.add_argument("--pitch", type=float, default=0.0, metavar="DEG",
                        help="the heads nodded by this much in both photos (positive: the "
                             "face down; default 0; else the sample's seed too, rendered "
                             "into generated/bench_heads/seed<N>[_<tone>][_<expression>]"
                             "_pitch<DEG>)")
    parser.add_argument("--light", default="studio", choices=list(LIGHTS),
                        help="how the heads are lit (default studio: soft, from the front; "
                             "window: from the subject's left, the other side in shade; "
                             "else the sample's seed too, rendered into generated/bench_heads/"
                             "seed<N>[_<tone>][_<expression>][_pitch<DEG>]_<light>)")


def photo_path(folder, view):
    """A rendered head's photo of ``view`` ("front" or "side"): the JPEG where there is one
    (``tools.make_sample --lens`` writes the lens into its EXIF, so the photo is taken as a
    pinhole camera of that lens), else the PNG (a parallel render, no EXIF)."""
    folder = Path(folder)
    jpeg = folder / f"{view}.jpg"
    return jpeg if jpeg.is_file() else folder / f"{view}.png"


def chosen_folders(args):
    """The folders of the options :func:`add_head_options` added (parsed ``args``)."""
    return head_folders(args.heads, args.render, args.skin, args.expression, args.pitch,
                        args.light)


def head_folders(heads, seeds, skin_tone="light", expression=None, pitch=0.0, light="studio"):
    """The rendered head folders a benchmark runs on: ``heads`` (paths) if given, else the
    sample; then ``generated/bench_heads/seed<N>`` for each of ``seeds``, rendered first
    when missing. Of another ``skin_tone`` (``--skin``), with an ``expression``, nodded
    (``pitch`` degrees) or in another ``light`` the sample's seed comes first instead of the
    sample, and each folder is
    ``seed<N>[_<skin_tone>][_<expression>][_pitch<pitch>][_<light>]``."""
    plain = skin_tone == "light" and expression is None and not pitch and light == "studio"
    if heads is not None:
        folders = [Path(h) for h in heads]
    elif plain:
        folders = [ROOT / "generated" / "sample"]
    else:
        folders, seeds = [], [DEFAULT_SEED, *seeds]
    suffix = "".join(f"_{part}" for part in (None if skin_tone == "light" else skin_tone,
                                             expression, f"pitch{pitch:g}" if pitch else None,
                                             None if light == "studio" else light)
                     if part is not None)
    for seed in seeds:
        folder = ROOT / "generated" / "bench_heads" / f"seed{seed}{suffix}"
        render_head(seed, folder, skin_tone, expression, pitch, light)
        folders.append(folder)
    return folders
