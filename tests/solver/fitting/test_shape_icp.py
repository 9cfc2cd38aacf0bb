"""Shape-ICP (solver/fitting/shape_icp.py) on synthetic linear models with known answers."""

import numpy as np
import pytest

from solver import OrthographicCamera
from solver.fitting.rows import ClosestPointRows, ImageRows, PointRows, ScalarRows
from solver.fitting.shape_icp import ShapeProblem, shape_icp
from solver.geometry import rotation_from_vector
from solver.model.linear_model import LinearModel


def _sphere(n):
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    th = np.pi * (1 + 5**0.5) * i
    return np.stack([np.cos(th) * np.sin(phi), np.sin(th) * np.sin(phi), np.cos(phi)], 1)


def _features(u):
    x, y, z = u.T
    return np.stack([x**3, y**3 * z, z**3, x * y, y * z, x * z, x * x - y * y,
                     3 * z * z - 1, x * y * z, np.exp(-((y + 1) ** 2) * 8)], 1)


def synthetic_model(n=600, k=8, seed=0):
    """A head-sized ellipsoid (metres) with a nose bump toward -Y and a smooth basis of
    k modes (standard-normal units, first mode about 4 mm RMS)."""
    rng = np.random.default_rng(seed)
    u = _sphere(n)
    mean = u * np.array([0.075, 0.095, 0.115])
    mean[:, 1] -= 0.03 * np.exp(-((u[:, 1] + 1) ** 2 + u[:, 2] ** 2) * 20)  # the "nose"
    f = _features(u)
    basis = np.einsum("nf,kfd->knd", f, rng.standard_normal((k, f.shape[1], 3)))
    sd = 0.004 * 0.8 ** np.arange(k)
    basis *= (sd / np.sqrt((basis**2).sum(axis=(1, 2))))[:, None, None]
    return LinearModel(mean, basis, sd, tuple(f"mode_{i}" for i in range(k)))


def two_region_model(n=800, k=4, seed=1):
    """Two regions (upper/lower) overlapping in a band; blended basis, gamma rows as the
    thesis' eq. 40 (unblended difference of the two regions at shared vertices)."""
    rng = np.random.default_rng(seed)
    base = synthetic_model(n, 1, seed)
    z = base.mean[:, 2] / 0.115
    band = 0.25
    in_a, in_b = z > -band, z < band
    w_a = np.clip((z + band) / (2 * band), 0, 1)
    f = _features(_sphere(n))
    comp = np.einsum("nf,rkfd->rknd", f, rng.standard_normal((2, k, f.shape[1], 3)))
    comp *= 0.003 / np.sqrt((comp**2).sum(axis=(2, 3)))[:, :, None, None]
    comp[0][:, ~in_a] = 0
    comp[1][:, ~in_b] = 0
    basis = np.concatenate([comp[0] * w_a[None, :, None], comp[1] * (1 - w_a)[None, :, None]])
    shared = np.flatnonzero(in_a & in_b)
    gamma = np.concatenate([comp[0][:, shared], -comp[1][:, shared]])  # (2k, s, 3)
    gamma = gamma.transpose(1, 2, 0).reshape(-1, 2 * k)
    return LinearModel(base.mean, basis, np.full(2 * k, 0.003),
                       tuple(f"r{r}_{i}" for r in range(2) for i in range(k)), gamma), shared


TRUE_ROT = rotation_from_vector([0.12, -0.2, 0.08])
TRUE_S = 1.06
TRUE_T = np.array([0.01, -0.02, 1.5])


def _truth(model, seed=3, scale=0.8):
    c = scale * np.random.default_rng(seed).standard_normal(model.n_coeffs)
    return c, TRUE_S * model.instance(c) @ TRUE_ROT.T + TRUE_T


def _rot_err_deg(a, b):
    return np.degrees(np.arccos(np.clip((np.trace(a.T @ b) - 1) / 2, -1, 1)))



def test_recovers_similarity_and_shape_noise_free():
    model = synthetic_model()
    c, x = _truth(model)
    v = np.arange(model.n_vertices)
    fit = shape_icp(model, PointRows(v, x), translation=x.mean(0), tolerance=1e-14)
    assert fit.converged and fit.iterations <= 12
    assert fit.scale == pytest.approx(TRUE_S, abs=1e-10)
    np.testing.assert_allclose(fit.rotation, TRUE_ROT, atol=1e-10)
    np.testing.assert_allclose(fit.translation, TRUE_T, atol=1e-10)
    np.testing.assert_allclose(fit.coeffs, c, atol=1e-8)
    assert fit.error < 1e-20
    # The error of eq. 46 decreases along the iterations.
    h = np.array(fit.error_history)
    assert np.all(np.diff(h) <= 1e-18)
    np.testing.assert_allclose(fit.world_vertices(model), x, atol=1e-10)
    assert fit.free[:7] == ("scale", "rotation x", "rotation y", "rotation z",
                            "translation x", "translation y", "translation z")
    assert fit.free[7:] == model.names


def test_noise_within_posterior_and_sigma_estimate():
    model = synthetic_model()
    c, x = _truth(model, seed=4)
    rng = np.random.default_rng(5)
    noise = 0.001  # 1 mm per coordinate
    fit = shape_icp(model, PointRows(np.arange(model.n_vertices),
                                     x + noise * rng.standard_normal(x.shape)),
                    translation=x.mean(0))
    assert fit.converged
    assert fit.sigma == pytest.approx(noise, rel=0.08)
    z = (fit.coeffs - c) / np.sqrt(np.diag(fit.coeff_covariance))
    assert np.abs(z).max() < 4.5  # stated tolerance: every coefficient within 4.5 sigma
    rms = np.sqrt(((fit.world_vertices(model) - x) ** 2).sum(1).mean())
    assert rms < 0.4e-3  # stated tolerance: model fit 0.4 mm RMS under 1 mm noise
    assert _rot_err_deg(fit.rotation, TRUE_ROT) < 0.2


def test_two_d_only_rows_with_some_3d_rows():
    model = synthetic_model()
    c, x = _truth(model, seed=6)
    n = model.n_vertices
    front = np.arange(0, n, 2)  # known only in x and z (a front photo, thesis approach 1)
    profile = np.arange(1, n, 25)  # a few with all coordinates
    mask = np.zeros((len(front), 3), bool)
    mask[:, [0, 2]] = True
    targets = x[front].copy()
    targets[:, 1] = np.nan  # unknown depth may be NaN
    rows = [PointRows(front, targets, mask=mask, weights=2.0, name="front"),
            PointRows(profile, x[profile], name="profile")]
    fit = shape_icp(model, rows, translation=x.mean(0), tolerance=1e-14)
    assert fit.converged
    np.testing.assert_allclose(fit.coeffs, c, atol=1e-8)
    np.testing.assert_allclose(fit.world_vertices(model), x, atol=1e-10)
    assert [g["name"] for g in fit.info["groups"]] == ["front", "profile"]
    assert fit.info["groups"][0]["rows"] == 2 * len(front)


def test_image_rows_through_orthographic_cameras():
    model = synthetic_model()
    c, x = _truth(model, seed=7)
    n = model.n_vertices
    front = OrthographicCamera.nominal("orthographic-front", (1200, 1600))
    side = OrthographicCamera.nominal("orthographic-right", (1200, 1600))
    # Cameras look at the head near the origin; put the truth there.
    x = x - TRUE_T + np.array([0.0, 0.0, 0.02])
    a, b = np.arange(0, n, 3), np.arange(1, n, 4)
    rows = [ImageRows(a, front.project(x[a]), front, name="front"),
            ImageRows(b, side.project(x[b]), side, weights=0.5, name="side")]
    fit = shape_icp(model, rows, tolerance=1e-14)
    assert fit.converged
    np.testing.assert_allclose(fit.world_vertices(model), x, atol=1e-10)
    np.testing.assert_allclose(fit.coeffs, c, atol=1e-7)
    assert fit.scale == pytest.approx(TRUE_S, abs=1e-10)
    # With pixel noise (0.5 px): within a stated tolerance of 0.3 mm RMS.
    rng = np.random.default_rng(8)
    for r in rows:
        r.set_pixels(r.pixels + 0.5 * rng.standard_normal(r.pixels.shape))
    fit = shape_icp(model, rows)
    assert np.sqrt(((fit.world_vertices(model) - x) ** 2).sum(1).mean()) < 0.3e-3
    assert fit.sigma == pytest.approx(0.5, rel=0.15)  # pixels


def test_a_solve_without_the_final_system_takes_the_same_steps():
    model = synthetic_model()
    c, x = _truth(model, seed=9)
    front = OrthographicCamera.nominal("orthographic-front", (1200, 1600))
    side = OrthographicCamera.nominal("orthographic-right", (1200, 1600))
    x = x - TRUE_T + np.array([0.0, 0.0, 0.02])
    rng = np.random.default_rng(3)
    v = np.arange(0, model.n_vertices, 5)
    rows = [ImageRows(v, front.project(x[v]) + rng.normal(size=(len(v), 2)), front),
            ImageRows(v, side.project(x[v]) + rng.normal(size=(len(v), 2)), side)]
    problem = ShapeProblem(model, rows, lambda2=0.3)
    for steps in (1, 3):
        full = problem.solve(max_iterations=steps, tolerance=0.0)
        fast = problem.solve(max_iterations=steps, tolerance=0.0, final_system=False)
        assert fast.iterations == full.iterations == steps
        np.testing.assert_array_equal(fast.coeffs, full.coeffs)
        np.testing.assert_array_equal(fast.rotation, full.rotation)
        assert (fast.scale, list(fast.translation)) == (full.scale, list(full.translation))
        # the last error is the step's own evaluation (no correspondences to refresh here)
        assert fast.error_history == pytest.approx(full.error_history, rel=1e-12)
        # and the normal matrix the step's start's, not the end's
        assert np.abs(fast.normal_matrix - full.normal_matrix).max() > 0.0


def test_image_rows_chain_rule_matches_finite_differences():
    # Through a perspective-like camera (nonlinear projection), the solver's Jacobian
    # must agree with finite differences of the residual: checked via a converged fit
    # whose gradient J^T W r vanishes.
    class Pinhole(OrthographicCamera):
        def project(self, points):
            p = points @ self.rotation.T + [0, 0, 0.6]
            return 1000 * p[:, :2] / p[:, 2:3] + self.offset

        def jacobian(self, points):
            p = points @ self.rotation.T + [0, 0, 0.6]
            j = np.zeros((len(p), 2, 3))
            j[:, 0, 0] = j[:, 1, 1] = 1000 / p[:, 2]
            j[:, :, 2] = -1000 * p[:, :2] / p[:, 2:3] ** 2
            return j @ self.rotation

    model = synthetic_model()
    c, x = _truth(model, seed=9)
    x = x - TRUE_T
    cams = [Pinhole(np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]), 1, (500, 500), (1000, 1000)),
            Pinhole(np.array([[0, -1.0, 0], [0, 0, -1], [1, 0, 0]]), 1, (500, 500), (1000, 1000))]
    v = np.arange(model.n_vertices)
    rows = [ImageRows(v, cam.project(x), cam, name=f"cam{i}") for i, cam in enumerate(cams)]
    fit = shape_icp(model, rows, tolerance=1e-15, max_iterations=50)
    np.testing.assert_allclose(fit.world_vertices(model), x, atol=1e-9)


def test_composed_groups_in_one_solve():
    # A profile cloud (closest points), front landmarks in pixels and a few 3-D points,
    # solved together from a perturbed start.
    model = synthetic_model()
    c, x = _truth(model, seed=10, scale=0.5)
    x = x - TRUE_T
    n = model.n_vertices
    front = OrthographicCamera.nominal("orthographic-front", (1000, 1000))
    mid = np.flatnonzero(np.abs(model.mean[:, 0]) < 0.01)  # midsagittal band
    land = np.arange(0, n, 15)
    rows = [ClosestPointRows(mid, x[mid], max_distance=0.015, name="profile"),
            ImageRows(land, front.project(x[land]), front, name="front landmarks"),
            PointRows(land[::4], x[land[::4]], weights=1e5, name="3-D")]
    fit = shape_icp(model, rows, rotation=rotation_from_vector([0.05, 0.1, 0.0]) @ TRUE_ROT,
                    scale=1.0, max_iterations=60, tolerance=1e-12)
    assert _rot_err_deg(fit.rotation, TRUE_ROT) < 0.05
    assert np.sqrt(((fit.world_vertices(model) - x) ** 2).sum(1).mean()) < 1e-4
    assert fit.info["groups"][0]["rows"] > 0


def test_closest_point_icp_from_rough_start():
    model = synthetic_model(n=2000)
    c, x = _truth(model, seed=11, scale=0.5)
    rng = np.random.default_rng(12)
    cloud = x + 0.0003 * rng.standard_normal(x.shape)
    v = np.arange(model.n_vertices)
    rows = ClosestPointRows(v, cloud, max_distance=0.03, reject_factor=3.0)
    # An ellipsoid's quadratic modes mimic small rotations, so start within ~3 degrees
    # (the real head, with nose and ears, is tested from 10 degrees in test_register.py).
    start = rotation_from_vector([0.03, -0.04, 0.02]) @ TRUE_ROT
    sim = shape_icp(model, rows, freeze="shape", rotation=start, translation=cloud.mean(0),
                    max_iterations=60)
    fit = shape_icp(model, rows, scale=sim.scale, rotation=sim.rotation,
                    translation=sim.translation, max_iterations=60, tolerance=1e-7)
    assert _rot_err_deg(fit.rotation, TRUE_ROT) < 0.5
    assert np.sqrt(((fit.world_vertices(model) - x) ** 2).sum(1).mean()) < 1e-3
    assert rows.inliers.mean() > 0.9
    # Symmetric correspondences reach the same answer.
    rows_s = ClosestPointRows(v, cloud, max_distance=0.03, symmetric=True)
    fit_s = shape_icp(model, rows_s, scale=fit.scale, rotation=fit.rotation,
                      translation=fit.translation, coeffs=fit.coeffs, max_iterations=30)
    assert np.sqrt(((fit_s.world_vertices(model) - x) ** 2).sum(1).mean()) < 1e-3


def test_freeze_options():
    model = synthetic_model()
    v = np.arange(model.n_vertices)
    # Target = similarity of the mean shape: shape frozen recovers it exactly.
    x = TRUE_S * model.mean @ TRUE_ROT.T + TRUE_T
    c0 = np.full(model.n_coeffs, 0.0)
    fit = shape_icp(model, PointRows(v, x), freeze=("shape",), translation=x.mean(0),
                    tolerance=1e-14)
    np.testing.assert_array_equal(fit.coeffs, c0)
    assert fit.coeff_covariance is None and len(fit.free) == 7
    np.testing.assert_allclose(fit.rotation, TRUE_ROT, atol=1e-10)
    # Scale frozen: stays exactly at its start value.
    fit = shape_icp(model, PointRows(v, x), freeze="scale", scale=1.0, translation=x.mean(0))
    assert fit.scale == 1.0 and "scale" not in fit.free
    # Rotation and translation frozen.
    r0 = rotation_from_vector([0, 0, 0.3])
    fit = shape_icp(model, PointRows(v, x), freeze=("rotation", "translation"), rotation=r0)
    np.testing.assert_allclose(fit.rotation, r0, atol=1e-15)
    np.testing.assert_array_equal(fit.translation, np.zeros(3))


def test_one_linear_step_is_exact_for_linear_problem():
    # Scale and rotation fixed: the residual is linear in (t, c), so one step solves it.
    model = synthetic_model()
    c = np.random.default_rng(13).standard_normal(model.n_coeffs)
    x = model.instance(c) + [0.01, 0.02, 0.03]
    v = np.arange(0, model.n_vertices, 7)
    problem = ShapeProblem(model, PointRows(v, x[v]), freeze=("scale", "rotation"))
    fit = problem.solve(max_iterations=1)
    assert fit.iterations == 1 and len(fit.error_history) == 2
    np.testing.assert_allclose(fit.coeffs, c, atol=1e-10)
    np.testing.assert_allclose(fit.translation, [0.01, 0.02, 0.03], atol=1e-12)
    # Reuse the prepared problem with new targets (the fast refit path).
    problem.groups[0].rows.set_targets(x[v] + [0.0, 0.0, 0.01])
    fit = problem.solve(max_iterations=1)
    np.testing.assert_allclose(fit.translation, [0.01, 0.02, 0.04], atol=1e-12)
    # max_iterations=0 only evaluates.
    fit0 = problem.solve(max_iterations=0)
    assert fit0.iterations == 0 and fit0.error > 0


def test_active_coefficients_and_n_coeffs():
    model = synthetic_model()
    c, x = _truth(model, seed=14)
    v = np.arange(model.n_vertices)
    start = np.zeros(model.n_coeffs)
    start[5:] = c[5:]
    fit = shape_icp(model, PointRows(v, x), n_coeffs=5, coeffs=start,
                    translation=x.mean(0), tolerance=1e-14)
    np.testing.assert_allclose(fit.coeffs, c, atol=1e-8)  # inactive ones were right already
    np.testing.assert_array_equal(fit.coeffs[5:], c[5:])
    assert fit.coeff_covariance.shape == (5, 5)
    fit = shape_icp(model, PointRows(v, x), active=[1, 3], translation=x.mean(0))
    assert np.count_nonzero(fit.coeffs) == 2 and fit.coeffs[1] != 0 and fit.coeffs[3] != 0


def test_priors_match_stacked_least_squares():
    # One step of the linear problem equals lstsq on [J; lambda1 Gamma; lambda2 Lambda].
    model, _ = two_region_model()
    rng = np.random.default_rng(15)
    v = np.arange(0, model.n_vertices, 3)
    y = model.mean[v] + 0.004 * rng.standard_normal((len(v), 3))
    lam1, lam2 = 0.3, 0.2
    for prior in ("eigen", "identity"):
        fit = shape_icp(model, PointRows(v, y), freeze=("scale", "rotation", "translation"),
                        lambda1=lam1, lambda2=lam2, prior=prior, max_iterations=1)
        a = model.basis[:, v].reshape(model.n_coeffs, -1).T
        lam = lam2 * (model.stddev if prior == "identity" else np.ones(model.n_coeffs))
        stacked = np.vstack([a, lam1 * model.gamma, np.diag(lam)])
        rhs = np.r_[(y - model.mean[v]).ravel(), np.zeros(len(model.gamma) + model.n_coeffs)]
        np.testing.assert_allclose(fit.coeffs, np.linalg.lstsq(stacked, rhs, rcond=None)[0],
                                   atol=1e-9)


def test_gamma_pulls_overlapping_regions_together():
    model, shared = two_region_model()
    rng = np.random.default_rng(16)
    u = _sphere(model.n_vertices)
    # A deformation the regions cannot both follow: they disagree in the overlap.
    y = model.mean + 0.006 * np.stack([u[:, 2] ** 2, np.sin(3 * u[:, 2]), u[:, 0]], 1)
    y += 0.0005 * rng.standard_normal(y.shape)
    v = np.arange(model.n_vertices)
    kw = dict(freeze=("scale", "rotation", "translation"), tolerance=1e-12)
    fits = [shape_icp(model, PointRows(v, y), lambda1=lam, **kw) for lam in (0, 1, 3, 10)]
    disagreement = [np.linalg.norm(model.gamma @ f.coeffs) for f in fits]
    assert disagreement[0] > 0.01  # metres: the regions really disagree without Gamma
    assert all(a > b for a, b in zip(disagreement, disagreement[1:], strict=False))
    assert disagreement[-1] < 0.1 * disagreement[0]
    # Gamma costs some data fit, not much.
    assert fits[0].error < fits[-1].error < 1.3 * fits[0].error
    assert len(shared) * 3 == model.gamma.shape[0]


@pytest.mark.parametrize("prior", ["eigen", "identity"])
def test_lambda_shrinks_coefficients(prior):
    model = synthetic_model()
    c, x = _truth(model, seed=17)
    rng = np.random.default_rng(18)
    v = np.arange(0, model.n_vertices, 10)
    y = x[v] + 0.002 * rng.standard_normal((len(v), 3))
    norms = []
    for lam in (0.0, 0.001, 0.01, 0.1) if prior == "eigen" else (0.0, 0.3, 3.0, 30.0):
        fit = shape_icp(model, PointRows(v, y), lambda2=lam, prior=prior,
                        translation=y.mean(0))
        w = model.stddev if prior == "identity" else 1.0
        norms.append(np.linalg.norm(w * fit.coeffs))
    assert all(a > b for a, b in zip(norms, norms[1:], strict=False))
    assert norms[-1] < 0.5 * norms[0]


def test_lambda_makes_underdetermined_system_solvable():
    model = synthetic_model()
    v = np.arange(3)  # 9 rows for 15 parameters
    y = model.mean[v] + 0.001
    with pytest.raises(ValueError, match="too few observations.*9 residual rows"):
        shape_icp(model, PointRows(v, y))
    fit = shape_icp(model, PointRows(v, y), lambda2=0.01, freeze=("rotation", "scale"))
    assert np.isfinite(fit.coeffs).all()


# ------------------------------------------------------------------------- bad input


def _rows(model, n=50):
    v = np.arange(n)
    return v, model.mean[v]



def test_bad_problem_input():
    model = synthetic_model()
    v, y = _rows(model)
    rows = PointRows(v, y)
    with pytest.raises(ValueError, match="vertex index 9999 out of range"):
        shape_icp(model, PointRows(np.array([0, 9999] * 20), np.zeros((40, 3))))
    with pytest.raises(ValueError, match="freeze: unknown"):
        shape_icp(model, rows, freeze=("size",))
    with pytest.raises(ValueError, match="every parameter is frozen"):
        shape_icp(model, rows, freeze=("scale", "rotation", "translation", "shape"))
    with pytest.raises(ValueError, match="lambda2: must be finite"):
        shape_icp(model, rows, lambda2=-1)
    with pytest.raises(ValueError, match="prior: must be"):
        shape_icp(model, rows, prior="ridge")
    with pytest.raises(ValueError, match="n_coeffs: must be in"):
        shape_icp(model, rows, n_coeffs=99)
    with pytest.raises(ValueError, match="active: expected unique"):
        shape_icp(model, rows, active=[0, 0])
    with pytest.raises(ValueError, match="rotation: not a proper rotation"):
        shape_icp(model, rows, rotation=np.diag([1.0, 1, -1]))
    with pytest.raises(ValueError, match="scale: must be finite and > 0"):
        shape_icp(model, rows, scale=0.0)
    with pytest.raises(ValueError, match="coeffs: expected 8"):
        shape_icp(model, rows, coeffs=np.zeros(3))
    with pytest.raises(ValueError, match="translation: expected 3"):
        shape_icp(model, rows, translation=[0, np.nan, 0])
    with pytest.raises(ValueError, match="rows: at least one"):
        shape_icp(model, [])
    with pytest.raises(ValueError, match="model: expected a LinearModel"):
        shape_icp(np.zeros((3, 3)), rows)


def test_singular_system_names_the_parameter():
    # One orthographic front view cannot see depth: translation along its axis (world Y)
    # is undetermined.
    model = synthetic_model()
    cam = OrthographicCamera.nominal("orthographic-front", (1000, 1000))
    v = np.arange(0, model.n_vertices, 5)
    rows = ImageRows(v, cam.project(model.mean[v]), cam, name="front")
    with pytest.raises(ValueError, match="singular system.*'translation y'"):
        shape_icp(model, rows, freeze="shape")
    # Freezing it (or adding a side view) makes it solvable.
    fit = shape_icp(model, rows, freeze=("shape", "translation"))
    assert fit.error < 1e-20
    # A coefficient whose basis vanishes on the used vertices is named too.
    basis = model.basis.copy()
    basis[2, v] = 0.0
    m2 = LinearModel(model.mean, basis, model.stddev, model.names)
    with pytest.raises(ValueError, match="no row constrains 'mode_2'"):
        shape_icp(m2, PointRows(v, model.mean[v]))
    # All correspondences rejected: too few rows, reported per group.
    far = ClosestPointRows(v, model.mean[v] + 1.0, max_distance=0.01, name="scan")
    with pytest.raises(ValueError, match="too few observations.*scan: 0"):
        shape_icp(model, far)


def test_set_priors_reuses_cached_system_correctly():
    # Changing priors between solves (as register's annealing does) must give exactly what
    # a fresh problem gives from the same start.
    model, _ = two_region_model()
    rng = np.random.default_rng(19)
    v = np.arange(0, model.n_vertices, 2)
    y = model.mean[v] + 0.003 * rng.standard_normal((len(v), 3))
    problem = ShapeProblem(model, PointRows(v, y))
    first = problem.solve(max_iterations=3)
    start = dict(scale=first.scale, rotation=first.rotation, translation=first.translation,
                 coeffs=first.coeffs)
    problem.set_priors(lambda1=0.5, lambda2=0.05, anneal=0.02)
    again = problem.solve(**start, max_iterations=3)
    fresh = ShapeProblem(model, PointRows(v, y), lambda1=0.5, lambda2=0.05)
    fresh.set_priors(anneal=0.02)
    ref = fresh.solve(**start, max_iterations=3)
    np.testing.assert_allclose(again.coeffs, ref.coeffs, atol=1e-12)
    np.testing.assert_allclose(again.normal_matrix, ref.normal_matrix, atol=1e-9)
    with pytest.raises(ValueError, match="anneal: must be finite"):
        problem.set_priors(anneal=-1.0)


def test_unprojectable_vertex_is_named():
    class Behind(OrthographicCamera):
        def project(self, points):
            px = super().project(points)
            px[points[:, 1] > 0.05] = np.nan  # "behind the camera"
            return px

    model = synthetic_model()
    cam = Behind(np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]), 2000.0, (500, 500), (1000, 1000))
    v = np.arange(model.n_vertices)
    first_bad = int(v[model.mean[:, 1] > 0.05][0])
    with pytest.raises(ValueError, match=f"front: vertex {first_bad} does not project"):
        shape_icp(model, ImageRows(v, np.zeros((len(v), 2)), cam, name="front"))


def test_set_camera_makes_a_cached_system_stale():
    # A problem solved once caches its final system; a camera swapped in through
    # set_camera must be used by the next solve (the cache is keyed on the rows' version).
    model = synthetic_model()
    x = model.mean  # the head at rest: only the camera differs
    v = np.arange(0, model.n_vertices, 3)
    cam = OrthographicCamera.nominal("orthographic-front", (1200, 1600))
    moved = OrthographicCamera(cam.rotation, cam.scale, cam.offset + [40.0, -25.0], cam.size,
                               cam.view)
    rows = ImageRows(v, cam.project(x[v]), cam, name="front")
    depth = PointRows(v[:1], x[v[:1]], mask=np.array([[False, True, False]]), name="depth")
    problem = ShapeProblem(model, [rows, depth], lambda2=1e-6,
                           freeze=("rotation", "scale", "shape"))
    first = problem.solve(max_iterations=0)  # builds and caches the system at the start
    rows.set_camera(cam)  # the same camera: nothing changes
    assert problem.solve(max_iterations=0).info["data_cost"] == first.info["data_cost"]
    rows.set_camera(moved)
    assert rows.camera is moved
    stale = problem.solve(max_iterations=0)
    # the cost at the start is the one through the new camera (40 and 25 px per point)
    expected = float(((moved.project(model.mean[v]) - rows.pixels) ** 2).sum())
    assert stale.info["data_cost"] == pytest.approx(expected, rel=1e-9)
    assert stale.info["data_cost"] != pytest.approx(first.info["data_cost"], rel=1e-3)
    # and the solve through it moves the head by the camera's offset (back in metres)
    fit = problem.solve(max_iterations=10, tolerance=1e-14)
    shift = np.array([40.0, -25.0]) / cam.scale  # u is world x, v is world -z
    np.testing.assert_allclose(fit.translation, [-shift[0], 0.0, shift[1]], atol=1e-9)
    with pytest.raises(ValueError, match="camera must be a Camera"):
        rows.set_camera("front")



class _EdgePointRows(PointRows):
    """3-D targets of points between two vertices, ``(1 - t) x_a + t x_b``, as scalar rows
    on both vertices (ScalarRows with idx (m, 2) and g (m, 2, 3))."""

    def __init__(self, vertices, ends, t, targets):
        super().__init__(vertices, np.zeros((len(vertices), 3)), name="edge points")
        self.ends, self.t, self.edge_targets = ends, t, targets

    def block(self, world, jacobian=True):
        t = self.t[:, None]
        p = (1 - t) * world[self.ends[:, 0]] + t * world[self.ends[:, 1]]
        r = (self.edge_targets - p).reshape(-1)  # x, y, z row per point
        w = np.ones(len(r))
        if not jacobian:
            return ScalarRows(None, None, None, None, float(r @ r), float(w.sum()), len(r))
        eye = np.tile(np.eye(3), (len(t), 1))  # (3m, 3)
        tt = np.repeat(self.t, 3)[:, None]
        g = np.stack([(1 - tt) * eye, tt * eye], axis=1)  # (3m, 2, 3)
        idx = np.repeat(self.ends, 3, axis=0)
        return ScalarRows(idx, g, r, w, float(r @ r), float(w.sum()), len(r))


class _MixedRows(PointRows):
    """Each vertex pulled toward its target, one scalar row per coordinate, plus rows on
    the mean x of vertex pairs weighted ``pair_w``: given as ``ScalarRows.mix`` of the
    coordinate rows, or (``explicit``) as rows on both vertices of their own; None: no
    pair rows."""

    def __init__(self, vertices, targets, pairs, pair_targets, pair_w, explicit):
        super().__init__(vertices, targets, name="mixed")
        self.pairs, self.pair_targets = pairs, pair_targets
        self.pair_w, self.explicit = pair_w, explicit

    def block(self, world, jacobian=True):
        n = len(world)
        r = (self.targets - world).reshape(-1)  # rows (vertex, coordinate)
        pr = self.pair_targets - world[self.pairs, 0].mean(axis=1)
        sq = float(r @ r) + (0.0 if self.pair_w is None else float(self.pair_w @ pr**2))
        if not jacobian:
            return ScalarRows(None, None, None, None, sq, float(n), 3 * n)
        g = np.tile(np.eye(3), (n, 1))
        plain = ScalarRows(np.repeat(np.arange(n), 3), g, r, np.ones(3 * n), sq, float(n),
                           3 * n)
        if self.pair_w is None:
            return plain
        if not self.explicit:
            mix = np.zeros((len(self.pairs), 3 * n))
            np.put_along_axis(mix, 3 * self.pairs, 0.5, axis=1)  # the pair's x rows
            plain.mix, plain.mix_r, plain.mix_w = mix, pr, self.pair_w
            return plain
        gp = np.zeros((len(self.pairs), 2, 3))
        gp[:, :, 0] = 0.5
        return [plain, ScalarRows(self.pairs, gp, pr, self.pair_w, 0.0, 0.0, 0)]


def test_mixed_rows_are_the_rows_they_combine():
    # Rows given as combinations of a block's rows (ScalarRows.mix) build the system the
    # same rows on their own vertices do, and a negative weight takes as much out.
    model = synthetic_model()
    rng = np.random.default_rng(21)
    v = np.arange(0, model.n_vertices, 7)
    targets = model.instance(rng.standard_normal(model.n_coeffs))[v]
    pairs = np.stack([np.arange(0, len(v) - 1, 2), np.arange(1, len(v), 2)], axis=1)
    pair_targets = targets[pairs, 0].mean(axis=1) + 0.001 * rng.standard_normal(len(pairs))
    pair_w = rng.uniform(0.2, 0.6, len(pairs))
    start = dict(scale=1.01, coeffs=0.3 * rng.standard_normal(model.n_coeffs))

    def system(w, explicit=False):
        rows = _MixedRows(v, targets, pairs, pair_targets, w, explicit)
        fit = ShapeProblem(model, rows, lambda2=0.1).solve(max_iterations=0, **start)
        return fit.normal_matrix, fit.info["cost"]

    (n_mix, c_mix), (n_own, c_own) = system(pair_w), system(pair_w, explicit=True)
    (n_plain, _), (n_neg, _) = system(None), system(-pair_w)
    scale = np.abs(n_own).max()
    np.testing.assert_allclose(n_mix, n_own, rtol=0, atol=1e-12 * scale)
    assert c_mix == pytest.approx(c_own, rel=1e-14)
    assert np.abs(n_mix - n_plain).max() > 1e-3 * scale  # the pair rows count
    np.testing.assert_allclose(n_neg, 2 * n_plain - n_own, rtol=0, atol=1e-12 * scale)


def test_rows_on_two_vertices_each_are_solved_exactly():
    # Every row sees a point between two vertices only. With scale and rotation fixed the
    # residual is linear, so one step must land on the head exactly: it would not with
    # either vertex's part of a row left out of the system.
    model = synthetic_model()
    c = np.random.default_rng(13).standard_normal(model.n_coeffs)
    x = model.instance(c) + [0.01, 0.02, 0.03]
    v = np.arange(model.n_vertices)
    ends = np.stack([v, np.roll(v, 1)], axis=1)
    t = np.random.default_rng(4).uniform(0.1, 0.9, len(v))
    target = (1 - t[:, None]) * x[ends[:, 0]] + t[:, None] * x[ends[:, 1]]
    rows = _EdgePointRows(v, ends, t, target)
    fit = ShapeProblem(model, rows, freeze=("scale", "rotation")).solve(max_iterations=1)
    np.testing.assert_allclose(fit.coeffs, c, atol=1e-10)
    np.testing.assert_allclose(fit.translation, [0.01, 0.02, 0.03], atol=1e-12)
    # with similarity free, from afar, the full fit
    fit = shape_icp(model, rows, translation=x.mean(0), tolerance=1e-14)
    np.testing.assert_allclose(fit.world_vertices(model), x, atol=1e-10)


@pytest.mark.parametrize("prefix", [8, 5])
def test_modes_gathered_vertex_major_give_the_same_system(prefix):
    # Rows on a run of consecutive vertices gather their modes from the caller's
    # vertex-major copy of the first modes (all 8, or 5 and the rest from the basis): the
    # same normal matrix and step as gathering from the basis itself.
    model = synthetic_model()
    rng = np.random.default_rng(17)
    c = rng.standard_normal(model.n_coeffs)
    x = model.instance(c) + [0.01, 0.02, 0.03]
    v = np.arange(100, 400)
    local = np.arange(len(v))
    ends = np.stack([local, np.roll(local, 1)], axis=1)
    t = rng.uniform(0.1, 0.9, len(v))
    target = (1 - t[:, None]) * x[v[ends[:, 0]]] + t[:, None] * x[v[ends[:, 1]]]
    vm = np.ascontiguousarray(model.basis[:prefix].transpose(1, 2, 0))
    start = dict(scale=1.02, coeffs=0.2 * rng.standard_normal(model.n_coeffs))
    fits = [ShapeProblem(model, _EdgePointRows(v, ends, t, target), lambda2=0.1,
                         vertex_major=m).solve(max_iterations=1, **start)
            for m in (None, vm)]
    scale = np.abs(fits[0].normal_matrix).max()
    np.testing.assert_allclose(fits[1].normal_matrix, fits[0].normal_matrix, rtol=0,
                               atol=1e-12 * scale)
    np.testing.assert_allclose(fits[1].coeffs, fits[0].coeffs, rtol=0, atol=1e-10)
    with pytest.raises(ValueError, match="vertex_major"):
        ShapeProblem(model, _EdgePointRows(v, ends, t, target), vertex_major=vm[:10])
