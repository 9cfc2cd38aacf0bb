"""3-D to 3-D registration (solver/register.py) with the real head model.

Targets are model instances (known similarity and coefficients) plus 0.5 mm Gaussian noise,
so the truth is known; stated tolerances: rotation < 0.5 degrees, scale within 1 %, RMS
vertex error < 1 mm (typical results are 0.05 degrees, 0.1 % and 0.1 mm).
"""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from solver.fitting.register import (
    estimate_normals,
    initial_similarity,
    register,
    smallest_eigenvectors,
)
from solver.geometry import rotation_from_vector


def _case(lin, coeff_scale, seed, keep=1.0, noise=0.0005):
    """World truth and a noisy, optionally subsampled point cloud of a model instance."""
    rng = np.random.default_rng(seed)
    c = coeff_scale * rng.standard_normal(lin.n_coeffs)
    axis = rng.standard_normal(3)
    rot = rotation_from_vector(np.radians(10.0) * axis / np.linalg.norm(axis))
    scale = 1.0 + rng.choice([-1, 1]) * rng.uniform(0.05, 0.1)
    trans = rng.uniform(-0.2, 0.2, 3)
    local = lin.instance(c)
    truth = scale * local @ rot.T + trans
    pick = rng.uniform(size=len(truth)) < keep
    cloud = truth[pick] + noise * rng.standard_normal((pick.sum(), 3))
    return dict(c=c, rot=rot, scale=scale, trans=trans, local=local, truth=truth,
                cloud=cloud, rng=rng)


def _rot_err_deg(a, b):
    return np.degrees(np.arccos(np.clip((np.trace(a.T @ b) - 1) / 2, -1, 1)))


def _rms_mm(a, b):
    return 1e3 * np.sqrt(((a - b) ** 2).sum(1).mean())


@pytest.fixture(scope="module")
def global_skin(model):
    return model.identity.take(model.skin)


@pytest.fixture(scope="module")
def regional_skin(model):
    return model.regional(10).take(model.skin)


def test_register_global_model(global_skin):
    case = _case(global_skin, 1.0, seed=0, keep=0.85)
    fit = register(global_skin, case["cloud"])
    assert _rot_err_deg(fit.rotation, case["rot"]) < 0.5
    assert fit.scale / case["scale"] == pytest.approx(1.0, abs=0.01)
    assert _rms_mm(fit.world_vertices(global_skin), case["truth"]) < 1.0
    # Nearest-point distance: noise plus the gaps of the 85 % subsample (spacing ~2.5 mm).
    assert fit.info["rms_distance"] < 2e-3
    assert fit.info["similarity_stage"]["iterations"] > 0 and fit.iterations >= 1
    assert fit.coeff_covariance.shape == (100, 100)


def test_register_regional_model(regional_skin):
    # Independent regions at 1 sd make implausible heads (folds under the chin); 0.6 sd.
    case = _case(regional_skin, 0.6, seed=1)
    fit = register(regional_skin, case["cloud"])
    assert _rot_err_deg(fit.rotation, case["rot"]) < 0.5
    assert fit.scale / case["scale"] == pytest.approx(1.0, abs=0.01)
    assert _rms_mm(fit.world_vertices(regional_skin), case["truth"]) < 1.0
    assert fit.converged
    # The smoothness rows Gamma pull the regions together where they overlap.
    tied = register(regional_skin, case["cloud"], lambda1=1.0)
    g = regional_skin.gamma
    assert np.linalg.norm(g @ tied.coeffs) < 0.7 * np.linalg.norm(g @ fit.coeffs)
    assert _rms_mm(tied.world_vertices(regional_skin), case["truth"]) < 2.0


def test_register_partial_cloud_with_outliers(regional_skin):
    # Only the front of the head is scanned (80 % of its points), plus 3 % stray points in
    # the bounding box: the edge and the strays must not drag the fit.
    case = _case(regional_skin, 0.6, seed=2)
    rng = case["rng"]
    covered = case["local"][:, 1] < 0.02  # the face looks toward -Y
    pick = covered & (rng.uniform(size=len(covered)) < 0.8)
    pts = case["truth"][pick] + 0.0005 * rng.standard_normal((pick.sum(), 3))
    lo, hi = case["truth"].min(0), case["truth"].max(0)
    cloud = np.vstack([pts, rng.uniform(lo, hi, (len(pts) * 3 // 100, 3))])
    fit = register(regional_skin, cloud)
    world = fit.world_vertices(regional_skin)
    assert _rms_mm(world[covered], case["truth"][covered]) < 1.0
    assert _rot_err_deg(fit.rotation, case["rot"]) < 0.5
    assert fit.info["inlier_fraction"] < 0.95  # uncovered vertices were rejected


def test_register_similarity_only_and_options(global_skin):
    # A similarity of the mean shape: the similarity stage alone recovers it, with the
    # point-to-plane and the thesis' point-to-point costs, and a reused tree.
    rot = rotation_from_vector(np.radians([4.0, -6.0, 5.0]))
    cloud = 1.07 * global_skin.mean @ rot.T + [0.01, 0.02, -0.03]
    tree = cKDTree(cloud)
    for kw in (dict(), dict(point_to_plane=False, boundary_ratio=None)):
        fit = register(global_skin, cloud, shape_iterations=0, tree=tree,
                       similarity_vertices=len(cloud), similarity_tolerance=1e-9,
                       similarity_iterations=60, **kw)
        assert _rot_err_deg(fit.rotation, rot) < 0.01
        assert fit.scale == pytest.approx(1.07, abs=1e-4)
        assert fit.coeff_covariance is None
        np.testing.assert_array_equal(fit.coeffs, 0.0)
    # Symmetric correspondences reach the same answer (from a near start, with shape).
    fit = register(global_skin, cloud, scale=1.07, rotation=rot, translation=[0.01, 0.02, -0.03],
                   symmetric=True, similarity_iterations=0, anneal=(), coarse_iterations=0,
                   shape_iterations=3)
    assert _rms_mm(fit.world_vertices(global_skin), cloud) < 0.05


def test_initial_similarity():
    rng = np.random.default_rng(3)
    pts = rng.standard_normal((500, 3)) * [0.08, 0.1, 0.12]
    s, r, t = initial_similarity(pts, 1.3 * pts + [1.0, 2.0, 3.0])
    assert s == pytest.approx(1.3)
    np.testing.assert_array_equal(r, np.eye(3))
    np.testing.assert_allclose(s * pts + t, 1.3 * pts + [1.0, 2.0, 3.0], atol=1e-12)
    with pytest.raises(ValueError, match="coincide"):
        initial_similarity(pts, np.ones((10, 3)))


def test_smallest_eigenvectors_match_eigh():
    rng = np.random.default_rng(4)
    a = rng.standard_normal((5000, 6, 3)) * [1.0, 0.5, 0.02]
    a = a @ np.linalg.qr(rng.standard_normal((3, 3)))[0].T
    cov = a.transpose(0, 2, 1) @ a
    v = smallest_eigenvectors(cov)
    ref = np.linalg.eigh(cov)[1][:, :, 0]
    np.testing.assert_allclose(np.abs((v * ref).sum(1)), 1.0, atol=1e-9)
    # Degenerate matrices fall back to eigh and still give unit vectors.
    deg = np.stack([np.eye(3), np.diag([1.0, 1e-12, 1e-12]), np.zeros((3, 3))])
    out = smallest_eigenvectors(deg)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0)
    assert abs(out[1, 0]) < 1e-9  # perpendicular to the line's direction


def test_estimate_normals_and_boundary():
    # Points on a sphere: normals are radial. A half plane: its edge scores high.
    rng = np.random.default_rng(5)
    u = rng.standard_normal((4000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    n = estimate_normals(0.1 * u)
    assert np.abs((n * u).sum(1)).min() > 0.98
    # Uniformly scattered points on a square: points at its edge have all their
    # neighbours on one side and score high, points inside score low.
    xy = rng.uniform(0.0, 0.08, (6000, 2))
    plane = np.c_[xy, 1e-5 * rng.standard_normal(len(xy))]
    n, score = estimate_normals(plane, with_boundary=True)
    assert np.abs(n[:, 2]).min() > 0.95
    spacing = 0.08 / np.sqrt(len(xy))
    to_edge = np.minimum(xy, 0.08 - xy).min(axis=1)
    edge, inside = to_edge < 0.5 * spacing, to_edge > 4 * spacing
    assert (score[edge] > 0.5).mean() > 0.65
    assert (score[inside] > 0.5).mean() < 0.04


def test_register_bad_input(global_skin):
    cloud = global_skin.mean.copy()
    bad = cloud.copy()
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match="cloud: row 3 is not finite"):
        register(global_skin, bad)
    with pytest.raises(ValueError, match="cloud: needs at least 4 points"):
        register(global_skin, cloud[:3])
    with pytest.raises(ValueError, match=r"cloud: expected an array of shape \(n, 3\)"):
        register(global_skin, cloud[:, :2])
    with pytest.raises(ValueError, match="tree: built on 10 points"):
        register(global_skin, cloud, tree=cKDTree(cloud[:10]))
    with pytest.raises(ValueError, match="weights: expected 11248"):
        register(global_skin, cloud, weights=np.ones(5))
    with pytest.raises(ValueError, match="coeffs: expected 100"):
        register(global_skin, cloud, coeffs=np.zeros(3))
    with pytest.raises(ValueError, match="rotation: not a proper rotation"):
        register(global_skin, cloud, rotation=-np.eye(3))
    # Cloud far away from the given start: every correspondence rejected.
    with pytest.raises(ValueError, match="too few observations.*cloud: 0"):
        register(global_skin, cloud + 10.0, scale=1.0, max_distance=0.05)
