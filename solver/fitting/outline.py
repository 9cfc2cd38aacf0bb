"""The head's outline in a photo: which vertices can form it (the candidates) and the rows
that pull a traced outline onto the silhouette of the posed model (thesis §4.4.1)."""

import numpy as np
from scipy.spatial import cKDTree

from ..cameras import OrthographicCamera
from ..geometry import vertex_normals
from ..memo import memo
from .rows import CameraRows, ScalarRows

# Outline rows are always kept within this many sigmas of the placement noise.
CONTOUR_KEEP_SIGMAS = 3.0
# A traced point's row fades out over this fraction of the cut-off either side of it
# (docs/DECISIONS.md, "The outline's cut-off fades").
SOFT_CUT = 0.25


#: An outline point's normal comes from the outline this many pixels either side of it.
NORMAL_SPAN_PX = 10.0

#: The landmarks whose height is the neck's base: below it the head model's neck widens
#: into shoulders (:func:`body_vertices`).
NECK_BASE = ("neck_base_left", "neck_base_right")


def body_vertices(model):
    """Which vertices lie below the neck's base, (V,) bool: the neck's foot and the
    shoulders (the mean head's height under that of the ``NECK_BASE`` landmarks). What a
    photo's outline shows there is the body under the clothes, or clothes coloured as skin,
    which the head model predicts less well than the head itself; its rows get a noise of
    their own (``noise.Noise.body_px``)."""
    def make():
        z = np.asarray(model.vertices, dtype=np.float64)[:, 2]
        return z < float(np.mean([z[model.landmark_vertex(n)] for n in NECK_BASE]))

    return memo(model, "body_vertices", make)


def body_weights(on_body, scale):
    """Each outline row's weight factor, (k,): ``scale`` (a view's
    ``noise.Noise.body_factor``) where the row meets the silhouette below the neck's base
    (``on_body`` (k,) bool), else 1."""
    return np.where(on_body, scale, 1.0)


def _median(x):
    """``np.median`` of a 1-D float array without NaN, to the bit, for a fraction of its
    call (once per outline update)."""
    n = len(x)
    k = n // 2
    if n % 2:
        return float(np.partition(x, k)[k])
    part = np.partition(x, (k - 1, k))
    return float((part[k - 1] + part[k]) / 2.0)


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
    shape to close a gap that is not noise. The cut fades: a row's weight falls smoothly
    from full to none over ``SOFT_CUT`` of that limit either side of it, and the cost
    counts the rest of the point at the cut-off, so a point near the limit moves the fit
    a little, not all or nothing.

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
    normal_span_px : float
        A point's normal is taken across the outline this far either side of it, pixels.
    body : array_like of bool, shape (n,), optional
        Which candidates lie below the neck's base (:func:`body_vertices`); a row whose
        silhouette point lies on such an edge weighs ``body_scale`` times as much
        (:func:`body_weights`).
    body_scale : float
    name : str
    """

    _face_corners = None

    def __init__(self, vertices, pixels, camera, weights=1.0, faces=None, edges=None,
                 max_distance=20.0, reject_factor=3.0, keep_distance=3.0, spacing_px=6.0,
                 normal_span_px=NORMAL_SPAN_PX, body=None, body_scale=1.0, name="contour"):
        self.name = name
        self.vertices = np.asarray(vertices, dtype=np.intp)
        self.body = np.zeros(len(self.vertices), bool) if body is None \
            else np.asarray(body, dtype=bool).reshape(-1)
        self.body_scale = float(body_scale)
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
        ahead = np.stack([np.interp(arc + normal_span_px, arc, p[:, k]) for k in (0, 1)], 1)
        behind = np.stack([np.interp(arc - normal_span_px, arc, p[:, k]) for k in (0, 1)], 1)
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
        self._reset()

    def _reset(self):
        self._reset_rows()
        self.cap = self.max_distance  # residual a point without a row counts as (pixels)
        self._updated = False
        self._last = None  # (camera, world) of the last update

    def _reset_rows(self):
        self.factors = np.zeros(0)  # each row's share of its point's weight
        self.points = np.zeros(0, np.intp)  # traced point of each row
        self.ends = np.zeros((0, 2), np.intp)  # candidate indices of its rim edge
        self.fractions = np.zeros(0)  # t along that edge

    @property
    def selected(self):
        """The candidate nearer each row's silhouette point, (k,)."""
        return np.where(self.fractions < 0.5, self.ends[:, 0], self.ends[:, 1])

    def rim(self, world):
        """Edges (a, b) among the candidates on the contour generator of the posed head,
        (E', 2) candidate indices."""
        return self.rim_edges(world)[:, :2]

    def rim_edges(self, world):
        """The rows of ``edges`` (a, b, face 1, face 2) on the contour generator of the
        posed head: one of their faces turned to the camera, the other away."""
        return self._rim_and_pixels(world)[0]

    def _rim_and_pixels(self, world):
        """(:meth:`rim_edges`, the candidates' projections (n, 2) or None). Through an
        orthographic camera a face turns to it exactly when its projection keeps its
        winding, so every candidate is projected once, and the projections serve the
        rim's edges too; other cameras compare each face's normal with the direction
        toward the camera."""
        f0, f1, f2 = self._corners()
        pixels = None
        if isinstance(self.camera, OrthographicCamera):
            pixels = self.camera.project(world)
            # the corners' u and v gathered one coordinate at a time (a third of the time
            # of gathering (F, 2) rows): the face's edges p1 - p0 and p2 - p0
            pu, pv = pixels[:, 0], pixels[:, 1]
            u0, v0 = pu.take(f0), pv.take(f0)
            # the sign of a turned-to face's projected area: its normal (the 2-D cross
            # product of its edges) seen along r0 x r1 (the image axes' normal) against
            # the direction toward the camera
            (a0, a1, a2), (b0, b1, b2) = self.camera.rotation[:2].tolist()
            t0, t1, t2 = self.camera.toward_camera(world[:1])[0].tolist()
            winding = (a1 * b2 - a2 * b1) * t0 + (a2 * b0 - a0 * b2) * t1 \
                + (a0 * b1 - a1 * b0) * t2
            area = (pu.take(f1) - u0) * (pv.take(f2) - v0) \
                - (pv.take(f1) - v0) * (pu.take(f2) - u0)
            facing = area * winding > 0
        else:
            a = world[f0]
            u, v = world[f1] - a, world[f2] - a
            normal = np.empty_like(u)  # u x v, the products np.cross takes, in its order
            normal[:, 0] = u[:, 1] * v[:, 2] - u[:, 2] * v[:, 1]
            normal[:, 1] = u[:, 2] * v[:, 0] - u[:, 0] * v[:, 2]
            normal[:, 2] = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
            toward = np.asarray(self.camera.toward_camera((a + world[f1] + world[f2]) / 3.0),
                                dtype=np.float64)
            facing = np.einsum("ij,ij->i", normal, toward) > 0
        return self.edges[facing[self.edges[:, 2]] != facing[self.edges[:, 3]]], pixels

    def _corners(self):
        """The faces' first, second and third corners, three contiguous (F,) arrays."""
        if self._face_corners is None:
            self._face_corners = tuple(np.ascontiguousarray(self.faces[:, k]) for k in range(3))
        return self._face_corners

    def _projected_edges(self, world, e, pixels=None):
        """Edges ``e`` (E, 2) in the photo: each one's first end and its direction,
        ((E, 2), (E, 2)) pixels (each vertex projected once; ``pixels``, the candidates'
        projections, when already known)."""
        if pixels is not None:
            ends = pixels[e]
            return ends[:, 0], ends[:, 1] - ends[:, 0]
        # the vertices used, sorted, and where each end is among them (np.unique's
        # answer, by a mark per candidate instead of a sort)
        mark = np.zeros(len(world), bool)
        mark[e.ravel()] = True
        used = np.flatnonzero(mark)
        at = np.cumsum(mark) - 1
        ends = self.camera.project(world[used])[at[e]]  # (E, 2, 2)
        return ends[:, 0], ends[:, 1] - ends[:, 0]

    def _unchanged(self, world):
        """Whether ``world`` is the head of the last update through the same camera (a cost
        evaluation, then the next solve's first build): the outline found then stands."""
        last = self._last
        if last is not None and last[0] is self.camera and last[1].shape == world.shape \
                and np.abs(last[1] - world).max(initial=0.0) < 1e-12:
            return True
        self._last = (self.camera, world.copy())
        return False

    def update(self, world):
        if self._unchanged(world):
            return
        rim, pixels = self._rim_and_pixels(world)
        e = rim[:, :2]
        points, ends, frac = np.zeros(0, np.intp), np.zeros((0, 2), np.intp), np.zeros(0)
        cap = self.max_distance
        if len(e):
            a, d = self._projected_edges(world, e, pixels)
            # Edges whose middle is within reach of a point (max_distance plus the longest
            # half edge), as flat (point, edge) pairs.
            reach = self.max_distance + 0.5 * float(np.linalg.norm(d, axis=1).max())
            near = self.tree.sparse_distance_matrix(cKDTree(a + 0.5 * d), reach,
                                                    output_type="ndarray")
            pi, ei = near["i"].astype(np.intp), near["j"].astype(np.intp)
            # q + s n = a + t d  (2-D cross products), a coordinate at a time: gathering
            # (m, 2) rows costs twice as much as two columns
            nx, ny = self.normals[:, 0].take(pi), self.normals[:, 1].take(pi)
            dx, dy = d[:, 0].take(ei), d[:, 1].take(ei)
            den = dx * ny - dy * nx
            ok = np.abs(den) > 1e-12
            den = np.where(ok, den, 1.0)
            qx = self.pixels[:, 0].take(pi) - a[:, 0].take(ei)
            qy = self.pixels[:, 1].take(pi) - a[:, 1].take(ei)
            t = (qx * ny - qy * nx) / den
            s = (qx * dy - qy * dx) / den
            ok &= (t >= 0.0) & (t <= 1.0) & (np.abs(s) <= self.max_distance)
            pi, ei, t, s = pi[ok], ei[ok], t[ok], s[ok]
            # per point the outermost crossing (largest s)
            order = np.lexsort((-s, pi))
            first = order[np.concatenate([[True], pi[order][1:] != pi[order][:-1]])] \
                if len(order) else order
            points, ends, frac, off = pi[first], e[ei[first]], t[first], np.abs(s[first])
            factors = np.ones(len(off))
            if self.reject_factor is not None and len(off):
                limit = max(self.reject_factor * _median(off), self.keep_distance)
                x = np.clip(((1 + SOFT_CUT) * limit - off) / (2 * SOFT_CUT * limit), 0, 1)
                factors = x * x * (3 - 2 * x)  # smoothstep: 1 well inside, 0 beyond
                keep = factors > 0
                points, ends, frac, factors = points[keep], ends[keep], frac[keep], factors[keep]
                cap = min(limit, self.max_distance)
        else:
            factors = np.zeros(0)
        self.points, self.ends, self.fractions, self.cap = points, ends, frac, cap
        self.factors = factors
        self._updated = True

    def unmatched_cost(self):
        """What the traced points without a row add to the cost: ``w cap^2`` each, as if
        they lay at the cut-off (a truncated quadratic), and so does the share of its
        weight a fading row lost. Without it a head that loses rows
        lowers its cost by the rows it dropped, and the fit, which keeps the lowest cost,
        drifts to heads whose outline misses awkward points."""
        missing = np.ones(len(self.pixels), bool)
        missing[self.points] = False
        part = float(self.point_weights[self.points] @ (1.0 - self.factors))
        return (float(self.point_weights[missing].sum()) + part) * self.cap**2

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
        w = self.row_weights
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

    @property
    def row_weights(self):
        """The weights of the current rows, (k,)."""
        return self.point_weights[self.points] * self.factors \
            * body_weights(self.body_rows, self.body_scale)

    @property
    def body_rows(self):
        """Whether each current row meets the silhouette below the neck's base, (k,)."""
        return self.body[self.selected]

    def pairs(self, world):
        """(candidate indices, pixels) of the current rows for a camera refit consistent
        with this cost: each row's nearer edge end, and where the row pulls it (its
        projection moved across the outline by the row's residual)."""
        sel = self.selected
        if not len(sel):
            return sel, np.zeros((0, 2))
        r = self.residuals(world)
        return sel, self.camera.project(world[sel]) + r[:, None] * self.row_normals


class OutlinePointRows(ContourRows):
    """Landmarks that are points of the head's outline in their photo (the jaw and chin of
    a front photo, ``assets/landmarks.json`` "outline"), each pulled across the posed
    model's silhouette there, not onto a fixed vertex: the outline moves over the surface
    as the head turns and as its shape changes, and where along it a person or a detector
    puts such a point is loosely defined.

    Each landmark q is matched to its nearest point s on the projected rim (an edge
    (a, b) at a fraction t, as in :class:`ContourRows`); the row is
    ``w (n . (q - s))^2`` with n the rim's outward normal there: across the outline is
    what the landmark measures, along it the silhouette may slide. The nearest rim, not
    the outermost: the jaw's outline in front of the ear lies inside the ear's. A landmark
    farther than ``max_distance`` from every rim edge gets no row (and counts as at that
    distance, :meth:`unmatched_cost`).

    Parameters
    ----------
    vertices : array_like of int, shape (n,)
        Copies of the outline candidates.
    pixels : array_like, shape (m, 2)
        The landmarks, one row each.
    camera : Camera
    weights : array_like, shape (m,)
        Weight of each landmark's row.
    faces, edges : ndarray
        The candidates' mesh (see :class:`ContourRows`).
    max_distance : float
    name : str
    """

    def __init__(self, vertices, pixels, camera, weights, faces, edges, max_distance=20.0,
                 name="outline points"):
        self.name = name
        self.vertices = np.asarray(vertices, dtype=np.intp)
        self.camera = camera
        self.faces = np.asarray(faces, dtype=np.intp).reshape(-1, 3)
        self.edges = np.asarray(edges, dtype=np.intp).reshape(-1, 4)
        self.pixels = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        self.point_weights = np.asarray(weights, dtype=np.float64).reshape(-1)
        if self.point_weights.shape != (len(self.pixels),):
            raise ValueError(f"{name}: {len(self.point_weights)} weights for "
                             f"{len(self.pixels)} points")
        self.normals = np.zeros((len(self.pixels), 2))
        self.max_distance = float(max_distance)
        self.reject_factor = None
        self.body, self.body_scale = np.zeros(len(self.vertices), bool), 1.0
        self._reset()

    def update(self, world):
        if self._unchanged(world):
            return
        rim, pixels = self._rim_and_pixels(world)
        self._reset_rows()
        if not len(rim) or not len(self.pixels):
            self._updated = True
            return
        e = rim[:, :2]
        a, d = self._projected_edges(world, e, pixels)
        # each landmark's nearest rim point among the edges with the nearest middles
        k = min(16, len(e))
        _, near = cKDTree(a + 0.5 * d).query(self.pixels, k=k)
        near = near.reshape(len(self.pixels), k)
        da = d[near]
        qa = self.pixels[:, None, :] - a[near]
        t = np.clip(np.einsum("mkj,mkj->mk", qa, da)
                    / np.maximum(np.einsum("mkj,mkj->mk", da, da), 1e-24), 0.0, 1.0)
        gap = np.linalg.norm(qa - t[..., None] * da, axis=2)
        pick = np.argmin(gap, axis=1)
        rows = np.arange(len(self.pixels))
        edge, t, gap = near[rows, pick], t[rows, pick], gap[rows, pick]
        normal = np.stack([d[edge, 1], -d[edge, 0]], axis=1)
        length = np.linalg.norm(normal, axis=1)
        keep = (gap <= self.max_distance) & (self.point_weights > 0) & (length > 1e-9)
        normal = normal / np.maximum(length, 1e-12)[:, None]
        # outward: away from the edge's first face (both faces of a fold project inside)
        face = self.faces[rim[edge, 2]]
        inside = (self.camera.project(world[face.reshape(-1)]) if pixels is None
                  else pixels[face.reshape(-1)]).reshape(-1, 3, 2).mean(axis=1)
        middle = a[edge] + 0.5 * d[edge]
        flip = np.einsum("ij,ij->i", normal, middle - inside) < 0
        normal[flip] *= -1.0
        self.points = rows[keep]
        self.factors = np.ones(len(self.points))  # no cut-off to fade: max_distance only
        self.ends = e[edge[keep]]
        self.fractions = t[keep]
        self.normals = np.zeros_like(self.normals)
        self.normals[self.points] = normal[keep]
        self._updated = True


class OutlineAlongRows(CameraRows):
    """The other half of a sliding landmark: where along the outline it lies, pulled to its
    vertex with its own, looser weight (thesis-style landmark row, projected on the
    outline's tangent). A person or a detector puts a jaw point on the outline, but only
    roughly where the name says along it; how roughly is estimated like any noise
    (``noise.Noise.along_px``): tight placements keep the vertex's information, loose ones
    let the point slide.

    Row i is ``w_i (t_i . (q_i - P(x_i)))^2`` with t_i the outline's tangent where
    ``outline`` (the :class:`OutlinePointRows` of the same landmarks, updated first) met it;
    a landmark that met no outline keeps both coordinates, as a fixed landmark does.

    Parameters
    ----------
    vertices : array_like of int, shape (m,)
        Copies of the landmarks' vertices.
    pixels : array_like, shape (m, 2)
    camera : Camera
    weights : array_like, shape (m,)
    outline : OutlinePointRows
        Rows of the same landmarks in the same order.
    name : str
    """

    def __init__(self, vertices, pixels, camera, weights, outline, name="outline along"):
        self.name = name
        self.vertices = np.asarray(vertices, dtype=np.intp)
        self.camera = camera
        self.pixels = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        self.weights = np.asarray(weights, dtype=np.float64).reshape(-1)
        self.outline = outline
        self.directions = np.tile(np.eye(2), (len(self.pixels), 1, 1))  # (m, 2, 2) rows

    def update(self, world):
        d = np.tile(np.eye(2), (len(self.pixels), 1, 1))
        pts = self.outline.points
        if len(pts):
            n = self.outline.row_normals
            d[pts, 0] = np.stack([-n[:, 1], n[:, 0]], axis=1)
            d[pts, 1] = 0.0
        self.directions = d

    def residuals(self, world):
        """(m, 2) rows' residuals: along the tangent (and 0), or both coordinates."""
        return np.einsum("mij,mj->mi", self.directions, self.pixels - self.camera.project(world))

    def block(self, world, jacobian=True):
        r = self.residuals(world)
        sq = float(self.weights @ np.einsum("ij,ij->i", r, r))
        used = np.any(self.directions != 0, axis=2)  # (m, 2)
        nrows = int(used[self.weights > 0].sum())
        if not jacobian:
            return ScalarRows(None, None, None, None, sq, float(self.weights.sum()), nrows)
        m = len(self.pixels)
        jac = np.asarray(self.camera.jacobian(world), dtype=np.float64).reshape(m, 2, 3)
        g = np.einsum("mij,mjk->mik", self.directions, jac)
        return ScalarRows(np.repeat(np.arange(m), 2), g.reshape(2 * m, 3), r.reshape(-1),
                          np.repeat(self.weights, 2), sq, float(self.weights.sum()), nrows)


def mean_normals(model):
    """Unit vertex normals of the mean head (area-weighted face normals), (V, 3), computed
    once per model."""
    return memo(model, "mean normals",
                lambda: vertex_normals(model.vertices, model.triangles()[0]))


def candidate_mesh(model, verts):
    """Triangles among candidate vertices and the edges two of them share.

    Returns
    -------
    faces : ndarray, shape (F, 3)
        Triangles whose corners are all candidates, as indices into ``verts``.
    edges : ndarray, shape (E, 4)
        Edges shared by exactly two of those triangles: (a, b, face 1, face 2).
    """
    tri, _, _ = model.triangles()
    local = np.full(model.n_vertices, -1, dtype=np.int64)
    local[verts] = np.arange(len(verts))
    faces = local[tri]
    faces = faces[(faces >= 0).all(axis=1)]
    return faces, shared_edges(faces, len(verts))


def shared_edges(faces, n_vertices):
    """Edges shared by exactly two of the triangles ``faces`` (F, 3) over ``n_vertices``
    vertices: (E, 4) as (a, b, face 1, face 2), a < b."""
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    # edges with their two faces: sort the 3F half-edges by their vertex pair
    half = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    owner = np.tile(np.arange(len(faces)), 3)
    half = np.sort(half, axis=1)
    key = half[:, 0] * n_vertices + half[:, 1]
    order = np.argsort(key, kind="stable")
    key, half, owner = key[order], half[order], owner[order]
    # exactly two faces per edge (an edge on three would be a defect; it is skipped)
    same = np.flatnonzero(key[1:] == key[:-1])
    two = same[(same + 2 >= len(key)) | (key[np.minimum(same + 2, len(key) - 1)] != key[same])]
    two = two[(two == 0) | (key[np.maximum(two - 1, 0)] != key[two])]
    return np.column_stack([half[two, 0], half[two, 1], owner[two], owner[two + 1]])


#: The profile's outline candidates' normals face across the left-right axis within this
#: (|n_x| on the mean head: about 24 degrees of margin for a turned head or another
#: identity).
PROFILE_NORMAL_X = 0.4


def profile_normal_bound(views):
    """The |n_x| bound of the profile's outline candidates for ``views`` (``ViewData``):
    ``PROFILE_NORMAL_X``, its margin widened by the most an orthographic side photo's
    camera looks off the left-right axis (a side photo short of a profile,
    ``OrthographicCamera.turned``, has the far cheek on its outline)."""
    off = 0.0
    for v in views:
        cam = v.camera
        if cam is None or cam.perspective or not v.side:
            continue
        d = np.asarray(cam.rotation, dtype=np.float64)[2]
        off = max(off, float(np.arccos(min(1.0, abs(d[0]) / np.linalg.norm(d)))))
    if off == 0.0:
        return PROFILE_NORMAL_X
    return float(np.sin(min(np.arcsin(PROFILE_NORMAL_X) + off, np.pi / 2)))


def outline_candidates(model, max_x=0.05, max_normal_x=PROFILE_NORMAL_X):
    """Vertices that can form the head's outline in a profile photo, with their mesh
    (computed once per model and bound): skin within ``max_x`` metres of the midsagittal
    plane whose normals (of the mean head) face across the left-right axis (|n_x| <
    ``max_normal_x``: ``profile_normal_bound``).

    Returns
    -------
    vertices : ndarray, shape (n,)
    faces : ndarray, shape (F, 3)
        Triangles whose corners are all candidates, as indices into ``vertices``.
    edges : ndarray, shape (E, 4)
        Edges shared by exactly two of those triangles: (a, b, face 1, face 2).
    """
    def make():
        v = model.vertices
        normal = mean_normals(model)
        skin = np.asarray(model.skin, dtype=np.int64)
        keep = (np.abs(v[skin, 0]) < max_x) & (np.abs(normal[skin, 0]) < max_normal_x)
        verts = np.union1d(skin[keep], np.asarray(model.profile_chain, dtype=np.int64))
        return (verts, *candidate_mesh(model, verts))

    return memo(model, ("outline_candidates", max_x, max_normal_x), make)


def view_outline(model, eng, state, view, margin=1.5):
    """Outline candidates of a photo that is not an orthographic profile (a front or
    three-quarter view, a perspective photo at any angle): the skin vertices of the head at
    ``state`` that the view's camera in ``state`` projects within ``margin`` times the
    contour threshold of the traced outline, with their mesh; ``ContourRows`` finds the
    outline among them each round (the outermost rim, so the inner folds near the outline,
    the far side of the nose or an ear's inner rim, do no harm).

    Every vertex near the outline, whatever way it faces: an ear is thin, and its outline
    runs along edges between faces that turn from the camera to across it within a
    millimetre or two, so a band of normals that face across the line of sight (on the
    mean head) misses some of their corners, and a traced point there meets no rim even on
    the true head. The margin (30 px by default) leaves room for the head to move during
    a stage; rows form only within the contour threshold anyway.

    Returns
    -------
    (vertices (n,), faces (F, 3), edges (E, 4))
    """
    skin = np.asarray(model.skin, dtype=np.int64)
    world = eng.world(state, skin)
    camera = state.cameras[view.name]
    dist, _ = cKDTree(outline_pixels(view)).query(camera.project(world))
    verts = skin[dist <= margin * eng.contour_threshold]
    return (verts, *candidate_mesh(model, verts))


def outline_pixels(view):
    """What of ``view`` lies on the head's outline: its traced outline's points and its
    sliding landmarks (``ViewData.slide``), (m, 2) pixels."""
    parts = [view.pixels[view.slide & (view.weights > 0)]]
    if view.contour is not None:
        parts.append(view.contour)
    return np.vstack(parts)


def own_outline_views(eng, state):
    """The views whose outline (traced, or of sliding landmarks) is matched to candidates
    of their own (:func:`view_outline`): every one but an orthographic profile's (a
    perspective photo from the side sees more than the midline: the rays to the outline
    fan out over the head)."""
    return [v for v in eng.views if len(outline_pixels(v))
            and not (v.side and not state.cameras[v.name].perspective)]


def view_outlines(model, eng, state):
    """Outline candidates found on the head of ``state`` for every view that does not use
    the profile's (:func:`own_outline_views`): view name -> (vertices, faces, edges),
    for ``Engine.joint(..., outlines=)``. A value, not kept on the views: each approach
    finds them on its own head, where it uses them."""
    return {v.name: view_outline(model, eng, state, v) for v in own_outline_views(eng, state)}

