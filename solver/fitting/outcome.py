"""What a fit ends with: the better approach chosen, the landmark residuals flagged, the
per-vertex uncertainty, the detail the model cannot express, and the reports on mirrors and
on each photo's projection, assembled into a ``FitResult``."""

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import gammainc

from ..cameras import OrthographicCamera
from ..cameras.mirror import triangulate_mirror
from ..cameras.projection_check import check_orthographic, check_projection, lens_distance
from ..memo import memo
from .engine import skin_basis32
from .result import FitResult, ViewResidual
from .tps import ThinPlateSpline

#: Identity coefficients beyond this percentile of the model's own heads are warned about.
PLAUSIBLE_PERCENTILE = 99.0


def choose(eng, joint, candidates, tie=0.05, by_cost=False):
    """The candidate whose landmarks and contour reproject best; within ``tie`` (relative)
    of the best, the one with the smallest shape prior (the more typical head). With
    ``by_cost`` "best" is the lowest posterior cost (residuals weighted by their estimated
    noise, plus the priors) instead of the plain pixel RMS, which an overfitted head wins."""
    scores = {}
    for name, (state, _) in candidates.items():
        fit = joint.cost(state) if by_cost else joint.reprojection_rms(state)
        scores[name] = (fit, eng.prior_cost(state.coeffs))
    best_rms = min(r for r, _ in scores.values())
    close = [n for n, (r, _) in scores.items() if r <= best_rms * (1.0 + tie) + 1e-9]
    chosen = min(close, key=lambda n: scores[n][1])
    return chosen, scores


def flag_residuals(residuals, sigmas=3.0, min_px=5.0):
    """Landmarks whose residual stands out (seed 000 §5: a residual far above the others
    means a data error).

    Each residual is compared with the mean and standard deviation of all the *other*
    residuals (leave-one-out, so an outlier does not hide itself by inflating the spread):
    flagged when above ``mean + sigmas * std`` and above ``min_px``.

    Parameters
    ----------
    residuals : dict of str -> ndarray (n,)
        Pixel residuals per view.
    sigmas, min_px : float

    Returns
    -------
    dict of str -> ndarray of bool
    """
    names = list(residuals)
    allr = np.concatenate([np.asarray(residuals[n], dtype=np.float64) for n in names]) \
        if names else np.zeros(0)
    m = len(allr)
    if m < 3:
        return {n: np.zeros(len(residuals[n]), bool) for n in names}
    s1, s2 = allr.sum(), (allr**2).sum()
    mean_o = (s1 - allr) / (m - 1)
    var_o = np.maximum((s2 - allr**2) / (m - 1) - mean_o**2, 0.0)
    flag = (allr > mean_o + sigmas * np.sqrt(var_o)) & (allr > min_px)
    out, i = {}, 0
    for n in names:
        k = len(residuals[n])
        out[n] = flag[i:i + k]
        i += k
    return out


def view_errors(camera, world, view):
    if not len(view.vertices):
        return np.zeros(0)
    return np.linalg.norm(camera.project(world[view.vertices]) - view.pixels, axis=1)


def landmark_residuals(eng, state, opts, local, skipped=(), outline=None):
    """Landmark residuals of the final head (``local`` includes any detail), flagged; a
    skipped view's (landmarks of weight 0 only, or none) unflagged. ``outline``: view name
    -> (landmark indices, pixel distances across the outline) of the sliding landmarks
    that met it, whose residuals these are (``Joint.outline_matches``)."""
    world = state.scale * local @ state.rotation.T + state.translation
    res = {v.name: view_errors(state.cameras[v.name], world, v) for v in eng.views}
    across = {}
    for name, (idx, r) in (outline or {}).items():
        res[name][idx] = np.abs(r)
        across[name] = set(np.asarray(idx).tolist())
    # the landmarks the fit used are compared with each other; those it left out are not
    used = {v.name: v.weights > 0 for v in eng.views}
    flags = flag_residuals({n: r[used[n]] for n, r in res.items()}, opts.flag_sigmas,
                           opts.flag_min_px)
    out = {}
    for v in eng.views:
        r = res[v.name]
        slid = across.get(v.name, set())
        flagged = np.zeros(len(r), bool)
        flagged[used[v.name]] = flags[v.name]
        out[v.name] = ViewResidual(
            list(v.names), r.copy(),
            [n for n, f in zip(v.names, flagged, strict=True) if f],
            [n for i, n in enumerate(v.names) if i in slid],
            [n for n, w in zip(v.names, v.weights, strict=True) if w == 0])
    for v in skipped:
        out[v.name] = ViewResidual(list(v.names), view_errors(v.camera, world, v), [])
    return out


def skin_maps(model):
    """Per model (computed once): non-skin vertices, the nearest skin vertex of each (to
    give them the skin's uncertainty) and the skin vertices that steer them (TPS
    controls)."""
    def make():
        n = model.n_vertices
        skin = np.asarray(model.skin, dtype=np.int64)
        is_skin = np.zeros(n, bool)
        is_skin[skin] = True
        other = np.flatnonzero(~is_skin)
        rest = model.vertices
        tree = cKDTree(rest[skin])
        nearest = skin[tree.query(rest[other])[1]] if len(other) else other
        # TPS controls: skin within 2 cm of a non-skin vertex (the eyelids, lips, mouth
        # corners that hold the eyes and teeth), thinned to about 300 by a stride.
        ctrl = np.zeros(0, np.int64)
        if len(other):
            d, _ = cKDTree(rest[other]).query(rest[skin], distance_upper_bound=0.02)
            near = skin[np.isfinite(d)]
            ctrl = near[::max(1, len(near) // 300)]
        return {"other": other, "nearest": nearest, "controls": ctrl}

    return memo(model, "skin maps", make)


def follow_skin(model, skin_disp):
    """Displacement of the non-skin parts (eyes, teeth, ...) that carries a skin-only
    displacement (regional modes are zero off the skin) smoothly onto them: a thin-plate
    spline through the skin around them, (V, 3), zero on the skin."""
    maps = skin_maps(model)
    out = np.zeros_like(skin_disp)
    ctrl, other = maps["controls"], maps["other"]
    if len(other) == 0 or len(ctrl) < 4 or not skin_disp[ctrl].any():
        return out
    rest = model.vertices
    tps = ThinPlateSpline.fit(rest[ctrl], rest[ctrl] + skin_disp[ctrl], regularization=1e-4)
    out[other] = tps.apply(rest[other]) - rest[other]
    return out


def vertex_uncertainty(model, eng, cov):
    """Posterior standard deviation of each vertex, millimetres: sqrt of the trace of
    B_v Sigma B_v^T over the skin (float32: display precision), the nearest skin vertex's
    value elsewhere."""
    maps = skin_maps(model)
    skin = np.asarray(model.skin, dtype=np.int64)
    b32 = skin_basis32(eng.lin, skin)
    evals, evecs = np.linalg.eigh(0.5 * (cov + cov.T))
    f = (np.sqrt(np.clip(evals, 0.0, None))[:, None] * evecs.T).astype(np.float32)
    y = f @ b32
    # squares summed in float32 too: 100 terms lose ~1e-6 relative, and converting the
    # (K, 3 S) product to float64 first cost as much as the product itself
    var = np.einsum("ij,ij->j", y, y).reshape(-1, 3).sum(axis=1, dtype=np.float64)
    out = np.zeros(model.n_vertices)
    out[skin] = 1000.0 * np.sqrt(var)
    out[maps["other"]] = out[maps["nearest"]]
    return out


def local_terms(model, eng, state, opts):
    """(identity coeffs, regional coeffs, identity+regional displacement (V, 3), the
    regional part (V, 3))."""
    k_id = int(opts.n_identity)
    c = state.coeffs
    parts = eng.lin.displacements(c)
    disp = parts[0].copy()
    for extra in parts[1:]:
        disp += extra
    reg = parts[-1] if opts.n_regional > 0 else np.zeros_like(disp)
    return c[:k_id].copy(), c[k_id:].copy(), disp, reg


def exact_detail(eng, state, local):
    """TPS in the model frame that moves every landmark vertex onto its target (the pixels
    it was placed at, in every photo that shows it), applied to all vertices: (V, 3)."""
    verts, _, tgt = eng.landmark_targets(state)
    if len(verts) < 4:
        return np.zeros_like(local)
    tgt_local = ((tgt - state.translation) @ state.rotation) / state.scale
    try:
        tps = ThinPlateSpline.fit(local[verts], tgt_local, regularization=0.0)
    except ValueError:
        return np.zeros_like(local)
    return tps.apply(local) - local


def make_result(model, eng, state, opts, method, info, uncertainty=None, detail=None,
                 skipped=(), outline=None):
    ident, regc, disp, reg = local_terms(model, eng, state, opts)
    if detail is None:
        detail = np.zeros_like(disp)
        if opts.n_regional > 0:
            detail += follow_skin(model, reg)
        if opts.exact_landmarks:
            detail += exact_detail(eng, state, model.vertices + disp + detail)
    local = model.vertices + disp + detail
    names = tuple(eng.lin.names[int(opts.n_identity):]) if opts.n_regional > 0 else ()
    return FitResult(
        method=method, scale=float(state.scale), rotation=state.rotation.copy(),
        translation=state.translation.copy(), identity_coeffs=ident,
        regional_coeffs=regc, regional_names=names, detail=detail, local_vertices=local,
        cameras={**state.cameras, **{v.name: v.camera for v in skipped}},
        residuals=landmark_residuals(eng, state, opts, local, skipped, outline),
        uncertainty=uncertainty, info=info)


def mirror_info(eng, state, opts):
    """Per mirror view: the plane, and each landmark seen directly and in the mirror
    triangulated from both rays (seed 001 eq. 3.5-3.7) with the gap between them: in
    metres and in pixels at the landmark's depth (gap * f / depth). A gap that stands out
    (``flag_residuals`` with the options' sigmas and pixel floor) means a landmark placed
    on different points in the two images. Returns (info, warnings)."""
    out, warnings = {}, []
    for m in eng.views:
        if m.mirror_of is None:
            continue
        r = eng.view(m.mirror_of)
        plane = state.planes[m.name]
        real = state.cameras[r.name].as_dlt()
        direct = {n: i for i, n in enumerate(r.names)}
        pairs = [(n, direct[n], j) for j, n in enumerate(m.names) if n in direct]
        names = [p[0] for p in pairs]
        d_px = r.pixels[[p[1] for p in pairs]]
        m_px = m.pixels[[p[2] for p in pairs]]
        mid, gaps = triangulate_mirror(real, plane, d_px, m_px)
        k = real.decompose()[0]
        depth = np.maximum(np.abs(real.depth(mid)), 1e-9)
        gap_px = gaps * float(np.sqrt(k[0, 0] * k[1, 1])) / depth
        flags = flag_residuals({"gaps": gap_px}, opts.flag_sigmas, opts.flag_min_px)["gaps"]
        flagged = [n for n, f in zip(names, flags, strict=True) if f]
        out[m.name] = {
            "mirror_of": r.name, "normal": plane.normal.copy(), "offset_m": plane.offset,
            "point_m": plane.point,
            "ray_gap_mm": {n: 1000.0 * float(g) for n, g in zip(names, gaps, strict=True)},
            "ray_gap_px": {n: float(g) for n, g in zip(names, gap_px, strict=True)},
            "flagged": flagged}
        if flagged:
            worst = ", ".join(f"{n} ({out[m.name]['ray_gap_px'][n]:.1f} px)" for n in flagged)
            warnings.append(f"view {m.name!r} (mirror of {r.name!r}): the direct and the "
                            f"mirrored ray of {worst} miss each other; check where these "
                            "landmarks are placed in both images")
    return out, warnings


def projection_info(model, result, eng, opts):
    """Seed 001 ch. 2: the parallel-projection error epsilon of every photo for the fitted
    head (its skin). Perspective cameras are always reported; an orthographic photo only
    when ``camera_distance_m`` is given or its lens is known (``ViewData.lens_mm``, from
    EXIF: ``lens_distance``), with a warning when its epsilon exceeds what the
    landmarks can tell (reading error 2 noise_px over the head's image size). Returns
    (info, warnings)."""
    pts = result.world_vertices[np.asarray(model.skin, dtype=np.int64)]
    out, warnings = {}, []
    reading = 2.0 * opts.noise_px
    for v in eng.views:
        cam = result.cameras[v.name]
        try:
            if cam.perspective:
                chk = check_projection(cam, pts, reading_error_px=reading, view=v.name)
            elif isinstance(cam, OrthographicCamera) and (
                    opts.camera_distance_m is not None or v.lens_mm is not None):
                distance = opts.camera_distance_m
                if distance is None:
                    distance = lens_distance(cam, v.lens_mm)
                chk = check_orthographic(cam, pts, distance, reading_error_px=reading,
                                         view=v.name)
                if chk.exceeds:
                    warnings.append(chk.message + (
                        "" if opts.camera_distance_m is not None else
                        f" (the distance from the photo's {v.lens_mm:g} mm lens, EXIF)"))
            else:
                continue
        except ValueError as e:  # e.g. a head point behind the camera: say so, go on
            warnings.append(str(e))
            continue
        out[v.name] = {"epsilon": chk.epsilon, "epsilon_max": chk.epsilon_max,
                       "distance_m": chk.distance, "depth_extent_m": chk.depth_extent,
                       "min_distance_m": chk.min_distance, "exceeds": chk.exceeds,
                       "perspective": cam.perspective}
    return out, warnings


def plausibility(coeffs, cameras=None):
    """How typical a head is under the model: the Mahalanobis norm of its identity
    coefficients (standard deviations) and the percentile of the model's own heads with a
    smaller norm (the squared norm of K standard-normal coefficients is chi-square with K
    degrees of freedom). Returns (info, warnings): a warning above PLAUSIBLE_PERCENTILE,
    and with it one per camera of ``cameras`` (view name -> Camera) whose focal length the
    fit estimated with no lens to hold it (``unknown_lens``): two photos' points tell a lens
    poorly, and a wrong one bends the head (docs/DECISIONS.md, "the lens of a
    three-quarter photo without EXIF")."""
    c = np.asarray(coeffs, dtype=np.float64).reshape(-1)
    norm = float(np.sqrt(c @ c))
    # the chi-square distribution function with len(c) degrees of freedom
    percentile = 100.0 * float(gammainc(0.5 * len(c), 0.5 * norm * norm)) if len(c) else 0.0
    info = {"mahalanobis": norm, "percentile": percentile, "n_coeffs": len(c),
            "largest_sigma": float(np.abs(c).max()) if len(c) else 0.0}
    warnings = []
    if percentile > PLAUSIBLE_PERCENTILE:
        warnings.append(f"the fitted head is implausible: its identity lies {norm:.1f} "
                        f"standard deviations from the mean head, beyond {percentile:.2f} % "
                        f"of the model's heads (one coefficient at "
                        f"{info['largest_sigma']:.1f} sigma); check the flagged landmarks "
                        "first, then for misplaced or mislabelled ones, left and right "
                        "exchanged or a profile of the other side; if they are right, raise "
                        "the placement noise (noise_px, --noise-px on the command line)")
        warnings += lens_warnings(cameras)
    return info, warnings


def lens_warnings(cameras):
    """One warning per camera of ``cameras`` (view name -> Camera) whose focal length the
    fit estimated with no lens to hold it (``unknown_lens``)."""
    return [f"view {name!r}: its lens is not known (no EXIF or lens given) and the fit "
            f"estimated it at {cam.lens_mm:.0f} mm, which the photos' points tell poorly; "
            "if you know the lens, give it (the photo's Focal Length in Blender, lens_mm in "
            "the view's camera, --lens with solver detect)"
            for name, cam in (cameras or {}).items() if unknown_lens(cam)]


def prior_raised_warning(first, first_rms_px, kept, factor):
    """The warning for a fit whose first head was implausible (``first``: its
    :func:`plausibility` info) and which kept ``kept``, fitted with the prior's weight
    raised ``factor`` times, since it reproduces the landmarks about as well."""
    now = kept.info["plausibility"]
    return (f"the head first fitted was implausible (its identity {first['mahalanobis']:.1f} "
            f"standard deviations from the mean head, beyond {first['percentile']:.2f} % of "
            f"the model's heads); with the prior's weight raised {factor:g} times a head "
            f"{now['mahalanobis']:.1f} from the mean head fits the landmarks about as well "
            f"({kept.rms_px():.1f} against {first_rms_px:.1f} px RMS) and was kept; check the "
            "flagged landmarks, and give the lens of a photo without EXIF if you know it")


def unknown_lens(camera):
    """Whether ``camera`` is a pinhole whose focal length the fit estimates freely (no lens
    given, so no prior on it)."""
    return bool(getattr(camera, "perspective", False) and getattr(camera, "free_focal", False)
                and getattr(camera, "focal_prior", None) is None)
