"""Detect Outline in three steps, as Detect Landmarks (detect_job.py): ``prepare_outlines``
(main thread: each photo's pixels, and whether its contour was traced by hand),
``OutlineJob.run`` (any thread: the detector only, no bpy), ``apply_outlines`` (main
thread: the contours drawn). Until the last step the scene is untouched.

The one rule, ``outline_plan``: a photo's outline is drawn as its contour unless the photo
has a contour traced (or edited) by hand and the artist did not ask to replace it.
"""

import dataclasses

from . import landmarks, photo_faces, photos
from .detect_job import PhotosJob, photo_images


def outline_plan(has_contour, detected, replace):
    """Whether a detected outline replaces a photo's contour: always when it has none or
    the one it has was detected (and not edited); a hand-traced one only with
    ``replace``."""
    return replace or not has_contour or detected


@dataclasses.dataclass
class OutlineTask:
    """One photo to find the outline on: read from the scene, then what was found."""

    view: str
    photo: str
    pixels: object
    has_contour: bool
    detected: bool
    face: object = None  # the detector's face on the photo, when found already (Auto Fit)
    points: object = None
    notes: list = dataclasses.field(default_factory=list)
    warnings: list = dataclasses.field(default_factory=list)
    problem: str = None
    seconds: float = 0.0

    def draws(self, replace):
        return self.points is not None and outline_plan(self.has_contour, self.detected,
                                                        replace)

    def lines(self, replace):
        """(level, line) for the report."""
        where = f"view {self.view!r} ({self.photo})"
        if self.problem is not None:
            return [("WARNING", f"{where}: {self.problem}")]
        if not self.draws(replace):
            return [("INFO", f"{self.view}: outline found ({len(self.points)} points), the "
                             "contour traced by hand kept")]
        return [("INFO", f"{self.view}: outline of {len(self.points)} points "
                         f"({'; '.join(self.notes[:2])})")] \
            + [("WARNING", f"{where}: {w}") for w in self.warnings]


@dataclasses.dataclass
class OutlineJob(PhotosJob):
    """The photos to find the outline on; a photo without an outline is a line of the
    report."""

    DOING = "finding the outline on"
    DONE = "drawing the outlines"

    def examine(self, task):
        if task.points is not None or task.problem is not None:
            return  # looked for already (Auto Fit: with the landmarks' detection)
        try:
            found = photo_faces.find_outline(task.pixels, task.face)
            task.points, task.notes, task.warnings = found.contour, found.notes, found.warnings
        except ValueError as e:
            task.problem = str(e)

    @property
    def found_any(self):
        return any(t.points is not None for t in self.tasks)

    def lines(self):
        return [line for t in self.tasks for line in t.lines(self.replace)]


def prepare_outlines(scene, view="", replace=False, read=None):
    """Read the photos to find the outline on (main thread): one view, or every photo
    (``read``: as ``detect_job.prepare_detection``'s).

    Raises
    ------
    ValueError
        One line: no photo of that view, or no photo at all.
    """
    tasks = []
    for plane, name, img in photo_images(scene, view, "find the outline on"):
        if img is None:
            continue
        tasks.append(OutlineTask(name, img.name, photos.detector_pixels(img, read),
                                 landmarks.contour_object(plane) is not None,
                                 landmarks.contour_is_detected(plane)))
    return OutlineJob(tasks, replace=replace)


def apply_outlines(scene, job):
    """Draw what the job found (main thread) as ``outline_plan`` says. Returns the
    contours drawn."""
    n = 0
    for task in job.tasks:
        plane = photos.find_plane(scene, task.view)
        if plane is None or not task.draws(job.replace):
            continue
        landmarks.set_detected_contour(plane, task.points)
        n += 1
    return n


def run_outlines(scene, view="", replace=False):
    """Find and draw at once (background mode, scripts, tests). Returns the job (its
    ``lines()`` are the report). Raises ``ValueError`` as ``prepare_outlines``, a missing
    model, or no outline on any photo (the lines joined): the scene is unchanged then."""
    job = prepare_outlines(scene, view, replace)
    job.run()
    if job.error is not None:
        raise job.error
    if not job.found_any:
        raise ValueError("; ".join(line for _, line in job.lines()))
    apply_outlines(scene, job)
    return job
