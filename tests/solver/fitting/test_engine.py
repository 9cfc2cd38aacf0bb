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
    skin = engine.skin_basis32(eng.lin, model.skin)
    first = eng.slice(np.arange(3))
    kept = eng.slice(np.arange(7))
    for i in range(200):  # far more subsets than are kept
        mean, basis = eng.slice(np.arange(i, i + 5))
        np.testing.assert_array_equal(mean, eng.lin.mean[i:i + 5])
        if i % 10 == 0:
            assert eng.slice(np.arange(7)) is kept  # used again: kept
        vm = eng.vertex_major(np.arange(i, i + 5))
        np.testing.assert_array_equal(vm, basis.transpose(1, 2, 0))
    assert engine.skin_basis32(eng.lin, model.skin) is skin
    again = eng.slice(np.arange(3))
    assert again is not first  # the subsets were forgotten, and come back the same
    np.testing.assert_array_equal(again[1], first[1])
    held = sum(sum(a.nbytes for a in v) if isinstance(v, tuple) else v.nbytes
               for k, v in eng._slices.items() if isinstance(k, bytes) or k[0] == "vm")
    assert held <= engine.SLICE_CACHE_BYTES


def test_forgotten_subsets_are_made_again_and_fit_the_same_head(model):
    """A batch worker forgets a head's vertex subsets (``forget_fit_subsets``): none is
    left (the skin's basis, which every fit asks for, is kept), and the next fit makes
    them again and lands on the same head as with them cached."""
    from solver import fit_head, forget_fit_subsets
    from solver.memo import memo_items

    case, _ = make_case(model, 6, noise_px=1.0)
    opts = FitOptions(n_identity=20)
    first = fit_head(model, case, opts).local_vertices
    cached = fit_head(model, case, opts).local_vertices

    def caches():
        return [dict(memo_items(lin))["slices"] for key, lin in memo_items(model)
                if isinstance(key, tuple) and key[:1] == (engine.FITTED_MODEL,)]

    def subsets():
        return [k for c in caches() for k in c if engine._is_subset_key(k)]

    assert subsets()
    kept = {k: v for c in caches() for k, v in c.items() if not engine._is_subset_key(k)}
    assert any(isinstance(k, tuple) and k[0] == "f32" for k in kept)
    forget_fit_subsets(model)
    assert not subsets()
    assert {k: v for c in caches() for k, v in c.items()} == kept
    again = fit_head(model, case, opts).local_vertices
    assert subsets()
    np.testing.assert_array_equal(again, cached)
    np.testing.assert_array_equal(again, first)


def test_prepare_fit_makes_what_every_fit_makes_once(model):
    """``prepare_fit`` (the add-on's warm-up) makes the fitted modes, the skin's float32
    basis and maps and the expressions of a model no fit has touched; the first fit then
    uses them as they are and lands on the head an unprepared model's fit does."""
    from solver import fit_head, prepare_fit
    from solver.memo import memo_items
    from solver.model.head_model import HeadModel

    with np.load(model.path) as data:
        fresh = HeadModel({k: data[k] for k in data.files}, model.path)
    opts = FitOptions(n_identity=20)
    key = (engine.FITTED_MODEL, 20, opts.n_regional)
    assert not memo_items(fresh) and "expressions" not in fresh.__dict__
    prepare_fit(fresh, opts)
    made = dict(memo_items(fresh))
    assert "skin maps" in made and "expressions" in fresh.__dict__
    slices = dict(memo_items(made[key]))["slices"]
    assert any(isinstance(k, tuple) and k[0] == "f32" for k in slices)
    case, _ = make_case(fresh, 7, noise_px=1.0)
    got = fit_head(fresh, case, opts)
    assert dict(memo_items(fresh))[key] is made[key]
    np.testing.assert_array_equal(got.local_vertices,
                                  fit_head(model, case, opts).local_vertices)
