"""The Detect Landmarks and Detect Outline operators (one photo, or every photo) and Auto
Fit (detection on the photos, then the Fit): in a thread with progress and Esc to cancel,
or at once in the background; each one undo step, the scene unchanged when it fails or is
cancelled."""

import bpy
from bpy.props import BoolProperty, StringProperty

from . import auto_fit_job, detect_job, outline_job, photos
from .fit_ops import report_fit_error, report_fitted
from .job_operator import JobOperator, interactive, running_problem
from .job_progress import JobCancelled
from .polls import object_mode_problem, poll_result

_REPLACE = ("Replace the landmarks placed or moved by hand too (otherwise they stay as they "
            "are, and only the others are detected)")


def _photos_problem(context):
    return None if photos.photo_planes(context.scene) else "Load a photo first (Photos panel)"


def _report_lines(op, lines):
    """The detection's report: the photos' lines as one INFO line, each warning its own."""
    info = [line for level, line in lines if level == "INFO"]
    if info:
        op.report({"INFO"}, "Detected: " + "; ".join(info))
    for level, line in lines:
        if level != "INFO":
            op.report({level}, line)


class _PhotosJob(JobOperator):
    """What Detect Landmarks and Auto Fit share: greyed out, saying why, without photos or
    while another job runs."""

    @classmethod
    def poll(cls, context):
        return poll_result(cls, object_mode_problem(context) or running_problem()
                           or _photos_problem(context))


class _DetectionJob(_PhotosJob):
    """What Detect Landmarks and Detect Outline share: their job module's ``RUN`` (in
    background mode), ``PREPARE`` and ``APPLY`` (the interactive job) on one view or every
    photo, and how they report."""

    RUN = PREPARE = APPLY = None  # staticmethods of the job module

    def report_error(self, e):
        if isinstance(e, JobCancelled):
            self.report({"WARNING"}, self.CANCELLED_LINE)
        elif isinstance(e, ValueError):
            self.report({"ERROR"}, str(e))
        else:
            self.report({"ERROR"}, f"Detection failed: {type(e).__name__}: {e}")

    def execute(self, context):
        try:
            job = self.RUN(context.scene, self.view, self.replace_hand_placed)
        except Exception as e:
            self.report_error(e)
            return {"CANCELLED"}
        _report_lines(self, job.lines())
        return {"FINISHED"}

    def invoke(self, context, event):
        if not interactive(context):
            return self.execute(context)
        try:
            job = self.PREPARE(context.scene, self.view, self.replace_hand_placed)
        except Exception as e:
            self.report_error(e)
            return {"CANCELLED"}
        return self.start_job(context, job)

    def finish_job(self, context, job, seconds):
        if not job.found_any:
            raise ValueError("; ".join(line for _, line in job.lines()))
        self.APPLY(context.scene, job)
        _report_lines(self, job.lines())


class HEADRECON_OT_detect_landmarks(_DetectionJob, bpy.types.Operator):
    """Find the face on the photo (or on every photo) and place its landmarks, shown as
    detected (orange) for you to check; landmarks you placed or moved by hand stay"""

    bl_idname = "headrecon.detect_landmarks"
    bl_label = "Detect Landmarks"
    bl_options = {"REGISTER", "UNDO"}
    CANCELLED_LINE = "Detection cancelled; the scene is as it was"
    THREAD_NAME = "HeadRecon detection"

    view: StringProperty(name="View", options={"SKIP_SAVE"},
                         description="The photo's view name (empty: every photo)")
    replace_hand_placed: BoolProperty(name="Replace Hand-Placed", options={"SKIP_SAVE"},
                                      description=_REPLACE)

    RUN = staticmethod(detect_job.run_detection)
    PREPARE = staticmethod(detect_job.prepare_detection)
    APPLY = staticmethod(detect_job.apply_detection)


class HEADRECON_OT_detect_outline(_DetectionJob, bpy.types.Operator):
    """Find the head's outline on the photo (or on every photo) from the person's
    segmentation (hair and clothes left out) and draw it as the photo's contour; a
    contour traced by hand stays unless replaced"""

    bl_idname = "headrecon.detect_outline"
    bl_label = "Detect Outline"
    bl_options = {"REGISTER", "UNDO"}
    CANCELLED_LINE = "Outline detection cancelled; the scene is as it was"
    THREAD_NAME = "HeadRecon outline"

    view: StringProperty(name="View", options={"SKIP_SAVE"},
                         description="The photo's view name (empty: every photo)")
    replace_hand_placed: BoolProperty(
        name="Replace Hand-Traced", options={"SKIP_SAVE"},
        description="Replace a contour traced or edited by hand too (otherwise it stays)")

    RUN = staticmethod(outline_job.run_outlines)
    PREPARE = staticmethod(outline_job.prepare_outlines)
    APPLY = staticmethod(outline_job.apply_outlines)


class HEADRECON_OT_auto_fit(_PhotosJob, bpy.types.Operator):
    """Detect the landmarks on every photo without landmarks placed by hand, and the
    outline on every photo without a contour traced by hand, then fit the head, in one
    step"""

    bl_idname = "headrecon.auto_fit"
    bl_label = "Auto Fit"
    bl_options = {"REGISTER", "UNDO"}
    CANCELLED_LINE = "Auto Fit cancelled; the scene is as it was"
    THREAD_NAME = "HeadRecon auto fit"

    replace_hand_placed: BoolProperty(
        name="Replace Hand-Placed", options={"SKIP_SAVE"},
        description="Detect on every photo, replacing the landmarks placed or moved by hand "
                    "too (otherwise photos with such landmarks are fitted as they are)")

    def report_error(self, e):
        if isinstance(e, JobCancelled):
            self.report({"WARNING"}, self.CANCELLED_LINE)
            return
        job = getattr(self, "job", None)
        if job is not None:  # what the detection did not find may be why
            for level, line in job.lines():
                if level != "INFO":
                    self.report({level}, line)
        report_fit_error(self, e)

    def _done(self, context, head, job):
        _report_lines(self, job.lines())
        report_fitted(self, context, head, job.fit)

    def execute(self, context):
        self.job = None
        try:
            self.job = job = auto_fit_job.prepare_auto_fit(context.scene,
                                                           self.replace_hand_placed)
            job.run()
            if job.error is not None:
                raise job.error
            head = auto_fit_job.apply_auto_fit(context.scene, job)
        except Exception as e:
            self.report_error(e)
            return {"CANCELLED"}
        self._done(context, head, job)
        return {"FINISHED"}

    def invoke(self, context, event):
        if not interactive(context):
            return self.execute(context)
        self.job = None
        try:
            job = auto_fit_job.prepare_auto_fit(context.scene, self.replace_hand_placed)
        except Exception as e:
            self.report_error(e)
            return {"CANCELLED"}
        return self.start_job(context, job)

    def finish_job(self, context, job, seconds):
        job.fit.timings["total"] = seconds
        head = auto_fit_job.apply_auto_fit(context.scene, job)
        self._done(context, head, job)


CLASSES = (HEADRECON_OT_detect_landmarks, HEADRECON_OT_detect_outline,
           HEADRECON_OT_auto_fit)
