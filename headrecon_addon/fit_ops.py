"""The Fit operator (in a thread, with progress and Esc to cancel, or at once in the
background), Reset to Defaults (the Advanced fit settings) and the Quick Refit operator."""

import threading
import time

import bpy

from . import fit_job, scene_to_case
from .live_refit import LIVE
from .polls import object_mode_problem, poll_result
from .properties import ADVANCED_FIT_SETTINGS

_running = {"job": None}


class HEADRECON_OT_fit(bpy.types.Operator):
    """Fit the head model to the landmarks on the photos: shape keys, texture, uncertainty"""

    bl_idname = "headrecon.fit"
    bl_label = "Fit Head"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        running = "A fit is running (Esc cancels it)" if _running["job"] is not None else None
        return poll_result(cls, object_mode_problem(context) or running
                           or scene_to_case.fit_problem(context.scene))

    def _report_error(self, e):
        if isinstance(e, fit_job.FitCancelled):
            self.report({"WARNING"}, "Fit cancelled; the scene is as it was")
        elif isinstance(e, FileNotFoundError | ValueError):
            self.report({"ERROR"}, str(e))
        else:
            self.report({"ERROR"}, f"The fit failed: {type(e).__name__}: {e}")

    def _done(self, context, head, job):
        unused = fit_job.unused_line(job)
        level = "WARNING" if job.error is not None or unused else "INFO"
        self.report({level}, f"Fitted {head.name}: {context.scene.headrecon.status}"
                    + (f"; {unused}" if unused else ""))
        if job.notes:
            self.report({"WARNING"}, "; ".join(job.notes))

    def execute(self, context):
        try:
            head, job = fit_job.run_fit(context.scene)
        except Exception as e:
            self._report_error(e)
            return {"CANCELLED"}
        self._done(context, head, job)
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        try:
            job = fit_job.prepare_job(context.scene)
        except Exception as e:
            self._report_error(e)
            return {"CANCELLED"}
        self.job = job
        self.t0 = time.perf_counter()
        _running["job"] = job
        self.thread = threading.Thread(target=job.run, name="HeadRecon fit", daemon=True)
        self.thread.start()
        wm = context.window_manager
        self.timer = wm.event_timer_add(0.05, window=context.window)
        wm.progress_begin(0, 100)
        wm.modal_handler_add(self)
        self._status(context)
        return {"RUNNING_MODAL"}

    def _status(self, context):
        pct = int(round(100 * min(max(self.job.fraction, 0.0), 1.0)))
        context.window_manager.progress_update(pct)
        if context.workspace is not None:
            context.workspace.status_text_set(
                f"HeadRecon: {self.job.message} ({pct} %)   Esc: cancel")

    def _cleanup(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self.timer)
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        _running["job"] = None

    def modal(self, context, event):
        if event.type == "ESC":
            self.job.cancelled = True  # the thread stops at its next progress report
            self._cleanup(context)
            self.report({"WARNING"}, "Fit cancelled; the scene is as it was")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"RUNNING_MODAL"}  # the scene must not change under a running fit
        if self.thread.is_alive():
            self._status(context)
            return {"RUNNING_MODAL"}
        self._cleanup(context)
        if self.job.error is not None:
            self._report_error(self.job.error)
            return {"CANCELLED"}
        try:
            self.job.timings["total"] = time.perf_counter() - self.t0
            head = fit_job.apply_job(context.scene, self.job)
        except Exception as e:
            self._report_error(e)
            return {"CANCELLED"}
        self._done(context, head, self.job)
        return {"FINISHED"}


class HEADRECON_OT_reset_fit_settings(bpy.types.Operator):
    """Set the Advanced fit settings (components, λ1, λ2, prior, landmark weight, exact
    landmarks) back to their defaults"""

    bl_idname = "headrecon.reset_fit_settings"
    bl_label = "Reset to Defaults"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        props = context.scene.headrecon
        for name in ADVANCED_FIT_SETTINGS:
            props.property_unset(name)
        return {"FINISHED"}


class HEADRECON_OT_live_refit_now(bpy.types.Operator):
    """Refit from the current landmark positions with the fast path (no new texture)"""

    bl_idname = "headrecon.refit_landmarks"
    bl_label = "Quick Refit"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return poll_result(cls, None if LIVE.ready() else
                           "Run Fit once first (quick refits start from it)")

    def execute(self, context):
        try:
            LIVE.step(context.scene, force=True, drag=False)
        except Exception as e:
            self.report({"ERROR"}, f"Quick refit failed: {e}")
            return {"CANCELLED"}
        if LIVE.error:
            self.report({"ERROR"}, LIVE.error)
            return {"CANCELLED"}
        return {"FINISHED"}


CLASSES = (HEADRECON_OT_fit, HEADRECON_OT_reset_fit_settings, HEADRECON_OT_live_refit_now)
