"""The JSON report of a fit that ``solver fit --report`` writes: residuals, coefficients,
cameras, uncertainty, timings and the files written."""

import json
import math
from pathlib import Path

import numpy as np

from .atomic import write_file_atomic

REPORT_FORMAT = "headrecon-fit-report"


def jsonable(x):
    """numpy / tuples / cameras -> plain JSON values (non-finite floats -> None)."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, np.generic):
        return jsonable(x.item())
    if isinstance(x, bool | int | str) or x is None:
        return x
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if hasattr(x, "to_dict"):
        return jsonable(x.to_dict())
    return repr(x)


def fit_report(case, model, result, options, outputs, timings, iris=None):
    """The report of one fit as plain JSON values.

    Parameters
    ----------
    case : LandmarkCase
        What was fitted (its ``source`` is the landmarks file).
    model : HeadModel
    result : FitResult
    options : dict
        The options the fit was asked for (the command line's), as given.
    outputs : dict of str -> path-like
        Files written ("obj", "mtl", "texture", "report").
    timings : dict of str -> float
        Seconds per step.
    iris : ndarray (3,), optional
        The irises' colour read off the photos with the texture (``iris_colour``), sRGB
        in [0, 1]: "iris_srgb" (null when no photo showed the irises or none was baked).

    Returns
    -------
    dict
        Format ``headrecon-fit-report`` version 1: per view the landmark residuals (each,
        mean, RMS, max, flagged), coefficients, the similarity, cameras, the uncertainty
        over the skin, timings, outputs and the fit's ``info``; non-finite numbers are None.
    """
    skin = getattr(model, "skin", None)
    unc = np.asarray(result.uncertainty, dtype=np.float64)
    unc_skin = unc[skin] if skin is not None and unc.size == model.n_vertices else unc
    residuals = {}
    for view, r in result.residuals.items():
        px = np.asarray(r.pixels, dtype=np.float64)
        residuals[view] = {
            "landmarks": dict(zip(r.names, px.tolist(), strict=True)),
            "mean_px": float(px.mean()) if px.size else None,
            "rms_px": result.rms_px(view) if px.size else None,
            "max_px": float(px.max()) if px.size else None,
            "flagged": list(r.flagged),
        }
    landmark_unc = {}
    for name, vertex in getattr(model, "landmarks", {}).items():
        if 0 <= vertex < unc.size:
            landmark_unc[name] = float(unc[vertex])
    # refit_state is the add-on's live-drag cache (large arrays), not a result
    info = {k: v for k, v in result.info.items() if k != "refit_state"}
    return jsonable({
        "format": REPORT_FORMAT,
        "version": 1,
        "landmarks_file": str(Path(case.source).resolve()),
        "method": result.method,
        "options": options,
        "similarity": {"scale": result.scale, "rotation": result.rotation,
                       "translation_m": result.translation},
        "coefficients": {
            "identity": result.identity_coeffs,
            "regional": dict(zip(result.regional_names,
                                 np.asarray(result.regional_coeffs).tolist(), strict=True)),
        },
        "residuals": residuals,
        "flagged": [list(x) for x in result.flagged()],
        "cameras": result.cameras,
        "uncertainty_mm": {
            "over": "skin" if unc_skin is not unc else "all vertices",
            "mean": float(unc_skin.mean()) if unc_skin.size else None,
            "median": float(np.median(unc_skin)) if unc_skin.size else None,
            "p95": float(np.percentile(unc_skin, 95)) if unc_skin.size else None,
            "max": float(unc_skin.max()) if unc_skin.size else None,
            "landmarks": landmark_unc,
        },
        "iris_srgb": None if iris is None else np.asarray(iris, float),
        "timings_s": timings,
        "outputs": {k: str(Path(v).resolve()) for k, v in outputs.items()},
        "info": info,
    })


def report_text(report):
    """A ``fit_report`` as the indented JSON text a report file holds."""
    return json.dumps(report, indent=1, allow_nan=False) + "\n"


def write_fit_report(path, report):
    """Write a ``fit_report`` as indented JSON, atomically."""
    write_file_atomic(path, report_text(report))
