"""What the fit's stages share (solver/fitting/engine.py): camera refits name their view."""

import numpy as np
import pytest

from solver import FitOptions
from solver.fitting import engine
from solver.fitting.engine import Engine
from solver.fitting.views import State, prepare_views
from solver.synthetic import make_case


def test_a_camera_that_cannot_be_refitted_names_its_view(model):
    case, _ = make_case(model, 5, noise_px=1.0)
    opts = FitOptions()
    views, _ = prepare_views(model, case, opts)
    eng = Engine.for_fit(model, views, opts)
    # a head shrunk to one point: every landmark projects onto one pixel, so no
    # similarity lays them onto the photo's
    state = State(np.eye(3), np.zeros(eng.lin.n_coeffs), {v.name: v.camera for v in views},
                  scale=0.0)
    with pytest.raises(ValueError, match=r"^view 'front': camera refit "
                                         r"\(orthographic-front\): .*undetermined"):
        eng.refit_cameras(state)


def test_many_vertex_subsets_do_not_evict_the_skins_basis(model, monkeypatch):
    case, _ = make_case(model, 5, noise_px=1.0)
    opts = FitOptions()
    views, _ = prepare_views(model, case, opts)
    eng = Engine.for_fit(model, views, opts)
    one = sum(a.nbytes for a in eng.slice(np.arange(100, 105)))
    monkeypatch.setattr(engine, "SLICE_CACHE_BYTES", 50 * one)  # room for about 50
    skin = eng.skin_basis32(model.skin)
    first = eng.slice(np.arange(3))
    kept = eng.slice(np.arange(7))
    for i in range(200):  # far more subsets than are kept
        mean, basis = eng.slice(np.arange(i, i + 5))
        np.testing.assert_array_equal(mean, eng.lin.mean[i:i + 5])
        if i % 10 == 0:
            assert eng.slice(np.arange(7)) is kept  # used again: kept
        vm = eng.vertex_major(np.arange(i, i + 5))
        np.testing.assert_array_equal(vm, basis.transpose(1, 2, 0))
    assert eng.skin_basis32(model.skin) is skin
    again = eng.slice(np.arange(3))
    assert again is not first  # the subsets were forgotten, and come back the same
    np.testing.assert_array_equal(again[1], first[1])
    held = sum(sum(a.nbytes for a in v) if isinstance(v, tuple) else v.nbytes
               for k, v in eng._slices.items() if isinstance(k, bytes) or k[0] == "vm")
    assert held <= engine.SLICE_CACHE_BYTES
