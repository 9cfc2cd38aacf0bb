"""The live refit: while a landmark moves, the head follows.

The last full fit stays in memory (``LIVE``, the one ``LiveRefit`` of the session; not
saved in the .blend: after reopening, fit once again). A depsgraph handler watches the
landmark positions; when one moved it asks the solver's fast path (``refit_landmarks``,
cameras and correspondences of that fit) and updates only the coefficient values, the
"fit_detail" key and the transform. The file handlers settle a drag before saving (and
pack the baked textures) and forget the fit when another file is loaded.
"""

import dataclasses
import time

import bpy
import numpy as np
from bpy.app.handlers import persistent

from . import app_handlers, landmarks, photos, result_to_scene, scene_to_case, shape_keys
from .solver_link import refit_landmarks

DRAG_SETTLE = 0.3  # seconds without a landmark move that end a drag


class LiveRefit:
    """The last full fit and the live refits that start from it.

    Attributes
    ----------
    base : FitResult or None
        The last full fit (its cameras and correspondences), None when none is kept.
    result : FitResult or None
        The result on the head now (the last fit or live refit).
    model, options, calibration
        That fit's head model, FitOptions and passpoint checks.
    head : str
        Name of the fitted head object.
    signature : ndarray or None
        The landmark positions seen last (``landmarks.landmark_signature``).
    busy : bool
        A refit is running (the handler does not start another).
    ms : float
        Duration of the last refit, milliseconds.
    error : str
        Why the last refit failed, for the panel ("" when it did not).
    moved_at : float
        ``time.monotonic()`` of the last refit (the drag settles DRAG_SETTLE after it).
    """

    def __init__(self):
        self.busy = False
        self.ms = 0.0
        self.error = ""
        self.moved_at = 0.0
        self.forget()

    def remember(self, scene, head, model, result, options, calibration=None):
        """Keep a full fit in memory: live refits start from its cameras and
        correspondences."""
        self.base = self.result = result
        self.model = model
        self.head = head.name
        self.error = ""
        self.options = dataclasses.replace(options, progress=None)
        self.calibration = dict(calibration or {})
        self.signature = landmarks.landmark_signature(photos.photo_planes(scene))

    def reset(self):
        """Forget the landmark positions seen last (the next step only records them)."""
        self.signature = None
        self.error = ""

    def forget(self):
        """Drop the fit in memory (live refits wait for the next full fit)."""
        self.base = self.result = self.model = self.options = self.signature = None
        self.head = ""
        self.calibration = {}

    def ready(self):
        """Whether a full fit is in memory for live refits."""
        return self.base is not None and bpy.data.objects.get(self.head) is not None

    def stats(self):
        """The panel's state: "ms" of the last refit, "error", "ready" (a full fit in
        memory) and "moved" (the head shown is a live refit's, not the full fit's: a
        Fit takes the moved points in fully, cameras and outline too)."""
        return {"ms": self.ms, "error": self.error, "ready": self.ready(),
                "moved": self.ready() and self.result is not self.base}

    def step(self, scene, force=False, drag=True):
        """Refit if a landmark moved since the last step (or ``force``).

        Parameters
        ----------
        force : bool
            Refit even if nothing moved.
        drag : bool
            Show the refit in drag mode (``shape_keys.show_live_shape``: one key to
            evaluate per frame); a timer settles the keys once the landmarks rest for
            DRAG_SETTLE seconds (``finish_drag``). False writes the settled form at once.

        Returns
        -------
        FitResult or None
            The refit's result, None when nothing moved or no fit is in memory.
        """
        if not self.ready():
            return None
        head = bpy.data.objects.get(self.head)
        sig = landmarks.landmark_signature(photos.photo_planes(scene))
        prev = self.signature
        self.signature = sig
        if not force and (prev is None or (prev.shape == sig.shape
                                           and np.array_equal(prev, sig))):
            return None
        t = time.perf_counter()
        case = scene_to_case.case_from_scene(scene)
        result = refit_landmarks(self.model, case, self.base, self.options)
        write = shape_keys.show_live_shape if drag else shape_keys.update_fit_values
        if not write(head, self.model, result):
            self.error = "the head's shape keys changed: run Fit again"
            return None
        head.matrix_world = result_to_scene.similarity_matrix(result)
        head.headrecon.fit_rms_px = result.rms_px()
        result_to_scene.update_residuals(scene, result, self.calibration)
        self.result = result
        self.ms = (time.perf_counter() - t) * 1000.0
        self.error = ""
        self.moved_at = time.monotonic()
        if drag and not bpy.app.timers.is_registered(settle_timer):
            bpy.app.timers.register(settle_timer, first_interval=DRAG_SETTLE)
        return result

    def finish_drag(self):
        """Settle the head's keys after a drag (coefficients + detail again). Returns True
        if there was a drag to settle."""
        head = bpy.data.objects.get(self.head) if self.head else None
        if head is None or head.type != "MESH" or not shape_keys.in_live_shape(head):
            return False
        return shape_keys.settle_live_shape(head)


LIVE = LiveRefit()


def settle_timer():
    """The drag's timer: settles the keys once the landmarks rested DRAG_SETTLE seconds."""
    rest = time.monotonic() - LIVE.moved_at
    if rest < DRAG_SETTLE:
        return DRAG_SETTLE - rest
    try:
        LIVE.finish_drag()
    except Exception as e:  # a timer must not raise
        LIVE.error = str(e)
    return None


@persistent
def _on_depsgraph_update(scene, depsgraph):
    if LIVE.busy or LIVE.base is None:
        return
    props = getattr(scene, "headrecon", None)
    if props is None or not props.live_refit or not depsgraph.id_type_updated("OBJECT"):
        return
    LIVE.busy = True
    try:
        LIVE.step(scene)
    except Exception as e:  # a handler must not raise: show it in the panel instead
        LIVE.error = str(e)
    finally:
        LIVE.busy = False


@persistent
def _on_load(*_args):
    LIVE.forget()
    for obj in bpy.data.objects:  # a file saved mid-drag by another path than Save
        if obj.type == "MESH" and shape_keys.in_live_shape(obj):
            shape_keys.settle_live_shape(obj)


@persistent
def _on_save_pre(*_args):
    LIVE.finish_drag()
    result_to_scene.pack_baked_textures()


_HANDLERS = (("depsgraph_update_post", _on_depsgraph_update), ("load_post", _on_load),
             ("save_pre", _on_save_pre))


def register_handlers():
    app_handlers.add(_HANDLERS)


def unregister_handlers():
    app_handlers.remove(_HANDLERS)
    if bpy.app.timers.is_registered(settle_timer):
        bpy.app.timers.unregister(settle_timer)
    LIVE.forget()
