"""Benchmark of the fit: accuracy on synthetic heads, speed, memory.

    python -m bench.bench_fit [--cases 20] [--noise 0 1 2] [--blas-threads 1]

Accuracy: seeded synthetic cases (solver/synthetic.py): a head drawn from the model's 100
identity modes, rotated up to 5 degrees, photographed by orthographic cameras into
1024-pixel-high front and right photos (each with its own scale and offset), landmarks
with Gaussian noise sigma, and the traced profile contour with the same noise. For each
method the error is the RMS distance over the skin vertices between the fitted and the
true head after a similarity alignment (Procrustes: photos cannot tell size), in mm.
"mean head" is the model's mean aligned the same way (the error before any fit).
Targets: <= 2.0 mm at sigma = 1 px.

Speed: wall time of ``fit_head`` (default options: combined) per case, median; of
``refit_landmarks`` after moving one landmark by 5 px (the drag path), median; each with
its process CPU time (``process_time``: on a shared machine wall time also counts the
other jobs). Targets: <= 0.5 s and <= 30 ms. Memory: peak resident set size of this
process (model loaded, all fits run; ``ru_maxrss``) and the peak of Python/numpy
allocations during one full fit (``tracemalloc``). Target: <= 500 MB.
"""

from bench import blas_threads


def _parse():
    p = blas_threads.parser("python -m bench.bench_fit", __doc__)
    p.add_argument("--cases", type=int, default=20, help="synthetic heads per noise level")
    p.add_argument("--noise", type=float, nargs="+", default=[0.0, 1.0, 2.0],
                   help="landmark noise levels, pixels")
    p.add_argument("--methods", nargs="+", default=["approach1", "approach2", "combined"])
    p.add_argument("--profile", action="store_true",
                   help="run the full fits and the refits under cProfile and print where "
                        "their time goes (the solver's functions; times then include the "
                        "profiler's overhead)")
    blas_threads.option_argument(p)
    return p.parse_args()


ARGS = blas_threads.script_args(_parse, __name__)

import copy  # noqa: E402
import cProfile  # noqa: E402
import pstats  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from bench.common import (  # noqa: E402
    machine_description,
    max_rss_mb,
    option_values,
    peak_memory,
)
from solver import FitOptions, fit_head, load_model, refit_landmarks  # noqa: E402
from solver.synthetic import make_case, skin_error_mm  # noqa: E402


def main(args):
    model = load_model()
    shared = option_values(args.set)
    print(f"machine: {machine_description()}")
    print(f"cases: {args.cases} per noise level, rotation <= 5 deg, 1024-px photos, "
          "front + right with contour"
          + "".join(f"; {k}={v!r}" for k, v in shared.items()) + "\n")
    methods = list(args.methods)
    table = {}
    fit_times, refit_times, fit_cpu, refit_cpu = [], [], [], []
    profiles = {"full fit": cProfile.Profile(), "refit": cProfile.Profile()} \
        if args.profile else {}
    chosen = {}
    for sigma in args.noise:
        errs = {m: [] for m in ["mean head"] + methods}
        for seed in range(args.cases):
            case, truth = make_case(model, 1000 + seed, noise_px=sigma, rotation_deg=5.0)
            errs["mean head"].append(skin_error_mm(model, model.vertices, truth.local_vertices))
            for m in methods:
                prof = profiles.get("full fit") if m == "combined" else None
                t, c0 = time.perf_counter(), time.process_time()
                res = _run(prof, fit_head, model, case, FitOptions(method=m, **shared))
                dt, dc = time.perf_counter() - t, time.process_time() - c0
                errs[m].append(skin_error_mm(model, res.local_vertices, truth.local_vertices))
                if m == "combined":
                    fit_times.append(dt)
                    fit_cpu.append(dc)
                    chosen[res.info["approach"]] = chosen.get(res.info["approach"], 0) + 1
                    if sigma == 1.0 and seed < 10:
                        moved = copy.deepcopy(case)
                        u, v = moved.views["front"].points["nose_tip"]
                        moved.views["front"].points["nose_tip"] = (u + 5.0, v)
                        for _ in range(3):
                            t, c0 = time.perf_counter(), time.process_time()
                            _run(profiles.get("refit"), refit_landmarks, model, moved, res,
                                 FitOptions(**shared))
                            refit_times.append(time.perf_counter() - t)
                            refit_cpu.append(time.process_time() - c0)
        table[sigma] = errs
        print(f"sigma = {sigma:g} px: RMS skin error after similarity alignment, mm")
        print(f"  {'method':<12}{'median':>9}{'mean':>9}{'max':>9}")
        for m, e in errs.items():
            print(f"  {m:<12}{np.median(e):9.2f}{np.mean(e):9.2f}{np.max(e):9.2f}")
        print()
    if chosen:
        print("combined chose: " + ", ".join(f"{k} {v}x" for k, v in sorted(chosen.items())))

    # Memory of one full fit (numpy reports its buffers to tracemalloc).
    case, _ = make_case(model, 999, noise_px=1.0)
    _, peak = peak_memory(lambda: fit_head(model, case, FitOptions(**shared)))
    rss = max_rss_mb()
    print("\nspeed and memory")
    if fit_times:
        print(f"  full fit (combined): median {statistics.median(fit_times):.3f} s, "
              f"max {max(fit_times):.3f} s over {len(fit_times)} fits (target <= 0.5 s); "
              f"CPU median {statistics.median(fit_cpu):.3f} s")
    if refit_times:
        print(f"  landmark refit: median {1000 * statistics.median(refit_times):.1f} ms, "
              f"max {1000 * max(refit_times):.1f} ms over {len(refit_times)} (target <= 30 ms); "
              f"CPU median {1000 * statistics.median(refit_cpu):.1f} ms")
    print(f"  peak allocations during one fit (tracemalloc): {peak / 2**20:.0f} MB")
    print(f"  peak resident memory of this process (ru_maxrss, model loaded): {rss:.0f} MB "
          "(target <= 500 MB)")
    for name, prof in profiles.items():
        _print_profile(name, prof)
    target = table.get(1.0, {}).get("combined")
    if target:
        ok = np.median(target) <= 2.0
        print(f"\naccuracy target (combined, sigma 1 px, median <= 2.0 mm): "
              f"{'met' if ok else 'NOT met'} ({np.median(target):.2f} mm)")


def _run(prof, fn, *args):
    """``fn(*args)``, under the profiler ``prof`` when one is given."""
    if prof is None:
        return fn(*args)
    return prof.runcall(fn, *args)


def _print_profile(name, prof, share=0.02):
    """The solver's functions that take at least ``share`` of the profiled calls' time
    (inclusive), per call of the profiled function: ms, share, own ms, calls."""
    stats = pstats.Stats(prof).stats
    top = [v for k, v in stats.items() if k[2] in ("fit_head", "refit_landmarks")]
    if not top:
        return
    calls, total = top[0][1], top[0][3]
    print(f"\nprofile of the {name} (cProfile, per {name}; inclusive ms, share, own ms, "
          f"calls): {1000 * total / calls:.1f} ms under the profiler")
    rows = sorted(((v[3], v[2], v[1], k) for k, v in stats.items()
                   if "/solver/" in k[0] and v[3] >= share * total), reverse=True)
    for cum, own, n, (path, line, func) in rows:
        where = path[path.rindex("/solver/") + 1:]
        print(f"  {1000 * cum / calls:8.1f} {100 * cum / total:5.1f} %"
              f" {1000 * own / calls:8.1f} {n / calls:7.1f}  {where}:{line} {func}")


if __name__ == "__main__":
    main(ARGS)
