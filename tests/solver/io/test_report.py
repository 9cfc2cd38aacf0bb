"""The fit report (solver/io/report.py): plain JSON values, the residuals' RMS as the fit
result gives it, written atomically."""

import json
import os

import numpy as np
import pytest

from solver import FitOptions, OrthographicCamera, fit_head
from solver.io.report import REPORT_FORMAT, fit_report, jsonable, write_fit_report
from solver.synthetic import make_case


def test_jsonable_gives_plain_json_values():
    cam = OrthographicCamera.nominal("orthographic-front", (100, 200))
    got = jsonable({1: (np.float32(0.5), np.arange(2)), "c": cam, "x": [float("nan"), True],
                    "o": object})
    assert got["1"] == [0.5, [0, 1]] and got["x"] == [None, True]
    assert got["c"] == jsonable(cam.to_dict()) and isinstance(got["o"], str)
    json.dumps(got, allow_nan=False)


@pytest.fixture(scope="module")
def fitted(model):
    case, _ = make_case(model, 3, noise_px=0.5, image_height=256)
    return case, fit_head(model, case, FitOptions(n_identity=10, method="approach1"))


def test_fit_report(tmp_path, model, fitted):
    case, result = fitted
    report = fit_report(case, model, result, {"components": 10}, {"obj": tmp_path / "h.obj"},
                        {"fit": 0.5})
    assert report["format"] == REPORT_FORMAT and report["version"] == 1
    assert report["options"] == {"components": 10} and report["timings_s"] == {"fit": 0.5}
    assert report["outputs"] == {"obj": str((tmp_path / "h.obj").resolve())}
    assert set(report["residuals"]) == set(result.residuals)
    for view, r in report["residuals"].items():
        assert r["rms_px"] == result.rms_px(view)
        assert r["max_px"] == max(r["landmarks"].values())
    assert len(report["coefficients"]["identity"]) == 10
    assert "refit_state" not in report["info"]
    assert 0 < report["uncertainty_mm"]["median"] <= report["uncertainty_mm"]["max"]
    assert report["iris_srgb"] is None
    brown = fit_report(case, model, result, {}, {}, {}, iris=np.array([0.4, 0.25, 0.1]))
    assert brown["iris_srgb"] == [0.4, 0.25, 0.1]
    path = tmp_path / "report.json"
    write_fit_report(path, report)
    assert json.loads(path.read_text(encoding="utf-8")) == report
    assert os.listdir(tmp_path) == ["report.json"]
