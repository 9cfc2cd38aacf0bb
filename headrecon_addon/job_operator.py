"""What the operators that run in the background share (Fit, Detect Landmarks, Auto Fit):
the job in a thread, its progress in the status bar, Esc to cancel, one job at a time.

A job is prepared on the main thread (it reads the scene), runs in a thread touching no
bpy data (``run``; errors kept in ``error``; ``cancelled`` stops it at its next progress
report; ``fraction`` and ``message`` say how far it is), and is applied on the main thread
when it is done: until then the scene is untouched, so Esc or an error leaves it as it was.
"""

import threading
import time

import bpy

#: The job running now (None: none): a second one would change the scene under it.
RUNNING = {"job": None}


def running_problem():
    """Why another job cannot start now (a sentence), or None."""
    return "HeadRecon is working (Esc cancels it)" if RUNNING["job"] is not None else None


def interactive(context):
    """Whether an operator can run its job in the background (a window to report to)."""
    return not bpy.app.background and context.window is not None


class JobOperator:
    """Operator mixin: ``start_job(context, job)`` from ``invoke`` runs the job in a thread;
    when it is done ``finish_job(context, job, seconds)`` applies it (its exceptions and the
    job's error go to ``report_error``). ``CANCELLED_LINE`` is reported on Esc."""

    CANCELLED_LINE = "Cancelled; the scene is as it was"
    THREAD_NAME = "HeadRecon job"

    def report_error(self, e):
        self.report({"ERROR"}, str(e))

    def start_job(self, context, job):
        self.job = job
        self.t0 = time.perf_counter()
        RUNNING["job"] = job
        self.thread = threading.Thread(target=job.run, name=self.THREAD_NAME, daemon=True)
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
        RUNNING["job"] = None

    def modal(self, context, event):
        if event.type == "ESC":
            self.job.cancelled = True  # the thread stops at its next progress report
            self._cleanup(context)
            self.report({"WARNING"}, self.CANCELLED_LINE)
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"RUNNING_MODAL"}  # the scene must not change under a running job
        if self.thread.is_alive():
            self._status(context)
            return {"RUNNING_MODAL"}
        self._cleanup(context)
        if self.job.error is not None:
            self.report_error(self.job.error)
            return {"CANCELLED"}
        try:
            self.finish_job(context, self.job, time.perf_counter() - self.t0)
        except Exception as e:
            self.report_error(e)
            return {"CANCELLED"}
        return {"FINISHED"}
