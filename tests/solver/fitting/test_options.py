"""The fit's options (solver/fitting/options.py): every numeric option is range-checked and
the message gives the range."""

import re
from types import SimpleNamespace

import pytest

from solver.fitting.options import INT_RANGES, RANGES, FitOptions, check_options

MODEL = SimpleNamespace(identity=SimpleNamespace(n_coeffs=100))


def test_defaults_pass():
    assert check_options(None, MODEL) == FitOptions()


@pytest.mark.parametrize("name", sorted(RANGES))
def test_numbers_outside_their_range_are_refused(name):
    lo, hi = RANGES[name]
    for bad in (hi * 10 + 1, lo - 1, float("nan"), float("inf"), 1e300, True, "1"):
        with pytest.raises(ValueError, match=re.escape(f"options.{name}: must be a number "
                                                       f"in [{lo:g}, {hi:g}], got")):
            check_options(FitOptions(**{name: bad}), MODEL)
    check_options(FitOptions(**{name: lo}), MODEL)
    check_options(FitOptions(**{name: hi}), MODEL)


def test_lambda2_1e300_names_the_range():
    with pytest.raises(ValueError, match=r"options\.lambda2: must be a number in \[0, 1e\+06\], "
                                         r"got 1e\+300"):
        check_options(FitOptions(lambda2=1e300), MODEL)


@pytest.mark.parametrize("name", sorted(INT_RANGES))
def test_whole_numbers_outside_their_range_are_refused(name):
    lo, hi = INT_RANGES[name]
    for bad in (lo - 1, hi + 1, 2.0, True):
        with pytest.raises(ValueError, match=rf"options\.{name}: must be an integer in "
                                             rf"{lo}\.\.{hi}"):
            check_options(FitOptions(**{name: bad}), MODEL)


def test_n_identity_against_the_model_and_regional_against_its_regions():
    with pytest.raises(ValueError, match=r"options\.n_identity: must be an integer in 0\.\.100"):
        check_options(FitOptions(n_identity=101), MODEL)

    def regional(n):
        if n > 20:
            raise ValueError(f"n_per_region: must be in 1..20, got {n}")

    model = SimpleNamespace(identity=MODEL.identity, regional=regional)
    with pytest.raises(ValueError, match=r"options\.n_regional: n_per_region: must be in "
                                         r"1\.\.20, got 21"):
        check_options(FitOptions(n_regional=21), model)
    check_options(FitOptions(n_regional=20), model)


def test_pixel_settings_in_photo_pixels():
    from solver.fitting.options import in_photo_pixels

    opts = in_photo_pixels(FitOptions(noise_px=2.0, flag_min_px=5.0), 4.0)
    assert (opts.noise_px, opts.contour_threshold_px, opts.flag_min_px, opts.pixel_scale) \
        == (8.0, 4.0 * FitOptions().contour_threshold_px, 20.0, 4.0)
    assert in_photo_pixels(FitOptions(), 1.0).noise_px == FitOptions().noise_px
    check_options(FitOptions(pixel_scale=None), MODEL)
