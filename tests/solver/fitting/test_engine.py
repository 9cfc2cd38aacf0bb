"""What the fit's stages share (solver/fitting/engine.py): camera refits name their view."""

import numpy as np
import pytest

from solver import FitOptions
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
