"""The Fit operator, writing a FitResult into the scene, and the live refit.

The fit runs in three steps so the interactive operator can keep Blender responsive and
cancel cleanly: ``prepare_job`` (main thread: reads landmarks and photo pixels from the
scene), ``FitJob.run`` (any thread: solver only, no bpy), ``apply_job`` (main thread:
shape keys, transform, texture, uncertainty, residual list, the perspective photos'
cameras). Until the last step the scene is untouched, so Esc (or an error) leaves it as
it was.

Calibration residuals: every view with passpoints is checked on its own by the solver's
``check_passpoints`` (seed 000 §5-6: each view's DLT from its passpoints, leave-one-out
suspects); its passpoints' residuals join the landmark residuals in the list, suspects
first.

Live refit: a depsgraph handler watches the landmark positions; when one moved it asks
the solver's fast path (``refit_landmarks``, cameras and correspondences of the last full
fit) and updates only the coefficient values, the "fit_detail" key and the transform.
"""

import dataclasses
import threading
import time

import bpy
import numpy as np
from bpy.app.handlers import persistent
from mathutils import Matrix

from . import landmarks, material, photos, reference_head, shape_keys
from .data import Transaction
from .polls import object_mode_problem, poll_result
from .solver_link import (
    FitOptions,
    bake_fit_texture,
    check_passpoints,
    fit_head,
    landmarks_file,
    load_model,
    refit_landmarks,
    uv_raster,
    uv_tiles,
)

UNCERTAINTY_COLOR = "fit_uncertainty"
UNCERTAINTY_MM = "fit_uncertainty_mm"
BAKED = "headrecon_baked"  # custom property on baked texture images


class FitCancelled(Exception):
    """Raised from the progress callback to stop a fit the artist cancelled."""


# --------------------------------------------------------------------------------------
# Inputs


def options_from_props(props, progress=None):
    """FitOptions from the scene's settings (``Scene.headrecon``)."""
    return FitOptions(method=props.method, n_identity=props.n_identity,
                      n_regional=props.n_regional, lambda1=props.lambda1,
                      lambda2=props.lambda2, prior=props.prior,
                      landmark_weight=props.landmark_weight,
                      exact_landmarks=props.exact_landmarks, progress=progress)


def fit_problem(scene):
    """Why the scene cannot be fitted yet (a sentence for the artist), or None."""
    planes = photos.photo_planes(scene)
    if not planes:
        return "Load a front and a profile photo first"
    counts = {p.headrecon.view: len(landmarks.landmark_objects(p)) for p in planes}
    need = landmarks_file.MIN_LANDMARKS_PER_VIEW
    # a view with passpoints gets its camera from them: its landmarks are optional
    calibrated = {p.headrecon.view for p in planes if landmarks.passpoint_objects(p)}
    few = [f"{v} ({n})" for v, n in counts.items() if n < need and v not in calibrated]
    if few:
        return f"Too few landmarks on {', '.join(few)}: place at least {need} per photo"
    total = sum(counts.values())
    if total < landmarks_file.MIN_LANDMARKS_TOTAL:
        return (f"Too few landmarks ({total}): place at least "
                f"{landmarks_file.MIN_LANDMARKS_TOTAL} in all")
    return None


def photo_arrays(scene):
    """Pixels of each view's real photo (not stand-ins): dict view -> (H, W, 4) float32."""
    out = {}
    for plane in photos.photo_planes(scene):
        img = plane.headrecon.image
        if img is None or img.get(photos.PLACEHOLDER) or img.size[0] == 0:
            continue
        out[plane.headrecon.view] = photos.image_to_array(img)
    return out


def calibration_checks(case):
    """Passpoint check of every view with passpoints (``check_passpoints`` per view, so
    one view that cannot be checked does not hide the others).

    Returns
    -------
    checks : dict of str -> (list of str, PasspointCheck)
        Per view: its passpoint names (the order of the check's arrays) and the check.
    notes : list of str
        Views that could not be checked, and the checks' own notes.
    """
    checks, notes = {}, []
    for name, view in case.views.items():
        if not view.passpoints:
            continue
        try:
            names, xyz, uv = case.passpoint_arrays(name)
            check = check_passpoints(xyz, {name: uv}, names, sizes={name: view.size})
        except ValueError as e:
            notes.append(f"view {name!r}: passpoints not checked: {e}")
            continue
        checks[name] = (names, check)
        notes += check.notes
    return checks, notes


@dataclasses.dataclass
class FitJob:
    """Everything a fit needs, read from the scene; ``run`` touches no bpy data."""

    model: object
    case: object
    options: object
    photos: dict
    texture_size: int = 1024
    bake: bool = True
    result: object = None
    calibration: dict = dataclasses.field(default_factory=dict)
    calibration_notes: list = dataclasses.field(default_factory=list)
    textures: dict = None
    error: BaseException = None
    cancelled: bool = False
    fraction: float = 0.0
    message: str = "starting"
    timings: dict = dataclasses.field(default_factory=dict)
    notes: list = dataclasses.field(default_factory=list)

    def progress(self, fraction, message):
        if self.cancelled:
            raise FitCancelled()
        self.fraction = float(fraction)
        self.message = str(message)

    def run_fit(self):
        """The fit. Errors are kept in ``error``, never raised."""
        try:
            t = time.perf_counter()
            self.options = dataclasses.replace(self.options, progress=self.progress)
            self.result = fit_head(self.model, self.case, self.options)
            self.timings["fit"] = time.perf_counter() - t
            self.calibration, self.calibration_notes = calibration_checks(self.case)
        except BaseException as e:  # noqa: B036  (kept for the main thread to report)
            self.error = e

    def run_bake(self):
        """The texture bake (after ``run_fit``). Errors are kept in ``error``."""
        if self.error is not None or not (self.bake and self.photos):
            return
        try:
            self.progress(1.0, "baking the texture")
            t = time.perf_counter()
            self.textures = bake_fit_texture(self.model, self.result, self.photos,
                                             size=self.texture_size)
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
    problem = fit_problem(scene)
    if problem:
        raise ValueError(problem)
    props = scene.headrecon
    case = landmarks.case_from_scene(scene)
    model = load_model()
    # The solver's own checks (names, bounds, counts), with its messages.
    problems = landmarks_file.check_case(case, model, for_fit=True)
    if problems:
        raise landmarks_file.LandmarksError("scene", problems)
    return FitJob(model=model, case=case, options=options_from_props(props),
                  photos=photo_arrays(scene) if props.bake_texture else {},
                  texture_size=int(props.texture_size), bake=props.bake_texture)


def warm_up(texture_size):
    """Load the model, build the texture bake's UV rasters and the eyelash texture in a
    background thread, so the artist's first Fit does not wait for them (they are cached).
    Only in the interactive UI: background runs pay when they fit."""
    if bpy.app.background:
        return None

    def work():
        try:
            model = load_model()
            material.cached_eyelash_alpha()
            for tile in uv_tiles(model):
                uv_raster(model, int(texture_size), tile=tile)
        except Exception:
            pass  # nothing lost: the fit builds what it needs and reports real problems

    thread = threading.Thread(target=work, name="HeadRecon warm-up", daemon=True)
    thread.start()
    return thread


# --------------------------------------------------------------------------------------
# Writing a result


def similarity_matrix(result):
    m = np.eye(4)
    m[:3, :3] = result.scale * np.asarray(result.rotation, dtype=np.float64)
    m[:3, 3] = np.asarray(result.translation, dtype=np.float64)
    return Matrix(m.tolist())


def skin_group_tiles(model):
    """UDIM tile of each skin material group, e.g. {"Face": 1001, "Head": 1002}."""
    out = {}
    first_uv = model.loop_uv[model.face_loop_start]
    tile = (1001 + np.floor(first_uv[:, 0]) + 10 * np.floor(first_uv[:, 1])).astype(int)
    for p, part in enumerate(model.part_names):
        group = material.part_group(part)
        if group in material.SKIN_GROUPS and group not in out:
            t = tile[model.face_part == p]
            if t.size:
                out[group] = int(np.bincount(t - 1001).argmax() + 1001)
    return out


def write_textures(head, model, textures):
    """Put baked tiles (dict tile -> (S, S, 3)) into the head's skin materials (packed
    into the .blend when it is saved, so the file carries its texture)."""
    images = []
    for group, tile in skin_group_tiles(model).items():
        if tile not in textures:
            continue
        mat = reference_head.part_material(head, group)
        if mat is None:
            continue
        old = material.skin_texture(mat)
        reuse = old if old is not None and old.get(BAKED) and old.users <= 1 else None
        img = photos.array_to_image(textures[tile], f"{head.name} {group} Texture", reuse)
        img[BAKED] = True  # packed when the file is saved (_on_save_pre): PNG-encoding
        material.set_skin_texture(mat, img)  # it here would slow every fit down
        images.append(img)
    return images


def write_uncertainty(mesh, mm):
    """The fit's per-vertex uncertainty as a colour attribute (ramp) and raw millimetres."""
    mm = np.asarray(mm, dtype=np.float64)
    rgba, vmax = material.uncertainty_colors(mm)
    attr = mesh.color_attributes.get(UNCERTAINTY_COLOR)
    if attr is not None and (attr.data_type != "FLOAT_COLOR" or attr.domain != "POINT"):
        mesh.color_attributes.remove(attr)
        attr = None
    if attr is None:
        attr = mesh.color_attributes.new(UNCERTAINTY_COLOR, "FLOAT_COLOR", "POINT")
    attr.data.foreach_set("color", rgba.ravel())
    raw = mesh.attributes.get(UNCERTAINTY_MM)
    if raw is None:
        raw = mesh.attributes.new(UNCERTAINTY_MM, "FLOAT", "POINT")
    raw.data.foreach_set("value", mm.astype(np.float32))
    mesh.color_attributes.active_color = mesh.color_attributes[UNCERTAINTY_COLOR]
    return vmax


def fit_method(result):
    """The approach that made ``result``: for a "combined" fit the one that won (the
    solver's ``info["approach"]``), not the method requested."""
    return str(result.info.get("approach", result.method))


def rms_residual(result):
    px = [np.asarray(r.pixels, dtype=np.float64) for r in result.residuals.values()]
    px = np.concatenate(px) if px else np.zeros(0)
    return float(np.sqrt(np.mean(px ** 2))) if px.size else 0.0


def residual_rows(result, calibration=None):
    """The residual list's rows: (rank, pixels, view, name, kind, message), sorted: flagged
    passpoints (suspects) first, then flagged landmarks, then the rest; worst first."""
    rows = []
    for view, r in result.residuals.items():
        flagged = set(r.flagged)
        for name, px in zip(r.names, np.asarray(r.pixels, dtype=np.float64), strict=True):
            rows.append((1 if name in flagged else 2, float(px), view, name, "LANDMARK", ""))
    for view, (names, check) in (calibration or {}).items():
        suspects = {s.name: s for s in check.suspects if s.view == view}
        px = np.asarray(check.residuals[view], dtype=np.float64)
        for name, r in zip(names, px, strict=True):
            s = suspects.get(name)
            rows.append((0 if s else 2, float(r), view, name, "PASSPOINT",
                         s.message if s else ""))
    rows.sort(key=lambda t: (t[0], -t[1]))
    return rows


def update_residuals(scene, result, calibration=None):
    """Fill the residual list (see ``residual_rows``) and colour landmarks and passpoints.
    Cheap enough for every live refit: rows are rewritten in place, a marker's material
    only changes when its flag does."""
    rows = residual_rows(result, calibration)
    props = scene.headrecon
    items = props.residuals
    if len(items) != len(rows):
        items.clear()
        for _ in rows:
            items.add()
        props.residual_index = -1
    for item, (rank, px, view, name, kind, message) in zip(items, rows, strict=True):
        item.view, item.landmark, item.pixels, item.flagged = view, name, px, rank < 2
        item.kind, item.message = kind, message
    by_view = {}
    for rank, px, view, name, kind, _ in rows:
        by_view.setdefault((view, kind), {})[name] = (rank < 2, px)
    for plane in photos.photo_planes(scene):
        for kind in landmarks.MARKER_ROLES:
            res = by_view.get((plane.headrecon.view, kind), {})
            for name, obj in landmarks.marker_objects(plane, kind).items():
                flagged, px = res.get(name, (False, -1.0))
                if obj.headrecon.flagged != flagged:
                    landmarks.set_landmark_state(obj, flagged, px)
                else:
                    obj.headrecon.residual_px = px


def apply_result(scene, model, result, textures=None, head=None, name=None, calibration=None,
                 notes=None):
    """Write a FitResult into the scene: shape keys, transform, texture, uncertainty,
    residuals, landmark colours; photo planes lined up with the fitted cameras (a
    perspective photo's Blender camera set to its fitted camera, whose parameters become
    the view's stored camera: exported, and the next fit's starting guess).

    Parameters
    ----------
    scene : bpy.types.Scene
    model : HeadModel
    result : FitResult
    textures : dict of int -> ndarray (S, S, 3), optional
        Baked tiles (``bake_fit_texture``).
    head : bpy.types.Object, optional
        Default: the scene's head; one is made (and linked) if there is none.
    name : str, optional
        Name of a head made here (default "HeadRecon Head").
    calibration : dict, optional
        Passpoint checks (``calibration_checks``) for the residual list.
    notes : list, optional
        Gets what showing the cameras dropped or could not do (one line per view).

    Returns
    -------
    bpy.types.Object
        The head.
    """
    head = head or scene.headrecon.head
    if head is not None and not reference_head.is_head(head):
        head = None
    with Transaction():
        created = head is None
        if created:
            head = reference_head.new_head_object(model, name or reference_head.HEAD_NAME)
        try:
            shape_keys.write_fit_keys(head, model, result)
        except Exception:
            if not created:
                shape_keys.remove_fit_keys(head)
            raise
        if textures:
            write_textures(head, model, textures)
        head.headrecon.uncertainty_max_mm = write_uncertainty(head.data, result.uncertainty)
        if created:
            scene.collection.objects.link(head)
    scene.headrecon.head = head
    head.matrix_world = similarity_matrix(result)
    head.headrecon.fit_method = fit_method(result)
    head.headrecon.fit_rms_px = rms_residual(result)
    update_residuals(scene, result, calibration)
    centre = result.world_vertices[model.skin].mean(axis=0)
    for plane in photos.photo_planes(scene):
        view = plane.headrecon.view
        cam = result.cameras.get(view)
        perspective = getattr(cam, "kind", None) in photos.photo_cameras.PERSPECTIVE_KINDS
        if cam is None or perspective != photos.is_perspective(plane):
            continue
        try:
            shown = photos.place_plane(plane, cam, centre=centre)
        except ValueError as e:  # a camera Blender cannot show: the fit itself stands
            shown = [f"camera not shown: {e}"]
        else:
            if perspective:  # (kept only when shown: a re-import must show it too)
                photos.store_fitted_camera(plane, cam)
        if notes is not None:
            notes += [f"view {view!r}: {w}" for w in shown]
    return head


def apply_job(scene, job, textures=True):
    """Main-thread half of a fit: write the job's result (and its baked texture unless
    ``textures`` is False); remember the result for live refits."""
    t = time.perf_counter()
    job.notes = list(job.calibration_notes)
    head = apply_result(scene, job.model, job.result, job.textures if textures else None,
                        calibration=job.calibration, notes=job.notes)
    job.timings["write"] = time.perf_counter() - t
    remember_fit(scene, head, job.model, job.result, job.options, job.calibration)
    _status(scene, head, job)
    return head


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
        write_textures(head, job.model, job.textures)
        job.timings["write"] += time.perf_counter() - t
    job.timings["total"] = time.perf_counter() - t0
    _status(scene, head, job)
    if job.error is not None:
        scene.headrecon.status += f"; texture not baked: {job.error}"
    return head, job


# --------------------------------------------------------------------------------------
# Live refit


_live = {"base": None, "result": None, "model": None, "options": None, "head": "",
         "signature": None, "busy": False, "ms": 0.0, "error": "", "moved_at": 0.0,
         "calibration": {}}


def remember_fit(scene, head, model, result, options, calibration=None):
    """Keep the last full fit in memory: live refits start from its cameras and
    correspondences (not saved in the .blend; after reopening, fit once again)."""
    _live.update(base=result, result=result, model=model, head=head.name, error="",
                 options=dataclasses.replace(options, progress=None),
                 calibration=dict(calibration or {}),
                 signature=landmarks.landmark_signature(photos.photo_planes(scene)))


def reset_live_state():
    """Forget the landmark positions seen last (the next step only records them)."""
    _live["signature"] = None
    _live["error"] = ""


def forget_fit():
    _live.update(base=None, result=None, model=None, options=None, head="", signature=None,
                 calibration={})


def last_result():
    """The FitResult on the head now (the last fit or live refit), or None."""
    return _live["result"]


def live_ready():
    """Whether a full fit is in memory for live refits."""
    return _live["base"] is not None and bpy.data.objects.get(_live["head"]) is not None


def live_stats():
    return {"ms": _live["ms"], "error": _live["error"], "ready": live_ready()}


DRAG_SETTLE = 0.3  # seconds without a landmark move that end a drag


def live_refit_step(scene, force=False, drag=True):
    """Refit if a landmark moved since the last step (or ``force``).

    Parameters
    ----------
    force : bool
        Refit even if nothing moved.
    drag : bool
        Show the refit in drag mode (``shape_keys.show_live_shape``: one key to evaluate
        per frame); a timer settles the keys once the landmarks rest for DRAG_SETTLE
        seconds (``finish_live_drag``). False writes the settled form at once.

    Returns
    -------
    FitResult or None
        The refit's result, None when nothing moved or no fit is in memory.
    """
    if not live_ready():
        return None
    head = bpy.data.objects.get(_live["head"])
    planes = photos.photo_planes(scene)
    sig = landmarks.landmark_signature(planes)
    prev = _live["signature"]
    _live["signature"] = sig
    if not force and (prev is None or (prev.shape == sig.shape and np.array_equal(prev, sig))):
        return None
    t = time.perf_counter()
    case = landmarks.case_from_scene(scene)
    model = _live["model"]
    result = refit_landmarks(model, case, _live["base"], _live["options"])
    write = shape_keys.show_live_shape if drag else shape_keys.update_fit_values
    if not write(head, model, result):
        _live["error"] = "the head's shape keys changed: run Fit again"
        return None
    head.matrix_world = similarity_matrix(result)
    head.headrecon.fit_rms_px = rms_residual(result)
    update_residuals(scene, result, _live["calibration"])
    _live["result"] = result
    _live["ms"] = (time.perf_counter() - t) * 1000.0
    _live["error"] = ""
    _live["moved_at"] = time.monotonic()
    if drag and not bpy.app.timers.is_registered(_settle_timer):
        bpy.app.timers.register(_settle_timer, first_interval=DRAG_SETTLE)
    return result


def finish_live_drag():
    """Settle the head's keys after a drag (coefficients + detail again). Returns True if
    there was a drag to settle."""
    head = bpy.data.objects.get(_live["head"]) if _live["head"] else None
    if head is None or head.type != "MESH" or not shape_keys.in_live_shape(head):
        return False
    return shape_keys.settle_live_shape(head)


def _settle_timer():
    rest = time.monotonic() - _live.get("moved_at", 0.0)
    if rest < DRAG_SETTLE:
        return DRAG_SETTLE - rest
    try:
        finish_live_drag()
    except Exception as e:  # a timer must not raise
        _live["error"] = str(e)
    return None


@persistent
def _on_depsgraph_update(scene, depsgraph):
    if _live["busy"] or _live["base"] is None:
        return
    props = getattr(scene, "headrecon", None)
    if props is None or not props.live_refit or not depsgraph.id_type_updated("OBJECT"):
        return
    _live["busy"] = True
    try:
        live_refit_step(scene)
    except Exception as e:  # a handler must not raise: show it in the panel instead
        _live["error"] = str(e)
    finally:
        _live["busy"] = False


@persistent
def _on_load(*_args):
    forget_fit()
    for obj in bpy.data.objects:  # a file saved mid-drag by another path than Save
        if obj.type == "MESH" and shape_keys.in_live_shape(obj):
            shape_keys.settle_live_shape(obj)


def pack_baked_textures():
    """Pack baked textures that are not packed, or changed since (they exist only in
    memory until then)."""
    for img in bpy.data.images:
        if img.get(BAKED) and img.has_data and (img.packed_file is None or img.is_dirty):
            img.pack()


@persistent
def _on_save_pre(*_args):
    finish_live_drag()
    pack_baked_textures()


_HANDLERS = (("depsgraph_update_post", _on_depsgraph_update), ("load_post", _on_load),
             ("save_pre", _on_save_pre))


def register_handlers():
    for kind, fn in _HANDLERS:
        handlers = getattr(bpy.app.handlers, kind)
        if fn not in handlers:
            handlers.append(fn)


def unregister_handlers():
    for kind, fn in _HANDLERS:
        handlers = getattr(bpy.app.handlers, kind)
        while fn in handlers:
            handlers.remove(fn)
    if bpy.app.timers.is_registered(_settle_timer):
        bpy.app.timers.unregister(_settle_timer)
    forget_fit()


# --------------------------------------------------------------------------------------
# The operator


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
                           or fit_problem(context.scene))

    def _report_error(self, e):
        if isinstance(e, FitCancelled):
            self.report({"WARNING"}, "Fit cancelled; the scene is as it was")
        elif isinstance(e, FileNotFoundError | ValueError):
            self.report({"ERROR"}, str(e))
        else:
            self.report({"ERROR"}, f"The fit failed: {type(e).__name__}: {e}")

    def _done(self, context, head, job):
        level = "WARNING" if job.error is not None else "INFO"
        self.report({level}, f"Fitted {head.name}: {context.scene.headrecon.status}")
        if job.notes:
            self.report({"WARNING"}, "; ".join(job.notes))

    def execute(self, context):
        try:
            head, job = run_fit(context.scene)
        except Exception as e:
            self._report_error(e)
            return {"CANCELLED"}
        self._done(context, head, job)
        return {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        try:
            job = prepare_job(context.scene)
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
            head = apply_job(context.scene, self.job)
        except Exception as e:
            self._report_error(e)
            return {"CANCELLED"}
        self._done(context, head, self.job)
        return {"FINISHED"}


class HEADRECON_OT_live_refit_now(bpy.types.Operator):
    """Refit from the current landmark positions with the fast path (no new texture)"""

    bl_idname = "headrecon.refit_landmarks"
    bl_label = "Quick Refit"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return poll_result(cls, None if live_ready() else
                           "Run Fit once first (quick refits start from it)")

    def execute(self, context):
        try:
            live_refit_step(context.scene, force=True, drag=False)
        except Exception as e:
            self.report({"ERROR"}, f"Quick refit failed: {e}")
            return {"CANCELLED"}
        if _live["error"]:
            self.report({"ERROR"}, _live["error"])
            return {"CANCELLED"}
        return {"FINISHED"}


CLASSES = (HEADRECON_OT_fit, HEADRECON_OT_live_refit_now)
