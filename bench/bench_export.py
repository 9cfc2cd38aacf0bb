"""Benchmark of the game exports: size and time of the .glb (and .fbx) of one fitted head
with its texture baked at 2048 x 1024 (two 1024-texel tiles).

    python -m bench.bench_export [--texture-size 1024] [--repeat 3] [--out DIR]
    HEADRECON_REALDATA=/path/to/shared/realdata python -m bench.bench_export  # from a worktree

Target: the game .glb under 15 MB. The head is fitted to the real photos of the scan
"james" (``bench/realistic_cases.py``; a real texture, which compresses as a real head's
does) when that scan is found, else to a synthetic case with smooth generated photos (a
texture far easier to compress: the size is then a lower bound, and says so). Also
printed, for comparison: the head exported as before the presets (identity in 100+ keys,
morph normals), the preset with morph normals, and the .fbx.
"""

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import bpy  # noqa: E402
import numpy as np  # noqa: E402

from bench.common import machine_description  # noqa: E402


def james_case(model):
    """(case, photos {view: (H, W, 3) float32, row 0 at the top}, label) from the scan
    "james", or None when it is not there."""
    from PIL import Image

    from bench.realistic_cases import calibrate, james_folder, load_scan, scan_cases

    folder = james_folder(ROOT)
    if not (folder / "james.obj").is_file():
        return None
    scan = load_scan(folder)
    calib = {photo: calibrate(scan, photo) for photo in scan.photos}
    cases, _ = scan_cases(scan, {p: c.camera for p, c in calib.items()})
    rgb = np.asarray(Image.open(folder / "james.jpg").convert("RGB"), dtype=np.float32) / 255
    half = rgb.shape[1] // 2
    photos = {"photo_a": rgb[:, :half], "photo_b": rgb[:, half:2 * half]}
    return cases["DLT, projected"], photos, "the real scan james (its two photos)"


def synthetic_case(model):
    from solver import synthetic

    case, _ = synthetic.make_case(model, 0)
    photos = {}
    for name, view in case.views.items():
        w, h = view.size
        u = np.linspace(0, 1, w)[None, :, None]
        v = np.linspace(0, 1, h)[:, None, None]
        photos[name] = np.concatenate([0.3 + 0.4 * u + 0 * v, 0.3 + 0.4 * v + 0 * u,
                                       0.5 + 0 * u + 0 * v], axis=2).astype(np.float32)
    return case, photos, "a synthetic case, smooth photos (a lower bound on the size)"


def timed(repeat, fn):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return out, statistics.median(times)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--texture-size", type=int, default=1024, help="texels per tile")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--out", type=Path, help="keep the files here (default: a temp folder)")
    args = p.parse_args(argv)

    import headrecon_addon
    from headrecon_addon import export, head_scene
    from solver import FitOptions, fit_head, load_model

    print(f"machine: {machine_description()}")
    model = load_model()
    case, photos, label = james_case(model) or synthetic_case(model)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if not headrecon_addon.is_registered():
        headrecon_addon.register()
    t0 = time.perf_counter()
    result = fit_head(model, case, FitOptions())
    head = head_scene.build_scene_from_fit(model, case, result, photos,
                                           texture_size=args.texture_size, name="head")
    n = args.texture_size
    print(f"head: {label}; fitted and baked ({2 * n} x {n} texture) in "
          f"{time.perf_counter() - t0:.2f} s; {len(head.data.vertices)} vertices, "
          f"{len(head.data.shape_keys.key_blocks) - 1} shape keys")

    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp)
        names = model.expression_names
        runs = [("game .glb (preset)", lambda: export.export_head(out / "game.glb", head, names)),
                ("game .glb, morph normals", lambda: export.export_head(
                    out / "normals.glb", head, names, morph_normals=True))]
        if export.exporter_available("FBX"):
            runs.append(("game .fbx (preset)", lambda: export.export_head(
                out / "game.fbx", head, names, "FBX")))

        def before():
            path = out / "before.glb"
            for o in bpy.context.view_layer.objects:
                o.select_set(o == head)
            bpy.ops.export_scene.gltf(filepath=str(path), export_format="GLB",
                                      use_selection=True, export_morph=True,
                                      export_morph_normal=True, export_apply=False)
            return path

        runs.append(("before the presets: every key, morph normals", before))
        for what, fn in runs:
            path, seconds = timed(args.repeat, fn)
            size = path.stat().st_size
            beside = sum(f.stat().st_size for f in path.parent.glob(f"{path.stem}_textures/*")
                         ) if path.suffix == ".fbx" else 0
            extra = f" (+ {beside / 1e6:.1f} MB of PNG beside it)" if beside else ""
            print(f"{what}: {size / 1e6:.1f} MB{extra}, export median {seconds:.2f} s "
                  f"(of {args.repeat})", flush=True)


if __name__ == "__main__":
    main()
