"""The views of a case as the fit uses them: landmarks as arrays with their model vertices
and weights, the camera each starts from (given, computed from passpoints, or posed on the
mean head), and the state a fit moves (head pose, coefficients, cameras, mirror planes)."""

from dataclasses import dataclass, field, replace

import numpy as np

from ..cameras import Camera, PinholeCamera, camera_class, fit_dlt, is_side_camera
from ..cameras.mirror import MirrorPlane
from ..io.case import LandmarkCase
from ..io.contour import THIN_SPACING_PX, thin_contour
from ..io.landmark_counts import landmarks_needed, too_few, too_few_distinct, too_few_in_all
from ..io.landmark_set import as_landmark_set
from .depth import DEPTH_SHARE
from .options import REFERENCE_PX_PER_M


@dataclass
class ViewData:
    """One photo of the case, as arrays.

    Attributes
    ----------
    name : str
    camera : Camera
        Current camera (replaced as the fit refits it).
    names : list of str
        Canonical landmark names.
    vertices : ndarray, shape (n,)
        Model vertex of each landmark.
    pixels : ndarray, shape (n, 2)
    weights : ndarray, shape (n,)
        Per-landmark weight (landmark weights of the options), before the view's weight
        and the 1 / noise^2 factor.
    side : bool
        The camera looks along the head's left-right axis (a profile photo).
    contour : ndarray, shape (m, 2) or None
        The traced outline's points, as placed.
    refit : bool
        Whether the fit may change this camera (False for a mirror view: its camera
        follows the real camera and the mirror plane).
    mirror_of : str or None
        The view whose camera, reflected in a mirror plane the fit estimates, is this
        view's camera (None: an ordinary view, or a mirror view whose camera is given and
        kept).

    contour_scale : float
        Weight of the outline's rows relative to ``contour_weight`` / noise^2 (the
        estimated outline noise, ``noise.Noise.contour_factor``).
    body_scale : float
        Weight of the outline's rows below the neck's base relative to its others
        (``noise.Noise.body_factor``).
    outline_point : ndarray of bool, shape (n,)
        The landmark is a point of the head's outline in a front photo
        (``LandmarkSet.outline_in``).
    in_profile : ndarray of bool, shape (n,)
        The landmark means a place in a profile photo (``LandmarkSet.has_meaning_in``).
    slide : ndarray of bool, shape (n,)
        Set once the cameras are placed (:func:`assign_roles`): the landmarks matched to
        the head's outline in this photo instead of to their vertices.
    dropped : list of str
        Landmarks left out of this photo (weight 0): outline points of a front photo, with
        no meaning in a profile photo.
    along_weights : ndarray, shape (n,)
        A sliding landmark's weight along the outline, as ``weights`` (the estimated noise
        along it, ``noise.Noise.along_factor``).
    groups : list of str
        Each landmark's definition group (``LandmarkSet.group_of``): landmarks of one group
        share one offset per photo (``definition.GroupedImageRows``).
    definition_m : float
        Standard deviation of that offset, metres (``FitOptions.definition_mm`` at first
        and at most, then as the fit's residuals say, ``noise.Noise.definition_m``).
    relative : ndarray, shape (n,)
        Each landmark's weight factor from its given uncertainty against its view's others
        (:func:`uncertainty_factors`; 1 without one): the noise is estimated on residuals
        scaled by it (``noise.estimate_noise``).
    depth : ndarray, shape (n,)
        Each landmark's depth toward the camera as a detector gave it (``View.depth``,
        px; NaN: none), held through mirror pairs (``depth.depth_rows``).
    depth_sigma : ndarray, shape (n,)
        Its standard deviation, px: ``depth.DEPTH_SHARE`` of the landmark's given
        uncertainty (NaN without one).
    detected : bool
        Its landmarks came with uncertainties of their own (``View.uncertainty``: a
        detector's): their groups' offsets are sized as ``definition.group_offsets`` says.
    lens_mm : float or None
        An orthographic photo's lens as its EXIF gives it (``camera_hints["lens_mm"]``,
        36 mm equivalent): tells how far the camera stood, for the parallel-projection
        check (``outcome.projection_info``).

    A view's outline candidates are not stored here: they depend on the head they were
    found on, so each stage passes its own to :meth:`Engine.joint` (``outlines``).
    """

    name: str
    camera: Camera | None
    names: list
    vertices: np.ndarray
    pixels: np.ndarray
    weights: np.ndarray
    side: bool
    contour: np.ndarray | None = None
    refit: bool = True
    mirror_of: str | None = None
    contour_scale: float = 1.0
    outline_point: np.ndarray | None = None
    in_profile: np.ndarray | None = None
    slide: np.ndarray | None = None
    dropped: list = field(default_factory=list)
    along_weights: np.ndarray | None = None
    groups: list | None = None
    definition_m: float = 0.0
    relative: np.ndarray | None = None
    depth: np.ndarray | None = None
    depth_sigma: np.ndarray | None = None
    detected: bool = False
    lens_mm: float | None = None
    body_scale: float = 1.0

    def __post_init__(self):
        n = len(self.vertices)
        if self.relative is None:
            self.relative = np.ones(n)
        for name in ("depth", "depth_sigma"):
            if getattr(self, name) is None:
                setattr(self, name, np.full(n, np.nan))
        if self.groups is None:
            self.groups = list(self.names)
        if self.along_weights is None:
            self.along_weights = np.asarray(self.weights, dtype=np.float64).copy()
        for name in ("outline_point", "in_profile"):
            if getattr(self, name) is None:
                setattr(self, name, np.full(n, name == "in_profile"))
        if self.slide is None:
            self.slide = np.zeros(n, bool)

    @property
    def fixed_weights(self):
        """``weights`` of the landmarks tied to their vertices (0 for those that slide)."""
        return np.where(self.slide, 0.0, self.weights)


#: A photo whose camera looks at the face within this many degrees of straight on is a
#: front photo for the landmarks' roles (:func:`assign_roles`), one within this many
#: degrees of the head's left-right axis a profile photo.
FRONTAL_DEGREES = 15.0
PROFILE_DEGREES = 20.0


def assign_roles(view, frontal, profile):
    """The landmarks' roles in ``view`` once its camera is placed: in a front photo
    (``frontal``) the outline points slide along the head's outline (``slide``); in a
    profile photo (``profile``) the outline points without a meaning there (the jaw's, the
    head's width) are left out (weight 0, named in ``dropped``).

    Raises
    ------
    ValueError
        Too few landmarks are left for the view's camera (naming the view).
    """
    view.slide = view.outline_point & bool(frontal)
    view.dropped = []
    if profile:
        drop = view.outline_point & ~view.in_profile & (view.weights > 0)
        if drop.any():
            view.dropped = [n for n, d in zip(view.names, drop, strict=True) if d]
            view.weights = np.where(drop, 0.0, view.weights)
            view.along_weights = np.where(drop, 0.0, view.along_weights)
            if view.refit and view.camera is not None:
                _check_count(f"view {view.name!r} (after leaving out "
                             f"{', '.join(view.dropped)}: no meaning in a profile photo)",
                             int(np.count_nonzero(view.weights)),
                             landmarks_needed(view.camera.min_refit_points))


def drop_warnings(views):
    """One note per view that had landmarks without a meaning there."""
    return [f"view {v.name!r}: {', '.join(v.dropped)} not used: "
            f"{'it has' if len(v.dropped) == 1 else 'they have'} no meaning in a profile "
            "photo (outline points of a front photo; see assets/landmarks.json)"
            for v in views if v.dropped]


@dataclass
class State:
    """Head pose, coefficients, cameras and mirror planes (view name -> MirrorPlane of the
    mirror views): ``world = scale * R (mean + B c) + t``."""

    rotation: np.ndarray
    coeffs: np.ndarray
    cameras: dict
    scale: float = 1.0
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    planes: dict = field(default_factory=dict)

    def copy(self):
        return replace(self, rotation=self.rotation.copy(), coeffs=self.coeffs.copy(),
                       cameras=dict(self.cameras), translation=self.translation.copy(),
                       planes=dict(self.planes))



def uncertainty_factors(view, floor_px):
    """Weight factors of a view's landmarks from their given uncertainties
    (``View.uncertainty``, px): (relative, floor). ``relative``: (the view's median given
    uncertainty / this one's)^2, which scales a landmark's weight against the others of its
    group (whose noise the fit estimates, ``noise.py``); ``floor``: (``floor_px`` / this
    one)^2, at most 1, the most weight the landmark may get (relative to 1 / floor_px^2):
    its given uncertainty is its noise floor. Both 1 for a landmark without one."""
    given = getattr(view, "uncertainty", None) or {}
    sigmas = [float(given[k]) for k in view.points if k in given]
    typical = float(np.median(sigmas)) if sigmas else 1.0
    relative = np.array([(typical / float(given[k])) ** 2 if k in given else 1.0
                         for k in view.points])
    floor = np.array([min(1.0, (floor_px / float(given[k])) ** 2) if k in given else 1.0
                      for k in view.points])
    return relative, floor


def photo_scale(model, case):
    """How much larger (or smaller) the head is in the case's photos than in the photos the
    fit's pixel settings are made for: in the view with the most landmarks (at least six;
    a profile's few midline points spread differently), their spread in pixels (RMS
    distance from their mean) per metre of the same landmarks' on the mean head, over the
    nearer end of ``REFERENCE_PX_PER_M``; 1 within it."""
    lms = as_landmark_set(model)
    named = {v.name: [k for k in v.points if lms.canonical(k) is not None]
             for v in case.views.values()}
    view = max(case.views.values(), key=lambda v: len(named[v.name]), default=None)
    keys = named[view.name] if view is not None else []
    if len(keys) < 6:
        return 1.0
    px = np.array([view.points[k] for k in keys], dtype=np.float64).reshape(-1, 2)
    x = model.vertices[[lms.vertices[lms.canonical(k)] for k in keys]]
    metres = np.sqrt(((x - x.mean(axis=0)) ** 2).sum(axis=1).mean())
    pixels = np.sqrt(((px - px.mean(axis=0)) ** 2).sum(axis=1).mean())
    if not (metres > 0 and pixels > 0 and np.isfinite(pixels)):
        return 1.0
    density = float(pixels / metres)
    smallest, largest = REFERENCE_PX_PER_M
    return density / largest if density > largest else \
        density / smallest if density < smallest else 1.0


def prepare_views(model, case, opts, cameras=None, noise=None):
    """The case's views as ``ViewData``; every problem is a ValueError naming the view or
    landmark. ``cameras`` (view name -> Camera, e.g. a previous fit's) replaces the file's
    cameras and nothing is computed. ``noise`` (a ``noise.Noise``) scales each landmark's
    weight and each outline's by the estimated placement noise.

    A mirror view (``View.mirror_of``) whose camera is not kept is linked to the view it
    mirrors: its camera is that view's camera reflected in a mirror plane the fit
    estimates, so the file's camera for it (often just ``{"kind": "dlt"}``) is not used.

    Landmarks per view and in all follow the one rule of ``io/landmark_counts.py`` (with
    ``outline_landmarks="slide"`` a front photo's outline points, which may slide, are not
    counted among the different landmarks the case needs). A
    passpoint camera with too few landmarks to refine it is kept as computed. A view with
    no usable landmark adds nothing to the head fit: it is returned in ``skipped`` (its
    camera still goes into the result).

    Returns
    -------
    views : list of ViewData
        The views the head is fitted to.
    skipped : list of ViewData
        Views with a camera but no usable landmark.
    """
    if not isinstance(case, LandmarkCase):
        raise ValueError(f"case: expected a LandmarkCase, got {type(case).__name__}")
    if not case.views:
        raise ValueError(f"{case.source}: the case has no views")
    lms = as_landmark_set(model)
    weights = dict(opts.landmark_weights or {})
    for key, val in weights.items():
        if lms.canonical(key) is None:
            raise ValueError(f"options.landmark_weights: unknown landmark {key!r}"
                             f"{lms.suggestion(key)}")
        if not isinstance(val, int | float) or not np.isfinite(val) or val < 0:
            raise ValueError(f"options.landmark_weights[{key!r}]: must be a finite number "
                             f">= 0, got {val!r}")
    weights = {lms.canonical(k): float(v) for k, v in weights.items()}
    # a larger photo's outline thinned to as many points as at the reference size
    thinning = THIN_SPACING_PX * (opts.pixel_scale or 1.0)
    fixed = set(opts.fixed_cameras)
    unknown = fixed - set(case.views)
    if unknown:
        raise ValueError(f"options.fixed_cameras: no view named {sorted(unknown)[0]!r} "
                         f"(views: {', '.join(case.views)})")
    n_vertices = model.n_vertices
    views, skipped = [], []
    total = 0
    tied = {}  # model vertex -> name of the landmarks tied to their vertex, over all views
    sliding = opts.outline_landmarks == "slide"
    for name, view in case.views.items():
        where = f"{case.source}: view {name!r}"
        kept = bool(getattr(view, "camera_fixed", False)) or name in fixed
        link = mirror_link(case, view, kept, where)
        names, verts, px, keys = [], [], [], []
        for key, uv in view.points.items():
            canon = lms.canonical(key)
            if canon is None:
                raise ValueError(f"{where}: unknown landmark {key!r}{lms.suggestion(key)}")
            uv = np.asarray(uv, dtype=np.float64).reshape(-1)
            if uv.shape != (2,) or not np.isfinite(uv).all():
                raise ValueError(f"{where}: landmark {key!r}: expected two finite pixel "
                                 f"coordinates, got {uv.tolist()}")
            vtx = lms.vertices[canon]
            if not 0 <= vtx < n_vertices:
                raise ValueError(f"{where}: landmark {key!r}: vertex {vtx} is not in the "
                                 "model")
            names.append(canon)
            verts.append(vtx)
            px.append(uv)
            keys.append(key)
        w = opts.landmark_weight * np.array([weights.get(n, 1.0) for n in names])
        relative, floor = uncertainty_factors(view, opts.noise_px)
        along = w * floor
        if noise is not None:
            along = w * np.minimum(floor, relative * [noise.along_factor(name, n)
                                                      for n in names])
            w = w * np.minimum(floor, relative * [noise.landmark_factor(name, n)
                                                  for n in names])
        else:
            w = w * floor
        used = int(np.count_nonzero(w))
        rule = {"kept": kept, "passpoints": bool(view.passpoints), "mirror": link is not None}
        if cameras is not None:
            if name not in cameras:
                raise ValueError(f"{where}: was not in that fit (views: "
                                 f"{', '.join(cameras)})")
            cam = cameras[name]
        elif link is not None:
            cam = None  # the real camera reflected, once that camera is placed
        else:
            cam = view.camera
            if cam is None:  # to be computed: the count first
                kind = camera_class((getattr(view, "camera_hints", {}) or {}).get("kind"))
                _check_count(where, used, landmarks_needed(
                    0 if kind is None else kind.min_refit_points, **rule))
                cam = compute_camera(model, case, view, lms, where)
        if cam is not None and not isinstance(cam, Camera):
            raise ValueError(f"{where}: camera of unknown kind ({type(cam).__name__}); "
                             "expected a solver.cameras.Camera")
        contour = None
        if view.contour is not None and len(view.contour) >= 2:
            c = np.asarray(view.contour, dtype=np.float64)
            if not np.isfinite(c).all():
                raise ValueError(f"{where}: contour has a point that is not finite")
            if len(np.unique(c.reshape(-1, 2), axis=0)) < 2:
                raise ValueError(f"{where}: contour needs at least 2 distinct points")
            contour = c.reshape(-1, 2)
            if thinning > THIN_SPACING_PX:
                contour = thin_contour(contour, thinning)
        side = cam is not None and is_side_camera(cam)
        tied.update((v, n) for n, v, wv in zip(names, verts, w, strict=True) if wv > 0 and not (
            sliding and not side and lms.outline_in(n, "front")))
        refit_points = 0 if cam is None else cam.min_refit_points
        # An orthographic profile photo with a traced outline needs no landmark: its camera
        # starts from the outline (contour_start.py), the head's pose from the other photos.
        rule["outline"] = contour is not None and side and not cam.perspective \
            and link is None
        _check_count(where, used, landmarks_needed(refit_points, **rule))
        # A camera is refitted on the head unless it is kept, follows a mirror, or comes
        # from passpoints with too few landmarks to refine it.
        refit = not kept and link is None and (
            rule["outline"] or used >= landmarks_needed(refit_points))
        total += used
        data = ViewData(name, cam, names, np.array(verts, dtype=np.int64),
                        np.array(px, dtype=np.float64).reshape(-1, 2), w, side, contour,
                        refit, link, 1.0 if noise is None else noise.contour_factor(name),
                        np.array([lms.outline_in(n, "front") for n in names], dtype=bool),
                        np.array([lms.has_meaning_in(n, "right")
                                  or lms.has_meaning_in(n, "left") for n in names],
                                 dtype=bool), along_weights=along,
                        groups=[lms.group_of(n) for n in names],
                        definition_m=0.0 if cam is None or cam.perspective
                        else _definition_m(opts, noise, name), relative=relative,
                        depth=np.array([view.depth.get(k, np.nan) for k in keys]),
                        depth_sigma=DEPTH_SHARE * np.array(
                            [view.uncertainty.get(k, np.nan) for k in keys]),
                        detected=any(k in view.uncertainty for k in keys),
                        lens_mm=_orthographic_lens(view, cam),
                        body_scale=1.0 if noise is None else noise.body_factor(name))
        (views if used or rule["outline"] else skipped).append(data)
    for v in views:
        if v.mirror_of is not None and any(u.name == v.mirror_of for u in skipped):
            raise ValueError(f"{case.source}: view {v.name!r} mirrors view {v.mirror_of!r}, "
                             "which has no usable landmark; the mirror is found from "
                             "landmarks placed in both")
    problem = too_few_in_all(total) or too_few_distinct(list(tied.values()), sliding)
    if problem is not None:
        raise ValueError(f"{case.source}: {problem}")
    return views, skipped


def _definition_m(opts, noise, view):
    """A view's landmark groups' definition offset, metres: ``FitOptions.definition_mm``
    at first and at most, less when the last fit's residuals say so. (The caller gives a
    perspective photo none: measured worse there, docs/DECISIONS.md.)"""
    most = 1e-3 * float(opts.definition_mm)
    if noise is None:
        return most
    return min(noise.definition_m.get(view, most), most)


def _check_count(where, used, need):
    problem = too_few(used, need)
    if problem is not None:
        raise ValueError(f"{where}: {problem}")


def unused_views(skipped, views):
    """What a fit left out, by view: ``{"skipped": [view names], "dropped": {view name:
    [landmark names]}}`` (the fit's ``info["unused"]``; the warnings say the same in
    words, ``skip_warnings`` and ``drop_warnings``)."""
    return {"skipped": [v.name for v in skipped],
            "dropped": {v.name: list(v.dropped) for v in views if v.dropped}}


def skip_warnings(skipped):
    return [f"view {v.name!r}: no usable landmark, so it adds nothing to the head fit"
            f"{' (its outline is not used)' if v.contour is not None else ''}; its camera is "
            "kept as given or computed from its passpoints" for v in skipped]


def mirror_link(case, view, kept, where):
    """The view a mirror view's camera is derived from (None: not a mirror view, or one
    whose camera is kept as given)."""
    target = getattr(view, "mirror_of", None)
    if target is None:
        return None
    if target not in case.views or target == view.name:
        raise ValueError(f"{where}: mirror_of names {target!r}, not another view of the case "
                         f"(views: {', '.join(case.views)})")
    if getattr(case.views[target], "mirror_of", None) is not None:
        raise ValueError(f"{where}: mirror_of names {target!r}, itself a mirror view; name "
                         "the view seen directly")
    if kept:
        if view.camera is None:
            raise ValueError(f"{where}: a mirror view whose camera is kept needs the camera's "
                             "parameters (or leave it free: it is then the real camera "
                             "reflected in the mirror)")
        return None
    return target


#: Lenses (mm, 35 mm equivalent) a pinhole camera without a stated focal length is tried
#: with; the one whose pose fits the mean head's landmarks best starts the fit.
TRIAL_LENSES_MM = (24.0, 35.0, 50.0, 85.0, 135.0)


def _orthographic_lens(view, camera):
    """The lens (mm, 36 mm equivalent) an orthographic photo's hints give, else None."""
    lens = (getattr(view, "camera_hints", {}) or {}).get("lens_mm")
    if camera is None or camera.perspective or lens is None:
        return None
    lens = float(lens)
    return lens if np.isfinite(lens) and lens > 0 else None


#: Relative standard deviation of the focal prior a stated ``lens_mm`` gives (EXIF data of
#: uncertain crop factor).
LENS_PRIOR_SIGMA = 0.05


def compute_camera(model, case, view, lms, where):
    """A camera for a view whose file gives only its kind (``View.camera`` None): a DLT
    from the view's passpoints when it has them (a "pinhole" kind: the nearest pinhole
    camera). Else self-calibrated on the mean head's landmarks, a start the fit refines: a
    DLT fitted to them; a pinhole camera posed on them with the file's focal length
    (``lens_mm``, then also a prior of LENS_PRIOR_SIGMA on it) or, without one, with the
    best of TRIAL_LENSES_MM. (A DLT or a free focal length fitted to the mean head would
    bend the camera to the mean head's shape: a head is shallow, so focal length and
    distance trade off.)"""
    hints = dict(getattr(view, "camera_hints", {}) or {})
    kind = hints.get("kind")
    if kind not in ("dlt", "pinhole"):
        raise ValueError(f"{where}: no camera parameters and no way to compute a camera of "
                         f"kind {kind!r} (give the parameters, or a 'dlt'/'pinhole' kind)")
    keys = [k for k in view.points if lms.canonical(k) is not None]
    verts = [lms.vertices[lms.canonical(k)] for k in keys]
    uv = np.array([view.points[k] for k in keys], dtype=np.float64).reshape(-1, 2)
    options = {}
    if "lens_mm" in hints:
        options["focal_prior"] = (float(hints["lens_mm"]), LENS_PRIOR_SIGMA)
    if hints.get("focal_prior") is not None:
        options["focal_prior"] = tuple(float(x) for x in hints["focal_prior"])
    if "free_focal" in hints:
        options["free_focal"] = bool(hints["free_focal"])
    if hints.get("direction_prior") is not None:
        options["direction_prior"] = tuple(float(x) for x in hints["direction_prior"])
    try:
        if view.passpoints:
            _, xyz, pts = case.passpoint_arrays(view.name)
            dlt = fit_dlt(xyz, pts, view.size).camera
            return dlt if kind == "dlt" else PinholeCamera.from_dlt(dlt, **options)
        if kind == "dlt":
            return fit_dlt(model.vertices[verts], uv, view.size).camera
        ppm = PinholeCamera.px_per_mm(view.size)
        if "focal_px" in hints:
            lenses = [float(hints["focal_px"]) / ppm]
        elif "lens_mm" in hints:
            lenses = [float(hints["lens_mm"])]
        else:
            lenses = list(TRIAL_LENSES_MM)
        best = None
        for lens in lenses:
            probe = PinholeCamera(lens * ppm, np.eye(3), np.zeros(3), view.size,
                                  free_focal=False, focal_range_mm=None)
            cam = probe.refit(model.vertices[verts], uv)
            err = float((cam.reprojection_error(model.vertices[verts], uv) ** 2).sum())
            if best is None or err < best[0]:
                best = (err, cam)
        cam = best[1]
        return PinholeCamera(cam.focal_px, cam.rotation, cam.centre, view.size, **options)
    except ValueError as e:
        raise ValueError(f"{where}: cannot compute the {kind} camera: {e}") from None


def saved_state(previous, eng, views, where):
    """The State a previous FitResult ended in (cameras of the views it had, mirror
    planes)."""
    saved = getattr(previous, "info", {}).get("refit_state") if previous is not None else None
    if saved is None:
        raise ValueError(f"{where}: expected a FitResult from fit_head (its info has no "
                         "'refit_state')")
    coeffs = np.asarray(saved["coeffs"], dtype=np.float64)
    if coeffs.shape != (eng.lin.n_coeffs,):
        raise ValueError(f"{where}: {coeffs.size} coefficients, but the model with these "
                         f"options has {eng.lin.n_coeffs} (n_identity and n_regional must "
                         "match)")
    missing = [v.name for v in views if v.name not in previous.cameras]
    if missing:
        raise ValueError(f"{where}: view {missing[0]!r} was not in that fit (views: "
                         f"{', '.join(previous.cameras)})")
    planes = {}
    for v in views:
        if v.mirror_of is None:
            continue
        p = saved.get("planes", {}).get(v.name)
        if p is None:
            raise ValueError(f"{where}: view {v.name!r} was not a mirror view in that fit")
        planes[v.name] = MirrorPlane(np.asarray(p["normal"], dtype=np.float64),
                                     float(p["offset"]))
    return State(np.asarray(previous.rotation, dtype=np.float64).copy(), coeffs.copy(),
                 {v.name: previous.cameras[v.name] for v in views}, float(previous.scale),
                 np.asarray(previous.translation, dtype=np.float64).copy(), planes), saved


def previous_cameras(previous, where):
    cams = getattr(previous, "cameras", None)
    if not isinstance(cams, dict) or "refit_state" not in getattr(previous, "info", {}):
        raise ValueError(f"{where}: expected a FitResult from fit_head (its info has no "
                         "'refit_state')")
    return cams

