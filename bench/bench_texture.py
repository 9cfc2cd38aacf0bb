"""Texture bake speed and memory: `python -m bench.bench_texture` from the repository root.

Bakes the real head model's skin (UV tiles 1001 "Face" and 1002 "Head and Neck") at
1024 x 1024 per tile from a front and a profile photo of 768 x 1024 (synthetic photos:
speed does not depend on their content), with nominal orthographic cameras. Prints the
machine, the median time of cold bakes (UV rasters built) and warm bakes (rasters
cached), a single-tile bake, and peak memory.
"""

import argparse

import numpy as np

from bench.common import (
    load_average,
    machine_description,
    max_rss_mb,
    median_time,
    peak_memory,
)
from solver import OrthographicCamera, load_model
from solver.texture.bake import bake_texture, bake_tiles
from solver.texture.uvs import clear_raster_cache, uv_raster, uv_tiles


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


def line(label, t):
    return (f"  {label:<30} median {t.median:.3f} s wall, {t.cpu_median:.3f} s CPU  "
            f"(wall min {t.min:.3f}, max {t.max:.3f})")


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
    print("bench_texture: texture bake of the skin from two photos")
    print(f"  machine: {machine_description()}")
    print(f"  photos: 2 x 768x1024 (front, right, right also mirrored); texture "
          f"{args.size}x{args.size} per tile, tiles {', '.join(map(str, tiles))}")

    def cold():
        clear_raster_cache(model)
        bake_tiles(model, world, views, args.size)

    def warm():
        bake_tiles(model, world, views, args.size)

    def raster_only():
        clear_raster_cache(model)
        for t in tiles:
            uv_raster(model, args.size, tile=t)

    rt = median_time(raster_only, args.cold_repeat, warmup=0)
    c = median_time(cold, args.cold_repeat, warmup=0)
    warm()  # make sure the rasters are cached
    texels = {t: len(uv_raster(model, args.size, tile=t).texel) for t in tiles}
    w = median_time(warm, args.repeat, warmup=0)
    face = median_time(lambda: bake_texture(model, world, views, args.size, tile=tiles[0]),
                       args.repeat, warmup=0)
    print("  covered texels: " + ", ".join(f"{t}: {n}" for t, n in texels.items()))
    print(line("UV raster build (all tiles):", rt))
    print(line("cold bake (raster + bake):", c))
    print(line("warm bake, all tiles:", w))
    print(line(f"warm bake, tile {tiles[0]} only:", face))
    print(f"  load average during the run: {load_average()} (wall times grow with other "
          "jobs; CPU time less so)")

    _, peak_warm = peak_memory(warm)
    clear_raster_cache(model)
    _, peak_cold = peak_memory(warm)
    print(f"  peak traced memory: warm bake {peak_warm / 2**20:.0f} MiB, cold bake "
          f"{peak_cold / 2**20:.0f} MiB; process max RSS {max_rss_mb():.0f} MiB "
          "(model included)")


if __name__ == "__main__":
    main()
