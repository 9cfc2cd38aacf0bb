"""The Fit operator (in a thread, with progress and Esc to cancel, or at once in the
background), Reset to Defaults (the Advanced fit settings) and the Quick Refit operator."""

import bpy

from . import fit_job, scene_to_case
from .job_operator import JobOperator, interactive, running_problem
from .job_progress import JobCancelled
from .live_refit import LIVE
from .polls import object_mode_problem, poll_result
from .properties import ADVANCED_FIT_SETTINGS


def report_fit_error(op, e):
    """Report a fit's error on operator ``op``: cancelled, bad input (its own message), or
    anything else (named as a failure)."""
    if isinstance(e, JobCancelled):
        op.report({"WARNING"}, "Fit cancelled; the scene is as it was")
    elif isinstance(e, FileNotFoundError | ValueError):
        op.report({"ERROR"}, str(e))
    else:
        op.report({"ERROR"}, f"The fit failed: {type(e).__name__}: {e}")


def report_fitted(op, context, head, job):
    """The Fit's report: the status line, what the fit left out, its notes."""
    unused = fit_job.unused_line(job)
    level = "WARNING" if job.error is not None or unused else "INFO"
    op.report({level}, f"Fitted {head.name}: {context.scene.headrecon.status}"
              + (f"; {unused}" if unused else ""))
    if job.notes:
        op.report({"WARNING"}, "; ".join(job.notes))


class HEADRECON_OT_fit(JobOperator, bpy.types.Operator):
    """Fit the head model to the landmarks on the photos: shape keys, texture, uncertainty"""

    bl_idname = "headrecon.fit"
    bl_label = "Fit Head"
    bl_options = {"REGISTER", "UNDO"}
    CANCELLED_LINE = "Fit cancelled; the scene is as it was"
    THREAD_NAME = "HeadRecon fit"

    @classmethod
    def poll(cls, context):
        return poll_result(cls, object_mode_problem(context) or running_problem()
                           or scene_to_case.fit_problem(context.scene))

    def report_error(self, e):
        report_fit_error(self, e)

    def execute(self, context):
        try:
            head, job = fit_job.run_fit(context.scene)
        except Exception as e:
            self.report_error(e)
            return {"CANCELLED"}
        report_fitted(self, context, head, job)
        return {"FINISHED"}

    def invoke(self, context, event):
        if not interactive(context):
            return self.execute(context)
        try:
            job = fit_job.prepare_job(context.scene)
        except Exception as e:
            self.report_error(e)
            return {"CANCELLED"}
        return self.start_job(context, job)

    def finish_job(self, context, job, seconds):
        job.timings["total"] = seconds
        head = fit_job.apply_job(context.scene, job)
        report_fitted(self, context, head, job)


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
