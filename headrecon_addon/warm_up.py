"""What the first Fit of a session would wait for, built ahead in a background thread as
soon as photos are in the scene: the head model, what every fit of it makes once, the
texture bake's UV rasters and the eyelash texture (each is cached where it is made)."""

import threading
import time

import bpy

from . import material
from .solver_link import load_model, prepare_fit, uv_raster, uv_tiles


def prepare(texture_size):
    """Load the model and make what the first Fit would wait for, here and now; returns
    the seconds of each part ("model", "fit", "rasters", "lashes")."""
    seconds = {}
    t = time.perf_counter()
    model = load_model()
    seconds["model"] = time.perf_counter() - t
    t = time.perf_counter()
    prepare_fit(model)
    seconds["fit"] = time.perf_counter() - t
    t = time.perf_counter()
    for tile in uv_tiles(model):
        uv_raster(model, int(texture_size), tile=tile)
    seconds["rasters"] = time.perf_counter() - t
    t = time.perf_counter()
    material.cached_eyelash_alpha()
    seconds["lashes"] = time.perf_counter() - t
    return seconds


def warm_up(texture_size):
    """:func:`prepare` in a background thread, so the artist's first Fit does not wait
    (what it makes is cached). Only in the interactive UI: background runs pay when they
    fit."""
    if bpy.app.background:
        return None

    def work():
        try:
            prepare(texture_size)
        except Exception:
            pass  # nothing lost: the fit builds what it needs and reports real problems

    thread = threading.Thread(target=work, name="HeadRecon warm-up", daemon=True)
    thread.start()
    return thread
