"""Checks after a fit (solver/fitting/checks.py): a single photo is warned, and so are
photos whose left and right are exchanged; a correct case gives no such warning."""

import dataclasses
import types

import numpy as np
import pytest

from solver import FitOptions, fit_head
from solver.cameras import ORTHO_VIEWS, OrthographicCamera
from solver.fitting.checks import implied_frame, mirrored_case, swap_name
from solver.synthetic import make_case, make_perspective_case


def side_warnings(result):
    return [w for w in result.info["warnings"] if "left and right look exchanged" in w]


def single_warnings(result):
    return [w for w in result.info["warnings"] if "is the only photo" in w]


def all_names_swapped(case):
    views = {n: dataclasses.replace(v, points={swap_name(k): p for k, p in v.points.items()})
             for n, v in case.views.items()}
    return dataclasses.replace(case, views=views)


def test_swap_name_exchanges_the_sides_only():
    assert swap_name("eye_outer_left") == "eye_outer_right"
    assert swap_name("jaw_1_right") == "jaw_1_left"
    assert swap_name("nose_tip") == "nose_tip"


def test_the_implied_frame_tells_a_mirrored_photo():
    rng = np.random.default_rng(0)
    pts = rng.normal(scale=0.05, size=(20, 3))
    front = ORTHO_VIEWS["orthographic-front"]
    frame = implied_frame(pts, 3000.0 * pts @ front[:2].T)
    assert frame == pytest.approx(front, abs=1e-9)
    mirrored = 3000.0 * pts @ front[:2].T * [-1.0, 1.0]
    assert implied_frame(pts, mirrored)[2] == pytest.approx([0.0, -1.0, 0.0], abs=1e-9)
    assert implied_frame(pts[:3], mirrored[:3]) is None  # too few to tell


@pytest.mark.parametrize("views, says", [(("front",), "depth"), (("right",), "width")])
def test_a_fit_from_one_photo_says_what_comes_from_the_prior(model, views, says):
    case, _ = make_case(model, 7, noise_px=1.0, views=views)
    res = fit_head(model, case, FitOptions(noise="fixed"))
    (warning,) = single_warnings(res)
    assert f"view {views[0]!r}" in warning and says in warning and "add a" in warning
    assert not side_warnings(res)


def test_all_left_and_right_names_swapped_are_detected(model):
    case, _ = make_case(model, 2, noise_px=1.0)
    res = fit_head(model, all_names_swapped(case))
    (warning,) = side_warnings(res)
    assert warning.startswith("view 'front':") and "'right'" in warning
    assert not single_warnings(res)


def test_a_left_profile_labelled_right_is_detected(model):
    case, _ = make_case(model, 4, noise_px=1.0, views=("front", "left"))
    left = case.views["left"]
    # the user took it for a right profile and named its landmarks so
    wrong = mirrored_case(case, ["left"]).views["left"]
    assert wrong.camera.view == "orthographic-right" and "ear_top_right" in wrong.points
    wrong = dataclasses.replace(wrong, name="side")
    res = fit_head(model, dataclasses.replace(case, views={"front": case.views["front"],
                                                           "side": wrong}))
    (warning,) = side_warnings(res)
    assert warning.startswith("view 'side':") and "a left profile" in warning
    assert left.camera.view == "orthographic-left"  # the original is untouched


def test_a_single_front_photo_with_its_sides_swapped_is_detected(model):
    # the fit as labelled reproduces it as well as the truth, by a head turned away
    case, _ = make_case(model, 3, noise_px=1.0, views=("front",))
    res = fit_head(model, all_names_swapped(case), FitOptions(noise="fixed"))
    (warning,) = side_warnings(res)
    assert "behind the head" in warning and "names of view 'front' exchanged" in warning


def test_perspective_photos_with_their_sides_swapped_are_detected(model):
    case, _ = make_perspective_case(model, 3, n_views=3, noise_px=1.0)
    res = fit_head(model, all_names_swapped(case), FitOptions(noise="fixed"))
    assert {w.split(":")[0] for w in side_warnings(res)} == \
        {f"view {n!r}" for n in case.views}


@pytest.mark.parametrize("seed", range(5))
def test_no_false_alarm_on_correct_cases(model, seed):
    case, _ = make_case(model, 100 + seed, noise_px=1.0)
    res = fit_head(model, case)
    assert not side_warnings(res) and not single_warnings(res), res.info["warnings"]


def test_no_false_alarm_on_a_perspective_case(model):
    case, _ = make_perspective_case(model, 3, n_views=2, noise_px=1.0)
    res = fit_head(model, case)
    assert not side_warnings(res) and not single_warnings(res), res.info["warnings"]


def test_the_mirrored_case_turns_a_right_profile_left():
    from solver.io.case import LandmarkCase, View

    size = (600, 800)
    front = View("front", None, size, OrthographicCamera.nominal("orthographic-front", size),
                 {"nose_tip": (300, 400)})
    side = View("side", None, size, OrthographicCamera.nominal("orthographic-right", size),
                {"ear_top_right": (100, 300), "nose_tip": (500, 400)})
    case = LandmarkCase({"front": front, "side": side}, "<test>")
    out = mirrored_case(case, ["side"])
    assert out.views["side"].camera.view == "orthographic-left"
    assert set(out.views["side"].points) == {"ear_top_left", "nose_tip"}
    assert out.views["front"] is front and case.views["side"] is side


def left_profile_labelled_right(model, seed):
    case, _ = make_case(model, seed, noise_px=1.0, views=("front", "left"), contour=False)
    return dataclasses.replace(case, views={"front": case.views["front"],
                                            "side": mirrored_case(case, ["left"]).views["left"]})


@pytest.mark.parametrize("labelled_px, mirrored_px, warned", [
    (10.0, 4.9, True), (10.0, 5.1, False), (1.2, 40.0, False)])
def test_a_disagreeing_view_is_warned_when_mirrored_it_fits_twice_as_well(
        model, labelled_px, mirrored_px, warned):
    from solver.fitting.checks import mirror_warnings
    from solver.fitting.options import check_options
    from solver.fitting.result import ViewResidual

    case = left_profile_labelled_right(model, 4)
    head = types.SimpleNamespace(local_vertices=model.vertices)

    def quick_fit(c, opts):
        assert opts.noise == "fixed" and opts.progress is None
        px = mirrored_px if c.views["side"].camera.view == "orthographic-left" else labelled_px
        return types.SimpleNamespace(residuals={"side": ViewResidual(["a", "b"],
                                                                     np.full(2, px))})

    out = mirror_warnings(model, case, head, check_options(None, model), quick_fit)
    assert bool(out) == warned
    if warned:
        assert out[0].startswith("view 'side':") and f"{mirrored_px:.1f} px RMS" in out[0]


def test_a_mirrored_case_that_cannot_be_fitted_is_no_evidence(model):
    from solver.fitting.checks import mirror_warnings
    from solver.fitting.options import check_options

    def quick_fit(c, opts):
        raise ValueError("view 'side': too few landmarks")

    head = types.SimpleNamespace(local_vertices=model.vertices)
    assert mirror_warnings(model, left_profile_labelled_right(model, 4), head,
                           check_options(None, model), quick_fit) == []
