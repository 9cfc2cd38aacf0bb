"""Landmark groups' shared definition offsets (solver/fitting/definition.py)."""

import numpy as np
import pytest

from solver import FitOptions, LandmarkCase, OrthographicCamera, View, fit_head
from solver.fitting.definition import (
    OUTLINE_DEFINITION,
    RATIO_GRID,
    GroupedImageRows,
    group_offsets,
)
from solver.fitting.rows import ImageRows, Rows, ScalarRows
from solver.fitting.shape_icp import ShapeProblem
from solver.geometry import rotation_from_vector
from solver.io.landmark_set import load_landmark_set
from solver.model.linear_model import LinearModel
from solver.synthetic import make_case, skin_error_mm

GROUPS = [0, 0, 0, 1, 1, 2, 0, 1, 3]


def _rows(sigma_m=0.003, seed=0):
    rng = np.random.default_rng(seed)
    cam = OrthographicCamera.nominal("orthographic-front", (768, 1024))
    x = rng.normal(size=(len(GROUPS), 3)) * 0.05
    px = cam.project(x) + rng.normal(size=(len(GROUPS), 2)) * 5.0
    w = rng.uniform(0.5, 2.0, len(GROUPS))
    return GroupedImageRows(np.arange(len(GROUPS)), px, cam, GROUPS, sigma_m, weights=w), x


def test_cost_is_the_groups_marginal_likelihood():
    rows, x = _rows()
    r = rows.pixels - rows.camera.project(x)
    jac = np.asarray(rows.camera.jacobian(x)).reshape(-1, 2, 3)
    px_per_m = np.sqrt(0.5 * (jac**2).sum(axis=(1, 2)))
    expected = 0.0
    for g in set(GROUPS):
        m = np.array(GROUPS) == g
        cov = np.diag(1.0 / rows.weights[m]) + (0.003 * px_per_m[m].mean()) ** 2
        expected += sum(r[m, a] @ np.linalg.solve(cov, r[m, a]) for a in range(2))
    assert rows.block(x).sq == pytest.approx(expected, rel=1e-9)


class _Whitened(Rows):
    """The explicit form of ``GroupedImageRows``: the whitened rows ``r_i - beta_G
    mean_w(r)``, each on all vertices of its group (what the block's mean rows replace)."""

    def __init__(self, rows):
        self.rows, self.vertices, self.name = rows, rows.vertices, "whitened"

    def block(self, world, jacobian=True):
        rows = self.rows
        n, w = len(world), rows.weights
        jac = np.asarray(rows.camera.jacobian(world)).reshape(n, 2, 3)
        beta, u = rows.shrink(jac)
        same = rows.labels[:, None] == rows.labels[None, :]
        coef = np.eye(n) - beta[:, None] * np.where(same, u[None, :], 0.0)  # (n, n)
        r = rows.pixels - rows.camera.project(world)
        rw = coef @ r
        sq = float(w @ (rw**2).sum(1))
        g = coef[:, None, :, None] * jac.transpose(1, 0, 2)[None]  # (n, 2, n, 3)
        return ScalarRows(np.tile(np.arange(n), (2 * n, 1)), g.reshape(2 * n, n, 3),
                          rw.reshape(-1), np.repeat(w, 2), sq, float(w.sum()), 2 * n)


def test_explicit_whitened_rows_match_the_cost_and_finite_differences():
    rows, x = _rows()
    ref = _Whitened(rows).block(x)
    assert ref.sq == pytest.approx(rows.block(x).sq, rel=1e-12)
    n = len(GROUPS)
    jac = ref.g  # (2n, n, 3)
    num = np.zeros_like(jac)
    for k in range(n):
        for a in range(3):
            moved = x.copy()
            moved[k, a] += 1e-7
            num[:, k, a] = -(_Whitened(rows).block(moved).r - ref.r) / 1e-7
    assert np.abs(num - jac).max() < 1e-5 * np.abs(jac).max()
    # A row depends only on its own group's vertices.
    other = np.array(GROUPS)[:, None] != np.array(GROUPS)[None, :]
    assert np.abs(jac.reshape(n, 2, n, 3)[other[:, None, :].repeat(2, 1)]).max() == 0.0


def test_mean_rows_give_the_explicit_rows_normal_equations_and_solution():
    # The block's plain rows less one weighted-mean row per group and axis (negative
    # weight) against the whitened rows on all of their group's vertices: the same system.
    rows, x = _rows(sigma_m=0.004, seed=3)
    rng = np.random.default_rng(5)
    model = LinearModel(x, rng.normal(size=(4, len(x), 3)) * 0.003, np.ones(4),
                        tuple(f"m{i}" for i in range(4)))
    # (a front photo does not see depth: the head's position stays)
    fast = ShapeProblem(model, rows, lambda2=0.5, freeze="translation")
    slow = ShapeProblem(model, _Whitened(rows), lambda2=0.5, freeze="translation")
    start = dict(scale=1.02, coeffs=np.array([0.3, -0.2, 0.1, 0.0]),
                 rotation=rotation_from_vector([0.02, -0.01, 0.03]))
    a, b = fast.solve(max_iterations=0, **start), slow.solve(max_iterations=0, **start)
    assert a.info["cost"] == pytest.approx(b.info["cost"], rel=1e-12)
    np.testing.assert_allclose(a.normal_matrix, b.normal_matrix, rtol=1e-9,
                               atol=1e-9 * np.abs(b.normal_matrix).max())
    a, b = fast.solve(tolerance=1e-14, **start), slow.solve(tolerance=1e-14, **start)
    np.testing.assert_allclose(a.coeffs, b.coeffs, atol=1e-9)
    np.testing.assert_allclose(a.rotation, b.rotation, atol=1e-9)
    assert a.scale == pytest.approx(b.scale, rel=1e-9)
    # and a group's mean rows do take something out: without them the system differs
    plain = ShapeProblem(model, ImageRows(rows.vertices, rows.pixels, rows.camera,
                                          weights=rows.weights), lambda2=0.5,
                         freeze="translation")
    c = plain.solve(max_iterations=0, **start)
    assert np.abs(c.normal_matrix - b.normal_matrix).max() > 1e-3 * np.abs(b.normal_matrix).max()


def test_zero_offset_is_plain_image_rows():
    rows, x = _rows(sigma_m=0.0)
    blk = rows.block(x)
    r = rows.pixels - rows.camera.project(x)
    assert blk.sq == pytest.approx(float(rows.weights @ (r**2).sum(1)))


def test_bad_groups_are_named():
    cam = OrthographicCamera.nominal("orthographic-front", (10, 10))
    with pytest.raises(ValueError, match=r"front: groups must have shape \(2,\)"):
        GroupedImageRows([0, 1], np.zeros((2, 2)), cam, [0], 0.002, name="front")
    with pytest.raises(ValueError, match="sigma_m must be >= 0"):
        GroupedImageRows([0, 1], np.zeros((2, 2)), cam, [0, 0], -1.0, name="front")


def test_every_landmark_has_a_group():
    lms = load_landmark_set()
    groups = {n: lms.group_of(n) for n in lms.names}
    assert all(groups.values())
    eye = {groups[lms.canonical(f"ibug{i:02d}")] for i in range(37, 43)}
    assert eye == {"eye_right"}
    assert groups[lms.canonical("ibug43")] == "eye_left"


def _shifted_groups(case, rng, px):
    """``case`` with each landmark group of each photo moved by its own random offset
    (``px`` RMS per axis, ``OUTLINE_DEFINITION`` times that for a front photo's outline
    points): a placement convention shared within a group."""
    lms = load_landmark_set()
    views = {}
    for name, v in case.views.items():
        off = {}
        pts = {}
        for n, p in v.points.items():
            canon = lms.canonical(n)
            g = lms.group_of(canon)
            if g not in off:
                scale = OUTLINE_DEFINITION if lms.outline_in(canon, "front") else 1.0
                off[g] = rng.normal(size=2) * px * scale
            pts[n] = np.asarray(p) + off[g]
        views[name] = View(name, None, v.size, v.camera, pts, contour=v.contour)
    return LandmarkCase(views, case.source)


def test_groups_shifted_together_are_told_from_the_shape(model):
    """Each group of landmarks placed 8 px off (per axis) together, 1 px noise on top:
    with the groups' offsets estimated the head is far nearer the truth than with
    independent errors, and the offsets' size is measured."""
    case, truth = make_case(model, 31, noise_px=1.0)
    moved = _shifted_groups(case, np.random.default_rng(31), 8.0)
    err, sizes = {}, {}
    for mm in (0.0, 2.0):
        r = fit_head(model, moved, FitOptions(definition_mm=mm))
        err[mm] = skin_error_mm(model, r.local_vertices, truth.local_vertices)
        sizes[mm] = r.info["noise"]["definition_mm"]
    assert err[2.0] < 0.75 * err[0.0], err
    assert sizes[0.0] == {}
    cam = truth.cameras["front"]
    expected_mm = 8.0 / (1e-3 * cam.scale)  # pixels per metre -> mm
    assert 0.6 * expected_mm < sizes[2.0]["front"] < 1.5 * expected_mm, (sizes, expected_mm)


def test_landmarks_on_their_vertices_keep_their_accuracy(model):
    """Landmarks placed on their vertices (1 px noise, no shared offsets): the estimated
    offsets fall to nothing (their size by maximum likelihood; one EM step a round left
    0.1 mm of them here) and the head is as good as with independent errors."""
    case, truth = make_case(model, 32, noise_px=1.0)
    err, sizes = {}, {}
    for mm in (0.0, 2.0):
        r = fit_head(model, case, FitOptions(definition_mm=mm))
        err[mm] = skin_error_mm(model, r.local_vertices, truth.local_vertices)
        sizes[mm] = r.info["noise"]["definition_mm"]
    assert err[2.0] < 1.1 * err[0.0], err
    assert max(sizes[2.0].values()) < 0.01, sizes


def _grouped_residuals(rng, groups=40, size=6, offset_px=3.0, noise_px=1.0):
    labels = np.repeat(np.arange(groups), size)
    shift = offset_px * rng.normal(size=(groups, 2))
    r = shift[labels] + noise_px * rng.normal(size=(len(labels), 2))
    jac = np.tile(np.array([[1000.0, 0, 0], [0, 1000.0, 0]]), (len(labels), 1, 1))  # px/m
    return r, labels, np.full(len(labels), 1.0 / noise_px ** 2), jac, shift


def test_group_offsets_find_the_shared_shift_and_its_size():
    # 40 groups of 6 points, each shifted by a 3-px offset, noise 1 px: the posterior
    # offsets follow the true shifts, and the statistic says how far the assumed size is
    # off (1 when right, below 1 when assumed too large, above when too small)
    rng = np.random.default_rng(5)
    r, labels, w, jac, shift = _grouped_residuals(rng)
    ratios = {}
    for assumed in (1.5, 3.0, 6.0):
        e, taken, ratio = group_offsets(r, labels, w, jac, assumed / 1000.0)
        ratios[assumed] = ratio
        assert 0 < taken <= 2 * 40
    e, _, _ = group_offsets(r, labels, w, jac, 3.0 / 1000.0)
    assert np.sqrt(np.mean((e[::6] - shift) ** 2)) < 0.6
    assert abs(ratios[3.0] - 1.0) < 0.2, ratios
    assert ratios[6.0] < 0.8 and ratios[1.5] > 1.2, ratios
    # one point 100 px off moves neither its group's offset nor the statistic much
    r[0] += 100.0
    e2, _, ratio2 = group_offsets(r, labels, w, jac, 3.0 / 1000.0)
    assert np.linalg.norm(e2[1] - e[1]) < 1.0 and abs(ratio2 - ratios[3.0]) < 0.2


def test_group_offsets_size_without_offsets_by_likelihood_and_for_detected_points():
    """Groups with no shared offset: the residuals' maximum likelihood says so at once
    (the grid's least ratio, whatever size was assumed), while a detector's points, whose
    offsets the head takes up before the residuals show them, get one EM step: it falls
    only part of the way. With true offsets both find their size."""
    rng = np.random.default_rng(7)
    r, labels, w, jac, _ = _grouped_residuals(rng, offset_px=0.0)
    for assumed in (1.5, 3.0, 6.0):
        assert group_offsets(r, labels, w, jac, assumed / 1000.0)[2] == RATIO_GRID[0]
        em = group_offsets(r, labels, w, jac, assumed / 1000.0, detected=True)[2]
        assert 0.05 < em < 0.5, (assumed, em)
    r, labels, w, jac, _ = _grouped_residuals(rng)
    for detected in (False, True):
        ratio = group_offsets(r, labels, w, jac, 3.0 / 1000.0, detected=detected)[2]
        assert abs(ratio - 1.0) < 0.2, (detected, ratio)
