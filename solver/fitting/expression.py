"""Expressions in the photos (issue: real faces): each photo may show the face at another
moment, with the eyes closed or a slight smile, while the fit's identity is one neutral
head. Left in the landmarks, an expression bends the identity (closed eyelids pull the
eyes' shape, a smile widens the mouth). So after a fit each photo's expression is estimated
from its landmarks (PHOTO_EXPRESSIONS of the model's shapes, per photo, solved together
with a change of the shared identity), the photo's landmarks are moved back to where the
neutral face would put them, and the fit is repeated with them: the identity sees a
neutral face, the expression is reported per photo.

An expression weight lies in [0, 1] (0: neutral, 1: the shape at full strength) with a
Gaussian prior of standard deviation ``EXPRESSION_SIGMA``, and is used from ``SHOWN`` up,
or from ``FAINT`` up where it stands ``SURE`` of its posterior standard deviations clear of
neutral, or ``AGREED`` of them in every photo (an open jaw only where a photo shows the lips
apart): a weight has to explain clearly more than noise, so a neutral photo keeps its
landmarks and the identity keeps what only an identity can explain, while a mouth a little
open, which the identity would half take, is still taken out (docs/DECISIONS.md).
"""

import dataclasses

import numpy as np
from scipy.optimize import lsq_linear
from scipy.spatial import cKDTree

#: Prior standard deviation of an expression weight.
EXPRESSION_SIGMA = 0.5
#: Weights from this up are applied (taken out of the photo's landmarks) and reported ...
SHOWN = 0.2
#: ... and from this up, those at least ``SURE`` posterior standard deviations (the identity
#: solved out) clear of 0; smaller ones never.
FAINT = 0.1
SURE = 5.0
#: ... or, from ``FAINT`` up, where every photo (two or more) reads it at least ``AGREED``
#: posterior standard deviations clear of 0: one photo's landmarks can carry a face's own
#: trait (lips parted at rest read in the front alone), an expression shows in all photos ...
AGREED = 3.0
#: ... and, for the open jaw, where a photo shows the lips apart: the inner lips' gap on the
#: midline at least this share of the eyes' height above the mouth (a detector reads a
#: closed mouth's lips a few per cent apart, more on a face looking up, whose chin the
#: photos alone would otherwise read as an open jaw).
LIPS_APART = 0.06
#: A photo's landmarks must show this share of an expression's largest movement over all
#: the set's landmarks (in pixels, through its camera) for the photo to be fitted with it:
#: a profile read off its outline (nasion, nose, lips, chin) cannot tell raised brows, and
#: would explain its points' own errors with them.
OBSERVED = 0.5
#: A photo whose camera the fit placed between these yaws about the head (degrees from
#: the front) is fitted without an expression: a three-quarter view far round, whose face
#: mesh points drift with the yaw (neutral rendered heads photographed at 45 degrees
#: either side read as smiling and squinting, weights up to 0.9, and taken out that bent
#: the identity). From the second on it is a profile, whose points are read off its
#: outline or placed by hand (docs/DECISIONS.md, "A three-quarter view far round is
#: fitted without an expression").
FAR_ROUND_DEG = (40.0, 70.0)
#: The expressions a photo is fitted with: those people show when photographed (eyes
#: closed or squinting, a smile, the jaw open, raised brows). The model's other shapes
#: (a pout, the jaw pushed sideways, the eyes looking away) would mostly fit the
#: difference between the person and the model's identities instead, and bend it.
PHOTO_EXPRESSIONS = ("eyeBlink_L", "eyeBlink_R", "eyeSquint_L", "eyeSquint_R",
                     "mouthSmile_L", "mouthSmile_R", "jawOpen", "browInnerUp_L",
                     "browInnerUp_R", "browOuterUp_L", "browOuterUp_R")


def estimate_expressions(model, case, result, noise_px, weights=None, lambda2=1.0):
    """Each photo's expression from the landmarks of ``case`` at the fit ``result``.

    The expression weights are solved together with a change of the identity, linearised
    at ``result`` (the identity with its prior ``lambda2^2 |c|^2``, the weights in [0, 1]
    with theirs): from the residuals alone, the part of an expression the identity had
    already bent to would be missed. Only the weights are returned; the fit itself then
    refits the identity to the landmarks with the expressions taken out.

    Parameters
    ----------
    model : HeadModel
    case : LandmarkCase
        The landmarks as placed (with the expression).
    result : FitResult
        A fit of the case (its cameras and neutral head).
    noise_px : dict of str -> float
        Per view: the landmarks' placement noise (standard deviation, pixels).
    weights : dict of str -> dict of str -> float, optional
        Per view and landmark: a weight factor (the noise estimate's Student-t weights; a
        missing landmark weighs 1; landmarks the fit left out or slid are not used).
    lambda2 : float
        Weight of the identity prior (``FitOptions.lambda2``).

    Returns
    -------
    weights : dict of str -> ndarray, shape (E,)
        Per view with at least 3 landmarks: expression weights in [0, 1], in
        ``model.expression_names`` order (0 but for PHOTO_EXPRESSIONS).
    sd : dict of str -> ndarray, shape (E,)
        The same views: each weight's posterior standard deviation (the identity change
        solved out, the bounds left aside; 0 but for PHOTO_EXPRESSIONS): how surely the
        landmarks tell it from neutral.
    """
    chosen = np.array([model.expression_names.index(n) for n in PHOTO_EXPRESSIONS
                       if n in model.expression_names], dtype=np.int64)
    expr = model.expressions  # (E, V, 3): the chosen ones' landmarks gathered per view
    k = len(result.identity_coeffs)
    basis = model.identity.basis[:k]  # (K, V, 3)
    lms = model.landmark_set
    world = result.world_vertices
    rot = result.scale * result.rotation.T
    # every landmark's movement by each expression, to tell which ones a photo shows
    at_all = expr[chosen[:, None], np.unique(list(lms.vertices.values()))] @ rot
    blocks = []  # per view: (name, identity columns (2n, K), expression columns (2n, E), r)
    for name, view in case.views.items():
        camera = result.cameras.get(name)
        res = result.residuals.get(name)
        if camera is None or res is None or not view.points \
                or FAR_ROUND_DEG[0] < abs(view_yaw_deg(result, camera)) < FAR_ROUND_DEG[1]:
            continue
        keys, canon, verts = _known(lms, view, skip=set(res.unused) | set(res.outline))
        if len(keys) < 3:
            continue
        jac = np.asarray(camera.jacobian(world[verts]), dtype=np.float64).reshape(-1, 2, 3)
        w = (weights or {}).get(name, {})
        sw = np.sqrt(np.array([w.get(c, 1.0) for c in canon])) / max(
            noise_px.get(name, 1.0), 1e-9)
        r = np.asarray([view.points[key] for key in keys], dtype=np.float64) \
            - camera.project(world[verts])
        at_view = expr[chosen[:, None], verts] @ rot  # (E, n, 3)
        seen = _observed(at_view, jac, at_all)
        blocks.append((name, _pixel_columns(basis[:, verts] @ rot, jac, sw),
                       _pixel_columns(at_view, jac, sw) * seen[None, :],
                       (r * sw[:, None]).reshape(-1)))
    if not blocks:
        return {}, {}
    n_e = len(chosen)
    cols = k + n_e * len(blocks)
    rows = sum(len(b[3]) for b in blocks)
    a = np.zeros((rows + cols, cols))
    rhs = np.zeros(rows + cols)
    at = 0
    for j, (_, ident, shown, r) in enumerate(blocks):
        a[at:at + len(r), :k] = ident
        a[at:at + len(r), k + j * n_e:k + (j + 1) * n_e] = shown
        rhs[at:at + len(r)] = r
        at += len(r)
    # priors: the identity stays near the mean head (c + dc), the expressions near neutral
    a[rows:rows + k, :k] = lambda2 * np.eye(k)
    rhs[rows:rows + k] = -lambda2 * np.asarray(result.identity_coeffs, dtype=np.float64)
    a[rows + k:, k:] = np.eye(cols - k) / EXPRESSION_SIGMA
    x, sd = _bounded_weights(a, rhs, k)
    x = applied(x.reshape(len(blocks), n_e), sd.reshape(len(blocks), n_e),
                np.asarray(model.expression_names)[chosen] == "jawOpen",
                lips_apart(lms, case)).reshape(-1)
    out, out_sd = {}, {}
    for j, (name, *_) in enumerate(blocks):
        out[name], out_sd[name] = np.zeros((2, len(model.expression_names)))
        out[name][chosen] = x[j * n_e:(j + 1) * n_e]
        out_sd[name][chosen] = sd[j * n_e:(j + 1) * n_e]
    return out, out_sd


def view_yaw_deg(result, camera):
    """The yaw (degrees) of ``camera``'s optical axis about the fitted head of ``result``:
    0 looking at the face from the front, +-90 from a side."""
    axis = result.rotation.T @ np.asarray(camera.rotation, dtype=np.float64)[2]
    return float(np.degrees(np.arctan2(axis[0], axis[1])))


def applied(weights, sd, jaw, apart):
    """The weights (P, E) of P photos with those left at neutral that do not clearly
    explain more than noise (posterior standard deviations ``sd`` (P, E)): kept from
    ``SHOWN`` up; from ``FAINT`` up where ``SURE`` deviations clear of 0 in their photo, or
    ``AGREED`` in every photo of two or more, for the open jaw (``jaw`` (E,) bool) only
    where the lips are ``apart`` (bool)."""
    faint = weights >= FAINT
    agreed = (faint & (weights >= AGREED * sd)).all(axis=0) & (len(weights) >= 2) \
        & (apart | ~jaw)
    keep = (weights >= SHOWN) | (faint & (weights >= SURE * sd)) | agreed
    return np.where(keep, weights, 0.0)


def lips_apart(lms, case):
    """Whether a photo of ``case`` shows the lips apart: the inner lips' gap on the midline
    at least ``LIPS_APART`` of the height of the eyes' inner corners above the mouth's
    middle (False where no photo gives those points)."""
    wanted = ("mouth_middle", "lip_lower_inner_middle", "eye_inner_right", "eye_inner_left")
    for view in case.views.values():
        p = {lms.canonical(k): np.asarray(v, dtype=np.float64) for k, v in view.points.items()}
        if all(n in p for n in wanted):
            gap = np.linalg.norm(p["lip_lower_inner_middle"] - p["mouth_middle"])
            eyes = 0.5 * (p["eye_inner_right"] + p["eye_inner_left"])
            if gap >= LIPS_APART * np.linalg.norm(eyes - p["mouth_middle"]):
                return True
    return False


def _observed(at_view, jac, at_all):
    """Which expressions (E,) a photo shows: the largest pixel movement among its landmarks
    (``at_view`` (E, n, 3), world offsets through their Jacobians ``jac`` (n, 2, 3)) at
    least OBSERVED times the expression's largest movement over every landmark of the set
    (``at_all`` (E, L, 3)) seen face on at the photo's scale (pixels a metre: the
    Jacobians' median largest singular value)."""
    moved = np.linalg.norm(np.einsum("nij,snj->sni", jac, at_view), axis=2)
    scale = np.median(np.linalg.svd(jac, compute_uv=False)[:, 0])
    full = np.linalg.norm(at_all, axis=2).max(axis=1) * scale
    return (moved.max(axis=1) >= OBSERVED * full).astype(np.float64)


def _bounded_weights(a, rhs, k):
    """The last columns' part (m,) of ``argmin |a x - rhs|`` over x = (free (k,), weights
    in [0, 1] (m,)): the free part is solved out exactly (whatever the weights, it is the
    least-squares fit of the rest, so the weights minimise what lies outside its columns'
    span), leaving a bounded problem in the weights alone. Returns (the weights, their
    standard deviations (m,) with the free part solved out and the bounds left aside)."""
    q, _ = np.linalg.qr(a[:, :k])
    ae, r = a[:, k:], rhs
    ae = ae - q @ (q.T @ ae)
    r = r - q @ (q.T @ r)
    m = ae.shape[1]
    sd = np.sqrt(np.diag(np.linalg.inv(ae.T @ ae)))
    return lsq_linear(ae, r, bounds=(np.zeros(m), np.ones(m)), method="bvls").x, sd


def _known(lms, view, skip=()):
    """The view's landmarks the set knows, but for the canonical names in ``skip``: (keys
    as given, canonical names, model vertices (n,))."""
    keys, canon = [], []
    for key in view.points:
        c = lms.canonical(key)
        if c is not None and c not in skip:
            keys.append(key)
            canon.append(c)
    return keys, canon, np.array([lms.vertices[c] for c in canon], dtype=np.int64)


def _pixel_columns(offsets, jac, sw):
    """World offsets (S, n, 3) of n landmarks through their camera Jacobians (n, 2, 3),
    weighted ``sw`` (n,): the (2n, S) columns of a linear least-squares problem."""
    moved = np.einsum("nij,snj->sni", jac, offsets)
    return (moved * sw[None, :, None]).reshape(len(offsets), -1).T


def neutral_case(model, case, result, expressions):
    """``case`` with each photo's landmarks and traced outline moved back by its expression
    (``expressions``, view -> weights): the pixels the neutral head of ``result`` would
    show them at, given the expression's pixel offsets through that photo's camera. Other
    views unchanged."""
    expr = model.expressions
    lms = model.landmark_set
    views = dict(case.views)
    for name, e in expressions.items():
        e = np.where(e >= FAINT, e, 0.0)
        if not e.any() or name not in result.cameras:
            continue
        view = case.views[name]
        camera = result.cameras[name]
        keys, _, verts = _known(lms, view)
        shift = _pixel_shift(result, camera, verts, e, expr)
        points = dict(view.points)
        for k, d in zip(keys, shift, strict=True):
            points[k] = tuple(np.asarray(view.points[k], dtype=np.float64) - d)
        views[name] = dataclasses.replace(
            view, points=points, contour=_neutral_contour(view.contour, result, name, e, expr))
    return dataclasses.replace(case, views=views)


def _neutral_contour(contour, result, name, weights, expr):
    """A photo's traced outline (n, 2) moved back as its landmarks are: each point by the
    pixel offset the expression ``weights`` (E,) of the shapes ``expr`` (E, V, 3) gives
    the model vertex the fit ``result`` matched nearest to it on that outline (an open
    jaw's chin, a smile's cheek lie outside the neutral head's outline). Unchanged where
    the fit matched none."""
    pairs = ((result.info or {}).get("refit_state") or {}).get("contour", {}).get(name)
    if contour is None or pairs is None or not len(pairs["vertices"]):
        return contour
    verts = np.asarray(pairs["vertices"], dtype=np.int64)
    moved = _pixel_shift(result, result.cameras[name], verts, weights, expr)
    nearest = cKDTree(np.asarray(pairs["pixels"], dtype=np.float64)).query(contour)[1]
    return contour - moved[nearest]


def _pixel_shift(result, camera, verts, weights, expr):
    """Where the expression ``weights`` (E,) of the shapes ``expr`` (E, V, 3) moves the
    vertices ``verts`` (n,) of the fit ``result``'s head in ``camera``'s photo: (n, 2)
    pixels."""
    world = result.world_vertices[verts]
    offset = result.scale * np.tensordot(weights, expr[:, verts], axes=1) @ result.rotation.T
    return camera.project(world + offset) - camera.project(world)


def expressions_moved(old, new, tolerance=SHOWN):
    """Whether any photo's expression weight changed by more than ``tolerance``."""
    if set(old) != set(new):
        return bool(new) or bool(old)
    return any(np.abs(old[k] - new[k]).max(initial=0.0) > tolerance for k in new)


def expression_report(model, expressions, values=None):
    """JSON-ready: per view, the expressions it showed (applied: weight >= FAINT) by name,
    with their weights, or with ``values`` (per view (E,), e.g. the weights' standard
    deviations) where given."""
    names = model.expression_names
    values = expressions if values is None else values
    return {view: {names[i]: float(values[view][i]) for i, w in enumerate(e) if w >= FAINT}
            for view, e in expressions.items() if view in values}
