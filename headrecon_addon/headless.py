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
without a face fails that head only. ``--lens MM`` gives the lens of detected photos whose
EXIF gives none (they are then perspective photos, as with ``solver detect --lens``).

This process plans the batch and, at ``--jobs 2`` or more, only waits on its workers: it
never imports bpy then (``batch_head``, the head's fit and outputs, does), so the workers
start at once. Scripts that build a head's scene themselves use ``head_scene``.
"""

import argparse
import contextlib
import importlib
import os
import sys
import time
from pathlib import Path

if __package__:  # no bpy here: a batch's own process plans and waits on its workers
    from . import batch_manifest, batch_stamp, batch_summary, batch_workers, blas_threads
    from .solver_link import (
        CLOTHES_MODES,
        FIT_METHODS,
        SHADING_MODES,
        load_model,
        solver_module,
        usable_cores,
    )


OUTPUTS = ("blend", "glb", "fbx", "obj", "texture", "report")
#: The outputs without ``--outputs``, by ``--no-texture``: the .blend, and the baked
#: texture as a PNG beside it (as Save Texture writes it in Blender).
DEFAULT_OUTPUTS = {False: ("blend", "texture"), True: ("blend",)}


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
    p.add_argument("--method", choices=FIT_METHODS)
    p.add_argument("--components", type=int, help="identity components to fit")
    p.add_argument("--regional", type=int, help="regional components per region (0: none)")
    p.add_argument("--exact", action="store_true", help="make the landmarks hit exactly")
    p.add_argument("--texture-size", type=int, default=1024)
    p.add_argument("--no-texture", action="store_true", help="do not bake a texture")
    p.add_argument("--texture-shading", choices=SHADING_MODES, default="keep",
                   help="keep the photos' light in the texture, or remove its low-frequency "
                        "part for a flat, albedo-like texture (default keep)")
    p.add_argument("--texture-clothes", choices=CLOTHES_MODES, default="leave-out",
                   help="leave out what the photos show of clothes below the chin (a collar, "
                        "a shirt) so the neck there gets the smooth fill, or keep the photos "
                        "as they are (default leave-out)")
    p.add_argument("--detect", nargs="+", action="append", metavar="PHOTO",
                   help="fit a head straight from its photos (landmarks detected, written as "
                        "<name>.landmarks.json beside the outputs); or a folder of one "
                        "head's photos, or of sub-folders one per head; repeatable")
    p.add_argument("--lens", type=solver_module("cli").lens_mm_arg, metavar="MM",
                   help="the lens (mm, 36 mm equivalent) of detected photos whose EXIF gives "
                        "none (as solver detect --lens): they are fitted as perspective "
                        "photos of it")
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
            "texture_clothes": args.texture_clothes,
            "bake_identity": args.bake_identity,
            "morph_normals": args.morph_normals, "method": args.method,
            "components": args.components, "regional": args.regional,
            "exact": args.exact}


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
                      "hash": digest, "warnings": list(h.warnings)})
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


def detected_head(head, lens_mm=None):
    """``head`` (a ``batch_manifest.Head`` with ``photos`` and no landmarks file) with its
    landmarks detected into ``<base>.landmarks.json`` (``solver.cli.detect_landmarks``, the
    detect command's own code; ``lens_mm``: its ``--lens``), or with the one-line error
    when its photos fail."""
    if head.error is not None or head.landmarks is not None or not head.photos:
        return head
    cli = solver_module("cli")
    landmarks = head.base.with_name(head.base.name + ".landmarks.json")
    warnings = []
    try:
        head.base.parent.mkdir(parents=True, exist_ok=True)
        cli.detect_landmarks([str(p) for p in head.photos], landmarks, quiet=True,
                             lens_mm=lens_mm, warnings=warnings)
    except (cli.CliError, ValueError, OSError) as e:
        message = str(e) if head.where in str(e) else f"{head.where}: {e}"
        return batch_manifest.Head(head.name, None, head.base, head.where, head.options,
                                   error=message, photos=head.photos)
    return batch_manifest.Head(head.name, landmarks, head.base, head.where, head.options,
                               photos=head.photos, warnings=tuple(warnings))


def detected_heads(groups, out, lens_mm=None):
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
                                                       photos=tuple(photos)), lens_mm))
    return heads


def _cluster_failed(task, message):
    return batch_summary.failed_row(
        task["name"], task["where"],
        f"{task['where']}: the cluster could not fit it ({message})")


def _in_process(tasks, model):
    from . import batch_head

    for task in tasks:
        yield task, batch_head.run_task(task, model)


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
    from . import batch_head

    model = load_model()
    batch_workers.serve(lambda task: batch_head.run_task(task, model))
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
        batch_manifest.fit_options(settings)  # a bad option fails here, once, not in every head
        out_dir = None if Path(args.out).suffix.lower() == ".blend" else Path(args.out)
        n_detect = len(detect_groups(args.detect))
        if out_dir is None and len(args.inputs) + n_detect > 1 and n_detect:
            raise ValueError(f"--out {args.out}: one .blend file for several heads; give a "
                             "folder instead")
        heads = batch_manifest.plan_heads(args.inputs, args.out) if args.inputs else []
        if args.lens is not None and not (args.detect or any(h.photos for h in heads)):
            raise ValueError(f"--lens {args.lens:g}: only for photos the batch detects "
                             "(--detect, a manifest's photos column); a landmarks file's "
                             "cameras give their own lens")
        heads = [detected_head(h, args.lens) for h in heads]  # a manifest's photos column
        heads += detected_heads(args.detect, args.out, args.lens)
        if out_dir is not None:
            solver_module("io.atomic").check_outputs(
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
    batch_stamp.remove_stale_partials(folder)
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
    sys.stdout.flush()
    sys.stderr.flush()
    bpy = sys.modules.get("bpy")  # not imported by a batch's own process at --jobs 2
    if bpy is not None and not bpy.app.binary_path and bpy.app.version < (4, 4, 0):
        os._exit(code)
    sys.exit(code)


if __name__ == "__main__":
    if not __package__:  # run as a file by `blender -b -P`: import as the package module
        sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
        _self = importlib.import_module("headrecon_addon.headless")
        _self.exit_process(_self.main(script_args(sys.argv)))
    exit_process(main(script_args(sys.argv)))
