"""Texture bake speed and memory: `python -m bench.bench_texture` from the repository root.

Bakes the real head model's skin (UV tiles 1001 "Face" and 1002 "Head and Neck") at
1024 x 1024 per tile from a front and a profile photo of 768 x 1024 (synthetic photos:
speed does not depend on their content), with nominal orthographic cameras. Prints the
machine, the median time of cold bakes (UV rasters built) and warm bakes (rasters
cached), a single-tile bake, and peak memory.
"""

import argparse
import os
import platform
import resource
import statistics
import time
import tracemalloc

import numpy as np
import scipy

from solver.cameras import OrthographicCamera
from solver.model import load_model
from solver.texture import bake_texture, bake_tiles, clear_raster_cache, uv_raster, uv_tiles


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def photos(width=768, height=1024, seed=0):
    """Front and right views: smooth colour fields plus noise, float32 in [0, 1]."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:height, 0:width] / max(width, height)
    views = []
    for k, view in enumerate(("orthographic-front", "orthographic-right")):
        base = np.stack([0.5 + 0.4 * np.sin(7 * xx + k), 0.5 + 0.4 * np.cos(5 * yy),
                         0.5 + 0.3 * np.sin(3 * (xx + yy))], -1)
        img = np.clip(base + 0.05 * rng.standard_normal(base.shape), 0, 1).astype(np.float32)
        views.append((img, OrthographicCamera.nominal(view, (width, height))))
    return views


def timed(fn, repeat):
    """Median wall and CPU (this process, all threads) seconds, and wall min/max."""
    wall, cpu = [], []
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return statistics.median(wall), statistics.median(cpu), min(wall), max(wall)


def line(label, t):
    return (f"  {label:<30} median {t[0]:.3f} s wall, {t[1]:.3f} s CPU  "
            f"(wall min {t[2]:.3f}, max {t[3]:.3f})")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=1024, help="texels per tile side")
    ap.add_argument("--repeat", type=int, default=5, help="warm bakes timed")
    ap.add_argument("--cold-repeat", type=int, default=3, help="cold bakes timed")
    args, _ = ap.parse_known_args(argv)  # `./run bench` passes its arguments to every bench

    model = load_model()
    views = photos()
    world = model.vertices
    tiles = uv_tiles(model)
    affinity = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None
    print("bench_texture: texture bake of the skin from two photos")
    print(f"  machine: {cpu_model()}, {os.cpu_count()} cores ({affinity} usable), "
          f"Python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}")
    print(f"  photos: 2 x 768x1024 (front, right, right also mirrored); texture "
          f"{args.size}x{args.size} per tile, tiles {', '.join(map(str, tiles))}")

    def cold():
        clear_raster_cache()
        bake_tiles(model, world, views, args.size)

    def warm():
        bake_tiles(model, world, views, args.size)

    def raster_only():
        clear_raster_cache()
        for t in tiles:
            uv_raster(model, args.size, tile=t)

    rt = timed(raster_only, args.cold_repeat)
    c = timed(cold, args.cold_repeat)
    warm()  # make sure the rasters are cached
    texels = {t: len(uv_raster(model, args.size, tile=t).texel) for t in tiles}
    w = timed(warm, args.repeat)
    face = timed(lambda: bake_texture(model, world, views, args.size, tile=tiles[0]),
                 args.repeat)
    print("  covered texels: " + ", ".join(f"{t}: {n}" for t, n in texels.items()))
    print(line("UV raster build (all tiles):", rt))
    print(line("cold bake (raster + bake):", c))
    print(line("warm bake, all tiles:", w))
    print(line(f"warm bake, tile {tiles[0]} only:", face))
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"  load average during the run: {load:.2f} (wall times grow with other jobs; "
          "CPU time less so)")

    tracemalloc.start()
    warm()
    _, peak_warm = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    clear_raster_cache()
    tracemalloc.start()
    warm()
    _, peak_cold = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux
    print(f"  peak traced memory: warm bake {peak_warm / 2**20:.0f} MiB, cold bake "
          f"{peak_cold / 2**20:.0f} MiB; process max RSS {rss:.0f} MiB (model included)")


if __name__ == "__main__":
    main()
