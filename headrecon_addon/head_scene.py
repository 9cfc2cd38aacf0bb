"""The artist's scene for a finished fit, built without the UI, and saving it as a .blend
with everything packed: what a batch's head, the demo and scripts write.

    reset_scene()
    head = build_scene_from_fit(model, case, result, images=photos_by_view)
    save_blend("head.blend")
"""

import importlib
from pathlib import Path

import bpy
import numpy as np

from . import case_to_scene, photos, result_to_scene, scene_collections
from .data import Transaction
from .solver_link import BakeOptions, bake_fit_texture, iris_colour


def ensure_registered():
    """Register the add-on's classes and properties unless they already are."""
    pkg = importlib.import_module(__package__)
    if not pkg.is_registered():
        pkg.register()


def reset_scene():
    """An empty scene (factory settings), the add-on registered."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    ensure_registered()


def images_for(case, images):
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
                         bake=True, name=None, textures=None, texture_shading="keep",
                         texture_clothes="leave-out", iris=None):
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
    iris : ndarray (3,), optional
        The irises' colour the caller read with its bake (``iris_colour``); read off the
        photos here when the texture is baked here.
    texture_shading : str
        ``BakeOptions.shading`` of the bake: "keep" or "remove" the photos' light.
    texture_clothes : str
        ``BakeOptions.clothes`` of the bake: "leave-out" what the photos show of clothes
        below the chin, or "keep" the photos as they are.

    Returns
    -------
    bpy.types.Object
        The head.
    """
    ensure_registered()
    scene = scene or bpy.context.scene
    with Transaction():
        imgs = images_for(case, images)
        planes = case_to_scene.build_view_planes(case, imgs)
        for plane in planes:
            scene_collections.link_tree(scene, photos.view_root(plane))
        case_to_scene.store_case_level(scene, case)
        if textures is None and bake:
            arrays = {v: photos.image_to_array(img) for v, img in imgs.items()
                      if not img.get(photos.PLACEHOLDER)}
            if arrays:
                textures = bake_fit_texture(model, result, arrays, size=int(texture_size),
                                            options=BakeOptions(shading=texture_shading,
                                                                clothes=texture_clothes))
                iris = iris_colour(model, result, arrays, case)
        calibration, _ = result_to_scene.calibration_checks(case)
        head = result_to_scene.apply_result(scene, model, result, textures, name=name,
                                            calibration=calibration, iris=iris)
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


