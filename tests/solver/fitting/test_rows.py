"""Rows of the shape-ICP (solver/fitting/rows.py): their input checks and the blocks they
return."""

import numpy as np
import pytest

from solver import OrthographicCamera
from solver.fitting.rows import ClosestPointRows, ImageRows, PointRows, ScalarRows
from tests.solver.fitting.test_shape_icp import _rows, synthetic_model


def test_bad_rows_input():
    model = synthetic_model()
    v, y = _rows(model)
    bad = y.copy()
    bad[7, 2] = np.nan
    with pytest.raises(ValueError, match="landmarks: target row 7 is not finite"):
        PointRows(v, bad, name="landmarks")
    with pytest.raises(ValueError, match=r"targets must have shape \(50, 3\)"):
        PointRows(v, y[:40])
    with pytest.raises(ValueError, match="mask must be a bool array"):
        PointRows(v, y, mask=np.ones((50, 2), bool))
    with pytest.raises(ValueError, match="weights must be finite and non-negative"):
        PointRows(v, y, weights=-1.0)
    with pytest.raises(ValueError, match=r"weights must be a scalar or shape \(50,\)"):
        PointRows(v, y, weights=np.ones(3))
    with pytest.raises(ValueError, match="vertices must be integer"):
        PointRows(v.astype(float), y)
    with pytest.raises(ValueError, match="vertices must be a non-empty"):
        PointRows(np.zeros((2, 2), int), y)
    with pytest.raises(ValueError, match="front: pixels"):
        ImageRows(v, y, OrthographicCamera.nominal("orthographic-front", (10, 10)),
                  name="front")
    with pytest.raises(ValueError, match="camera must be a Camera"):
        ImageRows(v, y[:, :2], "front")
    with pytest.raises(ValueError, match="max_distance must be > 0"):
        ClosestPointRows(v, y, max_distance=0)
    with pytest.raises(ValueError, match="scan: cloud: row 7"):
        ClosestPointRows(v, bad, name="scan")

def test_rows_return_scalar_rows_blocks():
    model = synthetic_model()
    v = np.arange(10)
    cam = OrthographicCamera.nominal("orthographic-front", (100, 100))
    rows = ImageRows(v, cam.project(model.mean[v]) + 1.0, cam)
    cost_only = rows.block(model.mean[v], jacobian=False)
    assert isinstance(cost_only, ScalarRows) and cost_only.g is None
    assert cost_only.sq == pytest.approx(20.0) and cost_only.nrows == 20
    full = rows.block(model.mean[v])
    assert full.g.shape == (20, 3) and full.r.shape == (20,) and full.idx.shape == (20,)
    masked = PointRows(v, model.mean[v], mask=np.tile([True, False, True], (10, 1)))
    assert isinstance(masked.block(model.mean[v]), ScalarRows)
