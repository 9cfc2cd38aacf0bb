"""Fit landmarks files without the UI and write .blend files (and .glb, .obj, texture,
report), one head after another or many in parallel.

    blender -b -P headrecon_addon/headless.py -- INPUT [INPUT ...] --out OUT [options]
    python -m headrecon_addon.headless INPUT [INPUT ...] --out OUT [options]

An ``INPUT`` is a landmarks file or a manifest (``.csv`` with a header row, or ``.jsonl``;
``batch_manifest``: one head a row, with options of its own). ``OUT`` is a ``.blend`` file
for one head, or a folder (``<name>.*`` per head, and ``summary.csv`` / ``summary.jsonl``).
``--outputs blend,glb,fbx,obj,texture,report`` chooses the files (default ``blend`` and,
unless ``--no-texture``, ``texture``: the baked texture as ``<name>_texture.png``; the
.glb and .fbx are the game export, ``export.export_head``, without morph normals unless
``--morph-normals``); ``--jobs N`` fits on N worker processes (``batch_workers``; default:
the cores), results streaming as they finish. A head whose inputs and settings are those
recorded with its outputs is skipped (``batch_stamp``) unless ``--force``; every file is
written under a temporary name and renamed, so a killed batch leaves no half file and
loses only the heads in flight. The batch goes on past a failed head; one line per head
(name, method, RMS residual, flagged landmarks, time) and a progress line on stderr; the
exit code is 1 if any head failed, 2 for bad arguments or an unreadable manifest.
``--bake-identity`` applies the identity in the .blend (Apply Identity: the fitted face is
the base mesh); ``--export glb|fbx`` and ``--glb`` add the game export to the outputs.

``--detect PHOTO [PHOTO ...]`` fits a head straight from its photos: the landmarks are
detected (``python -m solver detect``: views named and cameras guessed from the faces) and
written as ``<out>.landmarks.json`` beside the head's outputs, which then is fitted like
any landmarks file (the head named after the .blend, or in a folder ``OUT`` after the
photos' folder). ``--detect FOLDER``: the photos in it are one head (named after the
folder), or, with no photo but sub-folders of photos, each sub-folder is one. A manifest's
``photos`` column (the photos separated by ";") does the same for its row. A photo
without a face fails that head only.

Other code (the demo) builds scenes with :func:`build_scene_from_fit` and writes them
with :func:`save_blend`.
"""

import argparse
import contextlib
import importlib
import os
import shutil
import sys
import time
from pathlib import Path

if __package__:
    import bpy
    import numpy as np

    from . import (
        apply_identity,
        batch_manifest,
        batch_stamp,
        batch_summary,
        batch_workers,
        blas_threads,
        case_to_scene,
        export,
        heap,
        photos,
        result_to_scene,
        scene_collections,
    )
    from .data import Transaction
    from .solver_link import (
        SHADING_MODES,
        BakeOptions,
        FitOptions,
        bake_fit_texture,
        fit_head,
        forget_fit_subsets,
        load_landmarks,
        load_model,
        orthographic_lenses,
        solver,
        usable_cores,
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
                         bake=True, name=None, textures=None, texture_shading="keep"):
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
    texture_shading : str
        ``BakeOptions.shading`` of the bake: "keep" or "remove" the photos' light.

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
            scene_collections.link_tree(scene, photos.view_root(plane))
        case_to_scene.store_case_level(scene, case)
        if textures is None and bake:
            arrays = {v: photos.image_to_array(img) for v, img in imgs.items()
                      if not img.get(photos.PLACEHOLDER)}
            if arrays:
                textures = bake_fit_texture(model, result, arrays, size=int(texture_size),
                                            options=BakeOptions(shading=texture_shading))
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


OUTPUTS = ("blend", "glb", "fbx", "obj", "texture", "report")
#: The outputs without ``--outputs``, by ``--no-texture``: the .blend, and the baked
#: texture as a PNG beside it (as Save Texture writes it in Blender).
DEFAULT_OUTPUTS = {False: ("blend", "texture"), True: ("blend",)}
PARTIAL = ".partial-"  # temporary folders of heads in flight: ".<name>.partial-<pid>"


def _fit_options(settings):
    """FitOptions of a head's settings (``ValueError`` naming the option when bad)."""
    kw = {}
    for key, name in (("method", "method"), ("n_identity", "components"),
                      ("n_regional", "regional")):
        if settings.get(name) is not None:
            kw[key] = settings[name]
    if settings.get("exact"):
        kw["exact_landmarks"] = True
    return FitOptions(**kw)


def _solver_module(name):
    return importlib.import_module(f"{solver.__name__}.{name}")


def _summary_row(name, where, result, outputs, seconds):
    noise = (result.info.get("noise") or {}).get("landmark_px") or {}
    plaus = result.info.get("plausibility") or {}
    percentile = plaus.get("percentile")
    return {"name": name, "status": "done", "error": None,
            "method": result_to_scene.fit_method(result),
            "rms_px": round(float(result.rms_px()), 4),
            "noise_px": {v: round(float(x), 4) for v, x in noise.items()},
            "plausibility": None if percentile is None else round(float(percentile), 3),
            "warnings": list(result.info.get("warnings", ())),
            "flagged": len(result.flagged()), "seconds": round(seconds, 3),
            "outputs": {k: str(p) for k, p in outputs.items()}, "input": where}


def _targets(base, kinds):
    """Output kind -> final path of a head whose outputs are ``base.*``."""
    base = Path(base)
    named = {"blend": ".blend", "glb": ".glb", "fbx": ".fbx", "obj": ".obj",
             "report": ".report.json"}
    out = {k: base.with_name(base.name + named[k]) for k in kinds if k in named}
    if "obj" in kinds:
        out["mtl"] = base.with_name(base.name + ".mtl")
    if "texture" in kinds:
        out["texture"] = base.with_name(base.name + "_texture.png")
    return out


def write_head(task, model):
    """Fit one head of a batch and write its outputs; returns its summary row.

    Parameters
    ----------
    task : dict
        "name", "landmarks", "base" (outputs' path without suffix), "where" (the input
        in messages), "settings" (``outputs``, ``texture_size``, ``bake``,
        ``bake_identity``, ``morph_normals`` and the fit options), "hash" (recorded with
        the outputs, ``batch_stamp``).
    model : HeadModel

    Every output is written into a temporary folder beside the outputs and renamed into
    place; the record (``batch_stamp.write_record``) is written last.
    """
    t0 = time.perf_counter()
    name, path, base = task["name"], Path(task["landmarks"]), Path(task["base"])
    settings = task["settings"]
    kinds = settings["outputs"]
    options = _fit_options(settings)
    case = load_landmarks(path)
    targets = _targets(base, kinds)
    inputs = {"the landmarks file": path}
    inputs.update({f"the photo of view {v}": case.image_path(v) for v in case.views})
    _solver_module("io.atomic").check_outputs(
        {f"output {k}": p for k, p in targets.items()}, inputs)
    reset_scene()
    heap.release_free_memory()  # the last head's scene, before the fit and bake take more
    imgs = _images_for(case, None)  # fails fast on a missing photo, before the fit
    orthographic_lenses(case)  # the photos' EXIF lenses, for the projection check
    result = fit_head(model, case, options)
    forget_fit_subsets(model)  # this head's subsets: another head seldom asks for them
    for message in result.info.get("warnings", ()):
        print(f"{name}: warning: {message}", file=sys.stderr, flush=True)
    tiles = None
    if settings["bake"]:
        arrays = {v: photos.image_to_array(img) for v, img in imgs.items()
                  if not img.get(photos.PLACEHOLDER)}
        if arrays:
            tiles = bake_fit_texture(  # one thread: the batch's processes share the cores
                model, result, arrays, size=int(settings["texture_size"]),
                options=BakeOptions(shading=settings.get("texture_shading") or "keep",
                                    threads=1))
        heap.release_free_memory()  # the bake's temporaries, before Blender takes more
    if "texture" in kinds and tiles is None:
        raise ValueError(f"{task['where']}: no photo to bake the texture from")
    base.parent.mkdir(parents=True, exist_ok=True)
    staging = base.parent / f".{base.name}{PARTIAL}{os.getpid()}"
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir()
    try:
        staged = _write_staged(staging, base.name, name, kinds, model, case, result, imgs,
                               tiles, settings, targets, t0)
        for kind, tmp in staged.items():
            if tmp.is_dir():  # the .fbx's textures folder
                shutil.rmtree(targets[kind], ignore_errors=True)
            os.replace(tmp, targets[kind])
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    row = _summary_row(name, task["where"], result,
                       {k: p for k, p in targets.items() if k in staged},
                       time.perf_counter() - t0)
    batch_stamp.write_record(base, task["hash"], row)
    return row


def _write_staged(staging, stem, name, kinds, model, case, result, imgs, tiles, settings,
                  targets, t0):
    """Write a head's outputs into ``staging`` under their final names; returns kind ->
    staged path. ``imgs``: the photos as bpy images, ``tiles``: the baked texture."""
    staged = {}
    needs_scene = {"blend", "glb", "fbx"} & set(kinds)
    if needs_scene:
        head = build_scene_from_fit(model, case, result, imgs, bake=False, textures=tiles,
                                    name=name)
        if settings["bake_identity"]:
            apply_identity.apply_identity(head, model.expression_names)
        if "blend" in kinds:
            staged["blend"] = save_blend(staging / f"{stem}.blend")
        for fmt in ("glb", "fbx"):
            if fmt in kinds:
                staged[fmt] = export.export_head(staging / f"{stem}.{fmt}", head,
                                                 model.expression_names,
                                                 fmt.upper(),
                                                 morph_normals=settings["morph_normals"])
                if fmt == "fbx" and (staging / f"{stem}_textures").is_dir():
                    staged["fbx_textures"] = staging / f"{stem}_textures"
                    targets["fbx_textures"] = targets["fbx"].with_name(f"{stem}_textures")
    files = {}
    if "obj" in kinds:
        names, obj_files = _solver_module("io.export").head_obj_files(
            staging / f"{stem}.obj", model, result.local_vertices, tiles,
            staging / f"{stem}_texture.png" if tiles is not None else None)
        files.update(obj_files)
        staged.update({k: p for k, p in names.items() if k in ("obj", "mtl")})
        if tiles is not None:
            staged["obj_texture"] = names["texture"]
            targets["obj_texture"] = targets["obj"].with_name(f"{stem}_texture.png")
    if "texture" in kinds:
        staged.pop("obj_texture", None)
        targets.pop("obj_texture", None)
        tex = staging / f"{stem}_texture.png"
        if tex not in files:
            atlas, _, _ = _solver_module("io.export").texture_atlas(model, tiles)
            files[tex] = _solver_module("io.export").png_bytes(atlas)
        staged["texture"] = tex
    if "report" in kinds:
        rep = _solver_module("io.report")
        final = {k: targets[k] for k in ("blend", "glb", "fbx", "obj", "mtl", "texture")
                 if k in targets}
        final["report"] = targets["report"]
        text = rep.report_text(rep.fit_report(case, model, result, settings, final,
                                              {"total": time.perf_counter() - t0}))
        files[staging / f"{stem}.report.json"] = text
        staged["report"] = staging / f"{stem}.report.json"
    if files:
        _solver_module("io.atomic").write_files_atomic(files)
    return staged


def _outputs_arg(text):
    kinds = [k.strip().lower() for k in text.split(",") if k.strip()]
    bad = [k for k in kinds if k not in OUTPUTS]
    if bad or not kinds:
        raise argparse.ArgumentTypeError(
            f"{bad[0] if bad else text!r}: expected a comma-separated list of "
            f"{', '.join(OUTPUTS)}")
    return kinds


def _parser():
    p = argparse.ArgumentParser(
        prog="headless", description="Fit HeadRecon landmarks files (or manifests of them) "
                                     "and write .blend files and other outputs.")
    p.add_argument("inputs", nargs="*", metavar="INPUT",
                   help="landmarks files (.json) and manifests (.csv with a header, .jsonl)")
    p.add_argument("--out", metavar="OUT",
                   help="a .blend file (one head) or a folder (one set of outputs per head, "
                        "and summary.csv / summary.jsonl)")
    p.add_argument("--outputs", type=_outputs_arg, metavar="LIST",
                   help=f"comma-separated outputs per head: {', '.join(OUTPUTS)} "
                        "(default: blend,texture; blend with --no-texture)")
    p.add_argument("--jobs", type=int, metavar="N",
                   help="worker processes (default: the cores this process may use)")
    p.add_argument("--force", action="store_true",
                   help="fit every head again, even those unchanged since their outputs")
    p.add_argument("--export", choices=("glb", "fbx"),
                   help="also write a game export (fitted base, ARKit keys, texture) next to "
                        "each .blend (the same as adding it to --outputs)")
    p.add_argument("--glb", action="store_true", help="the same as --export glb")
    p.add_argument("--morph-normals", action="store_true",
                   help="write the morph targets' normals too (.glb; about doubles the file)")
    p.add_argument("--bake-identity", action="store_true",
                   help="apply the identity in the .blend: the fitted face becomes the base "
                        "mesh, the identity keys are removed, the expression keys still work")
    p.add_argument("--method", choices=batch_manifest.METHODS)
    p.add_argument("--components", type=int, help="identity components to fit")
    p.add_argument("--regional", type=int, help="regional components per region (0: none)")
    p.add_argument("--exact", action="store_true", help="make the landmarks hit exactly")
    p.add_argument("--texture-size", type=int, default=1024)
    p.add_argument("--no-texture", action="store_true", help="do not bake a texture")
    p.add_argument("--texture-shading", choices=SHADING_MODES, default="keep",
                   help="keep the photos' light in the texture, or remove its low-frequency "
                        "part for a flat, albedo-like texture (default keep)")
    p.add_argument("--detect", nargs="+", action="append", metavar="PHOTO",
                   help="fit a head straight from its photos (landmarks detected, written as "
                        "<name>.landmarks.json beside the outputs); or a folder of one "
                        "head's photos, or of sub-folders one per head; repeatable")
    p.add_argument("--cluster", metavar="ADDRESS",
                   help="run the heads on a Dask distributed cluster: its scheduler "
                        "(tcp://host:8786, or a scheduler file .json), or 'local' for a "
                        "one-machine cluster of --jobs worker processes (needs "
                        "dask[distributed], not bundled)")
    p.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    return p


def script_args(argv):
    """Arguments meant for this script: after "--" under ``blender -b -P``, else argv[1:]."""
    argv = list(argv)
    return argv[argv.index("--") + 1:] if "--" in argv else argv[1:]


def _settings(args):
    """The batch-wide settings (per-head manifest columns override them)."""
    kinds = list(args.outputs or DEFAULT_OUTPUTS[args.no_texture])
    for extra in (args.export, "glb" if args.glb else None):
        if extra and extra not in kinds:
            kinds.append(extra)
    if args.no_texture and "texture" in kinds:
        raise ValueError("--outputs texture: the texture is not baked with --no-texture")
    return {"outputs": [k for k in OUTPUTS if k in kinds], "bake": not args.no_texture,
            "texture_size": args.texture_size, "texture_shading": args.texture_shading,
            "bake_identity": args.bake_identity,
            "morph_normals": args.morph_normals, "method": args.method,
            "components": args.components, "regional": args.regional,
            "exact": args.exact}


def _remove_stale_partials(folder):
    """Remove the temporary folders a killed batch left (their process is gone)."""
    for tmp in folder.glob(f".*{PARTIAL}*"):
        try:
            pid = int(tmp.name.rsplit(PARTIAL, 1)[1])
            os.kill(pid, 0)  # still running: another batch's head in flight
        except (ValueError, ProcessLookupError):
            shutil.rmtree(tmp, ignore_errors=True)
        except PermissionError:
            pass


def _tasks(heads, settings, force):
    """Summary rows already known (failed rows, unchanged heads) and the tasks to run, in
    plan order: (rows, tasks) with rows[i] None where a task will fill it."""
    rows, tasks = [], []
    for i, h in enumerate(heads):
        if h.error:
            rows.append(batch_summary.failed_row(h.name, h.where, h.error))
            continue
        mine = {**settings, **h.options}
        try:
            digest = batch_stamp.content_hash(h.landmarks, mine)
        except OSError as e:
            rows.append(batch_summary.failed_row(
                h.name, h.where, f"{h.where}: landmarks {h.landmarks}: {e.strerror or e}"))
            continue
        done = None if force else batch_stamp.finished_record(h.base, digest)
        if done is not None:
            rows.append({**done, "status": "skipped", "input": h.where})
            continue
        rows.append(None)
        tasks.append({"index": i, "name": h.name, "landmarks": str(h.landmarks),
                      "base": str(h.base), "where": h.where, "settings": mine,
                      "hash": digest})
    return rows, tasks


#: Photo files a --detect folder is read for.
PHOTO_SUFFIXES = (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".bmp", ".webp")


def _photos_in(folder):
    return sorted(p for p in Path(folder).iterdir()
                  if p.is_file() and p.suffix.lower() in PHOTO_SUFFIXES)


def detect_groups(groups):
    """(name, photos, where) of each head to detect: every ``--detect`` group is a list of
    photos (one head, named after their folder) or a single folder (its photos one head,
    else each sub-folder of photos one head). ``ValueError`` naming a folder without
    photos."""
    out = []
    for group in groups or ():
        paths = [Path(p) for p in group]
        if len(paths) == 1 and paths[0].is_dir():
            folder = paths[0]
            photos = _photos_in(folder)
            if photos:
                out.append((folder.resolve().name, photos, f"--detect {folder}"))
                continue
            subs = [(d, _photos_in(d)) for d in sorted(folder.iterdir()) if d.is_dir()]
            subs = [(d, ps) for d, ps in subs if ps]
            if not subs:
                raise ValueError(f"--detect {folder}: no photos in it nor in its sub-folders "
                                 f"({', '.join(PHOTO_SUFFIXES)})")
            out += [(d.name, ps, f"--detect {d}") for d, ps in subs]
        else:
            name = paths[0].resolve().parent.name or "head"
            out.append((name, paths, "--detect " + " ".join(map(str, paths))))
    return out


def detected_head(head):
    """``head`` (a ``batch_manifest.Head`` with ``photos`` and no landmarks file) with its
    landmarks detected into ``<base>.landmarks.json`` (``solver.cli.detect_landmarks``, the
    detect command's own code), or with the one-line error when its photos fail."""
    if head.error is not None or head.landmarks is not None or not head.photos:
        return head
    cli = _solver_module("cli")
    landmarks = head.base.with_name(head.base.name + ".landmarks.json")
    try:
        head.base.parent.mkdir(parents=True, exist_ok=True)
        cli.detect_landmarks([str(p) for p in head.photos], landmarks, quiet=True)
    except (cli.CliError, ValueError, OSError) as e:
        message = str(e) if head.where in str(e) else f"{head.where}: {e}"
        return batch_manifest.Head(head.name, None, head.base, head.where, head.options,
                                   error=message, photos=head.photos)
    return batch_manifest.Head(head.name, landmarks, head.base, head.where, head.options,
                               photos=head.photos)


def detected_heads(groups, out):
    """Heads from ``--detect`` groups (``detect_groups``), each run through
    :func:`detected_head`."""
    out = Path(out)
    single = out.suffix.lower() == ".blend"
    heads = []
    for name, photos, where in detect_groups(groups):
        if single:  # the head is named after its .blend
            name = out.stem
        base = out.with_suffix("") if single else out / name
        heads.append(detected_head(batch_manifest.Head(name, None, base, where,
                                                       photos=tuple(photos))))
    return heads


def _run_task(task, model):
    """``write_head`` with any failure as a failed summary row."""
    t0 = time.perf_counter()
    try:
        return write_head(task, model)
    except Exception as e:  # report and go on with the batch
        message = str(e) if task["where"] in str(e) else f"{task['where']}: {e}"
        return batch_summary.failed_row(task["name"], task["where"], message,
                                        time.perf_counter() - t0)


def _cluster_failed(task, message):
    return batch_summary.failed_row(
        task["name"], task["where"],
        f"{task['where']}: the cluster could not fit it ({message})")


def _in_process(tasks, model):
    for task in tasks:
        yield task, _run_task(task, model)


def _head_line(row):
    if row["status"] == "failed":
        return f"{row['name']}: FAILED: {row['error']}"
    outs = ", ".join(row["outputs"].values())
    if row["status"] == "skipped":
        return f"{row['name']}: unchanged, skipped -> {outs}"
    return (f"{row['name']}: method {row['method']}, RMS {row['rms_px']:.2f} px, "
            f"{row.get('flagged', 0)} flagged, {row['seconds']:.2f} s -> {outs}")


def serve_worker():
    """A worker process of a batch: load the model once, then fit the heads sent to it."""
    model = load_model()
    batch_workers.serve(lambda task: _run_task(task, model))
    return 0


def main(argv):
    args = _parser().parse_args(argv)
    if args.worker:
        return serve_worker()
    try:
        if not (args.inputs or args.detect) or not args.out:
            raise ValueError("give the inputs (or --detect PHOTO ...) and --out OUT")
        if args.jobs is not None and args.jobs < 1:
            raise ValueError(f"--jobs {args.jobs}: give 1 or more")
        settings = _settings(args)
        _fit_options(settings)  # a bad option fails here, once, not in every head
        out_dir = None if Path(args.out).suffix.lower() == ".blend" else Path(args.out)
        n_detect = len(detect_groups(args.detect))
        if out_dir is None and len(args.inputs) + n_detect > 1 and n_detect:
            raise ValueError(f"--out {args.out}: one .blend file for several heads; give a "
                             "folder instead")
        heads = batch_manifest.plan_heads(args.inputs, args.out) if args.inputs else []
        heads = [detected_head(h) for h in heads]  # a manifest's photos column
        heads += detected_heads(args.detect, args.out)
        if out_dir is not None:
            _solver_module("io.atomic").check_outputs(
                {"summary.csv": out_dir / "summary.csv",
                 "summary.jsonl": out_dir / "summary.jsonl"},
                {f"input {p}": p for p in args.inputs})
        rows, tasks = _tasks(heads, settings, args.force)
        jobs = min(args.jobs or usable_cores(), len(tasks))
        if args.cluster:
            cluster = importlib.import_module(f"{__package__}.batch_cluster")
            cluster.distributed()  # not installed: one line, before anything runs
        model = load_model() if jobs <= 1 and tasks and not args.cluster else None
    except (ValueError, FileNotFoundError) as e:
        print(f"headless: {e}", file=sys.stderr)
        return 2
    with contextlib.ExitStack() as stack:
        client = None
        if args.cluster and tasks:
            try:
                client = stack.enter_context(cluster.client_for(args.cluster, max(jobs, 1)))
            except (OSError, ValueError) as e:  # no scheduler there, a bad address
                print(f"headless: --cluster {args.cluster}: {e}", file=sys.stderr)
                return 2
        return _run_batch(args, heads, rows, tasks, jobs, model, out_dir, client)


def _run_batch(args, heads, rows, tasks, jobs, model, out_dir, client):
    """The batch once planned: the known rows, then the tasks' rows as they finish (in
    this process, on local workers, or on the cluster of ``client``)."""
    folder = out_dir or Path(args.out).parent
    folder.mkdir(parents=True, exist_ok=True)
    _remove_stale_partials(folder)
    progress = batch_summary.Progress(len(heads))
    for row in rows:
        if row is not None:
            progress.add(row["status"], fitted=False)
            print(_head_line(row), flush=True)
    if client is not None:
        cluster = importlib.import_module(f"{__package__}.batch_cluster")
        results = cluster.run_cluster(tasks, client, _cluster_failed)
    elif jobs <= 1:
        blas_threads.limit_loaded()  # as a worker process has it
        results = _in_process(tasks, model)
    else:
        results = batch_workers.run_pool(tasks, jobs, batch_summary.worker_died_row)
    last_write = 0.0
    try:
        for task, row in results:
            rows[task["index"]] = row
            progress.add(row["status"])
            print(_head_line(row), flush=True)
            print(progress.line(), file=sys.stderr, flush=True)
            if out_dir is not None and time.monotonic() - last_write > 2.0:
                batch_summary.write_summaries(out_dir, [r for r in rows if r is not None])
                last_write = time.monotonic()
    except KeyboardInterrupt:  # the heads finished so far are written and recorded
        if out_dir is not None:
            batch_summary.write_summaries(out_dir, [r for r in rows if r is not None])
        print("headless: interrupted; run again to fit the heads not written",
              file=sys.stderr, flush=True)
        return 130
    if out_dir is not None:
        batch_summary.write_summaries(out_dir, rows)
    failed = progress.counts["failed"]
    skipped = progress.counts["skipped"]
    note = f" ({skipped} unchanged, skipped)" if skipped else ""
    print(f"{len(heads) - failed} of {len(heads)} heads written{note}", flush=True)
    if client is not None:
        try:
            loads = importlib.import_module(f"{__package__}.batch_cluster").loads_per_worker(
                client)
        except Exception as e:  # a worker gone at the end: the batch is done anyway
            print(f"cluster: the workers' model loads unknown ({e})", file=sys.stderr)
        else:
            counts = [sum(v.values()) for v in loads.values()]
            print(f"cluster: {len(loads)} workers, the model loaded "
                  f"{'/'.join(map(str, counts))} times on them", file=sys.stderr, flush=True)
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
