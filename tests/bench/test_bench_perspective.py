"""The perspective benchmark's verdict interval (bench/bench_perspective.py)."""

import numpy as np
import pytest

from bench.bench_perspective import ratio_interval


def test_identical_setups_give_a_ratio_of_exactly_one():
    errs = np.random.default_rng(1).gamma(9.0, 0.08, size=50)
    assert ratio_interval(errs, errs) == (1.0, 1.0)


def test_the_interval_holds_the_ratio_and_narrows_with_more_heads():
    rng = np.random.default_rng(2)
    widths = []
    for n in (20, 400):
        ref = rng.gamma(9.0, 0.075, size=n)
        errs = 1.2 * ref * rng.lognormal(0.0, 0.15, size=n)  # paired: same heads, noisier
        lo, hi = ratio_interval(errs, ref)
        ratio = np.median(errs) / np.median(ref)
        assert lo < ratio < hi
        widths.append(hi - lo)
    assert widths[1] < 0.5 * widths[0]


def test_pairing_makes_it_narrower_than_unpaired_resampling():
    rng = np.random.default_rng(3)
    ref = rng.gamma(9.0, 0.075, size=100)
    errs = 1.2 * ref * rng.lognormal(0.0, 0.05, size=100)
    lo, hi = ratio_interval(errs, ref)
    shuffled = rng.permutation(errs)  # the same errors, pairing broken
    lo2, hi2 = ratio_interval(shuffled, ref)
    assert hi - lo < 0.6 * (hi2 - lo2)


def test_mismatched_lengths_are_refused():
    with pytest.raises(ValueError, match="errs and ref_errs"):
        ratio_interval([1.0, 2.0], [1.0])
