"""Benchmark of the headless batch: heads per minute at ``--jobs 1`` and ``--jobs 2`` (and
their ratio), through a local Dask cluster of 2 workers (``--cluster local --jobs 2``),
peak memory of the largest process, and the size per head of each output.

    python -m bench.bench_batch [--heads 12] [--texture-size 1024] [--keep DIR] [--blend-only]
                                [--broken-row]

``--blend-only`` measures the .blend batches only (``--jobs 1``, ``--jobs 2``, the local
cluster), not the .glb and every-output ones. ``--broken-row`` adds a row whose landmarks
file is missing to the middle of the manifest (the issue's "one broken row among 50 good
ones": ``--heads 50 --broken-row``); each batch's line then names the failed rows with
their messages, and every good head must still be written (exit 1). The cluster batch is
left out when Dask distributed is not installed.

The heads are synthetic cases (``solver.synthetic.make_case``, saved with
``solver.io.save_landmarks``) with smooth generated photos, listed in a ``.csv`` manifest;
each configuration runs the real command (``python -m headrecon_addon.headless``) in a
fresh process with ``--force``, timed from start to exit (model loading included). The CPU
seconds per head (all processes of the batch) say what a machine free of other work would
do: 60 / (CPU s a head) heads per minute per core; the last lines give that rate for
``--jobs N`` on N free cores and its ratio to ``--jobs 1``, which a loaded machine's
wall-clock ratio cannot show. Each batch's line also gives the load average before it.

Targets: ``--jobs 2`` at least 1.7 x the rate of ``--jobs 1``; at ``--jobs 2`` at least 40
heads/min without a .glb (fit, texture, .blend) and 15 with the game .glb; under 800 MB a
worker.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from bench.common import load_average, machine_description  # noqa: E402

# Runs a command; prints its exit code, the peak resident memory (KiB) of the largest
# process below it and the CPU seconds of all of them.
_MEASURE = ("import resource, subprocess, sys; code = subprocess.call(sys.argv[1:], "
            "stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL); "
            "r = resource.getrusage(resource.RUSAGE_CHILDREN); "
            "print(code, r.ru_maxrss, r.ru_utime + r.ru_stime)")


def _photo(path, size, seed):
    from PIL import Image

    w, h = size
    rng = np.random.default_rng(seed)
    u, v = np.meshgrid(np.linspace(0, 1, w), np.linspace(0, 1, h))
    base = rng.uniform(0.2, 0.8, 3)
    rgb = np.stack([base[0] + 0.2 * u, base[1] + 0.2 * v, base[2] + 0.1 * (u - v)], axis=-1)
    Image.fromarray((np.clip(rgb, 0, 1) * 255).astype(np.uint8)).save(path)


def make_heads(folder, n, broken=False):
    """``n`` synthetic heads with photos in ``folder`` and their manifest; returns it.
    ``broken``: one more row in the middle, naming a landmarks file that does not exist."""
    from solver import load_model, save_landmarks, synthetic

    model = load_model()
    rows = ["name,landmarks"]
    for i in range(n):
        case, _ = synthetic.make_case(model, 1000 + i)
        for j, (vname, view) in enumerate(case.views.items()):
            _photo(folder / f"head{i:03d}_{vname}.png", view.size, 1000 + i + j)
            view.image = f"head{i:03d}_{vname}.png"
        save_landmarks(case, folder / f"head{i:03d}.json")
        rows.append(f"head{i:03d},head{i:03d}.json")
    if broken:
        rows.insert(1 + n // 2, "broken,missing.json")
    manifest = folder / "heads.csv"
    manifest.write_text("\n".join(rows) + "\n")
    return manifest


def run_batch(manifest, out, jobs, outputs, texture_size, cluster=None):
    """(seconds, CPU seconds, exit code, peak MB of the largest process, summary rows) of
    one batch (``cluster``: its ``--cluster`` address, e.g. "local")."""
    cmd = [sys.executable, "-m", "headrecon_addon.headless", str(manifest), "--out", str(out),
           "--jobs", str(jobs), "--outputs", outputs, "--texture-size", str(texture_size),
           "--force"] + (["--cluster", cluster] if cluster else [])
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _MEASURE, *cmd], cwd=ROOT, text=True,
                          capture_output=True, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    seconds = time.perf_counter() - t0
    code, rss_kib, cpu = proc.stdout.split()
    rows = [json.loads(x) for x in (out / "summary.jsonl").read_text().splitlines()]
    return seconds, float(cpu), int(code), int(rss_kib) / 1024.0, rows


def sizes_per_output(rows):
    """Mean bytes per head of each output kind (the .obj's .mtl counted with it)."""
    total = {}
    for row in rows:
        for kind, path in row["outputs"].items():
            kind = "obj" if kind == "mtl" else kind
            total[kind] = total.get(kind, 0) + Path(path).stat().st_size
    return {k: v / len(rows) for k, v in total.items()}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--heads", type=int, default=12)
    p.add_argument("--texture-size", type=int, default=1024)
    p.add_argument("--keep", type=Path, help="write the inputs and outputs here")
    p.add_argument("--blend-only", action="store_true",
                   help="only the .blend batches: --jobs 1, --jobs 2, the local cluster")
    p.add_argument("--broken-row", action="store_true",
                   help="one row of the manifest names a missing landmarks file")
    args = p.parse_args(argv)
    try:
        import distributed  # noqa: F401
        has_dask = True
    except ImportError:
        has_dask = False
    print(f"machine: {machine_description()}")
    with tempfile.TemporaryDirectory() as tmp:
        work = args.keep or Path(tmp)
        (work / "in").mkdir(parents=True, exist_ok=True)
        manifest = make_heads(work / "in", args.heads, broken=args.broken_row)
        print(f"{args.heads} synthetic heads{' and one broken row' if args.broken_row else ''}"
              f", texture {args.texture_size} px per tile")
        rates, cpu_rates = {}, {}
        configs = [("fit, texture, .blend", 1, "blend", None),
                   ("fit, texture, .blend", 2, "blend", None)]
        if has_dask:
            configs.append(("fit, texture, .blend", 2, "blend", "local"))
        if not args.blend_only:
            configs += [("fit, texture, .blend + game .glb", 1, "blend,glb", None),
                        ("fit, texture, .blend + game .glb", 2, "blend,glb", None),
                        ("every output", 2, "blend,glb,obj,texture,report", None)]
        for label, jobs, outputs, cluster in configs:
            out = work / f"out_{jobs}_{outputs.replace(',', '_')}{'_' + cluster if cluster else ''}"
            load = load_average()
            seconds, cpu, code, peak, rows = run_batch(manifest, out, jobs, outputs,
                                                       args.texture_size, cluster)
            ok = sum(r["status"] == "done" for r in rows)
            rate = 60.0 * ok / seconds
            rates[(label, jobs, cluster)] = rate
            cpu_rates[(label, jobs, cluster)] = 60.0 * jobs * ok / max(cpu, 1e-9)
            fit_s = np.median([r["seconds"] for r in rows if r["status"] == "done"])
            where = f"--cluster {cluster} " if cluster else ""
            print(f"{where}--jobs {jobs} --outputs {outputs}: {ok}/{len(rows)} heads in "
                  f"{seconds:.1f} s = {rate:.1f} heads/min (median {fit_s:.1f} s a head in "
                  f"its worker), {cpu / max(ok, 1):.1f} CPU s a head, peak {peak:.0f} MB in "
                  f"the largest process, exit {code} (load average before: {load})")
            for r in rows:
                if r["status"] == "failed":
                    print(f"  failed: {r['name']}: {r['error']}")
            if outputs.count(",") == 4:
                for kind, size in sizes_per_output([r for r in rows if r["status"] == "done"]
                                                   ).items():
                    print(f"  {kind}: {size / 1e6:.2f} MB a head")
        for label in ("fit, texture, .blend", "fit, texture, .blend + game .glb"):
            if (label, 1, None) in rates:
                one, two = cpu_rates[(label, 1, None)], cpu_rates[(label, 2, None)]
                print(f"{label}: --jobs 2 / --jobs 1 = "
                      f"{rates[(label, 2, None)] / rates[(label, 1, None)]:.2f} x; by CPU "
                      f"seconds on free cores: {one:.1f} and {two:.1f} heads/min, "
                      f"{two / one:.2f} x")
        if ("fit, texture, .blend", 2, "local") in rates:
            label = "fit, texture, .blend"
            print(f"{label}: --cluster local --jobs 2 / --jobs 1 = "
                  f"{rates[(label, 2, 'local')] / rates[(label, 1, None)]:.2f} x, "
                  f"/ --jobs 2 = {rates[(label, 2, 'local')] / rates[(label, 2, None)]:.2f} x")
        print(f"load average at the end: {load_average()}")


if __name__ == "__main__":
    main()
