"""The fit in three steps, so the interactive operator can keep Blender responsive and
cancel cleanly: ``prepare_job`` (main thread: reads landmarks and photo pixels from the
scene), ``FitJob.run`` (any thread: solver only, no bpy), ``apply_job`` (main thread:
shape keys, transform, texture, uncertainty, residual list, the perspective photos'
cameras). Until the last step the scene is untouched, so Esc (or an error) leaves it as
it was. ``run_fit`` runs the three at once.
"""

import dataclasses
import threading
import time

from . import plane_removal, result_to_scene, scene_to_case
from .job_progress import Progress
from .live_refit import LIVE
from .solver_link import (
    BakeOptions,
    LandmarksError,
    bake_fit_texture,
    check_case,
    fit_head,
    iris_colour,
    load_model,
)


@dataclasses.dataclass
class FitJob(Progress):
    """Everything a fit needs, read from the scene; ``run`` touches no bpy data."""

    model: object
    case: object
    options: object
    photos: dict
    texture_size: int = 1024
    bake: bool = True
    texture_shading: str = "keep"
    texture_clothes: str = "leave-out"
    result: object = None
    calibration: dict = dataclasses.field(default_factory=dict)
    calibration_notes: list = dataclasses.field(default_factory=list)
    textures: dict = None
    iris: object = None  # the irises' colour read off the photos (3,) sRGB, or None
    error: BaseException = None
    cancelled: bool = False
    fraction: float = 0.0
    message: str = "starting"
    timings: dict = dataclasses.field(default_factory=dict)
    notes: list = dataclasses.field(default_factory=list)
    scene_notes: list = dataclasses.field(default_factory=list)
    deleted_views: list = dataclasses.field(default_factory=list)

    def run_fit(self):
        """The fit. Errors are kept in ``error``, never raised."""
        try:
            t = time.perf_counter()
            self.options = dataclasses.replace(self.options, progress=self.progress)
            self.result = fit_head(self.model, self.case, self.options)
            self.timings["fit"] = time.perf_counter() - t
            self.calibration, self.calibration_notes = result_to_scene.calibration_checks(self.case)
        except BaseException as e:  # noqa: B036  (kept for the main thread to report)
            self.error = e

    def run_bake(self):
        """The texture bake (after ``run_fit``). Errors are kept in ``error``."""
        if self.error is not None or not (self.bake and self.photos):
            return
        try:
            self.progress(1.0, "baking the texture")
            t = time.perf_counter()
            options = BakeOptions(shading=self.texture_shading, clothes=self.texture_clothes)
            self.textures = bake_fit_texture(self.model, self.result, self.photos,
                                             size=self.texture_size, options=options)
            self.iris = iris_colour(self.model, self.result, self.photos, self.case)
            self.timings["bake"] = time.perf_counter() - t
        except BaseException as e:  # noqa: B036
            self.error = e

    def run(self):
        """Fit, then bake (the interactive operator's thread)."""
        self.run_fit()
        self.run_bake()


def prepare_job(scene):
    """Read the scene into a FitJob (main thread).

    Raises
    ------
    ValueError
        Too few landmarks, no photos, bad landmarks (message names view and landmark).
    FileNotFoundError
        The head model is missing.
    """
    problem = scene_to_case.fit_problem(scene)
    if problem:
        raise ValueError(problem)
    job = job_from_scene(scene, scene_to_case.case_for_fit(scene))
    check_for_fit(job.case, job.model)
    return job


def job_from_scene(scene, case):
    """A FitJob of ``case`` with the scene's settings, photos and notes (main thread; the
    head model loaded). Auto Fit gives the case later (None here), once detected."""
    props = scene.headrecon
    return FitJob(model=load_model(), case=case,
                  options=scene_to_case.options_from_props(props),
                  photos=scene_to_case.photo_arrays(scene) if props.bake_texture else {},
                  texture_size=int(props.texture_size), bake=props.bake_texture,
                  texture_shading=props.texture_shading,
                  texture_clothes=props.texture_clothes,
                  scene_notes=plane_removal.orphan_notes(scene),
                  deleted_views=plane_removal.deleted_views(scene))


def check_for_fit(case, model):
    """The solver's own checks of a case to fit (names, bounds, counts; any thread).

    Raises
    ------
    LandmarksError
        With the solver's messages, naming view and landmark.
    """
    problems = check_case(case, model, for_fit=True)
    if problems:
        raise LandmarksError("scene", problems)


def apply_job(scene, job, textures=True):
    """Main-thread half of a fit: write the job's result (and its baked texture unless
    ``textures`` is False); remember the result for live refits."""
    t = time.perf_counter()
    job.notes = list(job.scene_notes) + list(job.calibration_notes) \
        + list(job.result.info.get("warnings", ()))
    job.notes += expression_notes(job.result.info)
    head = result_to_scene.apply_result(scene, job.model, job.result,
                                        job.textures if textures else None,
                                        calibration=job.calibration, notes=job.notes,
                                        iris=job.iris if textures else None)
    job.timings["write"] = time.perf_counter() - t
    LIVE.remember(scene, head, job.model, job.result, job.options, job.calibration)
    _status(scene, head, job)
    return head


def expression_notes(info):
    """The Fit report's lines on the photos' expressions (``info`` a FitResult's): each
    one taken out of a photo's landmarks with its weight and, where the fit gave it, its
    standard deviation, so a weight the landmarks barely tell from neutral reads so."""
    sd = info.get("expression_sd", {})
    lines = []
    for view, shown in info.get("expressions", {}).items():
        if shown:
            each = [f"{n} {w:.2f}" + (f" \u00b1 {sd[view][n]:.2f}" if n in sd.get(view, {})
                                      else "") for n, w in shown.items()]
            lines.append(f"photo {view!r} showed {', '.join(each)} (taken out of its "
                         "landmarks: the head is neutral)")
    return lines


def unused_line(job):
    """What the fit left out, naming each view (for the Fit's report), or None: the views
    it skipped (no usable landmark), the landmarks it dropped per view, and the views
    whose photo plane was deleted (their markers not read)."""
    unused = job.result.info.get("unused", {}) if job.result is not None else {}
    parts = [f"view {v!r} skipped (no usable landmark)" for v in unused.get("skipped", ())]
    parts += [f"view {v!r}: {', '.join(names)} left out"
              for v, names in unused.get("dropped", {}).items()]
    parts += [f"view {v!r} not fitted (its photo plane was deleted)"
              for v in job.deleted_views]
    return "; ".join(parts) or None


def _status(scene, head, job):
    flagged = job.result.flagged()
    suspects = sum(len(check.suspects) for _, check in job.calibration.values())
    total = job.timings.get("total", sum(job.timings.values()))
    scene.headrecon.status = (f"{head.headrecon.fit_method}: RMS "
                              f"{head.headrecon.fit_rms_px:.2f} px, {len(flagged)} flagged"
                              + (f", {suspects} passpoint suspect{'s' * (suspects != 1)}"
                                 if suspects else "") + f", {total:.2f} s")


def run_fit(scene):
    """Synchronous fit of the scene (background mode, scripts, tests, redo).

    The texture bake runs in a thread while the shape keys are written (it needs the fit,
    not the keys). A failed bake leaves the fitted shape and raises nothing: its error is
    in ``job.error`` and the status line.

    Returns
    -------
    head : bpy.types.Object
    job : FitJob
    """
    t0 = time.perf_counter()
    job = prepare_job(scene)
    job.run_fit()
    if job.error is not None:
        raise job.error
    baker = threading.Thread(target=job.run_bake, name="HeadRecon bake", daemon=True)
    baker.start()
    try:
        head = apply_job(scene, job, textures=False)
    finally:
        baker.join()
    if job.error is None and job.textures:
        t = time.perf_counter()
        result_to_scene.write_textures(head, job.model, job.textures, job.iris)
        job.timings["write"] += time.perf_counter() - t
    job.timings["total"] = time.perf_counter() - t0
    _status(scene, head, job)
    if job.error is not None:
        scene.headrecon.status += f"; texture not baked: {job.error}"
    return head, job
