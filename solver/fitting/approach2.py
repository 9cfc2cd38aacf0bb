"""Approach 2 of the thesis (§4.4.3): TPS-ICP. A thin-plate spline takes the head's
landmark vertices to their 3-D targets, and the model is fitted to the warped skin."""

import numpy as np

from .outline import view_outlines
from .rows import PointRows
from .tps import ThinPlateSpline

# Share of the TPS-warped skin in approach 2's cost, relative to all landmarks.
DENSE_SHARE = 0.3


# Approach 2 stops once a round improves the reprojection error by less than this fraction.
A2_PROGRESS = 0.01


def dense_vertices(model, step=8):
    """Every ``step``-th skin vertex (about 1400): the dense 3-D rows of approach 2 (the
    skin is regularly meshed, so a stride is an even subsample)."""
    return np.asarray(model.skin, dtype=np.int64)[::step]


def approach2(eng, model, state, opts):
    """Thesis §4.4.3: TPS-ICP, repeated while the reprojection error falls.

    Each round warps the head with a thin-plate spline that takes its landmark vertices
    to their 3-D targets (``Engine.landmark_targets``), then fits the model to the warped
    skin (every 8th skin vertex) and to the targets themselves (weighted like the
    landmarks' pixels), with the traced outlines and the sliding landmarks (which have no
    3-D target) as in approach 1; the cameras follow.
    Outlines other than an orthographic profile's are matched to candidates found on the
    head approach 2 starts from (``info["outlines"]``, as in :func:`approach1`).
    """
    dense = dense_vertices(model)
    # Metres to the image rows' weighted pixels: a landmark's 3-D row weighs what its
    # pixel rows would (camera scale squared / noise^2); all dense rows together weigh
    # DENSE_SHARE times all landmarks (the warp between landmarks is a guess: it should
    # steer, not dominate).
    s2 = pixels_per_metre_sq(eng, state)
    n_lm = sum(int((v.weights > 0).sum()) for v in eng.views)
    w_lm = s2 * eng.inv_var * opts.landmark_weight
    own = view_outlines(model, eng, state)
    joint = eng.joint(eng.views, outlines=own)
    verts, _, tgt = eng.landmark_targets(state)
    side = [v for v in eng.views if v.contour is not None]
    # The shape-ICP works on copies of the vertices used: dense skin, landmarks, then the
    # outline candidates once per photo with a traced outline.
    nd, nl = len(dense), len(verts)
    mesh_rows = PointRows(np.arange(nd), eng.world(state, dense),
                          weights=DENSE_SHARE * w_lm * n_lm / nd, name="tps mesh")
    lm_rows = PointRows(np.arange(nd, nd + nl), tgt, weights=w_lm, name="tps landmarks")
    contour, parts, off = [], [], nd + nl
    for v in side:
        rows, cand = eng.contour_rows(v, off, own)
        contour.append((v, rows))
        parts.append(cand)
        off += len(cand)
    for v in eng.views:  # the sliding landmarks have no 3-D target: as in approach 1
        if v.name in joint.sliding:
            rows, copies, _ = eng.sliding_rows(v, off, own)
            contour += [(v, r) for r in rows]
            parts.append(copies)
            off += len(copies)
    # One problem for all rounds: only targets change, so the dense rows' Gram matrix
    # is computed once.
    copies = np.concatenate([dense, verts] + parts)
    problem = eng.problem(eng.copies_model(copies),
                          [mesh_rows, lm_rows] + [rows for _, rows in contour],
                          vertex_major=eng.vertex_major(copies))
    best = (joint.reprojection_rms(state), state.copy())
    history = [best[0]]
    for _ in range(opts.tps_iterations):
        _, cur, tgt = eng.landmark_targets(state)  # same vertices every round
        tps = ThinPlateSpline.fit(cur, tgt, regularization=0.0)
        mesh_rows.set_targets(tps.apply(eng.world(state, dense)))
        lm_rows.set_targets(tgt)
        for v, rows in contour:
            rows.set_camera(state.cameras[v.name])
        fit = problem.solve(scale=state.scale, rotation=state.rotation,
                            translation=state.translation, coeffs=state.coeffs,
                            max_iterations=3, tolerance=opts.tolerance, sigma=1.0,
                            final_system=False)
        state = state.copy()
        state.rotation, state.coeffs = fit.rotation, fit.coeffs
        state.scale, state.translation = fit.scale, fit.translation
        joint.cost(state)  # contour correspondences at the new head
        joint.refit(state)
        err = joint.reprojection_rms(state)
        history.append(err)
        if err < best[0]:
            improved = best[0] - err > A2_PROGRESS * best[0]
            best = (err, state.copy())
            if not improved:
                break
        else:
            break
    eng.use(best[1])
    return best[1], {"history": history, "outlines": own}


def pixels_per_metre_sq(eng, state):
    """Mean squared image scale of the cameras at the head (pixels per metre, squared)."""
    vals = []
    verts = np.concatenate([v.vertices for v in eng.views])
    centre = eng.world(state, verts).mean(axis=0, keepdims=True)
    for v in eng.views:
        jac = np.asarray(state.cameras[v.name].jacobian(centre)).reshape(2, 3)
        vals.append(0.5 * float((jac * jac).sum()))
    return float(np.mean(vals))

