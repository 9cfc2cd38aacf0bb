"""Error detection from passpoint residuals (seed 000 §5-6)."""

import numpy as np
import pytest

from solver.cameras.calib_errors import check_passpoints, error_norms
from tests.solver.cameras.support import dlt_camera

NAMES = [f"marker_{i:02d}" for i in range(20)]


def scene(rng, noise):
    cams = {name: dlt_camera(c) for name, c in (("front", [0.0, -1.2, 0.1]),
                                                ("side", [0.9, -0.8, 0.2]))}
    x = rng.uniform(-0.2, 0.2, (20, 3))
    px = {v: c.project(x) + rng.normal(0, noise, (20, 2)) for v, c in cams.items()}
    return x, px


def test_error_norms_follow_the_seed():
    n = error_norms([3.0, 4.0, np.nan, 0.0])
    assert n.count == 3
    assert n.res1 == pytest.approx(7.0 / 3)
    assert n.res2 == pytest.approx(np.sqrt(25.0 / 3))
    assert n.resm == 4.0
    # residual vectors are reduced to their lengths
    assert error_norms(np.array([[3.0, 4.0], [0.0, 0.0]])).resm == 5.0
    assert error_norms([1.0] * 10 + [20.0]).data_error_suspected()
    assert not error_norms([1.0, 1.2, 0.8]).data_error_suspected()


@pytest.mark.parametrize("noise", [0.0, 0.5])
def test_a_misplaced_passpoint_is_named(noise):
    rng = np.random.default_rng(1)
    x, px = scene(rng, noise)
    px["side"][7] += [12.0, -16.0]  # 20 px off
    px["front"][3] = np.nan  # not seen in the front photo
    chk = check_passpoints(x, px, NAMES)
    assert [(s.view, s.name) for s in chk.suspects] == [("side", "marker_07")]
    s = chk.suspects[0]
    assert s.predicted == pytest.approx(20.0, abs=3 * noise + 1e-6)
    assert s.residual < s.predicted  # the fit with the point bends toward it
    assert "marker_07" in chk.messages[0] and "'side'" in chk.messages[0]
    # seed 000 §6: resm well above res1 before, not after leaving the point out
    assert chk.norms.data_error_suspected()
    assert not chk.cleaned_norms.data_error_suspected()
    assert chk.cleaned_norms.resm < 4 * max(noise, 0.01)
    assert np.isnan(chk.residuals["front"][3])


def test_two_bad_points_and_clean_data():
    rng = np.random.default_rng(2)
    x, px = scene(rng, 0.3)
    clean = check_passpoints(x, {v: p.copy() for v, p in px.items()}, NAMES)
    assert clean.suspects == [] and clean.notes == []
    px["front"][2] += [0.0, 25.0]
    px["front"][11] += [-18.0, 0.0]
    chk = check_passpoints(x, px, NAMES)
    assert sorted(s.name for s in chk.suspects) == ["marker_02", "marker_11"]
    assert all(s.view == "front" for s in chk.suspects)


def test_small_views_are_noted_not_judged():
    rng = np.random.default_rng(3)
    x, px = scene(rng, 0.3)
    few = {"front": px["front"][:8]}
    chk = check_passpoints(x[:8], few, NAMES[:8])
    assert chk.suspects == []
    assert "too few" in chk.notes[0] and "need 9" in chk.notes[0]


def test_bad_views_name_the_view():
    rng = np.random.default_rng(4)
    x, px = scene(rng, 0.0)
    px["side"][5:] = np.nan
    with pytest.raises(ValueError, match="view 'side'.*at least 6"):
        check_passpoints(x, px, NAMES)
    with pytest.raises(ValueError, match="expected shape"):
        check_passpoints(x, {"front": px["front"][:3]}, NAMES)
