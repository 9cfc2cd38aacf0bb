"""The machinery the fit's approaches share: the views of a case as arrays, the rows they
give the shape-ICP, and the alternation "head given cameras / cameras given head".

Why alternate: each photo has its own camera (an orthographic photo: scale, in-plane
rotation, offset), and a camera's free parameters are its own business (``Camera.refit``),
so a perspective or DLT camera plugs in without the fit knowing its parametrisation. The
head's pose and shape are solved by the shape-ICP (``solver/shape_icp.py``) with the
cameras fixed; then every camera is refitted to the head; repeat. Both halves lower the
same weighted least-squares cost, so the cost never rises.

Gauge: orthographic photos cannot tell how large or where the head is, only how it looks;
when every camera is refitted the head's scale stays 1 and its translation 0 and the
cameras absorb both (the identity modes carry the head's size).
"""

from dataclasses import dataclass, field, replace

import numpy as np

from .cameras import Camera
from .shape_icp import ClosestPixelRows, ImageRows, ShapeProblem

#: The fit refuses a view with fewer landmarks than this (its camera needs 2 for a 2-D
#: similarity, one more to say anything about the head).
MIN_VIEW_LANDMARKS = 3


@dataclass
class ViewData:
    """One photo of the case, as arrays.

    Attributes
    ----------
    name : str
    camera : Camera
        Current camera (replaced as the fit refits it).
    names : list of str
        Canonical landmark names.
    vertices : ndarray, shape (n,)
        Model vertex of each landmark.
    pixels : ndarray, shape (n, 2)
    weights : ndarray, shape (n,)
        Per-landmark weight (options' landmark weights times the view's weight), before
        the 1 / noise^2 factor.
    side : bool
        The camera looks along the head's left-right axis (a profile photo).
    contour : ndarray, shape (m, 2) or None
        The traced outline densified to about one point per pixel (side views only).
    refit : bool
        Whether the fit may change this camera.
    """

    name: str
    camera: Camera
    names: list
    vertices: np.ndarray
    pixels: np.ndarray
    weights: np.ndarray
    side: bool
    contour: np.ndarray | None = None
    refit: bool = True


@dataclass
class State:
    """Head pose, coefficients and cameras: ``world = scale * R (mean + B c) + t``."""

    rotation: np.ndarray
    coeffs: np.ndarray
    cameras: dict
    scale: float = 1.0
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def copy(self):
        return replace(self, rotation=self.rotation.copy(), coeffs=self.coeffs.copy(),
                       cameras=dict(self.cameras), translation=self.translation.copy())


def is_side_camera(camera):
    """True when the camera looks along the world x axis (the head's left-right axis)."""
    d = np.asarray(camera.toward_camera(np.zeros((1, 3))), dtype=np.float64).reshape(3)
    return abs(d[0]) > 0.7 * np.linalg.norm(d)


def densify(polyline, step=1.0):
    """Points along a polyline about ``step`` pixels apart (vertices kept), (m, 2)."""
    p = np.asarray(polyline, dtype=np.float64)
    if len(p) < 2:
        return p.copy()
    seg = np.diff(p, axis=0)
    n = np.maximum(np.ceil(np.linalg.norm(seg, axis=1) / step).astype(int), 1)
    t = np.concatenate([np.arange(k) / k for k in n])
    i = np.repeat(np.arange(len(seg)), n)
    return np.vstack([p[i] + t[:, None] * seg[i], p[-1:]])


class ContourRows(ClosestPixelRows):
    """Profile-line rows (thesis §4.4.1): model vertices whose projection is pulled to the
    nearest point of the traced outline. Besides the distance threshold, a vertex whose
    nearest outline point is one of the outline's ends is dropped: it lies beyond what was
    traced (e.g. the neck below where the tracing stopped), not on it."""

    def __init__(self, vertices, pixels, camera, weights=1.0, max_distance=np.inf,
                 reject_factor=None, end_margin=3.0, name="contour"):
        super().__init__(vertices, pixels, camera, weights, max_distance, reject_factor, name)
        d0 = np.linalg.norm(self.pixels - self.pixels[0], axis=1)
        d1 = np.linalg.norm(self.pixels - self.pixels[-1], axis=1)
        self._at_end = (d0 <= end_margin) | (d1 <= end_margin)

    def update(self, world):
        proj = self.camera.project(world)
        dist, idx = self.tree.query(proj, distance_upper_bound=self.max_distance)
        ok = np.isfinite(dist)
        idx = np.where(ok, idx, 0)
        ok &= ~self._at_end[idx]
        if self.reject_factor is not None and ok.any():
            ok &= dist <= self.reject_factor * max(float(np.median(dist[ok])), 1.0)
        self.inliers = ok
        self.targets = self.pixels[idx]

    def pairs(self):
        """(vertices, target pixels) of the current inlier correspondences."""
        if self.inliers is None:
            return self.vertices[:0], np.zeros((0, 2))
        return self.vertices[self.inliers], self.targets[self.inliers]


class Engine:
    """Rows, camera refits and the alternation for one fit.

    Parameters
    ----------
    lin : LinearModel
        The model the fit changes (global modes, possibly with regional ones after them).
    views : list of ViewData
    chain : ndarray, shape (P,)
        Model vertices that form the head's outline in a profile photo.
    noise_px : float
        Landmark noise the weights assume (rows are weighted 1 / noise^2, so lambda2 = 1 is
        the Bayesian prior for standard-normal coefficients).
    lambda1, lambda2 : float
        Smoothness (per millimetre of region disagreement) and prior weights.
    prior : str
    contour_weight : float
    contour_threshold : float
        Largest pixel distance of a contour correspondence.
    fix_gauge : bool
        Keep the head's scale 1 and translation 0 (every camera is refitted).
    """

    def __init__(self, lin, views, chain, noise_px, lambda1, lambda2, prior, contour_weight,
                 contour_threshold, fix_gauge):
        self.lin = lin
        self.views = views
        self.chain = np.asarray(chain, dtype=np.int64)
        self.inv_var = 1.0 / noise_px**2
        self.lambda1 = 1000.0 * lambda1  # Gamma c is in metres; lambda1 is per millimetre
        self.prior = prior
        if prior == "identity":
            # shape_icp penalises stddev * c (metres): rescale so lambda2 = 1 has the same
            # overall strength as the eigen prior.
            sd = np.asarray(lin.stddev, dtype=np.float64)
            self.lambda2 = lambda2 / float(np.sqrt(np.mean(sd**2)))
        else:
            self.lambda2 = lambda2
        self.contour_weight = contour_weight
        self.contour_threshold = contour_threshold
        self.fix_gauge = fix_gauge
        self.freeze_sim = ("scale", "translation") if fix_gauge else ()
        self._lm_rows = {}
        self._contour_rows = {}

    # ------------------------------------------------------------------ geometry

    def local(self, state, vertices=None):
        """Model-space positions mean + B c, (n, 3) (all vertices if ``vertices`` is None)."""
        lin = self.lin
        if vertices is None:
            return lin.mean + np.tensordot(state.coeffs, lin.basis, axes=1)
        return lin.mean[vertices] + np.tensordot(state.coeffs, lin.basis[:, vertices], axes=1)

    def world(self, state, vertices=None):
        return state.scale * self.local(state, vertices) @ state.rotation.T + state.translation

    # ------------------------------------------------------------------ rows

    def landmark_rows(self, view, weight=1.0):
        """ImageRows of a view's landmarks (cached per view and weight)."""
        key = (view.name, float(weight))
        rows = self._lm_rows.get(key)
        if rows is None:
            rows = ImageRows(view.vertices, view.pixels, view.camera,
                             weights=weight * self.inv_var * view.weights,
                             name=f"landmarks {view.name}")
            self._lm_rows[key] = (view, rows)
        else:
            rows = rows[1]
        rows.camera = view.camera
        return rows

    def contour_rows(self, view):
        """ContourRows of a side view's outline against the profile chain (cached)."""
        rows = self._contour_rows.get(view.name)
        if rows is None:
            w = self.contour_weight * self.inv_var
            rows = ContourRows(self.chain, view.contour, view.camera, weights=w,
                               max_distance=self.contour_threshold, reject_factor=4.0,
                               name=f"contour {view.name}")
            self._contour_rows[view.name] = rows
        rows.camera = view.camera
        return rows

    def rows_for(self, views, front_weight=1.0, contour=True, landmarks=True):
        """Landmark rows of ``views`` (front views weighted ``front_weight``) and the
        contour rows of those with an outline."""
        rows = []
        for v in views:
            if landmarks and len(v.vertices):
                rows.append(self.landmark_rows(v, 1.0 if v.side else front_weight))
            if contour and v.contour is not None:
                rows.append(self.contour_rows(v))
        return rows

    def problem(self, rows, freeze=()):
        return ShapeProblem(self.lin, rows, lambda1=self.lambda1, lambda2=self.lambda2,
                            prior=self.prior, freeze=tuple(freeze) + self.freeze_sim)

    # ------------------------------------------------------------------ cameras

    def use(self, state):
        """Make ``state``'s cameras the views' current cameras (e.g. when another approach
        starts from a saved state)."""
        for v in self.views:
            v.camera = state.cameras[v.name]
        for view, rows in self._lm_rows.values():
            rows.camera = view.camera
        for name, rows in self._contour_rows.items():
            rows.camera = state.cameras[name]

    def refit_cameras(self, state, views=None, use_contour=True):
        """Every refittable camera refitted to the current head (landmarks and, for side
        views, the contour's current correspondences). Updates ``state.cameras`` and the
        views."""
        for v in self.views if views is None else views:
            if not v.refit:
                continue
            verts, px, w = [v.vertices], [v.pixels], [v.weights]
            rows = self._contour_rows.get(v.name)
            if use_contour and rows is not None:
                cv, cp = rows.pairs()
                if len(cv):
                    verts.append(cv)
                    px.append(cp)
                    w.append(np.full(len(cv), self.contour_weight))
            verts = np.concatenate(verts)
            cam = v.camera.refit(self.world(state, verts), np.vstack(px), np.concatenate(w))
            v.camera = cam
            state.cameras[v.name] = cam
        for view, rows in self._lm_rows.values():
            rows.camera = view.camera
        for name, rows in self._contour_rows.items():
            rows.camera = state.cameras[name]

    def init_cameras(self, state, robust_steps=4):
        """Start each refittable camera from the mean head: Procrustes of the landmark
        vertices' projections to the placed points, reweighted robustly (Cauchy) so one
        misplaced landmark does not tilt the start."""
        for v in self.views:
            if not v.refit:
                continue
            x = self.world(state, v.vertices)
            w = v.weights.copy()
            cam = v.camera.refit(x, v.pixels, w)
            for _ in range(robust_steps):
                r = np.linalg.norm(cam.project(x) - v.pixels, axis=1)
                c = max(2.0 * float(np.median(r)), 1e-6)
                cam = v.camera.refit(x, v.pixels, w / (1.0 + (r / c) ** 2))
            v.camera = cam
            state.cameras[v.name] = cam

    def camera_icp(self, state, views, max_steps=20, tolerance=1e-3):
        """ICP of the cameras alone (the head fixed): refresh the contour correspondences,
        refit, repeat until the contour/landmark cost stops falling. For a profile photo
        this is the similarity-only step of thesis §4.4.1: the side camera's 2-D similarity
        is exactly the head's scale, rotation in the sagittal plane and translation there.

        Returns the cost history (weighted squared pixels)."""
        history = []
        for _ in range(max_steps):
            cost = 0.0
            for v in views:
                x = self.world(state, v.vertices)
                r = v.camera.project(x) - v.pixels
                cost += float(v.weights @ (r * r).sum(1))
                if v.contour is not None:
                    rows = self.contour_rows(v)
                    xc = self.world(state, rows.vertices)
                    rows.update(xc)
                    d = rows.targets - v.camera.project(xc)
                    cost += self.contour_weight * float((d[rows.inliers] ** 2).sum())
            history.append(cost)
            self.refit_cameras(state, views)
            if len(history) >= 2 and history[-2] - history[-1] <= tolerance * history[-2]:
                break
        return history

    # ------------------------------------------------------------------ solving

    def alternate(self, state, rows, freeze=(), max_outer=30, inner=2, tolerance=1e-4,
                  refit=True):
        """Alternate shape-ICP steps (cameras fixed) and camera refits until the cost
        changes by less than ``tolerance`` (relative).

        Returns
        -------
        state : State
        history : list of float
            Cost after each round.
        fit : ShapeFit
            The last shape-ICP result (its covariance is at the final head, cameras fixed).
        """
        problem = self.problem(rows, freeze)
        history = []
        fit = None
        for _ in range(max(int(max_outer), 1)):
            fit = problem.solve(scale=state.scale, rotation=state.rotation,
                                translation=state.translation, coeffs=state.coeffs,
                                max_iterations=inner, tolerance=tolerance * 0.1, sigma=1.0)
            state.rotation, state.coeffs = fit.rotation, fit.coeffs
            state.scale, state.translation = fit.scale, fit.translation
            if refit:
                self.refit_cameras(state)
                cost = self.cost(problem, state)
            else:
                cost = fit.info["cost"]
            history.append(cost)
            if len(history) >= 2 and history[-2] - history[-1] <= tolerance * history[-2]:
                break
        return state, history, fit

    def cost(self, problem, state):
        """Weighted data cost plus prior of ``problem``'s rows at ``state`` (correspondences
        refreshed)."""
        fit = problem.solve(scale=state.scale, rotation=state.rotation,
                            translation=state.translation, coeffs=state.coeffs,
                            max_iterations=0, sigma=1.0)
        return fit.info["cost"]

    def covariance(self, state, rows):
        """Posterior covariance of the coefficients (K, K) given ``rows`` at ``state``
        (pose free, cameras fixed; rows weighted 1 / noise^2 so sigma = 1)."""
        problem = self.problem(rows)
        fit = problem.solve(scale=state.scale, rotation=state.rotation,
                            translation=state.translation, coeffs=state.coeffs,
                            max_iterations=0, sigma=1.0)
        return fit.coeff_covariance

    # ------------------------------------------------------------------ errors

    def reprojection(self, state, views=None):
        """Per view: landmark residuals (n,) in pixels."""
        out = {}
        for v in self.views if views is None else views:
            px = state.cameras[v.name].project(self.world(state, v.vertices))
            out[v.name] = np.linalg.norm(px - v.pixels, axis=1)
        return out

    def contour_error(self, state):
        """RMS pixel distance of the inlier contour correspondences over all side views
        (refreshed at ``state``), and how many there are."""
        sq, n = 0.0, 0
        for v in self.views:
            if v.contour is None:
                continue
            rows = self.contour_rows(v)
            rows.camera = state.cameras[v.name]
            x = self.world(state, rows.vertices)
            rows.update(x)
            if rows.inliers.any():
                d = rows.targets[rows.inliers] - rows.camera.project(x[rows.inliers])
                sq += float((d * d).sum())
                n += int(rows.inliers.sum())
        return (np.sqrt(sq / n) if n else 0.0), n

    def reprojection_rms(self, state):
        """RMS of all landmark and contour pixel residuals (the criterion between
        approaches)."""
        res = self.reprojection(state)
        sq = sum(float((r**2).sum()) for r in res.values())
        n = sum(len(r) for r in res.values())
        c_rms, c_n = self.contour_error(state)
        return float(np.sqrt((sq + c_rms**2 * c_n) / max(n + c_n, 1)))
