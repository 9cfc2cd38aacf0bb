"""The machinery the fit's stages share: the views of a case as arrays, the rows they give
the shape-ICP, and the joint solve of head and cameras.

Each photo has its own camera (an orthographic photo: scale, in-plane rotation, offset);
its free parameters are its own business (``Camera.refit``), so a perspective or DLT
camera plugs in without the fit knowing its parametrisation. The head's pose and shape are
solved by the shape-ICP (``solver/shape_icp.py``) together with a linearised image-plane
similarity of every camera (:class:`Joint`); after every step each camera is refitted to
what the step predicted.

Gauge: orthographic photos cannot tell how large or where the head is, only how it looks;
when every camera is refitted the head's scale stays 1 and its translation 0 and the
cameras absorb both (the identity modes carry the head's size).
"""

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import cKDTree

from .cameras import Camera
from .linear_model import LinearModel
from .shape_icp import ImageRows, Rows, ShapeProblem, _General

#: The fit refuses a view with fewer landmarks than this (its camera needs 2 for a 2-D
#: similarity, one more to say anything about the head).
MIN_VIEW_LANDMARKS = 3

# Pixels one unit of a camera mode's coefficient moves the photo (see Joint): large, so
# the shape prior the shape-ICP puts on every coefficient hardly restrains the cameras
# (a 10 px correction costs 0.01), yet it settles the split where a calibrated camera
# leaves the head's position and a refitted camera's offset equally free.
_MODE_PIXELS = 100.0


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
        Per-landmark weight (landmark weights of the options), before the view's weight
        and the 1 / noise^2 factor.
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


_SLICES = {}


def _slice_cache(lin):
    """Per linear model (kept alive with it): vertex-subset slices of its basis."""
    hit = _SLICES.get(id(lin))
    if hit is None or hit[0] is not lin:
        if len(_SLICES) >= 4:
            _SLICES.clear()
        hit = (lin, {})
        _SLICES[id(lin)] = hit
    return hit[1]


def set_camera(rows, camera):
    """Point image rows at a (refitted) camera. The version bump tells the shape-ICP that a
    system it cached for these rows is stale."""
    if rows.camera is not camera:
        rows.camera = camera
        rows._version = getattr(rows, "_version", 0) + 1


class ContourRows(Rows):
    """Profile-line rows (thesis §4.4.1): the model's outline in a photo pulled onto the
    traced outline.

    The model's outline is not a fixed set of vertices: the midsagittal profile is the
    silhouette only of a symmetric head seen exactly from the side; the brows, the nose's
    wings or the sides of the neck stick out beyond it, and a turned head shows other
    vertices. So ``vertices`` are candidates (vertices near the midline whose normals face
    roughly across the viewing direction), and every update finds the model's outline
    among them:

    1. the rim: candidates on an edge between a triangle facing the camera and one facing
       away (the contour generator of the posed head);
    2. the traced outline is cut into bins of ``bin_px`` pixels of arc length; each rim
       vertex belongs to the bin of its nearest traced point, and per bin the one farthest
       outward (along the outline's outward normal) is the model's outline there (a rim
       hidden behind another, e.g. the midline under the brows, loses).

    Each chosen vertex gives one point-to-line row ``w (n . (q - P(x)))^2`` with q its
    nearest traced point and n the normal there: across the outline is what a nearest
    point measures; along it the vertex may slide.

    Vertices whose nearest traced point is one of the outline's ends are left out (they
    lie beyond what was traced, e.g. the neck below where the tracing stopped), as are
    those farther than ``max_distance`` pixels, or than ``reject_factor`` times the median
    (but never below ``keep_distance``).

    Parameters
    ----------
    vertices : array_like of int, shape (n,)
    pixels : array_like, shape (m, 2)
        The traced outline densified to about one point per pixel, in drawing order.
    camera : Camera
    weights : float
        Weight of one row.
    faces : ndarray, shape (F, 3), optional
        Triangles among the candidates (indices into ``vertices``).
    edges : ndarray, shape (E, 4), optional
        Edges shared by two of those triangles: (vertex a, vertex b, face 1, face 2).
        Without faces and edges every candidate counts as rim.
    max_distance, reject_factor, keep_distance, end_margin, bin_px : float
    name : str
    """

    def __init__(self, vertices, pixels, camera, weights=1.0, faces=None, edges=None,
                 max_distance=20.0, reject_factor=4.0, keep_distance=5.0, end_margin=3.0,
                 bin_px=6.0, name="contour"):
        self.name = name
        self.vertices = np.asarray(vertices, dtype=np.intp)
        self.camera = camera
        self.weight = float(weights)
        self.faces = None if faces is None else np.asarray(faces, dtype=np.intp)
        self.edges = None if edges is None else np.asarray(edges, dtype=np.intp)
        p = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        if len(p) < 2:
            raise ValueError(f"{name}: the outline needs at least 2 points")
        self.pixels = p
        self.tree = cKDTree(p)
        tangent = np.gradient(p, axis=0)
        normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
        # Outward: away from the middle of what the outline encloses (it runs around the
        # head from neck to neck, so the mean of its points is inside).
        if float(np.einsum("ij,ij->", normal, p - p.mean(axis=0))) < 0:
            normal = -normal
        self.normals = normal
        d0 = np.linalg.norm(p - p[0], axis=1)
        d1 = np.linalg.norm(p - p[-1], axis=1)
        self._at_end = (d0 <= end_margin) | (d1 <= end_margin)
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
        self._bin = (arc // float(bin_px)).astype(np.int64)
        self.max_distance = float(max_distance)
        self.reject_factor = reject_factor
        self.keep_distance = float(keep_distance)
        self.selected = np.zeros(0, np.intp)  # candidate indices of the rows
        self.targets = np.zeros((0, 2))
        self.row_normals = np.zeros((0, 2))
        self._updated = False

    def rim(self, world):
        """Indices of the candidates on the contour generator of the posed head."""
        if self.faces is None or self.edges is None:
            return np.arange(len(world))
        f = self.faces
        a, b, c = world[f[:, 0]], world[f[:, 1]], world[f[:, 2]]
        normal = np.cross(b - a, c - a)
        toward = np.asarray(self.camera.toward_camera((a + b + c) / 3.0), dtype=np.float64)
        facing = np.einsum("ij,ij->i", normal, toward) > 0
        e = self.edges[facing[self.edges[:, 2]] != facing[self.edges[:, 3]]]
        mask = np.zeros(len(world), bool)
        mask[e[:, 0]] = True
        mask[e[:, 1]] = True
        return np.flatnonzero(mask)

    def update(self, world):
        rim = self.rim(world)
        proj = self.camera.project(world[rim])
        dist, j = self.tree.query(proj, distance_upper_bound=self.max_distance)
        ok = np.isfinite(dist)
        j = np.where(ok, j, 0)
        ok &= ~self._at_end[j]
        cand = rim[ok]
        jc = j[ok]
        out = np.einsum("ij,ij->i", proj[ok] - self.pixels[jc], self.normals[jc])
        # per bin the outermost candidate (ties: the first)
        b = self._bin[jc]
        top = np.full(int(self._bin[-1]) + 1, -np.inf)
        np.maximum.at(top, b, out)
        win = np.flatnonzero(out >= top[b])
        _, first = np.unique(b[win], return_index=True)
        pick = win[first]
        sel, off = cand[pick], np.abs(out[pick])
        if self.reject_factor is not None and len(off):
            limit = max(self.reject_factor * float(np.median(off)), self.keep_distance)
            keep = off <= limit
            sel, pick = sel[keep], pick[keep]
        self.selected = sel
        self.targets = self.pixels[jc[pick]]
        self.row_normals = self.normals[jc[pick]]
        self._updated = True

    def block(self, world, jacobian=True):
        if not self._updated:
            self.update(world)
        sel = self.selected
        x = world[sel]
        n = self.row_normals
        r = np.einsum("ij,ij->i", self.targets - self.camera.project(x), n) if len(sel) \
            else np.zeros(0)
        w = np.full(len(sel), self.weight)
        sq = float(w @ r**2)
        if not jacobian:
            return _General(None, None, None, None, sq, float(w.sum()), len(sel))
        jac = np.asarray(self.camera.jacobian(x), dtype=np.float64).reshape(len(sel), 2, 3)
        g = np.einsum("ij,ijk->ik", n, jac)  # d(n . P(x)) / dx
        return _General(sel, g, r, w, sq, float(w.sum()), len(sel))

    def residuals(self, world):
        """Signed pixel distances across the outline of the current rows, (k,)."""
        x = world[self.selected]
        return np.einsum("ij,ij->i", self.targets - self.camera.project(x), self.row_normals)

    def pairs(self, world):
        """(candidate indices, pixels) of the current rows, each pixel the foot of the
        vertex's projection on the outline's tangent line (where the row pulls it), for a
        camera refit consistent with this cost."""
        x = world[self.selected]
        proj = self.camera.project(x)
        rn = np.einsum("ij,ij->i", self.targets - proj, self.row_normals)
        return self.selected, proj + rn[:, None] * self.row_normals


class StackedModel:
    """Linear models over the same vertices, one after the other (the global modes, then
    the regional ones), without copying their bases into one (K, V, 3) array: the fit
    only ever needs a few hundred vertices at once, or the displacement of all.

    Attributes
    ----------
    parts : list of LinearModel
    mean : ndarray, shape (V, 3)
    stddev : ndarray, shape (K,)
    names : tuple of str
    gamma : ndarray, shape (G, K) or None
        The parts' Gamma rows side by side (zeros under the other parts' coefficients).
    """

    def __init__(self, parts):
        if not parts:
            raise ValueError("parts: at least one linear model is needed")
        self.parts = list(parts)
        self.mean = self.parts[0].mean
        self.stddev = np.concatenate([p.stddev for p in self.parts])
        self.names = tuple(n for p in self.parts for n in p.names)
        self.sizes = [p.n_coeffs for p in self.parts]
        k = sum(self.sizes)
        rows = []
        start = 0
        for p in self.parts:
            if p.gamma is not None:
                g = np.zeros((p.gamma.shape[0], k))
                g[:, start:start + p.n_coeffs] = p.gamma
                rows.append(g)
            start += p.n_coeffs
        self.gamma = np.vstack(rows) if rows else None

    @property
    def n_coeffs(self):
        return int(self.stddev.shape[0])

    def split(self, coeffs):
        """The coefficients of each part."""
        out, start = [], 0
        for k in self.sizes:
            out.append(coeffs[start:start + k])
            start += k
        return out

    def displacements(self, coeffs):
        """Displacement of every vertex by each part, list of (V, 3)."""
        return [np.tensordot(c, p.basis, axes=1) for c, p in zip(self.split(coeffs),
                                                                  self.parts, strict=True)]

    def slice(self, vertices):
        """(mean (n, 3), basis (K, n, 3)) of a vertex subset."""
        v = np.asarray(vertices, dtype=np.int64)
        basis = np.concatenate([p.basis[:, v] for p in self.parts])
        # C order: fancy indexing along axis 1 leaves another layout, and every product
        # with the slice would pay for it.
        return self.mean[v], np.ascontiguousarray(basis)


class Engine:
    """What the stages of one fit share: the model being fitted, the views, the weights.

    Parameters
    ----------
    lin : StackedModel
        The model the fit changes (global modes, possibly with regional ones after them).
    views : list of ViewData
    outline, outline_faces, outline_edges : ndarray
        Candidate vertices of the head's outline in a profile photo and their mesh (see
        ContourRows).
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

    def __init__(self, lin, views, outline, outline_faces, outline_edges, noise_px, lambda1,
                 lambda2, prior, contour_weight, contour_threshold, fix_gauge):
        self.lin = lin
        self.views = views
        self.outline = np.asarray(outline, dtype=np.int64)
        self.outline_faces = outline_faces
        self.outline_edges = outline_edges
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
        self._slices = _slice_cache(lin)
        # Gamma enters the cost only as Gamma^T Gamma: a factor with one row per
        # coefficient gives the same cost for far fewer rows than three per border vertex.
        self.gamma = None
        if lin.gamma is not None and lambda1 > 0:
            self.gamma = self._slices.get("gamma")
            if self.gamma is None:
                g = np.asarray(lin.gamma, dtype=np.float64)
                evals, evecs = np.linalg.eigh(g.T @ g)
                keep = evals > 1e-12 * max(float(evals[-1]), 1e-300)
                self.gamma = np.sqrt(evals[keep])[:, None] * evecs[:, keep].T
                self._slices["gamma"] = self.gamma

    # ------------------------------------------------------------------ geometry

    def local(self, state, vertices=None):
        """Model-space positions mean + B c, (n, 3) (all vertices if ``vertices`` is None)."""
        if vertices is None:
            return self.lin.mean + sum(self.lin.displacements(state.coeffs))
        mean, basis = self.slice(vertices)
        return mean + np.tensordot(state.coeffs, basis, axes=1)

    def slice(self, vertices):
        """(mean (n, 3), basis (K, n, 3)) of a vertex subset, cached with the model:
        gathering a few hundred vertices from the (K, V, 3) basis costs more than the rest
        of a Gauss-Newton step."""
        v = np.ascontiguousarray(vertices, dtype=np.int64)
        key = v.tobytes()
        hit = self._slices.get(key)
        if hit is None:
            if len(self._slices) > 64:
                self._slices.clear()
            hit = self.lin.slice(v)
            self._slices[key] = hit
        return hit

    def skin_basis32(self, skin):
        """The basis over the skin as float32 (K, 3 S), cached with the model (for the
        per-vertex uncertainty, where display precision is enough)."""
        key = ("f32",) + (np.asarray(skin, dtype=np.int64).tobytes(),)
        hit = self._slices.get(key)
        if hit is None:
            hit = np.concatenate([p.basis[:, skin].reshape(p.n_coeffs, -1).astype(np.float32)
                                  for p in self.lin.parts])
            self._slices[key] = hit
        return hit

    def world(self, state, vertices=None):
        return state.scale * self.local(state, vertices) @ state.rotation.T + state.translation

    def copies_model(self, vertices):
        """A LinearModel over copies of ``vertices`` (row i = vertex ``vertices[i]``), with
        the compressed Gamma: what a shape-ICP over those vertices needs."""
        mean, basis = self.slice(vertices)
        return LinearModel(mean, basis, self.lin.stddev, self.lin.names, self.gamma)

    def problem(self, lin, rows, freeze=(), gauge=None):
        """A ShapeProblem with the fit's priors; ``gauge`` (default: the engine's) says
        whether the head's scale and translation are frozen."""
        fix = self.fix_gauge if gauge is None else gauge
        sim = ("scale", "translation") if fix else ()
        return ShapeProblem(lin, rows, lambda1=self.lambda1, lambda2=self.lambda2,
                            prior=self.prior, freeze=tuple(freeze) + sim)

    def prior_cost(self, coeffs):
        """lambda2^2 |Lambda c|^2 + lambda1^2 |Gamma c|^2 as the shape-ICP counts it."""
        c = np.asarray(coeffs, dtype=np.float64)
        if self.prior == "identity":
            cost = self.lambda2**2 * float(((self.lin.stddev * c) ** 2).sum())
        else:
            cost = self.lambda2**2 * float(c @ c)
        if self.gamma is not None:
            gc = self.gamma @ c
            cost += self.lambda1**2 * float(gc @ gc)
        return cost

    # ------------------------------------------------------------------ cameras

    def use(self, state):
        """Make ``state``'s cameras the views' current cameras."""
        for v in self.views:
            v.camera = state.cameras[v.name]

    def refit_cameras(self, state, extra=None, views=None):
        """Every refittable camera (of ``views``, default all) refitted to the head of
        ``state``: its landmarks plus ``extra[view name]`` = list of (model vertices,
        pixels, weights) (e.g. contour correspondences). Updates ``state.cameras`` and the
        views."""
        extra = extra or {}
        for v in self.views if views is None else views:
            if not v.refit:
                continue
            verts, px, w = [v.vertices], [v.pixels], [v.weights]
            for ev, ep, ew in extra.get(v.name, ()):
                verts.append(ev)
                px.append(ep)
                w.append(ew)
            verts = np.concatenate(verts)
            state.cameras[v.name] = v.camera.refit(self.world(state, verts), np.vstack(px),
                                                   np.concatenate(w))
        self.use(state)

    def init_cameras(self, state, robust_steps=4):
        """Start each refittable camera from the head of ``state`` (the mean head):
        Procrustes of the landmark vertices' projections to the placed points, reweighted
        robustly (Cauchy) so one misplaced landmark does not tilt the start."""
        for v in self.views:
            if not v.refit:
                continue
            x = self.world(state, v.vertices)
            cam = v.camera.refit(x, v.pixels, v.weights)
            for _ in range(robust_steps):
                r = np.linalg.norm(cam.project(x) - v.pixels, axis=1)
                c = max(2.0 * float(np.median(r)), 1e-6)
                cam = v.camera.refit(x, v.pixels, v.weights / (1.0 + (r / c) ** 2))
            state.cameras[v.name] = cam
        self.use(state)

    def joint(self, views, front_weight=1.0, contour=True, landmarks=True):
        """A :class:`Joint` problem over the landmarks and contours of ``views``."""
        return Joint(self, views, front_weight, contour, landmarks)

    # ------------------------------------------------------------------ errors

    def reprojection(self, state, views=None):
        """Per view: landmark residuals (n,) in pixels."""
        out = {}
        for v in self.views if views is None else views:
            px = state.cameras[v.name].project(self.world(state, v.vertices))
            out[v.name] = np.linalg.norm(px - v.pixels, axis=1)
        return out


@dataclass
class _Prepared:
    problem: ShapeProblem
    model: LinearModel
    k: int
    rotation: np.ndarray
    freeze: tuple
    cameras_only: bool


class Joint:
    """Image rows of some views solved jointly for the head and the cameras.

    The shape-ICP knows one similarity and linear modes. To let it move the cameras in the
    same Gauss-Newton step as the head, every group of rows gets its own copies of the
    model vertices it uses, and each refittable camera gets four extra modes that move only
    its copies, within its image plane: the pixel fields of a shift in u, a shift in v, an
    in-plane rotation and a scaling of the photo, lifted to 3-D through the camera's
    Jacobian (pseudo-inverse). For an orthographic camera those span exactly its free
    parameters; the step is then a joint Gauss-Newton step, so the fit converges in a few
    rounds where alternating "head, then cameras" crawls along every motion that a camera
    and the head share. After each step the cameras are refitted exactly
    (``Camera.refit``) and the extra modes reset: they are re-linearised every round.
    """

    def __init__(self, eng, views, front_weight=1.0, contour=True, landmarks=True):
        self.eng = eng
        self.groups = []  # (view, kind, rows)
        orig = []
        off = 0
        for v in views:
            if landmarks and len(v.vertices):
                n = len(v.vertices)
                w = (1.0 if v.side else front_weight) * eng.inv_var * v.weights
                rows = ImageRows(np.arange(off, off + n), v.pixels, v.camera, weights=w,
                                 name=f"landmarks {v.name}")
                self.groups.append((v, "landmarks", rows))
                orig.append(v.vertices)
                off += n
            if contour and v.contour is not None:
                n = len(eng.outline)
                rows = ContourRows(np.arange(off, off + n), v.contour, v.camera,
                                   weights=eng.contour_weight * eng.inv_var,
                                   faces=eng.outline_faces, edges=eng.outline_edges,
                                   max_distance=eng.contour_threshold,
                                   name=f"contour {v.name}")
                self.groups.append((v, "contour", rows))
                orig.append(eng.outline)
                off += n
        if not self.groups:
            raise ValueError("views: no landmarks or contour to fit")
        self._prep = None
        self.orig = np.concatenate(orig)
        self.rows = [g[2] for g in self.groups]
        self.mean, self.basis = eng.slice(self.orig)
        # Gauge: when every camera here is refitted they absorb the head's scale and
        # position; a calibrated camera fixes them instead.
        self.gauge = all(v.refit and v.camera.min_refit_points > 0 for v in views)
        self.mode_views = []
        for v in views:
            if v.refit and v.camera.min_refit_points > 0:
                idx = np.concatenate([r.vertices for gv, _, r in self.groups if gv is v])
                lm = [r.vertices for gv, k, r in self.groups if gv is v and k == "landmarks"]
                self.mode_views.append((v, idx, lm[0] if lm else idx))

    def sync(self, state):
        self.eng.use(state)
        for v, _, rows in self.groups:
            set_camera(rows, state.cameras[v.name])

    def world(self, state):
        """World positions of the copies, (n, 3)."""
        local = self.mean + np.tensordot(state.coeffs, self.basis, axes=1)
        return state.scale * local @ state.rotation.T + state.translation

    def cost(self, state):
        """Weighted squared pixel residuals (correspondences refreshed) plus priors."""
        self.sync(state)
        x = self.world(state)
        total = 0.0
        for _, _, rows in self.groups:
            xs = x[rows.vertices]
            rows.update(xs)
            blocks = rows.block(xs, jacobian=False)
            blocks = blocks if isinstance(blocks, list | tuple) else [blocks]
            total += sum(float(b.sq) for b in blocks)
        return total + self.eng.prior_cost(state.coeffs)

    def contour_pairs(self, state):
        """view name -> [(model vertices, target pixels, weights)] of the current contour
        rows (for the camera refit)."""
        out = {}
        x = None
        for v, kind, rows in self.groups:
            if kind != "contour" or len(rows.selected) == 0:
                continue
            if x is None:
                x = self.world(state)
            sel, px = rows.pairs(x[rows.vertices])
            out.setdefault(v.name, []).append(
                (self.orig[rows.vertices[sel]], px, np.full(len(sel), self.eng.contour_weight)))
        return out

    def refit(self, state):
        """Refit every refittable camera to the head (landmarks + contour pairs)."""
        self.sync(state)
        self.eng.refit_cameras(state, self.contour_pairs(state))
        self.sync(state)

    def contour_residuals(self, state):
        """view name -> pixel distances across the outline of the contour rows at
        ``state`` (correspondences refreshed)."""
        self.sync(state)
        x = self.world(state)
        out = {}
        for v, kind, rows in self.groups:
            if kind != "contour":
                continue
            xs = x[rows.vertices]
            rows.update(xs)
            out[v.name] = np.abs(rows.residuals(xs))
        return out

    def model(self, state):
        """The copies' linear model at ``state``: the fitted modes, then 4 camera modes per
        refittable view (see the class docstring)."""
        eng = self.eng
        x = self.world(state)
        modes = []
        for v, idx, lm in self.mode_views:
            cam = state.cameras[v.name]
            xv = x[idx]
            p = cam.project(xv)
            jac = np.asarray(cam.jacobian(xv), dtype=np.float64).reshape(len(idx), 2, 3)
            d = p - cam.project(x[lm]).mean(axis=0)
            radius = max(float(np.sqrt((d * d).sum(1).mean())), 1e-9)
            fields = np.zeros((4, len(idx), 2))
            fields[0, :, 0] = 1.0
            fields[1, :, 1] = 1.0
            fields[2] = np.stack([-d[:, 1], d[:, 0]], axis=1) / radius
            fields[3] = d / radius
            jjt = np.einsum("nij,nkj->nik", jac, jac)
            pinv = np.einsum("nji,njk->nik", jac, np.linalg.inv(jjt))  # (n, 3, 2)
            lift = np.einsum("nij,fnj->fni", pinv, fields)  # world displacement per unit
            m = np.zeros((4, len(x), 3))
            # model frame (x = s R m + t), one unit of coefficient = _MODE_PIXELS pixels so
            # the shape prior on these coefficients is negligible.
            m[:, idx] = _MODE_PIXELS * (lift @ state.rotation) / state.scale
            modes.append(m)
        lin = eng.lin
        if not modes:
            return LinearModel(self.mean, self.basis, lin.stddev, lin.names, eng.gamma)
        extra = np.concatenate(modes)
        n_extra = extra.shape[0]
        gamma = None
        if eng.gamma is not None:
            gamma = np.hstack([eng.gamma, np.zeros((eng.gamma.shape[0], n_extra))])
        names = tuple(lin.names) + tuple(f"camera {i}" for i in range(n_extra))
        return LinearModel(self.mean, np.concatenate([self.basis, extra]),
                           np.concatenate([lin.stddev, np.full(n_extra, 1e-9)]), names, gamma)

    def prepare(self, state, freeze=(), cameras_only=False):
        """The shape-ICP problem over the copies with the camera modes linearised at
        ``state`` (reused while the head turns little: building it copies the basis)."""
        model = self.model(state)
        k = len(state.coeffs)
        active = np.arange(k, model.n_coeffs) if cameras_only else None
        if cameras_only:
            freeze = tuple(freeze) + ("rotation",)
        problem = ShapeProblem(model, self.rows, lambda1=self.eng.lambda1,
                               lambda2=self.eng.lambda2, prior=self.eng.prior,
                               freeze=tuple(freeze) + (("scale", "translation")
                                                       if self.gauge else ()),
                               active=active)
        return _Prepared(problem, model, k, state.rotation.copy(), tuple(freeze),
                         cameras_only)

    def _solve(self, prep, state, iterations):
        start = np.zeros(prep.model.n_coeffs)
        start[:prep.k] = state.coeffs
        self.sync(state)
        return prep.problem.solve(scale=state.scale, rotation=state.rotation,
                                  translation=state.translation, coeffs=start,
                                  max_iterations=iterations, tolerance=0.0, sigma=1.0)

    def step(self, state, freeze=(), inner=2, cameras_only=False, prep=None):
        """One joint Gauss-Newton round (``inner`` shape-ICP steps), then the cameras.

        The step moves each refittable camera through its modes; the camera is then
        refitted to what the step predicted: the new head's copies seen where the
        old camera saw them displaced by the modes. For an orthographic camera that is
        exactly the similarity the step chose (any camera kind gets its closest match),
        so camera and head stay one consistent Gauss-Newton step. Refittable cameras of
        views outside this problem are refitted to their landmarks.

        ``prep`` (from :meth:`prepare`) is reused when given; it is rebuilt when the head
        has turned by more than about 3 degrees since (its camera modes would be stale).
        """
        if prep is None or prep.freeze != tuple(freeze) or \
                prep.cameras_only != cameras_only or \
                np.abs(state.rotation - prep.rotation).max() > 0.05:
            prep = self.prepare(state, freeze, cameras_only)
        fit = self._solve(prep, state, inner)
        k, model = prep.k, prep.model
        new = state.copy()
        new.rotation, new.coeffs = fit.rotation, fit.coeffs[:k].copy()
        new.scale, new.translation = fit.scale, fit.translation
        if self.mode_views:
            full = model.mean + np.tensordot(fit.coeffs, model.basis, axes=1)
            head = self.mean + np.tensordot(new.coeffs, self.basis, axes=1)
            full = new.scale * full @ new.rotation.T + new.translation
            head = new.scale * head @ new.rotation.T + new.translation
            for v, idx, _ in self.mode_views:
                old = state.cameras[v.name]
                new.cameras[v.name] = old.refit(head[idx], old.project(full[idx]))
        inside = {v.name for v, _, _ in self.groups}
        outside = [v for v in self.eng.views if v.name not in inside]
        if outside:
            self.eng.refit_cameras(new, views=outside)
        self.sync(new)
        self._prep = prep
        return new

    def run(self, state, freeze=(), max_outer=20, inner=2, tolerance=1e-4,
            cameras_only=False, patience=2):
        """Rounds of :meth:`step` until the cost changes by less than ``tolerance``
        (relative) or has not reached a new low for ``patience`` rounds; returns the state
        of the lowest cost and the cost history.

        The contour's rows are a choice (which vertices form the outline), so near the end
        the choice can flip back and forth between two sets and the cost with it; the
        lowest one is kept.
        """
        best_cost = self.cost(state)
        best = state
        history = [best_cost]
        since = 0
        self._prep = None
        for _ in range(max(int(max_outer), 1)):
            state = self.step(state, freeze, inner, cameras_only, self._prep)
            cost = self.cost(state)
            history.append(cost)
            if cost < best_cost:
                since = 0 if cost < best_cost * (1.0 - tolerance) else since + 1
                best, best_cost = state, cost
            else:
                since += 1
            if abs(history[-2] - history[-1]) <= tolerance * history[-2] or since >= patience:
                break
        self.sync(best)
        self.cost(best)  # leave the correspondences at the returned state
        return best, history

    def covariance(self, state):
        """Posterior covariance (K, K) of the fitted coefficients at ``state``: the inverse
        of the normal matrix with pose and camera modes free (marginalised), rows weighted
        1 / noise^2 so sigma = 1."""
        prep = self.prepare(state)
        fit = self._solve(prep, state, 0)
        return fit.coeff_covariance[:prep.k, :prep.k]
