"""Groups of residual rows tied to model vertices, which the shape-ICP (``shape_icp.py``)
composes freely in one solve:

- ``PointRows``: vertex -> 3-D target, all coordinates or a subset (``mask``; thesis
  approach 1 uses the two known coordinates of front landmarks, eq. 47);
- ``ImageRows``: vertex -> pixel through any ``Camera`` (residual pixel - project(x), the
  Jacobian by the chain rule through ``camera.jacobian``), so perspective cameras plug in;
- ``ClosestPointRows``: ICP against a point cloud (KD-tree, distance threshold, optional
  symmetric correspondences; thesis §4.3.3).

Image rows (``CameraRows``) take a new camera through ``set_camera`` between solves. A
group's ``block`` returns ``IsotropicRows`` for full 3-D targets and ``ScalarRows`` (or a
list of blocks) for anything else, so rows defined elsewhere (the fit's outline rows) plug
in the same way.
"""

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..cameras import Camera
from ..errors import as_points


@dataclass
class IsotropicRows:
    """Full 3-D rows: per-vertex weight and world residual (target - x)."""

    alpha: np.ndarray  # (n,)
    resid: np.ndarray  # (n, 3)
    sq: float  # sum of w |r|^2 (the data cost of this group)
    wsum: float  # sum of the weights of points used (eq. 46 denominator)
    nrows: int  # scalar residual rows with positive weight


@dataclass
class ScalarRows:
    """A block of explicit scalar rows, what ``Rows.block`` returns for anything but full
    3-D targets: residual ``r_j = obs_j - pred_j`` with ``d pred_j / d x = g_j`` at the
    row's vertex, weighted ``w_j``.

    Attributes
    ----------
    idx : ndarray of int, shape (m,) or (m, c), or None
        Position of each row's vertex within the group, or of its ``c`` vertices when a
        row's prediction depends on several (a point on an edge: ``c = 2``); None: one row
        per vertex, in order. None together with ``g``, ``r``, ``w`` when only the cost
        was asked for (``block(..., jacobian=False)``).
    g : ndarray, shape (m, 3) or (m, c, 3), or None
        Derivative of each row's prediction by its vertex's (vertices') world position.
    r : ndarray, shape (m,) or None
    w : ndarray, shape (m,) or None
    sq : float
        Weighted sum of squared residuals of the block (its data cost).
    wsum : float
        Sum of the weights of the points used (eq. 46 denominator).
    nrows : int
        Scalar rows with positive weight.
    mix : ndarray, shape (q, m), or None
        Extra rows, each a combination of the block's rows: its prediction is
        ``mix @ pred``, so its derivative ``sum_j mix[., j] g_j`` costs no gather of its
        own (a group's mean row, ``definition.GroupedImageRows``).
    mix_r : ndarray, shape (q,), or None
        Their residuals.
    mix_w : ndarray, shape (q,), or None
        Their weights, which may be negative: a term taken out of the cost (``sq`` is the
        block's whole cost as given).
    """

    idx: np.ndarray | None
    g: np.ndarray | None
    r: np.ndarray | None
    w: np.ndarray | None
    sq: float
    wsum: float
    nrows: int
    mix: np.ndarray | None = None
    mix_r: np.ndarray | None = None
    mix_w: np.ndarray | None = None


def _vertex_array(vertices, name):
    v = np.asarray(vertices)
    if v.ndim != 1 or v.size == 0:
        raise ValueError(f"{name}: vertices must be a non-empty 1-D array, got shape {v.shape}")
    if not np.issubdtype(v.dtype, np.integer):
        raise ValueError(f"{name}: vertices must be integer indices, got dtype {v.dtype}")
    return v.astype(np.intp)


def _weight_array(weights, n, name):
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim == 0:
        w = np.full(n, float(w))
    if w.shape != (n,):
        raise ValueError(f"{name}: weights must be a scalar or shape ({n},), got {w.shape}")
    if not np.isfinite(w).all() or (w < 0).any():
        raise ValueError(f"{name}: weights must be finite and non-negative")
    return w


def _check_camera(camera, name):
    if not isinstance(camera, Camera) and not (hasattr(camera, "project")
                                               and hasattr(camera, "jacobian")):
        raise ValueError(f"{name}: camera must be a Camera (with project and jacobian), "
                         f"got {type(camera).__name__}")
    return camera


def _check_rejection(max_distance, reject_factor, name):
    """The ICP rows' outlier limits checked (both > 0); returns ``max_distance`` as float."""
    md = float(max_distance)
    if not md > 0:
        raise ValueError(f"{name}: max_distance must be > 0, got {max_distance!r}")
    if reject_factor is not None and not float(reject_factor) > 0:
        raise ValueError(f"{name}: reject_factor must be > 0, got {reject_factor!r}")
    return md


class Rows(ABC):
    """A group of residual rows tied to model vertices. Subclasses below.

    Attributes
    ----------
    vertices : ndarray, shape (n,)
        Model vertex indices the rows use.
    name : str
        Used in error messages and in ``ShapeFit.info``.
    """

    vertices: np.ndarray
    name: str
    _version = 0  # bumped when targets or the camera change: a cached system is stale

    def update(self, world):
        """Refresh correspondences from the current world positions (n, 3) of ``vertices``.
        Fixed-target groups do nothing."""
        return None

    @abstractmethod
    def block(self, world, jacobian=True):
        """Residuals (and, with ``jacobian``, their derivatives) at world positions (n, 3)."""

    def _per_vertex(self, values, what, dim):
        """``values`` as float64 of shape (n, dim), one row per vertex of the group, or a
        ValueError naming the group and ``what``."""
        n = len(self.vertices)
        a = np.asarray(values, dtype=np.float64)
        if a.shape != (n, dim):
            raise ValueError(f"{self.name}: {what} must have shape ({n}, {dim}), got {a.shape}")
        return a


class CameraRows(Rows):
    """Rows whose residuals are pixels of a photo seen through ``camera``.

    ``set_camera`` is how a caller that refits the photo's camera between solves (the fit
    alternating head and cameras) hands the new one over: it also tells a ``ShapeProblem``
    that a system it cached for these rows is stale.
    """

    camera: Camera

    def set_camera(self, camera):
        """Use ``camera`` from now on (a no-op when it is the current one).

        Raises
        ------
        ValueError
            ``camera`` has no ``project`` and ``jacobian``.
        """
        camera = _check_camera(camera, self.name)
        if camera is not self.camera:
            self.camera = camera
            self._version += 1

    def _pixel_block(self, world, targets, w, jacobian):
        """Rows ``targets - camera.project(x)`` (pixels, (n, 2)) weighted ``w`` (n,) per
        vertex, with the chain-rule derivatives through ``camera.jacobian``."""
        r = targets - _projected(self.camera, world, self.name, self.vertices)
        sq = float(w @ np.einsum("ij,ij->i", r, r))
        n = len(w)
        nrows = 2 * int((w > 0).sum())
        if not jacobian:
            return ScalarRows(None, None, None, None, sq, float(w.sum()), nrows)
        jac = np.asarray(self.camera.jacobian(world), dtype=np.float64).reshape(n, 2, 3)
        return ScalarRows(np.repeat(np.arange(n), 2), jac.reshape(2 * n, 3), r.reshape(-1),
                          np.repeat(w, 2), sq, float(w.sum()), nrows)


class PointRows(Rows):
    """Vertices pulled toward 3-D targets, in all coordinates or only the masked ones.

    Parameters
    ----------
    vertices : array_like of int, shape (n,)
    targets : array_like, shape (n, 3), metres (world)
        Unused coordinates (mask False) may hold any finite value or NaN.
    weights : float or array_like, shape (n,)
        Multiplies each point's squared residual.
    mask : array_like of bool, shape (n, 3), optional
        Which world coordinates of each target are known (default: all). A front-view
        landmark known in x and z only has mask ``[True, False, True]``.
    name : str
    """

    def __init__(self, vertices, targets, weights=1.0, mask=None, name="points"):
        self.name = name
        self.vertices = _vertex_array(vertices, name)
        n = len(self.vertices)
        if mask is None:
            self.mask = None
        else:
            m = np.asarray(mask)
            if m.shape != (n, 3) or m.dtype != bool:
                raise ValueError(f"{name}: mask must be a bool array of shape ({n}, 3), "
                                 f"got {m.dtype} {m.shape}")
            self.mask = None if m.all() else m
        self.weights = _weight_array(weights, n, name)
        self.set_targets(targets)

    def set_targets(self, targets):
        """Replace the targets (same shape), e.g. while a landmark is dragged."""
        t = self._per_vertex(targets, "targets", 3)
        used = np.ones(t.shape, bool) if self.mask is None else self.mask
        bad = used & ~np.isfinite(t)
        if bad.any():
            raise ValueError(f"{self.name}: target row {int(np.flatnonzero(bad.any(1))[0])} "
                             "is not finite (NaN or inf)")
        self.targets = np.where(used, t, 0.0)
        self._version += 1

    def block(self, world, jacobian=True):
        r = self.targets - world
        w = self.weights
        if self.mask is None:
            sq = float(w @ np.einsum("ij,ij->i", r, r))
            return IsotropicRows(w, r, sq, float(w.sum()), 3 * int((w > 0).sum()))
        pt, ax = np.nonzero(self.mask)
        rr = r[pt, ax]
        ww = w[pt]
        g = np.zeros((len(pt), 3))
        g[np.arange(len(pt)), ax] = 1.0
        used = np.zeros(len(w), bool)
        used[pt] = True
        return ScalarRows(pt, g, rr, ww, float(ww @ rr**2), float(w[used].sum()),
                        int((ww > 0).sum()))


class ImageRows(CameraRows):
    """Vertices pulled toward pixels of a photo through its camera.

    The residual of point i is ``pixels[i] - camera.project(x_i)`` in pixels, so weights
    convert pixels^2 to the cost's unit (e.g. ``(metres per pixel)^2`` to mix with 3-D rows).

    Parameters
    ----------
    vertices : array_like of int, shape (n,)
    pixels : array_like, shape (n, 2), pixels (origin top-left, v down)
    camera : Camera
    weights : float or array_like, shape (n,)
    name : str
    """

    def __init__(self, vertices, pixels, camera, weights=1.0, name="image"):
        self.name = name
        self.vertices = _vertex_array(vertices, name)
        self.camera = _check_camera(camera, name)
        self.weights = _weight_array(weights, len(self.vertices), name)
        self.set_pixels(pixels)

    def set_pixels(self, pixels):
        """Replace the target pixels (same shape), e.g. while a landmark is dragged."""
        p = self._per_vertex(pixels, "pixels", 2)
        self.pixels = as_points(p, f"{self.name}: pixels", dim=2)
        self._version += 1

    def block(self, world, jacobian=True):
        return self._pixel_block(world, self.pixels, self.weights, jacobian)


def _projected(camera, world, name, vertices):
    """``camera.project(world)``, or a ValueError naming the first vertex that does not
    project to a finite pixel (e.g. behind a perspective camera)."""
    px = np.asarray(camera.project(world), dtype=np.float64)
    bad = ~np.isfinite(px).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{name}: vertex {int(vertices[i])} does not project to a finite "
                         "pixel (behind the camera?)")
    return px


def _reject(dist, ok, max_distance, reject_factor, keep_distance=0.0):
    """Inlier mask: within ``max_distance``, and within ``reject_factor`` x median unless
    closer than ``keep_distance``."""
    ok = ok & (dist <= max_distance)
    if reject_factor is not None and ok.any():
        ok &= dist <= max(reject_factor * np.median(dist[ok]), keep_distance)
    return ok


class ClosestPointRows(Rows):
    """ICP rows: each vertex is pulled toward its nearest cloud point (thesis §4.3.3).

    Without normals the cost of an inlier vertex is the thesis' point-to-point
    ``w |q - x|^2``. With cloud normals it is point-to-plane plus a little point-to-point,
    ``w ((n . (q - x))^2 + tangential |q - x|^2)``: the distance along the normal is what
    the nearest point measures reliably, so ICP converges in a few steps instead of sliding
    slowly along the surface, and the small tangential term keeps the shape from drifting
    sideways.

    Parameters
    ----------
    vertices : array_like of int, shape (n,)
    cloud : array_like, shape (m, 3), metres (world)
    weights : float or array_like, shape (n,)
        Per-vertex weight of inliers.
    max_distance : float
        Correspondences farther than this (metres) are dropped (the thesis' threshold).
    reject_factor : float, optional
        Also drop correspondences farther than this many times the median distance...
    keep_distance : float
        ... unless they are closer than this (metres): early in a fit, true shape
        differences of several millimetres must not be mistaken for outliers.
    symmetric : bool
        Also pull, for every cloud point, its nearest vertex toward it (reaches parts of
        the cloud no vertex is nearest to; costs a tree on the vertices per iteration). Per
        vertex these pulls average into one target.
    normals : array_like, shape (m, 3), optional
        Unit normals of the cloud (sign irrelevant) for the point-to-plane cost.
    tangential : float
        Weight of the point-to-point term when ``normals`` are given.
    exclude : array_like of bool, shape (m,), optional
        Cloud points that may not serve as targets (e.g. the cloud's boundary: a vertex
        beyond the edge of a partial scan would otherwise be pulled onto the edge); a
        vertex whose nearest point is excluded gets no row.
    tree : scipy.spatial.cKDTree, optional
        A tree already built on ``cloud`` (reused across solves).
    workers : int
        Threads for the KD-tree query (-1: all).
    name : str
    """

    def __init__(self, vertices, cloud, weights=1.0, max_distance=np.inf, reject_factor=None,
                 keep_distance=0.0, symmetric=False, normals=None, tangential=0.1,
                 exclude=None, tree=None, workers=1, name="cloud"):
        self.name = name
        self.vertices = _vertex_array(vertices, name)
        self.weights = _weight_array(weights, len(self.vertices), name)
        self.cloud = as_points(cloud, f"{name}: cloud")
        if tree is not None and tree.n != len(self.cloud):
            raise ValueError(f"{name}: tree has {tree.n} points, cloud has {len(self.cloud)}")
        self.tree = cKDTree(self.cloud) if tree is None else tree
        md = _check_rejection(max_distance, reject_factor, name)
        self.normals = None
        if normals is not None:
            nrm = as_points(normals, f"{name}: normals")
            if nrm.shape != self.cloud.shape:
                raise ValueError(f"{name}: normals must have the cloud's shape "
                                 f"{self.cloud.shape}, got {nrm.shape}")
            length = np.linalg.norm(nrm, axis=1)
            if (length < 1e-12).any():
                raise ValueError(f"{name}: normal {int(np.argmin(length))} has zero length")
            self.normals = nrm / length[:, None]
        if not np.isfinite(tangential) or tangential < 0:
            raise ValueError(f"{name}: tangential must be finite and >= 0, got {tangential!r}")
        self.tangential = float(tangential)
        self.exclude = None
        if exclude is not None:
            ex = np.asarray(exclude)
            if ex.shape != (len(self.cloud),) or ex.dtype != bool:
                raise ValueError(f"{name}: exclude must be a bool array of shape "
                                 f"({len(self.cloud)},), got {ex.dtype} {ex.shape}")
            self.exclude = ex if ex.any() else None
        self.max_distance = md
        self.reject_factor = reject_factor
        self.keep_distance = float(keep_distance)
        self.symmetric = bool(symmetric)
        self.workers = workers
        self.targets = None
        self.inliers = None
        self.distances = None

    def update(self, world):
        dist, idx = self.tree.query(world, distance_upper_bound=self.max_distance,
                                    workers=self.workers)
        ok = np.isfinite(dist)
        if self.exclude is not None:
            ok &= ~self.exclude[np.where(ok, idx, 0)]
        ok = _reject(dist, ok, self.max_distance, self.reject_factor, self.keep_distance)
        idx = np.where(ok, idx, 0)
        self.distances = dist
        self.inliers = ok
        alpha = np.where(ok, self.weights, 0.0)
        tgt = self.cloud[idx]
        self.targets = tgt
        self._plane = None
        if self.normals is not None:
            self._plane = (self.normals[idx], alpha)
            alpha = self.tangential * alpha
        self._const = 0.0
        if self.symmetric:
            # Cloud -> model: each cloud point pulls its nearest vertex. For one vertex the
            # sum of w |q_j - x|^2 equals (sum w) |mean q - x|^2 + const, so the pulls fold
            # into one weighted target per vertex and the rows stay isotropic.
            d2, v = cKDTree(world).query(self.cloud, workers=self.workers)
            okr = _reject(d2, np.isfinite(d2), self.max_distance, self.reject_factor,
                          self.keep_distance)
            v, q = v[okr], self.cloud[okr]
            wr = self.weights[v]
            n = len(world)
            cnt = np.bincount(v, wr, minlength=n)
            acc = np.stack([np.bincount(v, wr * q[:, k], minlength=n) for k in range(3)], 1)
            tot = alpha + cnt
            use = tot > 0
            folded = np.where(use[:, None], (alpha[:, None] * tgt + acc)
                              / np.where(use, tot, 1.0)[:, None], tgt)
            # The constant the folding drops, so the reported error (eq. 46) stays the sum
            # of both directions' squared distances.
            self._const = float(alpha @ (tgt**2).sum(1) + wr @ (q**2).sum(1)
                                - tot @ (folded**2).sum(1))
            tgt, alpha = folded, tot
        self._iso_targets = tgt
        self.alpha = alpha

    def block(self, world, jacobian=True):
        if self.targets is None:
            self.update(world)
        blocks = []
        plane = self._plane
        a = self.alpha
        if a.any():
            r = self._iso_targets - world
            sq = max(float(a @ np.einsum("ij,ij->i", r, r)) + self._const, 0.0)
            blocks.append(IsotropicRows(a, r, sq, 0.0 if plane else float(a.sum()),
                               3 * int((a > 0).sum())))
        if plane is not None:
            nq, w = plane
            rp = np.einsum("ij,ij->i", self.targets - world, nq)
            blocks.append(ScalarRows(None, nq, rp, w, float(w @ rp**2), float(w.sum()),
                                   int((w > 0).sum())))
        if not blocks:
            blocks.append(IsotropicRows(a, np.zeros_like(world), 0.0, 0.0, 0))
        return blocks
