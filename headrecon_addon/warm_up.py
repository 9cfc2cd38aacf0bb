"""What the first Fit of a session would wait for, built ahead in a background thread as
soon as photos are in the scene: the head model, the texture bake's UV rasters and the
eyelash texture (each is cached where it is made)."""

import threading

import bpy

from . import material
from .solver_link import load_model, uv_raster, uv_tiles


def warm_up(texture_size):
    """Load the model, build the texture bake's UV rasters and the eyelash texture in a
    background thread, so the artist's first Fit does not wait for them (they are cached).
    Only in the interactive UI: background runs pay when they fit."""
    if bpy.app.background:
        return None

    def work():
        try:
            model = load_model()
            material.cached_eyelash_alpha()
            for tile in uv_tiles(model):
                uv_raster(model, int(texture_size), tile=tile)
        except Exception:
            pass  # nothing lost: the fit builds what it needs and reports real problems

    thread = threading.Thread(target=work, name="HeadRecon warm-up", daemon=True)
    thread.start()
    return thread
