"""One head of a batch in its worker (or the batch's own process at ``--jobs 1``): fit its
landmarks file, bake its texture, write the outputs its settings choose, atomically, and
return its summary row (``batch_summary``).

Every output is written into the head's staging folder (``batch_stamp.staging_folder``)
and renamed into place; the record (``batch_stamp.write_record``) is written last, so a
head killed part-way leaves no file and is fitted again.
"""

import os
import shutil
import sys
import time
from pathlib import Path

from . import (
    apply_identity,
    batch_manifest,
    batch_stamp,
    batch_summary,
    export,
    head_scene,
    heap,
    photos,
    result_to_scene,
)
from .solver_link import (
    BakeOptions,
    bake_fit_texture,
    fit_head,
    forget_fit_subsets,
    iris_colour,
    load_landmarks,
    orthographic_lenses,
    solver_module,
)


def run_task(task, model):
    """:func:`write_head`, with any failure as the head's failed summary row (the batch
    goes on)."""
    t0 = time.perf_counter()
    try:
        return write_head(task, model)
    except Exception as e:  # report and go on with the batch
        message = str(e) if task["where"] in str(e) else f"{task['where']}: {e}"
        return batch_summary.failed_row(task["name"], task["where"], message,
                                        time.perf_counter() - t0)


def _summary_row(name, where, result, outputs, seconds, detected=()):
    """A written head's summary row; its ``warnings`` those of its photos' detection
    (``detected``, when the batch detected its landmarks), then the fit's."""
    noise = (result.info.get("noise") or {}).get("landmark_px") or {}
    plaus = result.info.get("plausibility") or {}
    percentile = plaus.get("percentile")
    return {"name": name, "status": "done", "error": None,
            "method": result_to_scene.fit_method(result),
            "rms_px": round(float(result.rms_px()), 4),
            "noise_px": {v: round(float(x), 4) for v, x in noise.items()},
            "plausibility": None if percentile is None else round(float(percentile), 3),
            "warnings": [*detected, *result.info.get("warnings", ())],
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
        ``texture_shading``, ``texture_clothes``, ``bake_identity``, ``morph_normals`` and
        the fit options), "hash" (recorded with the outputs, ``batch_stamp``), optionally
        "warnings" (its photos' detection's, first in its summary row's).
    model : HeadModel

    Every output is written into a temporary folder beside the outputs and renamed into
    place; the record (``batch_stamp.write_record``) is written last.
    """
    t0 = time.perf_counter()
    name, path, base = task["name"], Path(task["landmarks"]), Path(task["base"])
    settings = task["settings"]
    kinds = settings["outputs"]
    options = batch_manifest.fit_options(settings)
    case = load_landmarks(path)
    targets = _targets(base, kinds)
    inputs = {"the landmarks file": path}
    inputs.update({f"the photo of view {v}": case.image_path(v) for v in case.views})
    solver_module("io.atomic").check_outputs(
        {f"output {k}": p for k, p in targets.items()}, inputs)
    head_scene.reset_scene()
    heap.release_free_memory()  # the last head's scene, before the fit and bake take more
    imgs = head_scene.images_for(case, None)  # fails fast on a missing photo, before the fit
    orthographic_lenses(case)  # the photos' EXIF lenses, for the projection check
    result = fit_head(model, case, options)
    forget_fit_subsets(model)  # this head's subsets: another head seldom asks for them
    for message in result.info.get("warnings", ()):
        print(f"{name}: warning: {message}", file=sys.stderr, flush=True)
    tiles = iris = None
    if settings["bake"]:
        arrays = {v: photos.image_to_array(img) for v, img in imgs.items()
                  if not img.get(photos.PLACEHOLDER)}
        if arrays:
            tiles = bake_fit_texture(  # one thread: the batch's processes share the cores
                model, result, arrays, size=int(settings["texture_size"]),
                options=BakeOptions(shading=settings.get("texture_shading") or "keep",
                                    clothes=settings.get("texture_clothes") or "leave-out",
                                    threads=1))
            iris = iris_colour(model, result, arrays, case)
        del arrays  # the photos as float arrays (25 MB a head): not held through the export
        heap.release_free_memory()  # the bake's temporaries, before Blender takes more
    if "texture" in kinds and tiles is None:
        raise ValueError(f"{task['where']}: no photo to bake the texture from")
    base.parent.mkdir(parents=True, exist_ok=True)
    staging = batch_stamp.staging_folder(base)
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir()
    try:
        staged = _write_staged(staging, base.name, name, kinds, model, case, result, imgs,
                               (tiles, iris), settings, targets, t0)
        for kind, tmp in staged.items():
            if tmp.is_dir():  # the .fbx's textures folder
                shutil.rmtree(targets[kind], ignore_errors=True)
            os.replace(tmp, targets[kind])
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    row = _summary_row(name, task["where"], result,
                       {k: p for k, p in targets.items() if k in staged},
                       time.perf_counter() - t0, task.get("warnings", ()))
    batch_stamp.write_record(base, task["hash"], row)
    return row


def _write_staged(staging, stem, name, kinds, model, case, result, imgs, baked, settings,
                  targets, t0):
    """Write a head's outputs into ``staging`` under their final names; returns kind ->
    staged path. ``imgs``: the photos as bpy images, ``baked``: the baked texture and the
    irises' colour (``(None, None)`` unbaked)."""
    tiles, iris = baked
    staged = {}
    needs_scene = {"blend", "glb", "fbx"} & set(kinds)
    if needs_scene:
        head = head_scene.build_scene_from_fit(model, case, result, imgs, bake=False,
                                               textures=tiles, name=name, iris=iris)
        if settings["bake_identity"]:
            apply_identity.apply_identity(head, model.expression_names)
        if "blend" in kinds:
            staged["blend"] = head_scene.save_blend(staging / f"{stem}.blend")
        if {"glb", "fbx"} & set(kinds) and apply_identity.identity_key_names(
                head, model.expression_names):
            # The .blend is written; a game file has the fitted base alone, so the identity
            # keys go now, before the exporter's copy of the head doubles them.
            apply_identity.apply_identity(head, model.expression_names)
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
        names, obj_files = solver_module("io.export").head_obj_files(
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
            atlas, _, _ = solver_module("io.export").texture_atlas(model, tiles)
            files[tex] = solver_module("io.export").png_bytes(atlas)
        staged["texture"] = tex
    if "report" in kinds:
        rep = solver_module("io.report")
        final = {k: targets[k] for k in ("blend", "glb", "fbx", "obj", "mtl", "texture")
                 if k in targets}
        final["report"] = targets["report"]
        text = rep.report_text(rep.fit_report(case, model, result, settings, final,
                                              {"total": time.perf_counter() - t0}, iris))
        files[staging / f"{stem}.report.json"] = text
        staged["report"] = staging / f"{stem}.report.json"
    if files:
        solver_module("io.atomic").write_files_atomic(files)
    return staged
