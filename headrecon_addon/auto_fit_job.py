"""Auto Fit as one job: detection on the photos, then the Fit, with the scene changed once
at the end. Prepared on the main thread (each photo's pixels, the scene's landmarks file
and fit settings), run in any thread (the detected landmarks merged into that file by
``detect_job.detection_plan``, the rule Detect Landmarks places them by; then the fit and
bake of ``fit_job``), applied on the main thread (the landmarks, then the fit's result), so
Esc or an error at any point leaves the scene as it was and one undo takes it all back.
"""

import dataclasses

from . import detect_job, fit_job, scene_to_case
from .solver_link import parse_landmarks

#: The share of the progress bar the detection takes (the fit has the rest).
DETECT_SHARE = 0.1


@dataclasses.dataclass
class AutoFitJob:
    """A detection and the fit of the scene's landmarks with what it found."""

    detect: detect_job.DetectJob
    fit: fit_job.FitJob
    document: dict  # the scene's landmarks file (scene_to_case.case_dict_from_scene)
    error: BaseException = None

    @property
    def cancelled(self):
        return self.detect.cancelled

    @cancelled.setter
    def cancelled(self, value):
        self.detect.cancelled = self.fit.cancelled = bool(value)

    @property
    def fraction(self):
        if self.fit.case is None:
            return DETECT_SHARE * self.detect.fraction
        return DETECT_SHARE + (1.0 - DETECT_SHARE) * self.fit.fraction

    @property
    def message(self):
        return self.detect.message if self.fit.case is None else self.fit.message

    def merged_case(self):
        """The scene's landmarks with the detected ones, as a LandmarkCase (any thread)."""
        views = self.document["views"]
        for task in self.detect.tasks:
            if task.face is None:
                continue
            view = views[task.view]
            points = dict(view.get("points", {}))
            sigma = dict(view.get("uncertainty", {}))
            place, remove, _ = detect_job.detection_plan(task.hand, task.detected,
                                                          task.face.points, self.detect.replace)
            for name in remove:
                points.pop(name, None)
                sigma.pop(name, None)
            for name in place:
                points[name] = list(task.face.points[name])
                sigma.pop(name, None)
                if name in task.face.uncertainty:
                    sigma[name] = task.face.uncertainty[name]
            view["points"] = points
            if sigma:
                view["uncertainty"] = sigma
            else:
                view.pop("uncertainty", None)
        return parse_landmarks(self.document, "<scene>", for_fit=False)

    def run(self):
        """Detect, merge, fit, bake. Errors are kept in ``error``, never raised."""
        self.detect.run()
        if self.detect.error is not None:
            self.error = self.detect.error
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
        """The detection's report lines (level, line)."""
        return self.detect.lines()


def prepare_auto_fit(scene, replace=False):
    """Read the scene for Auto Fit (main thread): the photos to detect on (those without a
    hand-placed landmark, or all with ``replace``), the landmarks file, the fit settings.

    Raises
    ------
    ValueError, FileNotFoundError
        No photos; the head model missing.
    """
    detect = detect_job.prepare_detection(scene, "", replace, skip_hand_placed=True)
    return AutoFitJob(detect, fit_job.job_from_scene(scene, None),
                      scene_to_case.case_dict_from_scene(scene))


def apply_auto_fit(scene, job):
    """Place the detected landmarks and write the fit (main thread). Returns the head."""
    detect_job.apply_detection(scene, job.detect)
    return fit_job.apply_job(scene, job.fit)

