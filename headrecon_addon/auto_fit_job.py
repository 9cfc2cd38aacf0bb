"""Auto Fit as one job: detection on the photos (landmarks and outlines), then the Fit,
with the scene changed once at the end. Prepared on the main thread (each photo's pixels,
the scene's landmarks file and fit settings), run in any thread (the detected landmarks
merged into that file by ``detect_job.detection_plan``, the rule Detect Landmarks places
them by, and the outlines as contours by ``outline_job.outline_plan``; then the fit and
bake of ``fit_job``), applied on the main thread (the landmarks, then the fit's result), so
Esc or an error at any point leaves the scene as it was and one undo takes it all back.
"""

import dataclasses

from . import detect_job, fit_job, outline_job, photos, scene_to_case
from .solver_link import parse_landmarks

#: The share of the progress bar the detection takes (the fit has the rest).
DETECT_SHARE = 0.1


@dataclasses.dataclass
class AutoFitJob:
    """A detection and the fit of the scene's landmarks with what it found."""

    detect: detect_job.DetectJob
    fit: fit_job.FitJob
    document: dict  # the scene's landmarks file (scene_to_case.case_dict_from_scene)
    outlines: outline_job.OutlineJob = None
    error: BaseException = None

    @property
    def cancelled(self):
        return self.detect.cancelled

    @cancelled.setter
    def cancelled(self, value):
        self.detect.cancelled = self.fit.cancelled = bool(value)
        if self.outlines is not None:
            self.outlines.cancelled = bool(value)

    @property
    def fraction(self):
        if self.fit.case is None:
            parts = [self.detect] + ([self.outlines] if self.outlines is not None else [])
            return DETECT_SHARE * sum(p.fraction for p in parts) / len(parts)
        return DETECT_SHARE + (1.0 - DETECT_SHARE) * self.fit.fraction

    @property
    def message(self):
        if self.fit.case is None:
            if self.outlines is not None and self.outlines.fraction > 0:
                return self.outlines.message
            return self.detect.message
        return self.fit.message

    def merged_case(self):
        """The scene's landmarks with the detected ones, as a LandmarkCase (any thread)."""
        views = self.document["views"]
        for task in self.detect.tasks:
            if task.face is None:
                continue
            view = views[task.view]
            points = dict(view.get("points", {}))
            sigma = dict(view.get("uncertainty", {}))
            depth = dict(view.get("depth", {}))
            place, remove, _ = detect_job.detection_plan(task.hand, task.detected,
                                                          task.face.points, self.detect.replace)
            for name in remove:
                points.pop(name, None)
                sigma.pop(name, None)
                depth.pop(name, None)
            for name in place:
                points[name] = list(task.face.points[name])
                sigma.pop(name, None)
                depth.pop(name, None)
                if name in task.face.uncertainty:
                    sigma[name] = task.face.uncertainty[name]
                if name in task.face.depth:
                    depth[name] = task.face.depth[name]
            view["points"] = points
            for key, given in (("uncertainty", sigma), ("depth", depth)):
                if given:
                    view[key] = given
                else:
                    view.pop(key, None)
        for name, yaw, turned, size in self.detect.camera_changes():
            view = views[name]
            if "camera" in view:  # as apply_detection places it
                view["camera"] = photos.held_near(view["camera"], yaw)
                if turned is not None:
                    view["camera"] = photos.turned_view_camera(view["camera"], turned, size)
        for task in self.outlines.tasks if self.outlines is not None else ():
            if task.draws(self.outlines.replace):
                views[task.view]["contour"] = [[float(u), float(v)] for u, v in task.points]
        return parse_landmarks(self.document, "<scene>", for_fit=False)

    def share_outlines(self):
        """What the landmarks' detection found given to the outline tasks of the same
        photos, not looked for again: the outlines it traced (``DetectJob.outline_views``,
        and a profile's, read for its landmarks) or why none was found, and each face the
        outline starts from."""
        faces = {t.view: t.face for t in self.detect.tasks if t.face is not None}
        for task in self.outlines.tasks if self.outlines is not None else ():
            face = faces.get(task.view)
            if face is None:
                continue
            task.face = face.found
            if face.outline is not None:
                task.points, task.notes = face.outline.contour, list(face.outline.notes)
                task.warnings = list(face.outline.warnings)
            elif face.outline_problem is not None:
                task.problem = face.outline_problem

    def run(self):
        """Detect, merge, fit, bake. Errors are kept in ``error``, never raised."""
        for part in (self.detect, self.outlines):
            if part is None:
                continue
            if part is self.outlines:
                self.share_outlines()
            part.run()
            if part.error is not None:
                self.error = part.error
                return
        try:
            case = self.merged_case()
            fit_job.check_for_fit(case, self.fit.model)
        except BaseException as e:  # noqa: B036  (kept for the main thread to report)
            self.error = e
            return
        self.fit.case = case
        self.fit.run()
        self.error = self.fit.error

    def lines(self):
        """The detection's report lines (level, line): landmarks, then outlines."""
        return self.detect.lines() + (self.outlines.lines() if self.outlines else [])


def prepare_auto_fit(scene, replace=False):
    """Read the scene for Auto Fit (main thread): the photos to detect on (those without a
    hand-placed landmark, or all with ``replace``), the landmarks file, the fit settings.

    Raises
    ------
    ValueError, FileNotFoundError
        No photos; the head model missing.
    """
    read = {}  # each photo's pixels read once for both detections
    detect = detect_job.prepare_detection(scene, "", replace, skip_hand_placed=True,
                                          read=read)
    outlines = outline_job.prepare_outlines(scene, "", replace, read=read)
    detect.outline_views = frozenset(t.view for t in outlines.tasks)
    return AutoFitJob(detect, fit_job.job_from_scene(scene, None),
                      scene_to_case.case_dict_from_scene(scene), outlines)


def apply_auto_fit(scene, job):
    """Place the detected landmarks and outlines and write the fit (main thread). Returns
    the head."""
    detect_job.apply_detection(scene, job.detect)
    if job.outlines is not None:
        outline_job.apply_outlines(scene, job.outlines)
    return fit_job.apply_job(scene, job.fit)

