"""Texture bake speed and memory: `python -m bench.bench_texture` from the repository root.

Bakes the real head model's skin (UV tiles 1001 "Face" and 1002 "Head and Neck") at
1024 x 1024 per tile from a front and a profile photo of 768 x 1024 (synthetic photos:
speed does not depend on their content), with nominal orthographic cameras. Prints the
machine, the UV rasters' build and their load from beside the model file, the median time
of cold bakes (UV rasters built) and warm bakes (rasters
cached; also without the equalisation and the seam fade, as the bake was before them), a
single-tile bake, and peak memory.

Then, on the rendered sample (``./run sample`` writes ``generated/sample/``; skipped when
it is missing), the seams: the sample is fitted, every photo pass sampled into the
texture (``bake_samples``), and the colour difference between views across the seam band
(``equalise.seam_difference``: where two passes each carry at least 20 % of a texel's
blend weight, averaged over 16 x 16 texel cells) printed before the equalisation, with
the gains and offsets (``fit_view_gains``, printed too) and with the levelling as well
(``equalised_colours``, the default); the back of the head's mean colour on either side
(each seen by one profile pass only); how much low-frequency light the shading
removal takes out (the spread of the smoothed luminance over the skin); and the clothes
the bake leaves out (``clothes.py``: the shirt against the truth's masks, the skin, and
the texels bluer than red with the clothes kept and left out); and how far apart the two
UV tiles meet at the vertices they share (``seams.tile_seam_difference``). On james' two
real photos (``../shared/realdata/james``, skipped when missing), detected and fitted as
``solver detect`` makes the case, the texels of his white collar's colour (light, red not
above green or blue: never skin, nor his dark hair) with the clothes kept and left out,
and the tiles' meeting too (a three-quarter photo sees the neck behind the jaw, where the
face's tile meets the back of the head's).
"""

import argparse
from pathlib import Path

import numpy as np

from bench.common import (
    load_average,
    machine_description,
    max_rss_mb,
    median_time,
    peak_memory,
)
from solver import OrthographicCamera, fit_head, load_landmarks, load_model
from solver.texture.bake import (
    CLOTHES_MODES,
    BakeOptions,
    bake_fit_texture,
    bake_samples,
    bake_texture,
    bake_tiles,
    equalised_colours,
    fit_view_gains,
)
from solver.texture.clothes import clothes_mask
from solver.texture.equalise import apply_gains, seam_difference
from solver.texture.seams import tile_seam_difference
from solver.texture.shading import LUMA, smooth_on_mesh, srgb_to_linear
from solver.texture.uvs import clear_raster_cache, uv_raster, uv_tiles

ROOT = Path(__file__).resolve().parent.parent
CELL = 16  # texels per side of the cells the seam difference averages over


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


def read_photo(path):
    """A photo as (H, W, 3) float32 in [0, 1]."""
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"), dtype=np.float32) / 255.0


def seam_numbers(samples, equalised):
    """``SeamDifference`` over every tile's texels of the raw colours and of each set of
    colours in ``equalised`` (dicts tile -> (P, N, 3))."""
    cols, ws, cells = [], [], []
    for tile, s in samples.items():
        texel = s.raster.texel
        per_row = -(-s.raster.size // CELL)
        cells.append(tile * per_row * per_row + (texel // s.raster.size // CELL) * per_row
                     + (texel % s.raster.size) // CELL)
        cols.append(s.colours)
        ws.append(s.weights)
    w, cell = np.concatenate(ws, 1), np.concatenate(cells)
    out = [seam_difference(np.concatenate(cols, 1), w, cell)]
    for colours in equalised:
        out.append(seam_difference(np.concatenate([colours[t] for t in samples], 1), w, cell))
    return out


def light_spread(model, result, tiles, length):
    """Std / mean of the skin's luminance smoothed over ``length`` metres (how much
    low-frequency light the texture holds)."""
    colour = np.zeros((len(model.vertices), 3))
    cover = np.zeros(len(model.vertices))
    tris = []
    for tile, tex in tiles.items():
        r = uv_raster(model, tex.shape[0], tile=tile)
        colour += r.gather @ tex.reshape(-1, 3)[r.texel]
        cover[r.vertices] += r.cover
        tris.append(r.triangles)
    has = cover > 0
    lum = srgb_to_linear(colour[has] / cover[has, None]) @ LUMA
    full = np.zeros(len(model.vertices))
    full[has] = lum
    s = smooth_on_mesh(full, result.world_vertices, np.concatenate(tris), length)[has]
    return float(s.std() / s.mean())


def back_sides(model, result, tiles):
    """Mean baked colour of the back of the head (behind the ears, above the neck) on the
    subject's left (+x, local) and right: what a photo pass's global correction does to
    the region only it sees."""
    out = []
    for side in (1, -1):
        sums, n = np.zeros(3), 0
        for tile, tex in tiles.items():
            r = uv_raster(model, tex.shape[0], tile=tile)
            pts = r.interp @ result.local_vertices
            sel = (pts[:, 1] > 0.03) & (side * pts[:, 0] > 0.02) & (pts[:, 2] > 0)
            sums += tex.reshape(-1, 3)[r.texel][sel].sum(axis=0)
            n += int(sel.sum())
        out.append(np.round(sums / max(n, 1), 3).tolist())
    return f"{out[0]} / {out[1]}"


def sample_seams(model, folder, size):
    case_path = Path(folder) / "sample.json"
    if not case_path.is_file():
        print(f"  sample: {case_path} is missing (./run sample); seams not measured")
        return
    case = load_landmarks(case_path, known_names=model)
    result = fit_head(model, case)
    photos = {v: read_photo(case.image_path(v)) for v in case.views}
    views = [(photos[v], result.cameras[v]) for v in case.views]
    sim = (result.scale, result.rotation, result.translation)
    print(f"  sample seams ({folder}, views {', '.join(case.views)}, texture {size}^2 per "
          f"tile; band: both passes >= 20 % of the weight, {CELL}x{CELL} texel cells):")
    for label, opts in (("default (seam feather on)", BakeOptions()),
                        ("seam feather off", BakeOptions(seam_feather=0.0))):
        samples = bake_samples(model, result.world_vertices, views, size, similarity=sim,
                               options=opts)
        gain, offset = fit_view_gains(samples, opts)
        gains_only = {t: apply_gains(s.colours, gain, offset) for t, s in samples.items()}
        levelled = equalised_colours(samples, result.world_vertices, opts)
        before, gained, after = seam_numbers(samples, [gains_only, levelled])
        print(f"    {label}: colour difference across the seam band "
              f"{100 * before.relative:.2f} % before equalisation, "
              f"{100 * gained.relative:.2f} % with the gains and offsets, "
              f"{100 * after.relative:.2f} % levelled too ({before.absolute:.4f} -> "
              f"{gained.absolute:.4f} -> {after.absolute:.4f} of full scale, "
              f"{before.texels} band texels)")
    view_of_pass = next(iter(samples.values())).view
    names = list(case.views)
    for k, v in enumerate(view_of_pass):
        print(f"    pass {k} (view {names[v]}): gain {np.round(gain[k], 3).tolist()}, "
              f"offset {np.round(offset[k], 4).tolist()}")
    tiles = bake_fit_texture(model, result, photos, size)
    print(f"    back of the head, mean colour on the subject's left / right (the profile "
          f"mirrored / seen directly): {back_sides(model, result, tiles)}")
    head_size = float(np.linalg.norm(np.ptp(result.world_vertices[model.skin], axis=0)))
    length = BakeOptions().shading_length * head_size
    for shading in ("keep", "remove"):
        tiles = bake_fit_texture(model, result, photos, size,
                                 options=BakeOptions(shading=shading))
        print(f"    shading {shading}: low-frequency light spread (std / mean of the skin's "
              f"luminance smoothed over {100 * length:.1f} cm) "
              f"{100 * light_spread(model, result, tiles, length):.1f} %")
    sample_clothes(model, folder, case, result, photos, size)
    print(f"    {tile_seam(model, tiles, size)}")


def tile_seam(model, tiles, size):
    """A line: how far apart the UV ``tiles`` (tile -> texture) meet at their shared
    vertices (``seams.tile_seam_difference``), median and largest share, of full scale."""
    d = tile_seam_difference({t: uv_raster(model, size, tile=t) for t in tiles}, tiles)
    return (f"tiles meet at {len(d)} shared vertices: colour difference median "
            f"{np.median(d):.3f}, 90 % {np.percentile(d, 90):.3f}, max {d.max():.3f} of "
            "full scale")


def sample_clothes(model, folder, case, result, photos, size):
    """The clothes left out of the bake (``clothes.py``) against the sample's truth: the
    shirt is what its photo shows of the person but not of the head alone (its truth's
    alpha masks), counted where the head is (its columns); skin is a clearly warm pixel.
    Then the texels bluer than red (the shirt's grey-blue, never skin) with the clothes
    kept and left out."""
    truth_path = Path(folder) / "truth.npz"
    if not truth_path.is_file():
        return
    truth = np.load(truth_path)
    for name in case.views:
        key = "front" if name == "front" else "side"
        mask = clothes_mask(model, result.world_vertices, result.cameras[name], photos[name])
        if mask is None:
            print(f"    clothes, {name}: the cheeks not seen; nothing left out")
            continue
        head = truth[f"head_alpha_{key}"] > 127
        person = truth[f"alpha_{key}"] > 127
        cols = np.flatnonzero(head.any(axis=0))
        where = np.zeros_like(head)
        where[:, cols.min():cols.max() + 1] = True
        img = photos[name]
        warm = person & (img[..., 0] - img[..., 2] > 0.1)
        print(f"    clothes, {name}: {100 * mask[person & ~head & where].mean():.2f} % of the "
              f"shirt where the head is left out, {100 * mask[warm].mean():.2f} % of the skin")
    for mode in CLOTHES_MODES:
        tiles = bake_fit_texture(model, result, photos, size, options=BakeOptions(clothes=mode))
        cold = sum(int((t[..., 2] > t[..., 0] + 0.02).sum()) for t in tiles.values())
        print(f"    clothes {mode}: {cold} texels bluer than red")


def james_texture(model, size):
    """The texels of james' white collar's colour (mean over 0.4, red not above green or
    blue) in the bake from his two real photos (detected, fitted), with the clothes kept
    and left out, and how far apart the tiles meet (:func:`tile_seam`); nothing when the
    scan is missing."""
    from bench.realistic_cases import james_folder, scan_photo_halves
    from solver.detect import Detector
    from solver.detect.detected_case import detect_photos

    folder = james_folder(ROOT)
    if not folder.is_dir():
        print(f"    james: {folder} missing; skipped")
        return
    halves = scan_photo_halves(folder)
    case = detect_photos([(None, p) for p in halves], Detector(), halves.__getitem__)
    result = fit_head(model, case)
    photos = {name: halves[Path(view.image).name].astype(np.float32) / 255.0
              for name, view in case.views.items()}
    for mode in CLOTHES_MODES:
        tiles = bake_fit_texture(model, result, photos, size, options=BakeOptions(clothes=mode))
        collar = sum(int(((t[..., 0] <= np.maximum(t[..., 1], t[..., 2]))
                          & (t[..., :3].mean(-1) > 0.4)).sum()) for t in tiles.values())
        print(f"    james, clothes {mode}: {collar} texels of the white collar's colour")
    print(f"    james, {tile_seam(model, tiles, size)}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=1024, help="texels per tile side")
    ap.add_argument("--repeat", type=int, default=5, help="warm bakes timed")
    ap.add_argument("--cold-repeat", type=int, default=3, help="cold bakes timed")
    ap.add_argument("--sample", default=str(ROOT / "generated" / "sample"),
                    help="the rendered sample whose seams are measured")
    ap.add_argument("--seams-only", action="store_true",
                    help="only the sample's seams (no timing)")
    args, _ = ap.parse_known_args(argv)  # `./run bench` passes its arguments to every bench

    model = load_model()
    if args.seams_only:
        print("bench_texture: seams of the texture bake")
        sample_seams(model, args.sample, args.size)
        james_texture(model, args.size)
        return
    views = photos()
    world = model.vertices
    tiles = uv_tiles(model)
    print("bench_texture: texture bake of the skin from two photos")
    print(f"  machine: {machine_description()}")
    print(f"  photos: 2 x 768x1024 (front, right, right also mirrored); texture "
          f"{args.size}x{args.size} per tile, tiles {', '.join(map(str, tiles))}")

    def cold():
        clear_raster_cache(model, stored=True)
        bake_tiles(model, world, views, args.size)

    def warm():
        bake_tiles(model, world, views, args.size)

    def raster_only(stored=True):
        clear_raster_cache(model, stored=stored)
        for t in tiles:
            uv_raster(model, args.size, tile=t)

    rt = median_time(raster_only, args.cold_repeat, warmup=0)
    rl = median_time(lambda: raster_only(stored=False), args.cold_repeat, warmup=0)
    c = median_time(cold, args.cold_repeat, warmup=0)
    warm()  # make sure the rasters are cached
    texels = {t: len(uv_raster(model, args.size, tile=t).texel) for t in tiles}
    w = median_time(warm, args.repeat, warmup=0)
    plain_opts = BakeOptions(equalise=False, seam_feather=0.0)
    plain = median_time(lambda: bake_tiles(model, world, views, args.size, options=plain_opts),
                        args.repeat, warmup=0)
    face = median_time(lambda: bake_texture(model, world, views, args.size, tile=tiles[0]),
                       args.repeat, warmup=0)
    print("  covered texels: " + ", ".join(f"{t}: {n}" for t, n in texels.items()))
    print(line("UV raster build (all tiles):", rt))
    print(line("UV raster load (stored by the build):", rl))
    print(line("cold bake (raster + bake):", c))
    print(line("warm bake, all tiles:", w))
    print(line("  without equalise, seam fade:", plain))
    print(line(f"warm bake, tile {tiles[0]} only:", face))
    print(f"  load average during the run: {load_average()} (wall times grow with other "
          "jobs; CPU time less so)")

    _, peak_warm = peak_memory(warm)
    clear_raster_cache(model, stored=True)
    _, peak_cold = peak_memory(warm)
    print(f"  peak traced memory: warm bake {peak_warm / 2**20:.0f} MiB, cold bake "
          f"{peak_cold / 2**20:.0f} MiB; process max RSS {max_rss_mb():.0f} MiB "
          "(model included)")
    sample_seams(model, args.sample, args.size)
    james_texture(model, args.size)


if __name__ == "__main__":
    main()
