"""What a fit returns: everything the add-on writes back and the CLI reports.

The head's vertices in the object's own (local) space are

    local = model.vertices + identity.basis . identity_coeffs
                           + regional.basis . regional_coeffs + detail

and in the world ``scale * local @ rotation.T + translation``. The add-on turns exactly
these terms into shape keys (one per coefficient, plus "fit detail") and the object
transform, so its sliders reproduce ``local`` to float32 precision.
"""

from dataclasses import dataclass, field

import numpy as np

from ..errors import rms


@dataclass
class ViewResidual:
    """Landmark residuals of one view: image distance between the placed landmark and the
    fitted head's projection of it, in pixels."""

    names: list
    pixels: np.ndarray  # (n,) pixels
    flagged: list = field(default_factory=list)  # names whose residual stands out
    # names matched to the head's outline: their residual is the distance across it
    outline: list = field(default_factory=list)
    unused: list = field(default_factory=list)  # names the fit left out (weight 0)


@dataclass
class FitResult:
    """Outcome of fitting the head model to landmarks on photos.

    Attributes
    ----------
    method : str
        "approach1", "approach2" or "combined" (which one won is in ``info``).
    scale : float
        Similarity scale (dimensionless; the model is in metres).
    rotation : ndarray, shape (3, 3)
        Similarity rotation, local -> world.
    translation : ndarray, shape (3,), metres
    identity_coeffs : ndarray, shape (K,)
        Global identity coefficients in standard deviations.
    regional_coeffs : ndarray, shape (R,) or (0,)
        Regional coefficients in standard deviations, ordered as ``regional_names``.
    regional_names : tuple of str
    detail : ndarray, shape (V, 3), metres
        What the linear model cannot express (e.g. the TPS remainder that makes the
        landmarks hit exactly); zeros when not used.
    local_vertices : ndarray, shape (V, 3), metres
        Whole head in local space (see module docstring).
    cameras : dict of str -> Camera
        Each view's fitted camera.
    residuals : dict of str -> ViewResidual
    uncertainty : ndarray, shape (V,), millimetres
        Posterior standard deviation of each vertex position given the landmarks.
    info : dict
        Iterations, errors per iteration, timings (seconds), chosen approach.
    """

    method: str
    scale: float
    rotation: np.ndarray
    translation: np.ndarray
    identity_coeffs: np.ndarray
    regional_coeffs: np.ndarray
    regional_names: tuple
    detail: np.ndarray
    local_vertices: np.ndarray
    cameras: dict
    residuals: dict
    uncertainty: np.ndarray
    info: dict = field(default_factory=dict)

    @property
    def world_vertices(self):
        """Whole head in world space, shape (V, 3), metres."""
        return self.scale * self.local_vertices @ self.rotation.T + self.translation

    def rms_px(self, view=None):
        """RMS landmark residual in pixels: of one view, or (``view`` None) of all views'
        landmarks together, those the fit left out (``unused``) not counted; 0.0 where
        there are none."""
        views = self.residuals.values() if view is None else [self.residuals[view]]
        px = [np.asarray(r.pixels, dtype=np.float64).reshape(-1)[
            ~np.isin(np.asarray(r.names, dtype=object), r.unused)] for r in views]
        return rms(np.concatenate(px) if px else np.zeros(0))

    def flagged(self):
        """(view, landmark) pairs whose residual stands out, worst first."""
        out = []
        for view, r in self.residuals.items():
            px = dict(zip(r.names, r.pixels, strict=True))
            out += [(px[n], view, n) for n in r.flagged]
        return [(v, n) for _, v, n in sorted(out, reverse=True)]
