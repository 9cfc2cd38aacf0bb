"""What a fit ends with (solver/fitting/outcome.py): the plausibility of the fitted head."""

import numpy as np
import pytest
from scipy.stats import chi2

from solver import fit_head, refit_landmarks
from solver.fitting.fit import PRIOR_RMS_SLACK
from solver.fitting.outcome import PLAUSIBLE_PERCENTILE, plausibility
from solver.synthetic import make_case


def test_plausibility_is_the_chi_square_percentile_of_the_norm():
    info, warnings = plausibility(np.zeros(100))
    assert info["mahalanobis"] == 0.0 and info["percentile"] == 0.0 and not warnings
    # a head whose squared norm is the median of chi-square(100) lies at the 50th percentile
    c = np.full(100, np.sqrt(chi2.median(100) / 100))
    info, warnings = plausibility(c)
    assert info["percentile"] == pytest.approx(50.0, abs=1e-6) and not warnings
    assert info["mahalanobis"] == pytest.approx(np.sqrt(chi2.median(100)))


def test_a_head_beyond_the_99th_percentile_is_warned():
    k = 100
    just_in = np.full(k, np.sqrt(chi2.ppf(0.985, k) / k))
    beyond = np.full(k, np.sqrt(chi2.ppf(0.995, k) / k))
    assert not plausibility(just_in)[1]
    info, warnings = plausibility(beyond)
    assert info["percentile"] > PLAUSIBLE_PERCENTILE
    assert len(warnings) == 1 and "implausible" in warnings[0] and "noise_px" in warnings[0]


def test_an_implausible_head_names_each_camera_whose_lens_was_estimated_freely():
    from solver import OrthographicCamera, PinholeCamera

    beyond = np.full(100, np.sqrt(chi2.ppf(0.995, 100) / 100))
    size = (768, 1024)
    cameras = {
        "free": PinholeCamera.look_at([0.5, -1.8, 0.0], [0, 0, 0], size, lens_mm=172.0),
        "exif": PinholeCamera.look_at([0.0, -1.0, 0.0], [0, 0, 0], size, lens_mm=50.0,
                                      focal_prior=(50.0, 0.05)),
        "known": PinholeCamera.look_at([0.0, -1.0, 0.0], [0, 0, 0], size, lens_mm=50.0,
                                       free_focal=False),
        "front": OrthographicCamera.nominal("orthographic-front", size),
    }
    _, warnings = plausibility(beyond, cameras)
    assert len(warnings) == 2 and warnings[1].startswith("view 'free': its lens is not known")
    assert "172 mm" in warnings[1] and "--lens" in warnings[1]
    assert plausibility(np.zeros(100), cameras)[1] == []  # a plausible head: nothing to say


def test_fits_report_plausibility_and_warn_of_implausible_heads(model):
    case, truth = make_case(model, 1003, noise_px=1.0)
    res = fit_head(model, case)
    p = res.info["plausibility"]
    assert p["n_coeffs"] == 100 and p["percentile"] < PLAUSIBLE_PERCENTILE
    assert not [w for w in res.info["warnings"] if "implausible" in w]
    assert refit_landmarks(model, case, res).info["plausibility"]["mahalanobis"] == \
        pytest.approx(p["mahalanobis"], rel=0.02)  # the same landmarks: about the same head
    # a head four times as far from the mean as the model's own heads
    odd, _ = make_case(model, 1003, noise_px=1.0, coeff_scale=4.0)
    res = fit_head(model, odd)
    assert res.info["plausibility"]["percentile"] > PLAUSIBLE_PERCENTILE
    assert [w for w in res.info["warnings"] if "implausible" in w]
    # its landmarks tell it from a head nearer the mean: a stronger prior fits them worse,
    # so the fit keeps the unusual head
    prior = res.info["prior"]
    assert prior["factor"] == 1.0
    assert prior["tried"][0]["rms_px"] > PRIOR_RMS_SLACK * prior["first"]["rms_px"]
