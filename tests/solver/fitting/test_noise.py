"""The placement noise estimated from the fit (solver/fitting/noise.py): the estimate, the
Student-t weights, and what they do to a fit."""

import copy

import numpy as np
import pytest
from scipy.spatial import cKDTree

from solver import FitOptions, fit_head, refit_landmarks
from solver.fitting import fit
from solver.fitting.noise import BODY_MIN_ROWS, Noise, consistency, estimate_noise
from solver.fitting.outline import body_vertices
from solver.fitting.result import ViewResidual
from solver.synthetic import make_case, skin_error_mm


def test_estimate_recovers_a_known_sigma_and_drops_an_outlier():
    rng = np.random.default_rng(0)
    names = [f"p{i}" for i in range(200)]
    r = np.linalg.norm(rng.normal(scale=4.0, size=(200, 2)), axis=1)
    r[7] = 100.0  # one landmark placed 100 px off
    c = np.abs(rng.normal(scale=2.0, size=150))
    noise = estimate_noise({"front": ViewResidual(names, r)}, {"front": (c, np.zeros(150, bool))},
                           effective=0.0,
                           floor_px=1.0)
    assert noise.landmark_px["front"] == pytest.approx(4.0, rel=0.1)
    assert noise.contour_px["front"] == pytest.approx(2.0, rel=0.15)
    w = noise.weights["front"]
    assert w["p7"] < 0.01 and np.median(list(w.values())) == pytest.approx(1.0, abs=0.2)
    assert list(noise.report()["down_weighted"]["front"]) == ["p7"]
    assert noise.report()["weights"]["front"] == w  # every landmark's final weight
    # the floor holds: well-placed landmarks are not trusted beyond noise_px
    tiny = estimate_noise({"front": ViewResidual(names, r * 0.01)}, {}, 0.0, floor_px=1.0)
    assert tiny.landmark_px["front"] == pytest.approx(1.0)


def test_consistency_turns_the_t_scale_into_the_gaussian_sigma():
    rng = np.random.default_rng(1)
    sq = (rng.normal(size=(400000, 2)) ** 2).sum(axis=1)
    s2 = 1.0
    for _ in range(60):
        s2 = (7.0 * sq / (5.0 + sq / s2)).mean() / 2.0
    assert consistency(2) == pytest.approx(s2, rel=5e-3)


@pytest.mark.parametrize("sigma", [2.0, 4.0])
def test_a_known_noise_is_recovered_within_20_percent(model, sigma):
    case, _ = make_case(model, 2, noise_px=sigma, contour_noise_px=sigma)
    res = fit_head(model, case)
    for view, est in res.info["noise"]["landmark_px"].items():
        assert est == pytest.approx(sigma, rel=0.2), view
    assert res.info["noise"]["fits"] >= 2


def test_one_landmark_100_px_off_moves_the_head_less_than_0_3_mm(model):
    case, _ = make_case(model, 3, noise_px=1.0)
    bad = copy.deepcopy(case)
    u, v = bad.views["front"].points["nose_tip"]
    bad.views["front"].points["nose_tip"] = (u + 100.0, v)
    good, worse = fit_head(model, case), fit_head(model, bad)
    # issue 15 asks < 0.3 mm: 0.26 (0.32 before the outline landmarks had their own noise;
    # docs/DECISIONS.md)
    assert skin_error_mm(model, worse.local_vertices, good.local_vertices) < 0.3
    assert "nose_tip" in worse.info["noise"]["down_weighted"]["front"]
    # with the noise fixed the same landmark drags the head (what the estimate prevents)
    fixed = FitOptions(noise="fixed")
    assert skin_error_mm(model, fit_head(model, bad, fixed).local_vertices,
                         fit_head(model, case, fixed).local_vertices) > 1.0


def test_noisier_landmarks_keep_the_head_nearer_the_mean(model):
    case, _ = make_case(model, 4, noise_px=6.0)
    est = fit_head(model, case)
    fixed = fit_head(model, case, FitOptions(noise="fixed"))
    assert np.linalg.norm(est.identity_coeffs) < 0.8 * np.linalg.norm(fixed.identity_coeffs)


def test_the_refit_keeps_the_estimated_weights(model):
    case, _ = make_case(model, 3, noise_px=1.0)
    bad = copy.deepcopy(case)
    u, v = bad.views["front"].points["nose_tip"]
    bad.views["front"].points["nose_tip"] = (u + 100.0, v)
    res = fit_head(model, bad)
    again = refit_landmarks(model, bad, res)
    assert skin_error_mm(model, again.local_vertices, res.local_vertices) < 0.2


def test_bad_noise_option_is_named(model):
    case, _ = make_case(model, 3, noise_px=1.0)
    with pytest.raises(ValueError, match="options.noise"):
        fit_head(model, case, FitOptions(noise="guess"))


def test_a_group_without_an_estimate_keeps_the_floors_weight():
    noise = Noise(landmark_px={"front": 4.0}, floor_px=1.0)
    # a view the estimate had no landmarks for: placed with the floor, weight 1
    assert noise.landmark_factor("side", "nose_tip") == pytest.approx(1.0)
    assert noise.contour_factor("side") == pytest.approx(1.0)
    # an estimated view: the Student-t precision of its sigma
    assert noise.landmark_factor("front", "nose_tip") == pytest.approx(
        1.0 / (16.0 * consistency(2)))


def test_sliding_landmarks_are_a_group_of_their_own_and_unused_ones_do_not_count():
    rng = np.random.default_rng(2)
    inner = [f"p{i}" for i in range(60)]
    jaw = [f"j{i}" for i in range(17)]
    r = np.concatenate([np.linalg.norm(rng.normal(scale=2.0, size=(60, 2)), axis=1),
                        np.abs(rng.normal(scale=6.0, size=17)), [500.0]])
    res = ViewResidual(inner + jaw + ["far"], r, outline=jaw, unused=["far"])
    along = {"front": (jaw, rng.normal(scale=10.0, size=17))}
    noise = estimate_noise({"front": res}, {}, 0.0, 1.0, along)
    assert noise.landmark_px["front"] == pytest.approx(2.0, rel=0.2)
    assert noise.outline_px["front"] == pytest.approx(6.0, rel=0.35)
    assert noise.along_px["front"] == pytest.approx(10.0, rel=0.35)
    assert "far" not in noise.weights["front"]
    # a sliding landmark weighs by its own group's noise, across and along
    assert noise.landmark_factor("front", "j3") == pytest.approx(
        noise.weights["front"]["j3"] / (noise.outline_px["front"] ** 2 * consistency(1)))
    assert noise.along_factor("front", "j3") == pytest.approx(
        1.0 / (noise.along_px["front"] ** 2 * consistency(1)))
    assert noise.along_factor("front", "p3") == noise.landmark_factor("front", "p3")


def test_a_landmark_given_as_more_uncertain_counts_at_its_own_scale():
    rng = np.random.default_rng(4)
    names = [f"p{i}" for i in range(80)]
    # the last 20 were given 4 times as uncertain (relative weight 1/16), and are
    r = np.linalg.norm(rng.normal(scale=2.0, size=(80, 2)), axis=1)
    r[60:] *= 4.0
    relative = {"front": {n: (1.0 / 16.0 if i >= 60 else 1.0) for i, n in enumerate(names)}}
    noise = estimate_noise({"front": ViewResidual(names, r)}, {}, 0.0, 1.0,
                           relative=relative)
    assert noise.landmark_px["front"] == pytest.approx(2.0, rel=0.2)
    # as typical against their own uncertainty as the others: not outliers
    w = noise.weights["front"]
    assert np.median([w[n] for n in names[60:]]) == pytest.approx(1.0, abs=0.25)
    # read at face value, they inflate the view's noise and look like outliers
    plain = estimate_noise({"front": ViewResidual(names, r)}, {}, 0.0, 1.0)
    assert plain.landmark_px["front"] > 1.3 * noise.landmark_px["front"]


def test_outline_landmarks_on_their_vertices_are_a_group_of_their_own():
    rng = np.random.default_rng(3)
    inner = [f"p{i}" for i in range(60)]
    jaw = [f"j{i}" for i in range(17)]
    r = np.concatenate([np.linalg.norm(rng.normal(scale=2.0, size=(60, 2)), axis=1),
                        np.linalg.norm(rng.normal(scale=8.0, size=(17, 2)), axis=1)])
    res = ViewResidual(inner + jaw, r)
    noise = estimate_noise({"front": res}, {}, 0.0, 1.0, rim={"front": set(jaw)})
    # the jaw's 8 px do not make the eyes and the nose look 4 px off
    assert noise.landmark_px["front"] == pytest.approx(2.0, rel=0.2)
    assert noise.rim_px["front"] == pytest.approx(8.0, rel=0.35)
    assert noise.landmark_factor("front", "j3") == pytest.approx(
        noise.weights["front"]["j3"] / (noise.rim_px["front"] ** 2 * consistency(2)))
    assert noise.landmark_factor("front", "p3") == pytest.approx(
        noise.weights["front"]["p3"] / (noise.landmark_px["front"] ** 2 * consistency(2)))
    assert noise.report()["rim_px"] == {"front": noise.rim_px["front"]}
    # fewer than three: with the inner landmarks (no estimate of their own)
    few = estimate_noise({"front": ViewResidual(inner + jaw[:2], r[:62])}, {}, 0.0, 1.0,
                         rim={"front": set(jaw)})
    assert few.rim_px == {} and few.rim_names == {}
    assert "j1" in few.weights["front"]


def test_the_outline_below_the_neck_has_a_noise_of_its_own():
    rng = np.random.default_rng(3)
    head = np.abs(rng.normal(scale=0.3, size=600))    # the head's outline: well fitted
    body = np.abs(rng.normal(scale=1.2, size=80))     # the body's: four times as far off
    flags = np.r_[np.zeros(600, bool), np.ones(80, bool)]
    noise = estimate_noise({}, {"front": (np.r_[head, body], flags)}, 0.0, floor_px=1.0)
    assert noise.contour_px["front"] == pytest.approx(1.0)  # the head's, at the floor
    assert noise.body_px["front"] == pytest.approx(4.0, rel=0.2)
    assert noise.body_factor("front") == pytest.approx(1 / 16, rel=0.4)
    assert noise.report()["body_px"] == noise.body_px
    # as well fitted as the head, or too few rows for an estimate: weighed as the outline
    same = estimate_noise({}, {"front": (np.abs(rng.normal(scale=0.3, size=680)), flags)},
                          0.0, floor_px=1.0)
    assert same.body_factor("front") == pytest.approx(1.0, abs=0.3)
    few = flags & (np.arange(680) < 600 + BODY_MIN_ROWS - 1)
    alone = estimate_noise({}, {"front": (np.r_[head, body], few)}, 0.0, floor_px=1.0)
    assert "front" not in alone.body_px and alone.body_factor("front") == 1.0


def _outline_off_the_body(model, seed, push_px=6.0):
    """A case with a dense traced profile (as a detector's) whose part below the neck's
    base lies ``push_px`` out (clothes the colour of skin): (case, truth, the case with
    the clean outline)."""
    case, truth = make_case(model, seed, noise_px=1.0, contour_points=600,
                            contour_noise_px=0.3)
    clean = copy.deepcopy(case)
    c = np.asarray(case.views["right"].contour, float)
    skin = np.asarray(model.skin)
    seen = truth.cameras["right"].project(truth.world_vertices[skin])
    on_body = body_vertices(model)[skin[cKDTree(seen).query(c)[1]]]
    assert 60 <= on_body.sum() <= 120
    t = np.gradient(c, axis=0)
    out = np.stack([t[:, 1], -t[:, 0]], axis=1) / np.linalg.norm(t, axis=1)[:, None]
    out *= np.sign(np.einsum("ij,ij->", out, c - c.mean(axis=0)))
    case.views["right"].contour = np.where(on_body[:, None], c + push_px * out, c)
    return case, truth, clean


def test_an_outline_off_the_body_below_the_neck_loses_its_weight(model):
    # that part gets a noise of its own and the head stays near the one fitted to the
    # clean outline (1.0 mm without the body's noise)
    case, truth, clean_case = _outline_off_the_body(model, 1)
    clean = fit_head(model, clean_case)
    res = fit_head(model, case)
    noise = res.info["noise"]
    assert noise["body_px"]["right"] > 2.5 * noise["contour_px"]["right"]
    fitted = clean.info["noise"]
    assert fitted["body_px"]["right"] < 1.5 * fitted["contour_px"]["right"]
    error = skin_error_mm(model, res.local_vertices, truth.local_vertices)
    assert error < skin_error_mm(model, clean.local_vertices, truth.local_vertices) + 0.45
    assert error < 0.95


def test_a_first_fit_bent_to_the_body_is_no_start(model, monkeypatch):
    # where the first round's outline below the neck departs from the rest by more than
    # BODY_RESTART times its noise, the next round starts from the mean head: here at 1.2
    # (this case's first round reads 1.5-2) it lands nearer the truth than going on from
    # the bent head; a clean outline never starts again
    case, truth, clean_case = _outline_off_the_body(model, 2)
    monkeypatch.setattr(fit, "BODY_RESTART", 1.2)
    res = fit_head(model, case)
    assert res.info["noise"]["restarted"]
    assert not fit_head(model, clean_case).info["noise"]["restarted"]
    monkeypatch.setattr(fit, "BODY_RESTART", np.inf)
    going_on = fit_head(model, case)
    assert not going_on.info["noise"]["restarted"]
    assert skin_error_mm(model, res.local_vertices, truth.local_vertices) \
        < skin_error_mm(model, going_on.local_vertices, truth.local_vertices) - 0.05
