"""The machinery the fit's stages share: the views of a case as arrays, the rows they give
the shape-ICP, and the joint solve of head and cameras.

Each photo has its own camera; its free parameters enter the joint Gauss-Newton step as
extra modes of the shape-ICP (:class:`Joint`), one block per camera:

- orthographic (and any kind the fit does not know): the 2-D similarity of the photo
  (shift, in-plane rotation, scale), moved exactly by ``Camera.refit`` after each step;
- pinhole (``solver/pinhole.py``): its own parameters (rotation, centre, log focal
  length), moved exactly; a focal prior (EXIF) enters the step as the prior of its mode;
- DLT: the 11 directions of its projection matrix, refitted after each step;
- a mirror view (one camera and a flat mirror, seed 001 ch. 3): no camera of its own. It
  is the real camera reflected in the mirror plane (:func:`mirror_camera`), so its rows
  move with the real camera's parameters and with three of the plane's (the tilt of its
  normal, its offset).

Gauge (:meth:`Engine.gauge`): photos whose cameras are all free cannot tell how large the
head is or where it is, only how it looks; then the head's scale stays 1 and its
translation 0, and the cameras absorb both (the identity modes carry the head's size).
When every free camera is perspective the head's rotation is kept too: the world is the
head's frame and the cameras stand around it. One calibrated perspective camera (alone or
with a mirror) cannot tell the head's size from its distance either: the head's scale
stays 1 (the model's size), which also fixes the mirror's distance.
"""

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from ..cameras.base import Camera, OrthographicCamera
from ..cameras.dlt import DLTCamera
from ..cameras.mirror import MirrorPlane, estimate_mirror
from ..cameras.pinhole import FREE_FOCAL_POINTS, PinholeCamera, pixel_by_camera_point
from ..model.linear_model import LinearModel
from .shape_icp import CameraRows, ImageRows, ScalarRows, ShapeProblem, rotation_from_vector, skew

# Pixels one unit of a camera mode's coefficient moves the photo (see Joint): large, so
# the shape prior the shape-ICP puts on every coefficient hardly restrains the cameras
# (a 10 px correction costs 0.01), yet it settles the split where a calibrated camera
# leaves the head's position and a refitted camera's offset equally free.
_MODE_PIXELS = 100.0

# Fractions of a joint step tried when the whole step raises the cost (perspective cameras).
_DAMPING = (0.5, 0.25, 0.1)


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
        The traced outline's points, as placed.
    refit : bool
        Whether the fit may change this camera (False for a mirror view: its camera
        follows the real camera and the mirror plane).
    mirror_of : str or None
        The view whose camera, reflected in a mirror plane the fit estimates, is this
        view's camera (None: an ordinary view, or a mirror view whose camera is given and
        kept).

    A view's outline candidates are not stored here: they depend on the head they were
    found on, so each stage passes its own to :meth:`Engine.joint` (``outlines``).
    """

    name: str
    camera: Camera | None
    names: list
    vertices: np.ndarray
    pixels: np.ndarray
    weights: np.ndarray
    side: bool
    contour: np.ndarray | None = None
    refit: bool = True
    mirror_of: str | None = None


@dataclass
class State:
    """Head pose, coefficients, cameras and mirror planes (view name -> MirrorPlane of the
    mirror views): ``world = scale * R (mean + B c) + t``."""

    rotation: np.ndarray
    coeffs: np.ndarray
    cameras: dict
    scale: float = 1.0
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    planes: dict = field(default_factory=dict)

    def copy(self):
        return replace(self, rotation=self.rotation.copy(), coeffs=self.coeffs.copy(),
                       cameras=dict(self.cameras), translation=self.translation.copy(),
                       planes=dict(self.planes))


def is_side_camera(camera, at=None):
    """True when the camera looks along the world x axis (the head's left-right axis) at
    the point ``at`` (3,) (default the origin)."""
    p = np.zeros((1, 3)) if at is None else np.asarray(at, dtype=np.float64).reshape(1, 3)
    d = np.asarray(camera.toward_camera(p), dtype=np.float64).reshape(3)
    return abs(d[0]) > 0.7 * np.linalg.norm(d)


def is_perspective(camera):
    """True for a central projection (pinhole, DLT): rays through one centre."""
    return isinstance(camera, PinholeCamera | DLTCamera)


def mirror_camera(camera, plane):
    """The camera of a mirror view: ``camera`` reflected in ``plane`` (seed 001 eq. 3.11-
    3.13), which maps a physical point to where its mirror image appears in the photo.

    Parameters
    ----------
    camera : PinholeCamera or DLTCamera
        The real camera.
    plane : MirrorPlane

    Returns
    -------
    PinholeCamera or DLTCamera
        Same kind and intrinsics; rotation R M (determinant -1), centre reflected.
    """
    if isinstance(camera, PinholeCamera):
        centre = plane.reflect_points(camera.centre[None, :])[0]
        return camera.replaced(rotation=camera.rotation @ plane.matrix, centre=centre)
    if isinstance(camera, DLTCamera):
        return camera.transformed(plane.homogeneous)
    raise ValueError(f"a mirror view needs a perspective (pinhole or DLT) camera, got "
                     f"{type(camera).__name__}: a parallel projection cannot place a mirror")


def as_dlt(camera):
    """A DLTCamera for ``camera`` (a pinhole camera converted; a lens term the DLT cannot
    match is dropped)."""
    if isinstance(camera, DLTCamera):
        return camera
    if isinstance(camera, PinholeCamera):
        try:
            return camera.to_dlt()
        except ValueError:
            return camera.replaced(k1=0.0).to_dlt()
    raise ValueError(f"expected a perspective camera, got {type(camera).__name__}")


# ----------------------------------------------------------------------------- camera modes
# Pixel fields: how the projections of points move per unit of a camera's (or a mirror
# plane's) parameter, shape (P, n, 2). The joint step lifts them into extra shape modes.


def _plane_axes(normal):
    """Two unit vectors completing ``normal`` to an orthonormal frame."""
    a = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(normal, a)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(normal, e1)


def plane_fields(real, plane, points):
    """Pixel fields (3, n, 2) of the mirror images of ``points`` (n, 3) seen by ``real``,
    per unit tilt of the plane's normal along its two axes (radians) and per metre of its
    offset (see :func:`moved_plane`)."""
    x = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    n = plane.normal
    e1, e2 = _plane_axes(n)
    dist = x @ n - plane.offset
    jac = np.asarray(real.jacobian(plane.reflect_points(x)), dtype=np.float64)
    d = np.empty((3, len(x), 3))  # d(reflected point) / d(parameter)
    for j, e in enumerate((e1, e2)):
        d[j] = -2.0 * ((x @ e)[:, None] * n + dist[:, None] * e)
    d[2] = 2.0 * n
    return np.einsum("kij,pkj->pki", jac.reshape(len(x), 2, 3), d)


def moved_plane(plane, step):
    """The plane moved by ``step`` (3,): normal tilted by step[0] along the first axis of
    :func:`_plane_axes` and step[1] along the second, offset + step[2] metres."""
    n = plane.normal
    e1, e2 = _plane_axes(n)
    m = n + step[0] * e1 + step[1] * e2
    return MirrorPlane(m / np.linalg.norm(m), float(plane.offset + step[2]))


def pinhole_fields(camera, points, focal=True):
    """Pixel fields (6 or 7, n, 2) of a PinholeCamera's parameters at world points (n, 3):
    a rotation increment in the camera frame (``R <- rot(w) R``, radians, 3), the centre
    (metres, 3) and, with ``focal``, the log focal length (k1 included)."""
    x = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    rot = camera.rotation
    xc = (x - camera.centre) @ rot.T
    f, k1 = camera.focal_px, camera.k1
    g, p = pixel_by_camera_point(xc, f, k1)
    rho2 = (p * p).sum(axis=1)
    by_rot = -np.einsum("nij,njk->nik", g, skew(xc))  # x_c += w x x_c
    by_centre = -g @ rot
    out = [by_rot[:, :, i] for i in range(3)] + [by_centre[:, :, i] for i in range(3)]
    if focal:
        out.append(f * p * (1.0 + k1 * rho2)[:, None])
    return np.stack(out)


def moved_pinhole(camera, step):
    """The camera moved by ``step`` (6 or 7,) in the order of :func:`pinhole_fields`; the
    focal length is kept inside ``focal_range_mm``."""
    f = camera.focal_px
    if len(step) > 6:
        f = f * float(np.exp(np.clip(step[6], -1.0, 1.0)))
        if camera.focal_range_mm is not None:
            ppm = camera.px_per_mm(camera.size)
            f = float(np.clip(f, camera.focal_range_mm[0] * ppm, camera.focal_range_mm[1] * ppm))
    return camera.replaced(focal_px=f, rotation=rotation_from_vector(step[:3]) @ camera.rotation,
                           centre=camera.centre + step[3:6])


def dlt_fields(camera, points):
    """Pixel fields (12, n, 2) of the 12 entries of a DLT matrix (lens terms left out)."""
    x = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    pm = camera.matrix
    xt = np.column_stack([x, np.ones(len(x))])
    h = xt @ pm.T
    w = h[:, 2]
    q = h[:, :2] / w[:, None]
    out = np.zeros((12, len(x), 2))
    for j in range(4):
        a = xt[:, j] / w
        out[j, :, 0] = a
        out[4 + j, :, 1] = a
        out[8 + j] = -q * a[:, None]
    return out


def similarity_fields(camera, points, centre_points):
    """Pixel fields (4, n, 2) of a 2-D similarity of the photo: shifts in u and v, and a
    rotation and a scaling about the projection of ``centre_points``' mean (both
    normalised to one pixel at their RMS radius)."""
    p = camera.project(points)
    d = p - camera.project(centre_points).mean(axis=0)
    radius = max(float(np.sqrt((d * d).sum(1).mean())), 1e-9)
    fields = np.zeros((4, len(p), 2))
    fields[0, :, 0] = 1.0
    fields[1, :, 1] = 1.0
    fields[2] = np.stack([-d[:, 1], d[:, 0]], axis=1) / radius
    fields[3] = d / radius
    return fields


def focal_prior(camera, n_points):
    """(log f0 in pixels, relative sigma) of a pinhole camera whose focal length is free in
    the fit (``free_focal`` and at least FREE_FOCAL_POINTS points) and has a prior, else
    None."""
    if not isinstance(camera, PinholeCamera) or not focal_free(camera, n_points) \
            or camera.focal_prior is None:
        return None
    mm, sigma = camera.focal_prior
    return float(np.log(mm * camera.px_per_mm(camera.size))), float(sigma)


def focal_free(camera, n_points):
    """Whether the fit moves a pinhole camera's focal length (as ``PinholeCamera.refit``
    does: ``free_focal`` and enough points)."""
    return bool(camera.free_focal) and n_points >= FREE_FOCAL_POINTS


def refit_plane(real, plane, points, pixels, weights, iterations=10):
    """The mirror plane that best maps ``points`` (n, 3) onto ``pixels`` (n, 2) through the
    real camera, from ``plane`` (Gauss-Newton on the tilt and offset, weighted squared
    pixels; a step that does not lower the cost is halved).

    Returns
    -------
    MirrorPlane
    """
    x = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    q = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    if np.count_nonzero(w) < 2:
        return plane

    def cost(pl):
        r = q - real.project(pl.reflect_points(x))
        return float(w @ (r * r).sum(axis=1)), r

    c0, r = cost(plane)
    for _ in range(iterations):
        jac = plane_fields(real, plane, x)  # (3, n, 2)
        a = np.einsum("pni,qni,n->pq", jac, jac, w)
        b = np.einsum("pni,ni,n->p", jac, r, w)
        try:
            step = np.linalg.solve(a + 1e-12 * np.trace(a) * np.eye(3), b)
        except np.linalg.LinAlgError:
            break
        for _ in range(6):
            cand = moved_plane(plane, step)
            c1, r1 = cost(cand)
            if c1 < c0:
                break
            step = 0.5 * step
        else:
            break
        done = c0 - c1 <= 1e-10 * c0
        plane, c0, r = cand, c1, r1
        if done:
            break
    return plane


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


# Outline rows are always kept within this many sigmas of the placement noise.
CONTOUR_KEEP_SIGMAS = 3.0
# An outline point's normal comes from the outline this many pixels either side of it.
_NORMAL_SPAN_PX = 10.0


class ContourRows(CameraRows):
    """Profile-line rows (thesis §4.4.1): each traced outline point pulled onto the model's
    outline in the photo.

    The model's outline is the silhouette of the posed mesh: the projection of its rim,
    the edges between a triangle facing the camera and one facing away. It is not a fixed
    set of vertices (the brows, the nose's wings or the sides of the neck stick out beyond
    the midsagittal profile, and a turned head shows other vertices), so ``vertices`` are
    candidates (vertices whose normals face roughly across the viewing direction), and
    every update finds the rim among their triangles anew.

    One row per traced point q (the data, not the model, gives the rows: a point the artist
    placed is one measurement with its own error, while a line joining two of them cuts
    every bend of the head's outline, by up to 2 px at the nose or the chin when they are
    15 px apart). The line through q along the outline's outward normal n crosses the
    projected rim edges; the outermost crossing is the silhouette there (a rim hidden
    behind another, e.g. the midline under the brows, lies inside). It lies on an edge
    (a, b) at a fraction t, and the row is ``w (n . (q - ((1 - t) P(x_a) + t P(x_b))))^2``:
    across the outline is what one point measures; along it the silhouette may slide.

    Points without a crossing within ``max_distance`` pixels get no row, nor do those
    farther than ``reject_factor`` times the median distance (but never below
    ``keep_distance``): once the fit is close, that trims the points the mesh cannot follow
    (an ear's notch, hair, a tracing that cut a corner); kept, they pull the head out of
    shape to close a gap that is not noise.

    A point weighs ``weights`` when it stands for at least ``spacing_px`` of outline (half
    the way to each neighbour), less when the points are denser: a hand-drawn stroke
    wobbles over a few pixels, so its many close points are not many measurements.

    Parameters
    ----------
    vertices : array_like of int, shape (n,)
    pixels : array_like, shape (m, 2)
        The traced outline's points in drawing order, as placed (not densified).
    camera : Camera
    weights : float
        Weight of one point.
    faces : ndarray, shape (F, 3)
        Triangles among the candidates (indices into ``vertices``).
    edges : ndarray, shape (E, 4)
        Edges shared by two of those triangles: (vertex a, vertex b, face 1, face 2).
    max_distance, reject_factor, keep_distance, spacing_px : float
    name : str
    """

    def __init__(self, vertices, pixels, camera, weights=1.0, faces=None, edges=None,
                 max_distance=20.0, reject_factor=3.0, keep_distance=3.0, spacing_px=6.0,
                 name="contour"):
        self.name = name
        self.vertices = np.asarray(vertices, dtype=np.intp)
        self.camera = camera
        self.weight = float(weights)
        if faces is None or edges is None:
            raise ValueError(f"{name}: the outline candidates need their faces and edges")
        self.faces = np.asarray(faces, dtype=np.intp).reshape(-1, 3)
        self.edges = np.asarray(edges, dtype=np.intp).reshape(-1, 4)
        p = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        if len(p):  # a point placed twice is one point
            p = p[np.concatenate([[True], np.any(np.diff(p, axis=0) != 0, axis=1)])]
        if len(p) < 2:
            raise ValueError(f"{name}: the outline needs at least 2 distinct points")
        self.pixels = p
        self.tree = cKDTree(p)
        seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
        arc = np.concatenate([[0.0], np.cumsum(seg)])
        # Normals from the outline 10 px either side: a dense stroke's neighbours are too
        # close to give a direction through their placement noise.
        ahead = np.stack([np.interp(arc + _NORMAL_SPAN_PX, arc, p[:, k]) for k in (0, 1)], 1)
        behind = np.stack([np.interp(arc - _NORMAL_SPAN_PX, arc, p[:, k]) for k in (0, 1)], 1)
        tangent = ahead - behind
        normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
        # Outward: away from the middle of what the outline encloses (it runs around the
        # head from neck to neck, so the mean of its points is inside).
        if float(np.einsum("ij,ij->", normal, p - p.mean(axis=0))) < 0:
            normal = -normal
        self.normals = normal
        share = np.zeros(len(p))
        share[:-1] += seg / 2.0
        share[1:] += seg / 2.0
        self.point_weights = self.weight * np.minimum(1.0, share / float(spacing_px))
        self.max_distance = float(max_distance)
        self.reject_factor = reject_factor
        self.keep_distance = float(keep_distance)
        self.points = np.zeros(0, np.intp)  # traced point of each row
        self.cap = self.max_distance  # residual a point without a row counts as (pixels)
        self.ends = np.zeros((0, 2), np.intp)  # candidate indices of its rim edge
        self.fractions = np.zeros(0)  # t along that edge
        self._updated = False
        self._last = None  # (camera, world) of the last update

    @property
    def selected(self):
        """The candidate nearer each row's silhouette point, (k,)."""
        return np.where(self.fractions < 0.5, self.ends[:, 0], self.ends[:, 1])

    def rim(self, world):
        """Edges (a, b) among the candidates on the contour generator of the posed head,
        (E', 2) candidate indices."""
        f = self.faces
        a, b, c = world[f[:, 0]], world[f[:, 1]], world[f[:, 2]]
        normal = np.cross(b - a, c - a)
        toward = np.asarray(self.camera.toward_camera((a + b + c) / 3.0), dtype=np.float64)
        facing = np.einsum("ij,ij->i", normal, toward) > 0
        return self.edges[facing[self.edges[:, 2]] != facing[self.edges[:, 3]], :2]

    def update(self, world):
        # The same head through the same camera again (a cost evaluation, then the next
        # solve's first build): the outline found last time stands.
        last = self._last
        if last is not None and last[0] is self.camera and last[1].shape == world.shape \
                and np.abs(last[1] - world).max(initial=0.0) < 1e-12:
            return
        self._last = (self.camera, world.copy())
        e = self.rim(world)
        points, ends, frac = np.zeros(0, np.intp), np.zeros((0, 2), np.intp), np.zeros(0)
        cap = self.max_distance
        if len(e):
            used, inv = np.unique(e, return_inverse=True)
            ends = self.camera.project(world[used])[inv.reshape(-1, 2)]  # (E', 2, 2)
            a, d = ends[:, 0], ends[:, 1] - ends[:, 0]
            # Edges whose middle is within reach of a point (max_distance plus the longest
            # half edge), as flat (point, edge) pairs.
            reach = self.max_distance + 0.5 * float(np.linalg.norm(d, axis=1).max())
            near = self.tree.sparse_distance_matrix(cKDTree(a + 0.5 * d), reach,
                                                    output_type="ndarray")
            pi, ei = near["i"].astype(np.intp), near["j"].astype(np.intp)
            q, n = self.pixels[pi], self.normals[pi]
            # q + s n = a + t d  (2-D cross products)
            den = d[ei, 0] * n[:, 1] - d[ei, 1] * n[:, 0]
            ok = np.abs(den) > 1e-12
            den = np.where(ok, den, 1.0)
            qa = q - a[ei]
            t = (qa[:, 0] * n[:, 1] - qa[:, 1] * n[:, 0]) / den
            s = (qa[:, 0] * d[ei, 1] - qa[:, 1] * d[ei, 0]) / den
            ok &= (t >= 0.0) & (t <= 1.0) & (np.abs(s) <= self.max_distance)
            pi, ei, t, s = pi[ok], ei[ok], t[ok], s[ok]
            # per point the outermost crossing (largest s)
            order = np.lexsort((-s, pi))
            first = order[np.concatenate([[True], pi[order][1:] != pi[order][:-1]])] \
                if len(order) else order
            points, ends, frac, off = pi[first], e[ei[first]], t[first], np.abs(s[first])
            if self.reject_factor is not None and len(off):
                limit = max(self.reject_factor * float(np.median(off)), self.keep_distance)
                keep = off <= limit
                points, ends, frac = points[keep], ends[keep], frac[keep]
                cap = min(limit, self.max_distance)
        self.points, self.ends, self.fractions, self.cap = points, ends, frac, cap
        self._updated = True

    def unmatched_cost(self):
        """What the traced points without a row add to the cost: ``w cap^2`` each, as if
        they lay at the cut-off (a truncated quadratic). Without it a head that loses rows
        lowers its cost by the rows it dropped, and the fit, which keeps the lowest cost,
        drifts to heads whose outline misses awkward points: on two perspective photos such
        heads cost less than the fit started from the true head but were 0.1-0.3 mm
        further from it."""
        missing = np.ones(len(self.pixels), bool)
        missing[self.points] = False
        return float(self.point_weights[missing].sum()) * self.cap**2

    @property
    def targets(self):
        """The traced points of the rows, (k, 2) pixels."""
        return self.pixels[self.points]

    @property
    def row_normals(self):
        """The outline's outward normals at them, (k, 2)."""
        return self.normals[self.points]

    def _silhouette(self, world):
        """The rows' silhouette points, (k, 2) pixels."""
        if not len(self.points):
            return np.zeros((0, 2))
        t = self.fractions[:, None]
        return (1.0 - t) * self.camera.project(world[self.ends[:, 0]]) \
            + t * self.camera.project(world[self.ends[:, 1]])

    def block(self, world, jacobian=True):
        if not self._updated:
            self.update(world)
        k = len(self.points)
        n = self.row_normals
        r = self.residuals(world)
        w = self.point_weights[self.points]
        sq = float(w @ r**2)
        if not jacobian:
            return ScalarRows(None, None, None, None, sq, float(w.sum()), k)
        if k == 0:  # no traced point meets the head's outline (yet)
            return ScalarRows(self.ends, np.zeros((0, 2, 3)), r, w, 0.0, 0.0, 0)
        t = self.fractions[:, None]
        jac = np.asarray(self.camera.jacobian(world[self.ends.reshape(-1)]),
                         dtype=np.float64).reshape(k, 2, 2, 3)
        # d(n . silhouette point) / d(x_a, x_b)
        g = np.einsum("ij,icjk->ick", n, jac) * np.concatenate([1.0 - t, t], axis=1)[..., None]
        return ScalarRows(self.ends, g, r, w, sq, float(w.sum()), k)

    def residuals(self, world):
        """Signed pixel distances across the outline of the current rows, (k,): positive
        where the traced point lies outside the model's silhouette."""
        return np.einsum("ij,ij->i", self.targets - self._silhouette(world), self.row_normals)

    def pairs(self, world):
        """(candidate indices, pixels) of the current rows for a camera refit consistent
        with this cost: each row's nearer edge end, and where the row pulls it (its
        projection moved across the outline by the row's residual)."""
        sel = self.selected
        if not len(sel):
            return sel, np.zeros((0, 2))
        r = self.residuals(world)
        return sel, self.camera.project(world[sel]) + r[:, None] * self.row_normals


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
        # take, not basis[:, v]: fancy indexing along axis 1 leaves another layout, which
        # every product with the slice would pay for (or a second copy to mend it).
        return self.mean[v], np.concatenate([np.take(p.basis, v, axis=1) for p in self.parts])


class Engine:
    """What the stages of one fit share: the model being fitted, the views, the weights.

    Parameters
    ----------
    lin : StackedModel
        The model the fit changes (global modes, possibly with regional ones after them).
    views : list of ViewData
    outline, outline_faces, outline_edges : ndarray
        Candidate vertices of the head's outline in an orthographic profile photo and their
        mesh (see ContourRows): what a view's contour rows use unless the stage gives the
        view candidates of its own (``outlines`` of :meth:`joint`).
    noise_px : float
        Landmark noise the weights assume (rows are weighted 1 / noise^2, so lambda2 = 1 is
        the Bayesian prior for standard-normal coefficients).
    lambda1, lambda2 : float
        Smoothness (per millimetre of region disagreement) and prior weights.
    prior : str
    contour_weight : float
    contour_threshold : float
        Largest pixel distance of a contour correspondence.
    """

    def __init__(self, lin, views, outline, outline_faces, outline_edges, noise_px, lambda1,
                 lambda2, prior, contour_weight, contour_threshold):
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
        # Outline rows within this of the traced line are always kept (ContourRows): three
        # sigmas of the placement noise.
        self.contour_keep = CONTOUR_KEEP_SIGMAS * noise_px
        self._by_name = {v.name: v for v in views}
        self.fixed_similarity = self.gauge(views)
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

    # ------------------------------------------------------------------ views

    def view(self, name):
        """The ViewData called ``name``."""
        return self._by_name[name]

    def real_view(self, view):
        """The view whose camera ``view``'s camera is (itself unless a mirror view)."""
        return self._by_name[view.mirror_of] if view.mirror_of is not None else view

    def camera_moves(self, view):
        """Whether the fit moves the camera of ``view`` (a mirror view's: its real one)."""
        real = self.real_view(view)
        return bool(real.refit and real.camera is not None
                    and real.camera.min_refit_points > 0)

    def mirrors_of(self, view):
        """The mirror views whose camera is ``view``'s camera reflected."""
        return [u for u in self.views if u.mirror_of == view.name]

    def gauge(self, views):
        """The head's similarity parameters the views cannot determine, to keep fixed:

        - every camera free: ("scale", "translation"), plus "rotation" when every camera is
          perspective (an orthographic camera keeps its viewing direction, which fixes the
          head's turn; free perspective cameras turn with the head);
        - a calibrated orthographic camera, or two calibrated perspective ones, measure
          the head: nothing;
        - else (one calibrated perspective camera, with or without a mirror): ("scale",):
          size and distance trade off along the rays; the model's size decides.
        """
        views = list(views)
        fixed = [v for v in views if not self.camera_moves(v)]
        if not fixed:
            out = ("scale", "translation")
            if views and all(is_perspective(self.real_view(v).camera) for v in views):
                out += ("rotation",)
            return out
        if any(not is_perspective(self.real_view(v).camera) for v in fixed):
            return ()
        if sum(1 for v in fixed if v.mirror_of is None) >= 2:
            return ()
        return ("scale",)

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
        """A ShapeProblem with the fit's priors; ``gauge`` (default: the engine's, see
        :meth:`gauge`) are the head's similarity parameters kept fixed besides ``freeze``."""
        fix = self.fixed_similarity if gauge is None else tuple(gauge)
        return ShapeProblem(lin, rows, lambda1=self.lambda1, lambda2=self.lambda2,
                            prior=self.prior, freeze=tuple(freeze) + fix)

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

    def camera_prior_cost(self, state, views=None):
        """The focal-length priors of the free pinhole cameras (of ``views``' real cameras,
        default all): sum of ((log f - log f0) / sigma)^2, the cost ``PinholeCamera.refit``
        adds for points weighted as inverse pixel variances."""
        total = 0.0
        seen = set()
        for v in self.views if views is None else views:
            real = self.real_view(v)
            if real.name in seen or not self.camera_moves(real) or self.lambda2 <= 0:
                continue
            seen.add(real.name)
            cam = state.cameras[real.name]
            prior = focal_prior(cam, self.landmark_count(real))
            if prior is not None:
                total += ((np.log(cam.focal_px) - prior[0]) / prior[1]) ** 2
        return float(total)

    def landmark_count(self, view):
        """Weighted landmarks a real camera is seen through: its own and its mirror
        views'."""
        return int(sum(np.count_nonzero(u.weights) for u in [view] + self.mirrors_of(view)))

    # ------------------------------------------------------------------ cameras

    def use(self, state):
        """Make ``state``'s cameras the views' current cameras."""
        for v in self.views:
            v.camera = state.cameras[v.name]

    def finish_views(self, state):
        """After the cameras are placed: which views look along the head's left-right axis
        (at the head's landmarks)."""
        self.use(state)
        verts = np.concatenate([v.vertices for v in self.views])
        centre = self.world(state, verts).mean(axis=0)
        axis = state.rotation[:, 0]
        for v in self.views:
            d = np.asarray(v.camera.toward_camera(centre[None, :]), dtype=np.float64)[0]
            v.side = bool(abs(d @ axis) > 0.7 * np.linalg.norm(d))

    def _camera_points(self, state, view, extra):
        """(world points, pixels, weights) a real camera is refitted to: its landmarks,
        ``extra`` pairs, and its mirror views' landmarks and pairs with the points
        reflected in their planes (the real camera sees the reflection where the mirror
        image is)."""
        pts, px, w = [], [], []
        for u in [view] + self.mirrors_of(view):
            x = [self.world(state, u.vertices)]
            q, ww = [u.pixels], [u.weights]
            for ev, ep, ew in extra.get(u.name, ()):
                x.append(self.world(state, ev))
                q.append(ep)
                ww.append(ew)
            x = np.concatenate(x)
            if u is not view:
                x = state.planes[u.name].reflect_points(x)
            pts.append(x)
            px.append(np.vstack(q))
            w.append(np.concatenate(ww))
        return np.concatenate(pts), np.vstack(px), self.inv_var * np.concatenate(w)

    def refit_cameras(self, state, extra=None, views=None):
        """Every free camera (of ``views``, default all) refitted to the head of
        ``state``: its landmarks plus ``extra[view name]`` = list of (model vertices,
        pixels, weights) (e.g. contour correspondences), with weights read as inverse
        pixel variances (times 1 / noise^2) so a pinhole camera's focal prior weighs as it
        should. A real camera also fits its mirror views' points; then each mirror plane
        is refitted with its real camera kept. Updates ``state.cameras`` (and
        ``state.planes``) and the views."""
        extra = extra or {}
        todo = list(self.views if views is None else views)
        names = {v.name for v in todo}
        for v in todo:
            if not v.refit or v.mirror_of is not None:
                continue
            x, q, w = self._camera_points(state, v, extra)
            state.cameras[v.name] = v.camera.refit(x, q, w)
            names.update(u.name for u in self.mirrors_of(v))
        for u in self.views:
            if u.mirror_of is None or u.name not in names:
                continue
            real = state.cameras[u.mirror_of]
            x, q, w = [self.world(state, u.vertices)], [u.pixels], [u.weights]
            for ev, ep, ew in extra.get(u.name, ()):
                x.append(self.world(state, ev))
                q.append(ep)
                w.append(ew)
            plane = refit_plane(real, state.planes[u.name], np.concatenate(x), np.vstack(q),
                                np.concatenate(w))
            state.planes[u.name] = plane
            state.cameras[u.name] = mirror_camera(real, plane)
        self.use(state)

    def init_cameras(self, state, robust_steps=4):
        """Start each free camera from the head of ``state`` (the mean head): fitted to the
        landmark vertices' placed pixels, reweighted robustly (Cauchy) so one misplaced
        landmark does not tilt the start; a pinhole camera's pose only (its focal length
        fitted to the mean head would bend to the mean head's shape; the joint rounds fit
        it with the shape). Then each mirror view's plane from the landmarks seen both
        directly and in the mirror (:meth:`initial_plane`)."""
        for v in self.views:
            if not v.refit or v.mirror_of is not None:
                continue
            x = self.world(state, v.vertices)
            w = self.inv_var * v.weights
            probe = _pose_only(v.camera)
            cam = probe.refit(x, v.pixels, w)
            for _ in range(robust_steps):
                r = np.linalg.norm(cam.project(x) - v.pixels, axis=1)
                c = max(2.0 * float(np.median(r)), 1e-6)
                cam = probe.refit(x, v.pixels, w / (1.0 + (r / c) ** 2))
            if probe is not v.camera:
                cam = v.camera.replaced(rotation=cam.rotation, centre=cam.centre)
            state.cameras[v.name] = cam
        for v in self.views:
            if v.mirror_of is not None:
                state.planes[v.name] = self.initial_plane(state, v)
                state.cameras[v.name] = mirror_camera(state.cameras[v.mirror_of],
                                                      state.planes[v.name])
        self.use(state)

    def initial_plane(self, state, view):
        """A mirror view's plane from its real camera (seed 001 §3.2.2,
        ``solver.mirror.estimate_mirror``): the normal from the viewing rays of the
        landmarks seen both directly and in the mirror (the file names both by the
        subject's true side, so pairs match by name), the distance from a length on the
        current head: the two paired landmarks farthest apart.

        Raises
        ------
        ValueError
            Fewer than 2 landmarks in both views, a real camera that is not perspective,
            or pairs that do not fix the normal (names the view).
        """
        real_view = self.view(view.mirror_of)
        where = f"view {view.name!r} (mirror of {real_view.name!r})"
        real = state.cameras[real_view.name]
        if not is_perspective(real):
            raise ValueError(f"{where}: the mirror needs a perspective camera in "
                             f"{real_view.name!r} (pinhole or DLT), got {real.kind}")
        direct = {n: i for i, n in enumerate(real_view.names) if real_view.weights[i] > 0}
        common = [(direct[n], j) for j, n in enumerate(view.names)
                  if n in direct and view.weights[j] > 0]
        if len(common) < 2:
            raise ValueError(f"{where}: {len(common)} landmark(s) seen both directly and in "
                             "the mirror; the mirror's plane needs at least 2")
        i_d = np.array([a for a, _ in common])
        i_m = np.array([b for _, b in common])
        x = self.world(state, real_view.vertices[i_d])
        d = np.linalg.norm(x[:, None] - x[None], axis=2)
        a, b = np.unravel_index(int(np.argmax(d)), d.shape)
        names = [real_view.names[i] for i in i_d]
        try:
            fit = estimate_mirror(as_dlt(real), real_view.pixels[i_d], view.pixels[i_m],
                                  names, known_length=(names[a], names[b], float(d[a, b])))
        except ValueError as e:
            raise ValueError(f"{where}: {e}") from None
        return fit.plane

    def joint(self, views, front_weight=1.0, contour=True, landmarks=True, outlines=None,
              keep_distance=None):
        """A :class:`Joint` problem over the landmarks and contours of ``views``;
        ``outlines`` (view name -> (vertices, faces, edges)) are the outline candidates of
        the views that do not use the profile's (:meth:`outline_candidates`);
        ``keep_distance`` (pixels, default ``contour_keep``): contour rows within it are
        never trimmed (``ContourRows``)."""
        return Joint(self, views, front_weight, contour, landmarks, outlines, keep_distance)

    def outline_candidates(self, view, outlines=None):
        """(vertices (n,), faces (F, 3), edges (E, 4)) the contour rows of ``view`` choose
        the model's outline from: ``outlines[view.name]`` when given, else the engine's
        profile candidates."""
        own = None if outlines is None else outlines.get(view.name)
        if own is not None:
            return own
        return self.outline, self.outline_faces, self.outline_edges

    # ------------------------------------------------------------------ errors

    def reprojection(self, state, views=None):
        """Per view: landmark residuals (n,) in pixels."""
        out = {}
        for v in self.views if views is None else views:
            px = state.cameras[v.name].project(self.world(state, v.vertices))
            out[v.name] = np.linalg.norm(px - v.pixels, axis=1)
        return out


@dataclass
class _Block:
    """Free parameters of one camera ("camera": the real camera of ``view``, seen by the
    ``users`` views: itself and its mirror views) or of a mirror plane ("plane": of the
    mirror view ``view``)."""

    kind: str
    view: ViewData
    users: list


@dataclass
class _Prepared:
    problem: ShapeProblem
    model: LinearModel
    k: int
    rotation: np.ndarray
    freeze: tuple
    cameras_only: bool
    layout: list  # per block: (block, mode kind, number of modes, units, start, prior)
    start: np.ndarray  # coefficients of the camera modes at the linearisation point
    reusable: bool
    frozen: tuple  # everything frozen (with the gauge)


class Joint:
    """Image rows of some views solved jointly for the head and the cameras.

    The shape-ICP knows one similarity and linear modes. To let it move the cameras in the
    same Gauss-Newton step as the head, every group of rows gets its own copies of the
    model vertices it uses, and each free camera (and mirror plane) gets extra modes that
    move only the copies it sees: the pixel fields of its parameters (see the module
    docstring), lifted to 3-D through each copy's camera Jacobian (pseudo-inverse), so a
    mode's coefficient moves those projections exactly as the parameter would, to first
    order. The step is then a joint Gauss-Newton step, so the fit converges in a few
    rounds where alternating "head, then cameras" crawls along every motion that a camera
    and the head share. After each step the cameras and planes are moved by their modes'
    coefficients (or refitted to what the step predicted) and the modes reset: they are
    re-linearised every round.

    A pinhole camera's focal prior is the prior of its focal mode: one unit of that mode
    is ``sigma * lambda2`` in log f, and its coefficient starts at the camera's distance
    from the prior, so the shape-ICP's ``lambda2^2 c^2`` is exactly the prior's cost.
    """

    def __init__(self, eng, views, front_weight=1.0, contour=True, landmarks=True,
                 outlines=None, keep_distance=None):
        self.eng = eng
        self.views = list(views)
        # view name -> (vertices, faces, edges): candidates found for this problem's head
        self.outlines = dict(outlines or {})
        self.groups = []  # (view, kind, rows)
        orig = []
        off = 0
        for v in self.views:
            if landmarks and len(v.vertices):
                n = len(v.vertices)
                w = (1.0 if v.side else front_weight) * eng.inv_var * v.weights
                rows = ImageRows(np.arange(off, off + n), v.pixels, v.camera, weights=w,
                                 name=f"landmarks {v.name}")
                self.groups.append((v, "landmarks", rows))
                orig.append(v.vertices)
                off += n
            if contour and v.contour is not None:
                cand, faces, edges = eng.outline_candidates(v, self.outlines)
                n = len(cand)
                rows = ContourRows(np.arange(off, off + n), v.contour, v.camera,
                                   weights=eng.contour_weight * eng.inv_var,
                                   faces=faces, edges=edges,
                                   max_distance=eng.contour_threshold,
                                   keep_distance=eng.contour_keep if keep_distance is None
                                   else keep_distance,
                                   name=f"contour {v.name}")
                self.groups.append((v, "contour", rows))
                orig.append(cand)
                off += n
        if not self.groups:
            raise ValueError("views: no landmarks or contour to fit")
        self._prep = None
        self._fit = None
        self.orig = np.concatenate(orig)
        self.rows = [g[2] for g in self.groups]
        self.mean, self.basis = eng.slice(self.orig)
        self.view_idx, self.view_lm = {}, {}
        for v, kind, rows in self.groups:
            self.view_idx.setdefault(v.name, []).append(rows.vertices)
            if kind == "landmarks":
                self.view_lm[v.name] = rows.vertices
        self.view_idx = {k: np.concatenate(i) for k, i in self.view_idx.items()}
        self.members = [v for v in self.views if v.name in self.view_idx]
        # Gauge: the head's similarity parameters these views cannot determine.
        self.gauge = eng.gauge(self.members)
        self.blocks = []
        for v in eng.views:
            if v.mirror_of is not None or not eng.camera_moves(v):
                continue
            users = [u for u in self.members if u is v or u.mirror_of == v.name]
            if users:
                self.blocks.append(_Block("camera", v, users))
        self.blocks += [_Block("plane", u, [u]) for u in self.members
                        if u.mirror_of is not None]

    def sync(self, state):
        self.eng.use(state)
        for v, _, rows in self.groups:
            rows.set_camera(state.cameras[v.name])

    def world(self, state):
        """World positions of the copies, (n, 3)."""
        local = self.mean + np.tensordot(state.coeffs, self.basis, axes=1)
        return state.scale * local @ state.rotation.T + state.translation

    def cost(self, state):
        """Weighted squared pixel residuals (correspondences refreshed) plus priors (shape
        and focal length)."""
        self.sync(state)
        x = self.world(state)
        total = 0.0
        for _, _, rows in self.groups:
            xs = x[rows.vertices]
            rows.update(xs)
            blocks = rows.block(xs, jacobian=False)
            blocks = blocks if isinstance(blocks, list | tuple) else [blocks]
            total += sum(float(b.sq) for b in blocks)
            if isinstance(rows, ContourRows):
                total += rows.unmatched_cost()
        return total + self.eng.prior_cost(state.coeffs) + self.camera_prior_cost(state)

    def camera_prior_cost(self, state):
        """The focal priors of the cameras this problem moves."""
        return self.eng.camera_prior_cost(state, [b.view for b in self.blocks
                                                  if b.kind == "camera"])

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
        """Refit every free camera and mirror plane to the head (landmarks + contour
        pairs)."""
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

    # ------------------------------------------------------------------ camera modes

    def _block_fields(self, blk, state, x):
        """Pixel fields of one block over the copies it moves.

        Returns (mode kind, copy indices (m,), fields (P, m, 2) per natural unit, units
        (P,) natural units per coefficient, start (P,) coefficients now, prior (P,) bool:
        modes whose shape-ICP prior is a real prior, not a negligible one)."""
        eng = self.eng
        v = blk.view
        if blk.kind == "plane":
            idx = self.view_idx[v.name]
            f = plane_fields(state.cameras[v.mirror_of], state.planes[v.name], x[idx])
            return ("plane", idx, f, *_unit_scale(f), np.zeros(3, bool))
        cam = state.cameras[v.name]
        idx, pts = [], []
        for u in blk.users:
            i = self.view_idx[u.name]
            idx.append(i)
            pts.append(x[i] if u is v else state.planes[u.name].reflect_points(x[i]))
        idx, pts = np.concatenate(idx), np.concatenate(pts)
        if isinstance(cam, PinholeCamera):
            n_lm = eng.landmark_count(v)
            free_f = focal_free(cam, n_lm)
            f = pinhole_fields(cam, pts, free_f)
            units, start = _unit_scale(f)
            has_prior = np.zeros(len(f), bool)
            prior = focal_prior(cam, n_lm)
            if prior is not None and eng.lambda2 > 0:
                units[6] = prior[1] * eng.lambda2
                start[6] = (np.log(cam.focal_px) - prior[0]) / units[6]
                has_prior[6] = True
            return ("pinhole", idx, f, units, start, has_prior)
        if isinstance(cam, DLTCamera):
            f = dlt_fields(cam, pts)
            flat = f.reshape(len(f), -1)
            _, sv, vt = np.linalg.svd(flat, full_matrices=False)
            keep = sv > 1e-9 * sv[0]
            f = vt[keep].reshape(-1, len(idx), 2)
            return ("refit", idx, f, *_unit_scale(f), np.zeros(len(f), bool))
        own = self.view_idx[v.name]
        lm = self.view_lm.get(v.name, own)
        f = similarity_fields(cam, x[own], x[lm])
        return ("refit", own, f, np.full(4, _MODE_PIXELS), np.zeros(4), np.zeros(4, bool))

    def model(self, state):
        """The copies' linear model at ``state``: the fitted modes, then the camera and
        plane modes (see the class docstring); with the layout of the extra modes and their
        start coefficients."""
        eng = self.eng
        lin = eng.lin
        if not self.blocks:
            return (LinearModel(self.mean, self.basis, lin.stddev, lin.names, eng.gamma), [],
                    np.zeros(0))
        mean, extra_b, layout, start, sd = self._extra_modes(state)
        n_extra = extra_b.shape[0]
        gamma = None
        if eng.gamma is not None:
            gamma = np.hstack([eng.gamma, np.zeros((eng.gamma.shape[0], n_extra))])
        names = tuple(lin.names) + tuple(f"camera {i}" for i in range(n_extra))
        # own arrays: replace_modes writes into them
        model = LinearModel(np.array(mean), np.concatenate([self.basis, extra_b]),
                            np.concatenate([lin.stddev, sd]), names, gamma)
        return model, layout, start

    def _extra_modes(self, state):
        """(mean of the copies with the prior modes' start folded out (n, 3), the camera and
        plane modes (P, n, 3) in the model frame, layout, start coefficients (P,),
        stddev (P,))."""
        x = self.world(state)
        n = len(x)
        # each copy's camera Jacobian, pseudo-inverted (J^T (J J^T)^-1, the 2x2 inverse
        # written out): pixel fields -> world displacement; pinv[0] takes the u part
        pinv = np.zeros((2, n, 3))
        for v in self.members:
            idx = self.view_idx[v.name]
            jac = np.asarray(state.cameras[v.name].jacobian(x[idx]),
                             dtype=np.float64).reshape(len(idx), 2, 3)
            ju, jv = jac[:, 0], jac[:, 1]
            a = (ju * ju).sum(axis=1)[:, None]
            b = (ju * jv).sum(axis=1)[:, None]
            d = (jv * jv).sum(axis=1)[:, None]
            det = a * d - b * b
            pinv[0, idx] = (ju * d - jv * b) / det
            pinv[1, idx] = (jv * a - ju * b) / det
        modes, layout, starts, sds = [], [], [], []
        mean = self.mean
        for blk in self.blocks:
            kind, idx, f, units, start, has_prior = self._block_fields(blk, state, x)
            f = f * units[:, None, None]
            lift = f[:, :, 0:1] * pinv[0, idx] + f[:, :, 1:2] * pinv[1, idx]
            m = np.zeros((len(f), n, 3))
            # model frame (x = s R m + t)
            m[:, idx] = (lift @ state.rotation) / state.scale
            if start.any():
                mean = mean - np.tensordot(start, m, axes=1)
            modes.append(m)
            layout.append((blk, kind, len(f), units, start, has_prior))
            starts.append(start)
            # a prior mode keeps its prior under prior="identity" (which weighs by stddev)
            sds.append(np.where(has_prior, 1.0, 1e-9))
        return (mean, np.concatenate(modes), layout, np.concatenate(starts),
                np.concatenate(sds))

    def prepare(self, state, freeze=(), cameras_only=False, previous=None):
        """The shape-ICP problem over the copies with the camera modes linearised at
        ``state`` (reused while the head turns little if every camera is orthographic:
        building it copies the basis). A ``previous`` problem of the same layout is
        re-linearised in place (``ShapeProblem.replace_modes``) instead of rebuilt."""
        k = len(state.coeffs)
        if cameras_only:
            freeze = tuple(freeze) + ("rotation",)
        frozen = tuple(freeze) + tuple(self.gauge)
        if previous is not None and previous.frozen == frozen and self.blocks and \
                previous.cameras_only == cameras_only:
            mean, extra_b, layout, start, sd = self._extra_modes(state)
            same = len(layout) == len(previous.layout) and all(
                a[0] is b[0] and a[1] == b[1] and a[2] == b[2]
                for a, b in zip(layout, previous.layout, strict=True))
            if same and np.array_equal(sd, previous.model.stddev[k:]):
                previous.problem.replace_modes(k, extra_b, mean)
                return replace(previous, rotation=state.rotation.copy(), layout=layout,
                               start=start)
        model, layout, start = self.model(state)
        active = np.arange(k, model.n_coeffs) if cameras_only else None
        problem = ShapeProblem(model, self.rows, lambda1=self.eng.lambda1,
                               lambda2=self.eng.lambda2, prior=self.eng.prior,
                               freeze=frozen, active=active)
        reusable = all(kind == "refit" and isinstance(state.cameras[b.view.name],
                                                      OrthographicCamera)
                       for b, kind, *_ in layout)
        return _Prepared(problem, model, k, state.rotation.copy(), tuple(freeze),
                         cameras_only, layout, start, reusable, frozen)

    def _solve(self, prep, state, iterations):
        start = np.zeros(prep.model.n_coeffs)
        start[:prep.k] = state.coeffs
        start[prep.k:] = prep.start
        self.sync(state)
        return prep.problem.solve(scale=state.scale, rotation=state.rotation,
                                  translation=state.translation, coeffs=start,
                                  max_iterations=iterations, tolerance=0.0, sigma=1.0)

    def step(self, state, freeze=(), inner=2, cameras_only=False, prep=None):
        """One joint Gauss-Newton round (``inner`` shape-ICP steps), then the cameras.

        The step moves each free camera through its modes. A pinhole camera and a mirror
        plane take the step's parameter change directly; any other camera is refitted to
        what the step predicted: the new head's copies seen where the old camera saw them
        displaced by the modes (for an orthographic camera exactly the similarity the step
        chose; any kind gets its closest match), so camera and head stay one consistent
        Gauss-Newton step. Mirror cameras follow their real camera and plane. Free cameras
        of views outside this problem are refitted to their landmarks.

        ``prep`` (from :meth:`prepare`) is reused when given and reusable; it is rebuilt
        when the head has turned by more than about 3 degrees since (its camera modes
        would be stale), and always for perspective cameras and mirrors (their modes
        carry the camera's parameters).
        """
        if prep is None or not prep.reusable or prep.freeze != tuple(freeze) or \
                prep.cameras_only != cameras_only or \
                np.abs(state.rotation - prep.rotation).max() > 0.05:
            prep = self.prepare(state, freeze, cameras_only,
                                previous=None if prep is None or prep.reusable else prep)
        self._fit = self._solve(prep, state, inner)
        self._prep = prep
        return self.apply(state, 1.0)

    def apply(self, state, alpha):
        """The state after a fraction ``alpha`` of the last :meth:`step`'s change (from
        ``state``, the state that step started from): 1 the whole step; less when the
        whole step overshoots (a perspective camera's modes are linear in its parameters,
        its projection is not)."""
        prep, fit = self._prep, self._fit
        k, model = prep.k, prep.model
        new = state.copy()
        if alpha == 1.0:
            new.rotation, new.coeffs = fit.rotation, fit.coeffs[:k].copy()
            new.scale, new.translation = fit.scale, fit.translation
        else:
            turn = Rotation.from_matrix(fit.rotation @ state.rotation.T).as_rotvec()
            new.rotation = rotation_from_vector(alpha * turn) @ state.rotation
            new.coeffs = state.coeffs + alpha * (fit.coeffs[:k] - state.coeffs)
            new.scale = state.scale * (fit.scale / state.scale) ** alpha
            new.translation = state.translation + alpha * (fit.translation - state.translation)
        full = head = None
        col = k
        moved = set()
        for blk, kind, p, units, start, _ in prep.layout:
            delta = alpha * (fit.coeffs[col:col + p] - start) * units
            col += p
            v = blk.view
            if kind == "plane":
                new.planes[v.name] = moved_plane(state.planes[v.name], delta)
                continue
            old = state.cameras[v.name]
            moved.add(v.name)
            if kind == "pinhole":
                new.cameras[v.name] = moved_pinhole(old, delta)
                continue
            if full is None:
                c_full = fit.coeffs.copy()
                c_full[:k] = new.coeffs
                c_full[k:] = prep.start + alpha * (fit.coeffs[k:] - prep.start)
                full = model.mean + np.tensordot(c_full, model.basis, axes=1)
                head = self.mean + np.tensordot(new.coeffs, self.basis, axes=1)
                full = new.scale * full @ new.rotation.T + new.translation
                head = new.scale * head @ new.rotation.T + new.translation
            pts, px = [], []
            for u in blk.users:
                i = self.view_idx[u.name]
                h = head[i] if u is v else state.planes[u.name].reflect_points(head[i])
                pts.append(h)
                px.append(state.cameras[u.name].project(full[i]))
            try:
                new.cameras[v.name] = old.refit(np.concatenate(pts), np.vstack(px))
            except ValueError:  # too few copies for this kind: keep the camera this round
                new.cameras[v.name] = old
        for u in self.eng.views:
            if u.mirror_of is not None and u.name in new.planes:
                new.cameras[u.name] = mirror_camera(new.cameras[u.mirror_of],
                                                    new.planes[u.name])
        inside = {v.name for v in self.members} | moved
        outside = [v for v in self.eng.views if v.name not in inside and v.mirror_of is None]
        if outside:
            self.eng.refit_cameras(new, views=outside)
        self.sync(new)
        return new

    def run(self, state, freeze=(), max_outer=20, inner=2, tolerance=1e-4,
            cameras_only=False, patience=2):
        """Rounds of :meth:`step` until the cost changes by less than ``tolerance``
        (relative) or has not reached a new low for ``patience`` rounds; returns the state
        of the lowest cost and the cost history.

        The contour's rows are a choice (which vertices form the outline), so near the end
        the choice can flip back and forth between two sets and the cost with it; the
        lowest one is kept. A step of perspective cameras that raises the cost is cut
        back (:meth:`apply`, fractions _DAMPING) before it counts.
        """
        best_cost = self.cost(state)
        best = state
        history = [best_cost]
        since = 0
        if self._prep is not None and self._prep.reusable:
            self._prep = None  # (a perspective problem is re-linearised in place instead)
        for _ in range(max(int(max_outer), 1)):
            start = state
            state = self.step(start, freeze, inner, cameras_only, self._prep)
            cost = self.cost(state)
            if cost > history[-1] and not self._prep.reusable:
                # a perspective step that overshot: take part of it
                for alpha in _DAMPING:
                    trial = self.apply(start, alpha)
                    c = self.cost(trial)
                    if c < cost:
                        state, cost = trial, c
                    if c <= history[-1]:
                        break
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

    def settle(self, state, max_rounds=10, tolerance=1e-4, **run_kw):
        """Self-calibration: alternate a full re-calibration of every free camera and
        mirror plane (``Camera.refit`` on the landmarks and contour pairs, with all of its
        parameters and priors: a pinhole camera's principal point and k1 when free, its
        focal range) and joint rounds (:meth:`run`), until the re-calibration lowers the
        cost by less than ``tolerance`` (relative): cameras and shape agree. At most
        ``max_rounds`` re-calibrations. Returns (state, cost history of the joint rounds
        appended, re-calibrations made)."""
        cost = self.cost(state)
        history = []
        rounds = 0
        for _ in range(max(int(max_rounds), 0)):
            trial = state.copy()
            try:
                self.refit(trial)
            except ValueError:  # a camera cannot be refitted alone: the joint rounds rule
                break
            rounds += 1
            c = self.cost(trial)
            if not c < cost * (1.0 - tolerance):
                break
            state, hist = self.run(trial, tolerance=tolerance, **run_kw)
            history += hist
            cost = self.cost(state)
        self.sync(state)
        self.cost(state)
        return state, history, rounds

    def covariance(self, state):
        """Posterior covariance (K, K) of the fitted coefficients at ``state``: the inverse
        of the normal matrix with pose and camera modes free (marginalised), rows weighted
        1 / noise^2 so sigma = 1."""
        last = self._prep
        prep = self.prepare(state, previous=None if last is None or last.reusable else last)
        fit = self._solve(prep, state, 0)
        return fit.coeff_covariance[:prep.k, :prep.k]


def _pose_only(camera):
    """A pinhole camera's copy whose ``refit`` moves only its pose (other kinds: itself)."""
    if not isinstance(camera, PinholeCamera):
        return camera
    return PinholeCamera(camera.focal_px, camera.rotation, camera.centre, camera.size,
                         camera.principal_point, camera.k1, free_focal=False,
                         focal_range_mm=None)


def _unit_scale(fields):
    """Units (P,) making each field move the points by _MODE_PIXELS pixels RMS per unit of
    coefficient (so the shape prior on the coefficient is negligible), and zero starts."""
    rms = np.sqrt((fields**2).sum(axis=2).mean(axis=1))
    return _MODE_PIXELS / np.maximum(rms, 1e-12), np.zeros(len(fields))
