"""Fit landmarks files without the UI and write .blend files (and .glb / .fbx).

    blender -b -P headrecon_addon/headless.py -- A.json [B.json ...] --out OUT
        [--bake-identity] [--export glb|fbx] [--morph-normals]
    python -m headrecon_addon.headless A.json [B.json ...] --out OUT [...]

``OUT`` is a ``.blend`` file for one input, or a folder (one ``<name>.blend`` per input).
Each .blend holds the head with its shape keys, transform, uncertainty attributes and the
baked texture packed into the file, plus the photo planes with their landmarks. A batch
goes on past a failed file; one summary line per head (name, method, RMS residual,
flagged landmarks, time); the exit code is 1 if any file failed, 2 for bad arguments.
``--bake-identity`` applies the identity in the .blend (Apply Identity: the fitted face is
the base mesh); ``--export glb|fbx`` writes the game export next to each .blend
(``export.export_head``: fitted base, ARKit keys, texture, no morph normals unless
``--morph-normals``); ``--glb`` is ``--export glb``.

Other code (the demo) builds scenes with :func:`build_scene_from_fit` and writes them
with :func:`save_blend`.
"""

import argparse
import importlib
import sys
import time
from pathlib import Path

if __package__:
    import bpy
    import numpy as np

    from . import apply_identity, case_to_scene, export, photos, result_to_scene
    from .data import Transaction
    from .solver_link import (
        FitOptions,
        bake_fit_texture,
        fit_head,
        load_landmarks,
        load_model,
    )


def ensure_registered():
    """Register the add-on's classes and properties unless they already are."""
    pkg = importlib.import_module(__package__)
    if not pkg.is_registered():
        pkg.register()


def reset_scene():
    """An empty scene (factory settings), the add-on registered."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    ensure_registered()


def _images_for(case, images):
    """bpy images per view from ``images`` (view -> path, bpy Image or ndarray (H, W, 3|4)
    in [0, 1] with row 0 at the top); views not given use the case's own photo paths (a
    grey stand-in when the file names none)."""
    images = dict(images or {})
    out = {}
    for view in case.views:
        given = images.get(view)
        if given is None:
            out.update(case_to_scene.load_case_images(_only(case, view)))
        elif isinstance(given, bpy.types.Image):
            out[view] = given
        elif isinstance(given, str | Path):
            out[view] = photos.load_image(given)
        else:
            arr = np.asarray(given, dtype=np.float32)
            if arr.ndim != 3 or arr.shape[2] not in (3, 4):
                raise ValueError(f"images[{view!r}]: expected (H, W, 3|4), got {arr.shape}")
            out[view] = photos.array_to_image(arr, f"HeadRecon {view} photo")
    return out


def _only(case, view):
    return type(case)({view: case.views[view]}, case.source)


def build_scene_from_fit(model, case, result, images=None, scene=None, texture_size=1024,
                         bake=True, name=None, textures=None):
    """Build the artist's scene for a finished fit: photo planes with landmarks (and
    contour, passpoints), a Blender camera per perspective photo set to its fitted camera,
    and the head with shape keys, transform, uncertainty and baked texture; the residual
    list with the passpoint checks.

    Parameters
    ----------
    model : HeadModel
    case : LandmarkCase
    result : FitResult
        ``fit_head(model, case, ...)``.
    images : dict of str -> (path | bpy.types.Image | ndarray (H, W, 3|4)), optional
        Photo of each view (default: the paths in the case).
    scene : bpy.types.Scene, optional
        Default: the current scene.
    texture_size : int
        Baked texture size in texels.
    bake : bool
        Bake the texture from the photos (when ``textures`` is not given).
    name : str, optional
        The head object's name (default "HeadRecon Head").
    textures : dict of int -> ndarray (S, S, 3|4), optional
        A bake the caller already has (``bake_fit_texture(model, result, ...)``, UDIM tile
        -> texture, row 0 at the top): used as it is, nothing is baked again.

    Returns
    -------
    bpy.types.Object
        The head.
    """
    ensure_registered()
    scene = scene or bpy.context.scene
    with Transaction():
        imgs = _images_for(case, images)
        planes = case_to_scene.build_view_planes(case, imgs)
        for plane in planes:
            photos.link_object(photos.view_root(plane), scene.collection)
        case_to_scene.store_case_level(scene, case)
        if textures is None and bake:
            arrays = {v: photos.image_to_array(img) for v, img in imgs.items()
                      if not img.get(photos.PLACEHOLDER)}
            if arrays:
                textures = bake_fit_texture(model, result, arrays, size=int(texture_size))
        calibration, _ = result_to_scene.calibration_checks(case)
        head = result_to_scene.apply_result(scene, model, result, textures, name=name,
                                            calibration=calibration)
    return head


def save_blend(path):
    """Save the current file to ``path`` (a .blend) with every photo and texture packed,
    so it opens anywhere. Returns the path."""
    path = Path(path).resolve()
    path.parent.mkdir(parents=True, exist_ok=True)
    for img in bpy.data.images:
        if img.packed_file is None and img.source == "FILE" and img.has_data:
            img.pack()
    result_to_scene.pack_baked_textures()
    prefs = bpy.context.preferences.filepaths
    versions = prefs.save_version
    prefs.save_version = 0  # no head.blend1 backups next to batch output
    try:
        bpy.ops.wm.save_as_mainfile(filepath=str(path), check_existing=False, compress=True)
    finally:
        prefs.save_version = versions
    return path


def fit_file(path, out, model, options=None, texture_size=1024, bake=True, export_format=None,
             bake_identity=False, morph_normals=False):
    """Fit one landmarks file and write its .blend (with the identity applied when
    ``bake_identity``) and, with ``export_format`` ("GLB" | "FBX"), its game export next to
    it. Returns a summary dict."""
    t0 = time.perf_counter()
    case = load_landmarks(path)
    reset_scene()
    imgs = _images_for(case, None)  # fails fast on a missing photo, before the fit
    result = fit_head(model, case, options or FitOptions())
    for message in result.info.get("warnings", ()):
        print(f"{Path(path).stem}: warning: {message}", file=sys.stderr, flush=True)
    head = build_scene_from_fit(model, case, result, imgs, texture_size=texture_size,
                                bake=bake, name=Path(path).stem)
    if bake_identity:
        apply_identity.apply_identity(head, model.expression_names)
    written = [save_blend(out)]
    if export_format:
        written.append(export.export_head(Path(out), head, model.expression_names,
                                          export_format, morph_normals=morph_normals))
    return {"name": Path(path).stem, "method": result_to_scene.fit_method(result),
            "rms_px": result.rms_px(), "flagged": len(result.flagged()),
            "seconds": time.perf_counter() - t0, "outputs": [str(p) for p in written]}


def plan_outputs(inputs, out):
    """Output .blend path of each input: ``out`` itself for one input ending in .blend,
    else ``out/<stem>.blend``. Raises ValueError for clashing names."""
    out = Path(out)
    if out.suffix.lower() == ".blend":
        if len(inputs) != 1:
            raise ValueError(f"--out {out}: one .blend file for {len(inputs)} inputs; give a "
                             "folder instead")
        return [(Path(inputs[0]), out)]
    plan = [(Path(p), out / f"{Path(p).stem}.blend") for p in inputs]
    seen = {}
    for src, dst in plan:
        if dst in seen:
            raise ValueError(f"{src} and {seen[dst]} would both write {dst}; rename one")
        seen[dst] = src
    return plan


def _parser():
    p = argparse.ArgumentParser(
        prog="headless", description="Fit HeadRecon landmarks files and write .blend files.")
    p.add_argument("landmarks", nargs="+", metavar="LANDMARKS.json")
    p.add_argument("--out", required=True, metavar="OUT",
                   help="a .blend file (one input) or a folder (one .blend per input)")
    p.add_argument("--export", choices=("glb", "fbx"),
                   help="also write a game export (fitted base, ARKit keys, texture) next to "
                        "each .blend")
    p.add_argument("--glb", action="store_true", help="the same as --export glb")
    p.add_argument("--morph-normals", action="store_true",
                   help="write the morph targets' normals too (.glb; about doubles the file)")
    p.add_argument("--bake-identity", action="store_true",
                   help="apply the identity in the .blend: the fitted face becomes the base "
                        "mesh, the identity keys are removed, the expression keys still work")
    p.add_argument("--method", choices=("combined", "approach1", "approach2"))
    p.add_argument("--components", type=int, help="identity components to fit")
    p.add_argument("--regional", type=int, help="regional components per region (0: none)")
    p.add_argument("--exact", action="store_true", help="make the landmarks hit exactly")
    p.add_argument("--texture-size", type=int, default=1024)
    p.add_argument("--no-texture", action="store_true", help="do not bake a texture")
    return p


def script_args(argv):
    """Arguments meant for this script: after "--" under ``blender -b -P``, else argv[1:]."""
    argv = list(argv)
    return argv[argv.index("--") + 1:] if "--" in argv else argv[1:]


def main(argv):
    args = _parser().parse_args(argv)
    try:
        plan = plan_outputs(args.landmarks, args.out)
    except ValueError as e:
        print(f"headless: {e}", file=sys.stderr)
        return 2
    kw = {}
    for key, value in (("method", args.method), ("n_identity", args.components),
                       ("n_regional", args.regional)):
        if value is not None:
            kw[key] = value
    if args.exact:
        kw["exact_landmarks"] = True
    try:
        options = FitOptions(**kw)
        model = load_model()
    except (ValueError, FileNotFoundError) as e:
        print(f"headless: {e}", file=sys.stderr)
        return 2
    export_format = (args.export or ("glb" if args.glb else "")).upper() or None
    failed = 0
    for src, dst in plan:
        try:
            s = fit_file(src, dst, model, options, args.texture_size, not args.no_texture,
                         export_format, args.bake_identity, args.morph_normals)
        except Exception as e:  # report and go on with the batch
            failed += 1
            print(f"{src.stem}: FAILED: {e}", flush=True)
            continue
        print(f"{s['name']}: method {s['method']}, RMS {s['rms_px']:.2f} px, "
              f"{s['flagged']} flagged, {s['seconds']:.2f} s -> {', '.join(s['outputs'])}",
              flush=True)
    print(f"{len(plan) - failed} of {len(plan)} heads written", flush=True)
    return 1 if failed else 0


def exit_process(code):
    """Exit with ``code``. The bpy module before 4.4 crashes while Python shuts down
    (Blender issue #125376, exit status -11 whatever the script returned), so there the
    process ends at once, after flushing its output."""
    import bpy as _bpy

    sys.stdout.flush()
    sys.stderr.flush()
    if not _bpy.app.binary_path and _bpy.app.version < (4, 4, 0):
        import os

        os._exit(code)
    sys.exit(code)


if __name__ == "__main__":
    if not __package__:  # run as a file by `blender -b -P`: import as the package module
        sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
        _self = importlib.import_module("headrecon_addon.headless")
        _self.exit_process(_self.main(script_args(sys.argv)))
    exit_process(main(script_args(sys.argv)))
