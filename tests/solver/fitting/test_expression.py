"""Expressions in the photos (solver/fitting/expression.py): each photo's expression
estimated from its landmarks and taken out of them, so it does not bend the identity."""

import dataclasses

import numpy as np
import pytest

from solver import FitOptions, fit_head, refit_landmarks
from solver.fitting import expression
from solver.fitting.expression import (
    AGREED,
    FAINT,
    FAR_ROUND_DEG,
    LIPS_APART,
    SHOWN,
    SURE,
    applied,
    estimate_expressions,
    expression_report,
    lips_apart,
    neutral_case,
    view_yaw_deg,
)
from solver.synthetic import (
    make_case,
    make_perspective_case,
    resample_polyline,
    skin_error_mm,
    trace_silhouette,
)


def _with_expression(model, case, truth, weights, noise_px=1.0, seed=0, outline=False):
    """``case`` photographed again with the face showing ``weights`` ({expression name:
    weight}): every landmark where the true head with that expression projects, plus the
    same kind of noise; with ``outline`` the profile's outline traced again from that head
    (``make_case``'s 100 points, the same noise)."""
    rng = np.random.default_rng(seed)
    local = truth.local_vertices + model.expression_offsets(weights)
    world = truth.scale * local @ truth.rotation.T + truth.translation
    views = {}
    for name, view in case.views.items():
        keys = list(view.points)
        verts = [model.landmark_vertex(k) for k in keys]
        px = truth.cameras[name].project(world[verts]) + noise_px * rng.normal(size=(len(keys), 2))
        contour = view.contour
        if outline and contour is not None:
            traced = resample_polyline(trace_silhouette(model, world, truth.cameras[name]), 100)
            contour = traced + noise_px * rng.normal(size=traced.shape)
        views[name] = dataclasses.replace(view, points={k: tuple(p) for k, p in
                                                        zip(keys, px, strict=True)},
                                          contour=contour)
    return dataclasses.replace(case, views=views)


@pytest.fixture(scope="module")
def closed(model):
    case, truth = make_case(model, 31, noise_px=1.0)
    shut = _with_expression(model, case, truth, {"eyeBlink_L": 1.0, "eyeBlink_R": 1.0})
    # the open eyes with the same placement noise: only the expression differs
    return _with_expression(model, case, truth, {}), shut, truth


def test_closed_eyes_keep_the_identity(model, closed):
    case, shut, truth = closed
    open_fit = fit_head(model, case)
    shut_fit = fit_head(model, shut)
    assume_neutral = fit_head(model, shut, FitOptions(expressions="neutral"))
    gap = skin_error_mm(model, shut_fit.local_vertices, open_fit.local_vertices)
    gap_neutral = skin_error_mm(model, assume_neutral.local_vertices, open_fit.local_vertices)
    # about the same identity whether the eyes were open or closed (0.17 mm here, the
    # issue asks < 0.5; assumed neutral 0.51): the closed eyelids do not bend it
    assert gap < 0.5 and gap < 0.85 * gap_neutral
    # each photo's expression is reported: both eyes closed (the right one in the profile)
    shown = shut_fit.info["expressions"]
    for view in ("front", "right"):
        assert shown[view].get("eyeBlink_R", 0.0) > 0.6, shown[view]
    assert shown["front"].get("eyeBlink_L", 0.0) > 0.6
    # with how surely: every reported weight has its standard deviation, and closed eyes
    # on these points stand several of them clear of neutral
    sd = shut_fit.info["expression_sd"]
    assert {v: set(e) for v, e in sd.items()} == {v: set(e) for v, e in shown.items()}
    assert all(0.0 < s < 1.0 for e in sd.values() for s in e.values())
    assert shown["front"]["eyeBlink_R"] > 3 * sd["front"]["eyeBlink_R"]
    assert "expressions" not in assume_neutral.info
    assert "expression_sd" not in assume_neutral.info
    # the drag refit keeps the expression taken out of the landmarks (a one-step preview
    # of the same head); without, the closed eyelids would pull as in the neutral fit
    again = refit_landmarks(model, shut, shut_fit)
    assert skin_error_mm(model, again.local_vertices, shut_fit.local_vertices) < 0.25


def test_neutral_case_moves_landmarks_back_by_the_expression(model, closed):
    case, shut, truth = closed
    fit = fit_head(model, case)
    e = np.zeros(len(model.expression_names))
    e[model.expression_names.index("eyeBlink_L")] = 1.0
    back = neutral_case(model, shut, fit, {"front": e})
    # only the front view moves, and mostly its left eyelid points
    assert back.views["right"].points == shut.views["right"].points
    moved = {k: np.linalg.norm(np.subtract(back.views["front"].points[k], p))
             for k, p in shut.views["front"].points.items()}
    assert max(moved, key=moved.get).endswith("_left") and "eye" in max(moved, key=moved.get)
    assert moved["nose_tip"] < 0.5
    # what is reported: names at or above FAINT (the estimate leaves no smaller one)
    e[model.expression_names.index("jawOpen")] = 0.5 * FAINT
    assert expression_report(model, {"front": e}) == {"front": {"eyeBlink_L": 1.0}}


@pytest.fixture(scope="module", params=[(34, 0.3), (35, 0.3), (34, 0.2), (36, 0.2)])
def jaw_open(model, request):
    seed, weight = request.param
    case, truth = make_case(model, seed, noise_px=1.0)
    opened = _with_expression(model, case, truth, {"jawOpen": weight}, outline=True)
    return _with_expression(model, case, truth, {}, outline=True), opened, truth, weight


def test_neutral_case_moves_the_outline_back_too(model, jaw_open):
    # The open jaw's chin lies below the neutral head's outline in the profile; taken out,
    # the outline's points lie on the neutral head's again.
    case, opened, truth, weight = jaw_open
    fit = fit_head(model, case)
    e = np.zeros(len(model.expression_names))
    e[model.expression_names.index("jawOpen")] = weight
    back = neutral_case(model, opened, fit, {"right": e})
    true = trace_silhouette(model, truth.world_vertices, truth.cameras["right"])

    def off(points):  # the outline's points' distances from the neutral head's outline
        return np.linalg.norm(points[:, None] - true[None], axis=2).min(axis=1)

    before, after = off(opened.views["right"].contour), off(back.views["right"].contour)
    moved = before > 3.0  # the chin and the lips (a few points trace the open mouth)
    assert moved.sum() >= 6 and np.median(before[moved]) > 25.0 * weight
    assert np.median(after[moved]) < 0.25 * np.median(before[moved]), after[moved]
    # the skull's outline (from the nose on) does not move with the jaw
    assert np.abs(back.views["right"].contour - opened.views["right"].contour)[40:].max() < 0.5
    assert back.views["front"].contour is None


def test_an_open_jaw_keeps_the_identity_with_the_profile_outline(model, jaw_open):
    case, opened, truth, weight = jaw_open
    neutral_fit = fit_head(model, case)
    open_fit = fit_head(model, opened)
    # found in both photos, a mouth a little open (0.2) too: the identity would take part
    # of it, and the estimate (0.19-0.22) is taken out below SHOWN as it is sure
    for view in ("front", "right"):
        assert open_fit.info["expressions"][view].get("jawOpen", 0.0) > 0.75 * weight
    gap = skin_error_mm(model, open_fit.local_vertices, neutral_fit.local_vertices)
    # 0.3 open: 0.29 and 0.33 mm; 0.59 and 0.74 with the open jaw left in the outline (the
    # chin stretched to it), 3.1 assumed neutral; 0.2 open: 0.24 and 0.33 mm, 2.03 and 1.72
    # where only weights from SHOWN up were taken out
    assert gap < 0.45, gap


MIDLINE = ("nasion", "nose_tip", "subnasale", "lip_upper_middle", "pogonion", "chin_bottom")


def test_a_photo_is_fitted_only_with_the_expressions_its_landmarks_show(model):
    # Raised brows: a profile with its brow points shows them; a profile read off its
    # outline (midline points only) cannot, and must not explain its points with them.
    case, truth = make_case(model, 32, noise_px=0.5)
    raised = _with_expression(model, case, truth, {"browInnerUp_L": 1.0, "browInnerUp_R": 1.0},
                              noise_px=0.5, seed=1)
    shown = fit_head(model, raised).info["expressions"]
    assert shown["right"].get("browInnerUp_R", 0.0) > 0.5, shown
    side = raised.views["right"]
    midline = dataclasses.replace(raised, views={
        **raised.views, "right": dataclasses.replace(
            side, points={k: p for k, p in side.points.items() if k in MIDLINE})})
    assert len(midline.views["right"].points) == len(MIDLINE)
    shown = fit_head(model, midline).info["expressions"]
    assert not any(n.startswith("brow") for n in shown["right"]), shown
    assert shown["front"].get("browInnerUp_R", 0.0) > 0.5, shown


def test_a_faint_expression_is_taken_where_every_photo_reads_it():
    # Two photos, two expressions (the second the open jaw): faint (0.15) and 3.75 of
    # their standard deviations clear of neutral.
    faint, sd = np.full((2, 2), 0.15), np.full((2, 2), 0.04)
    jaw = np.array([False, True])
    assert (applied(faint, sd, jaw, apart=True) == faint).all()
    # the open jaw only where a photo shows the lips apart (a raised chin reads as one)
    assert (applied(faint, sd, jaw, apart=False) == [[0.15, 0.0], [0.15, 0.0]]).all()
    # read in one photo only (the other's 0.05 is under FAINT): a trait, not an expression
    one = np.array([[0.15, 0.15], [0.05, 0.15]])
    assert (applied(one, sd, jaw, apart=True) == [[0.0, 0.15], [0.0, 0.15]]).all()
    # a single photo needs SURE deviations; from SHOWN up a weight is always kept
    assert (applied(faint[:1], sd[:1], jaw, apart=True) == 0.0).all()
    assert (applied(faint[:1], sd[:1] / 2, jaw, apart=True) == faint[:1]).all()
    assert (applied(np.full((1, 2), SHOWN), sd[:1] * 10, jaw, apart=False) == SHOWN).all()


def test_lips_apart_reads_the_inner_lips_gap_in_a_photo_that_shows_both(model):
    case, truth = make_case(model, 31, noise_px=0.0)
    lms = model.landmark_set
    assert not lips_apart(lms, case)  # the model's closed mouth
    front = case.views["front"].points
    eyes = 0.5 * (np.asarray(front["eye_inner_right"]) + np.asarray(front["eye_inner_left"]))
    height = np.linalg.norm(eyes - np.asarray(front["mouth_middle"]))

    def lowered(by):  # the lower lip's inner midline point moved down by ``by`` heights
        p = np.asarray(front["mouth_middle"]) + (0.0, by * height)
        return dataclasses.replace(case, views={**case.views, "front": dataclasses.replace(
            case.views["front"], points={**front, "lip_lower_inner_middle": tuple(p)})})

    assert lips_apart(lms, lowered(1.2 * LIPS_APART))
    assert not lips_apart(lms, lowered(0.8 * LIPS_APART))
    # a photo without the inner lips (a profile) tells nothing
    profile = dataclasses.replace(case, views={"right": case.views["right"]})
    assert "lip_lower_inner_middle" not in profile.views["right"].points
    assert not lips_apart(lms, profile)


def test_an_open_jaw_both_photos_read_is_taken_out_where_the_lips_are_apart(model, monkeypatch):
    # Open 0.12 behind 4-px points: the front reads it surely, the profile 3.6 of its
    # standard deviations clear of neutral, under SURE: taken as every photo reads it.
    case, truth = make_case(model, 36, noise_px=4.0)
    opened = _with_expression(model, case, truth, {"jawOpen": 0.12}, noise_px=4.0, outline=True)
    info = fit_head(model, opened).info
    shown, sd = info["expressions"], info["expression_sd"]
    assert shown["front"]["jawOpen"] > 0.1 and shown["right"]["jawOpen"] > 0.1, shown
    assert AGREED <= shown["right"]["jawOpen"] / sd["right"]["jawOpen"] < SURE, sd
    # where no photo shows the lips apart (read as closed) the profile's is left in
    monkeypatch.setattr(expression, "LIPS_APART", 1.0)
    shown = fit_head(model, opened).info["expressions"]
    assert shown["front"]["jawOpen"] > 0.1 and "jawOpen" not in shown["right"], shown


def test_a_three_quarter_view_far_round_is_fitted_without_an_expression(model):
    # three photos: near the front, 51 degrees to one side, 30 to the other
    case, truth = make_perspective_case(model, 0, n_views=3, yaw_deg=60)
    fit = fit_head(model, case)
    yaws = {name: view_yaw_deg(fit, camera) for name, camera in fit.cameras.items()}
    for name, yaw in yaws.items():
        assert yaw == pytest.approx(view_yaw_deg(truth, truth.cameras[name]), abs=1.0)
    far = {name for name, yaw in yaws.items() if FAR_ROUND_DEG[0] < abs(yaw) < FAR_ROUND_DEG[1]}
    assert far == {"photo1"}
    weights, sd = estimate_expressions(model, case, fit, {name: 1.0 for name in case.views})
    assert set(weights) == set(sd) == set(case.views) - far
