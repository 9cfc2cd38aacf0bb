"""Helpers for the add-on tests (tests/addon/): the bpy module, an empty scene, a synthetic
case written to disk with photos (and a scene it is imported into), and snapshots of
bpy.data for "nothing changed" checks."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from tests import ROOT

if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import bpy  # noqa: E402  (after the path: tests run from anywhere)

# bpy.data collections a failed operator must leave as they were.
DATA_KINDS = ("objects", "meshes", "curves", "cameras", "materials", "images", "collections")


def addon():
    """The add-on package, registered."""
    import headrecon_addon

    if not headrecon_addon.is_registered():
        headrecon_addon.register()
    return headrecon_addon


def empty_scene():
    """Factory settings with an empty scene; the add-on registered. Returns the scene."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    addon()
    return bpy.context.scene


def imported_scene(path, texture_size="512"):
    """An empty scene with the landmarks file ``path`` imported (Import Landmarks)."""
    scene = empty_scene()
    assert bpy.ops.headrecon.import_landmarks(filepath=str(path)) == {"FINISHED"}
    scene.headrecon.texture_size = texture_size
    return scene


def snapshot():
    """Names in each bpy.data collection of DATA_KINDS (sorted lists)."""
    return {k: sorted(i.name for i in getattr(bpy.data, k)) for k in DATA_KINDS}


def write_photo(path, size, seed=0):
    """A smooth colour photo of ``size`` (w, h) written as PNG: colours vary across the
    image so a bake has something to sample."""
    from PIL import Image

    w, h = size
    rng = np.random.default_rng(seed)
    u = np.linspace(0.0, 1.0, w)[None, :]
    v = np.linspace(0.0, 1.0, h)[:, None]
    base = rng.uniform(0.2, 0.8, size=3)
    rgb = np.stack([base[0] + 0.2 * u + 0 * v, base[1] + 0.2 * v + 0 * u,
                    base[2] + 0.1 * (u - v)], axis=-1)
    Image.fromarray((np.clip(rgb, 0, 1) * 255).astype(np.uint8)).save(path)
    return path


def synthetic_files(model, folder, seed=1, photos=True, name="case", **kw):
    """A synthetic case (solver/synthetic.py) saved as ``folder/<name>.json`` with a photo
    per view. Returns (path, case, truth)."""
    from solver import synthetic
    from solver.io import landmarks_file

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    case, truth = synthetic.make_case(model, seed, **kw)
    if photos:
        for i, (vname, view) in enumerate(case.views.items()):
            fname = f"{name}_{vname}.png"
            write_photo(folder / fname, view.size, seed + i)
            view.image = fname
    path = folder / f"{name}.json"
    case.source = str(path)
    landmarks_file.save_landmarks(case, path)
    return path, landmarks_file.load_landmarks(path), truth


def run_python(args, env=None, timeout=600, cwd=ROOT):
    """Run ``python args...`` (this interpreter) in a subprocess; returns CompletedProcess."""
    full_env = dict(os.environ)
    full_env["PYTHONPATH"] = os.pathsep.join(
        [str(ROOT)] + ([full_env["PYTHONPATH"]] if full_env.get("PYTHONPATH") else []))
    full_env.update(env or {})
    return subprocess.run([sys.executable, *map(str, args)], cwd=cwd, env=full_env,
                          capture_output=True, text=True, timeout=timeout)


def add_passpoints(case, truth, view, rng, n=14, misplace=None, noise_px=0.3):
    """Give ``view`` of a synthetic case the passpoints of a calibration object around the
    head (``n`` points in a box about the face, those the photo shows), its camera to be
    computed from them (``{"kind": "dlt"}``, calibrated). ``misplace``: (index, pixels)
    moves one passpoint's pixel that far. Returns the passpoint names."""
    centre = truth.world_vertices.mean(axis=0)
    xyz = centre + rng.uniform(-1.0, 1.0, size=(n, 3)) * np.array([0.1, 0.1, 0.12])
    cam = truth.cameras[view]
    v = case.views[view]
    px = cam.project(xyz) + noise_px * rng.normal(size=(n, 2))
    inside = (px > 5).all(axis=1) & (px < np.array(v.size) - 5).all(axis=1)
    names = [f"pp{i:02d}" for i in range(n) if inside[i]]
    xyz, px = xyz[inside], px[inside]
    if misplace is not None:
        i, dist = misplace
        px[i] += (dist, 0.0) if px[i, 0] + dist < v.size[0] else (-dist, 0.0)
    case.passpoints = dict(zip(names, xyz, strict=True))
    v.passpoints = dict(zip(names, px, strict=True))
    v.camera, v.camera_hints, v.calibrated = None, {"kind": "dlt"}, True
    return names


def save_case(case, folder, name, photos=True, seed=0):
    """Write a case (photos named after its views, one photo per image when views share
    one) as ``folder/<name>.json``; returns (path, case as loaded)."""
    from solver.io import landmarks_file

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    if photos:
        for i, (vname, view) in enumerate(case.views.items()):
            src = view.mirror_of or vname
            fname = f"{name}_{src}.png"
            if not (folder / fname).exists():
                write_photo(folder / fname, view.size, seed + i)
            view.image = fname
    path = folder / f"{name}.json"
    case.source = str(path)
    landmarks_file.save_landmarks(case, path)
    return path, landmarks_file.load_landmarks(path, for_fit=False)


def key_blocks(head):
    """The shape keys of the head object."""
    return head.data.shape_keys.key_blocks
