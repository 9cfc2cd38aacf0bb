"""The rendered model heads the photos-only benchmarks fit (``bench_corrections``,
``bench_photo_size``, ``bench_photo_variants``): the sample and ``TEN_HEADS`` more, each
folder holding its front and profile photos, ``sample.json`` (the exact landmarks) and
``truth.npz`` (the true head), rendered by ``tools.make_sample`` when missing."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def render_head(seed, folder):
    """Render a model head's sample photos into ``folder`` unless they are there."""
    if (folder / "truth.npz").is_file():
        return
    print(f"rendering seed {seed} into {folder} ...", flush=True)
    subprocess.run([sys.executable, "-m", "tools.make_sample", "--seed", str(seed),
                    "--out", str(folder)], cwd=ROOT, check=True, stdout=subprocess.DEVNULL)


#: The model heads the photos-only benchmarks render and fit besides the sample.
TEN_HEADS = [101, 201, 202, 203, 204, 205, 206, 207, 208]


def add_head_options(parser, render=None):
    """``--heads`` (rendered sample folders; default the sample) and ``--render`` (model
    seeds; default ``render``, else ``TEN_HEADS``), as :func:`head_folders` takes them."""
    parser.add_argument("--heads", nargs="*", default=None,
                        help="rendered sample folders (default: the sample and the --render "
                             "ones)")
    parser.add_argument("--render", nargs="*", type=int,
                        default=TEN_HEADS if render is None else render,
                        help="model seeds rendered into generated/bench_heads/seed<N> if "
                             "missing")


def head_folders(heads, seeds):
    """The rendered head folders a benchmark runs on: ``heads`` (paths) if given, else the
    sample; then ``generated/bench_heads/seed<N>`` for each of ``seeds``, rendered first
    when missing."""
    folders = [Path(h) for h in heads] if heads is not None \
        else [ROOT / "generated" / "sample"]
    for seed in seeds:
        folder = ROOT / "generated" / "bench_heads" / f"seed{seed}"
        render_head(seed, folder)
        folders.append(folder)
    return folders
