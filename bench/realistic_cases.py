"""Realistic cases for ``bench.bench_realistic``, and the surface distance that scores a fit.

- Out-of-model heads: a model identity (coefficients drawn as ``make_case`` draws them)
  plus a smooth displacement no model combination can express (Gaussian bumps with their
  part in the span of the identity modes and of a similarity projected out over the skin),
  optionally with an expression of ``model.expressions``, photographed like ``make_case``
  (orthographic front and right profile, 1024 px) with landmarks as people give them.
- Landmarks as people give them: per landmark a fixed definition bias plus random noise;
  the outline landmarks (iBUG 1-17, jaw and chin) on the head's apparent outline in the
  photo, anywhere on their own stretch of it; the profile's traced outline with 1-2 px
  noise.
- The real scan "james" (menpo3d's test data, BSD-3; read from a folder outside the
  repository): its mesh, its 68 landmarks mapped to iBUG numbers by the geometry, and
  its texture's two real photos, each calibrated by the DLT from the texture coordinates.
- The score: RMS distance from points sampled on the true surface to the fitted head's
  surface (point to triangle), after a similarity + ICP alignment of fit to truth.

Axes as everywhere in the project: metres, Blender axes (Z up, face toward -Y, subject's
left +X).
"""

import json
import os
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from solver import DLTCamera, LandmarkCase, OrthographicCamera, PinholeCamera, View, fit_dlt
from solver.cameras import ORTHO_VIEWS
from solver.detect.detected_case import detected_depth
from solver.detect.view_guess import point_uncertainty
from solver.fitting.register import register
from solver.geometry import rotation_from_vector, skew, vertex_normals
from solver.io.landmark_set import load_landmark_set
from solver.io.obj import read_obj as solver_read_obj
from solver.procrustes import Similarity, similarity_procrustes
from solver.synthetic import (
    random_rotation,
    resample_polyline,
    trace_outline,
    trace_silhouette,
    visible_landmarks,
)
from solver.texture.raster import depth_buffer, rasterize

#: iBUG numbers of the outline landmarks (jaw and chin: points of the face's outline).
OUTLINE_IBUG = tuple(range(1, 18))
#: The one outline landmark kept in a profile photo: the menton (chin_bottom) lies on the
#: profile's outline; the other jaw and chin names have no clear place there.
PROFILE_OUTLINE_IBUG = (9,)

#: Expressions of the "with expression" cases: name -> {expression key: weight range}.
EXPRESSIONS = {
    "eyes closed": {"eyeBlink_L": (0.85, 1.0), "eyeBlink_R": (0.85, 1.0)},
    "slight smile": {"mouthSmile_L": (0.3, 0.5), "mouthSmile_R": (0.3, 0.5)},
    "jaw a little open": {"jawOpen": (0.15, 0.3)},
    "eyes closed, slight smile": {"eyeBlink_L": (0.85, 1.0), "eyeBlink_R": (0.85, 1.0),
                                  "mouthSmile_L": (0.3, 0.5), "mouthSmile_R": (0.3, 0.5)},
}


# ---------------------------------------------------------------- meshes and the score


def part_triangles(model, parts=("Face", "Head and Neck")):
    """Triangles (T, 3) of the model whose corners all belong to the named parts (the
    default: the skin)."""
    tri = model.triangles()[0]
    keep = np.isin(model.vertex_part, [model.part_names.index(p) for p in parts])
    return tri[keep[tri].all(axis=1)]


def triangles_within(triangles, mask):
    """The triangles whose three corners are in ``mask`` (a bool per vertex)."""
    return triangles[mask[triangles].all(axis=1)]


def sample_surface(vertices, triangles, n, rng):
    """``n`` points uniformly distributed over a triangle mesh's area, (n, 3)."""
    v = vertices[triangles]
    area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
    t = rng.choice(len(triangles), size=int(n), p=area / area.sum())
    r1, r2 = rng.random(int(n)), rng.random(int(n))
    s = np.sqrt(r1)
    return ((1 - s)[:, None] * v[t, 0] + (s * (1 - r2))[:, None] * v[t, 1]
            + (s * r2)[:, None] * v[t, 2])


def closest_on_triangles(p, a, b, c):
    """Closest point to each ``p`` on the triangle ``a b c`` (all (..., 3)); the region
    tests of Ericson's *Real-Time Collision Detection* §5.1.5, vectorised."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
    bp = p - b
    d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
    cp = p - c
    d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2

    def ratio(num, den):
        return np.divide(num, den, out=np.zeros_like(num), where=den != 0)

    den = va + vb + vc
    out = a + ab * ratio(vb, den)[..., None] + ac * ratio(vc, den)[..., None]
    # Later assignments win: from the interior out to the corners, as the tests' order.
    e = d4 - d3, d5 - d6
    regions = [
        ((va <= 0) & (e[0] >= 0) & (e[1] >= 0), b + (c - b) * ratio(e[0], e[0] + e[1])[..., None]),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + ac * ratio(d2, d2 - d6)[..., None]),
        ((d6 >= 0) & (d5 <= d6), c),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + ab * ratio(d1, d1 - d3)[..., None]),
        ((d3 >= 0) & (d4 <= d3), b),
        ((d1 <= 0) & (d2 <= 0), a),
    ]
    for mask, point in regions:
        out = np.where(mask[..., None], point, out)
    return out


def _subdivision_centroids(m):
    """Barycentric centroids (m*m, 3) of the m*m triangles of a triangle's regular
    subdivision (each edge cut into m)."""
    up = [(i + 1 / 3, j + 1 / 3) for i in range(m) for j in range(m - i)]
    down = [(i + 2 / 3, j + 2 / 3) for i in range(m - 1) for j in range(m - 1 - i)]
    b = np.array(up + down) / m
    return np.column_stack([1.0 - b.sum(axis=1), b])


class Surface:
    """A triangle mesh's surface, for point-to-surface distances.

    A KD-tree holds proxy points of the triangles: each triangle's centroid, or for a
    triangle longer than ``spacing`` the centroids of its regular subdivision, so every
    point of a triangle lies within ``reach`` (at most ``spacing``) of one of its proxies.
    A query takes the triangles of the ``k`` nearest proxies. Exactly: a triangle nearer
    than that best distance ``d`` has a proxy within ``d + reach``, so the triangles of
    all proxies in that ball are searched as well.
    """

    def __init__(self, vertices, triangles, k=8, spacing=0.002):
        self.vertices = np.asarray(vertices, dtype=np.float64)
        self.triangles = np.asarray(triangles, dtype=np.int64).reshape(-1, 3)
        corners = self.vertices[self.triangles]
        edge = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2).max(axis=1)
        cuts = np.maximum(np.ceil(edge / spacing), 1).astype(int)
        points, owner = [], []
        for m in np.unique(cuts):
            tri = np.flatnonzero(cuts == m)
            b = _subdivision_centroids(int(m))
            points.append(np.einsum("pk,tkd->tpd", b, corners[tri]).reshape(-1, 3))
            owner.append(np.repeat(tri, len(b)))
        self.owner = np.concatenate(owner)
        self.reach = float((edge / cuts).max())
        self.tree = cKDTree(np.concatenate(points))
        self.k = int(min(k, len(self.owner)))

    def _pairs(self, p, point, tri):
        """Distances and closest points of the (point index, triangle) pairs."""
        c = self.vertices[self.triangles[tri]]
        q = closest_on_triangles(p[point], c[:, 0], c[:, 1], c[:, 2])
        return np.linalg.norm(q - p[point], axis=1), q

    def closest(self, points, exact=True):
        """(distances (n,), closest surface points (n, 3)) of points (n, 3); with
        ``exact`` False, among the triangles of the k nearest proxies only (what an ICP
        step needs)."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        n = len(p)
        pd, pi = self.tree.query(p, k=self.k)
        pd, pi = pd.reshape(n, -1), pi.reshape(n, -1)
        point = np.repeat(np.arange(n), pi.shape[1])
        d, q = self._pairs(p, point, self.owner[pi.ravel()])
        j = np.argmin(d.reshape(n, -1), axis=1) + np.arange(n) * pi.shape[1]
        dist, best = d[j], q[j]
        todo = np.flatnonzero(dist > pd[:, -1] - self.reach) if exact else []
        if len(todo):
            balls = self.tree.query_ball_point(p[todo], dist[todo] + self.reach)
            size = np.array([len(b) for b in balls])
            point = np.repeat(todo, size)
            tri = self.owner[np.concatenate([np.asarray(b, dtype=np.int64) for b in balls])]
            pair = np.unique(point * len(self.triangles) + tri)
            point, tri = pair // len(self.triangles), pair % len(self.triangles)
            d, q = self._pairs(p, point, tri)
            order = np.lexsort((d, point))
            first = order[np.r_[True, point[order][1:] != point[order][:-1]]]
            better = d[first] < dist[point[first]]
            dist[point[first][better]] = d[first][better]
            best[point[first][better]] = q[first][better]
        return dist, best


def align_icp(surface, samples, start, iterations=30, tolerance=1e-3, tangential=0.1):
    """The similarity that best lays a mesh (a :class:`Surface`) onto sample points of the
    true surface: ICP from ``start`` (a Similarity mesh -> truth), each step a Gauss-Newton
    step of the distances from the samples to their closest points on the mesh (point to
    plane, the plane normal to the distance's direction, plus ``tangential`` times point
    to point), until the RMS distance falls by less than ``tolerance`` of itself.

    Returns
    -------
    Similarity
        Mesh -> truth.
    distances : ndarray (n,)
        Metres from each sample to the aligned mesh's surface (exact); their RMS is the
        score.
    """
    sim, best = start, (np.inf, start)
    for _ in range(iterations):
        d, q = surface.closest(sim.inverse().apply(samples), exact=False)
        rms = sim.scale * float(np.sqrt(np.mean(d**2)))
        if rms > best[0] * (1.0 - tolerance):
            break
        best = (rms, sim)
        x = sim.apply(q)
        r = samples - x
        length = np.linalg.norm(r, axis=1, keepdims=True)
        n = np.divide(r, length, out=np.zeros_like(r), where=length > 1e-12)
        c = x.mean(axis=0)
        xc = x - c
        # x -> c + (1 + sigma) R(omega) (x - c) + tau, linearised: unknowns sigma, omega, tau
        plane = np.column_stack([(n * xc).sum(axis=1), np.cross(xc, n), n])
        point = np.zeros((len(x), 3, 7))
        point[:, :, 0] = xc
        point[:, :, 1:4] = -skew(xc)
        point[:, :, 4:] = np.eye(3)
        w = np.sqrt(tangential)
        a = np.vstack([plane, w * point.reshape(-1, 7)])
        rhs = np.concatenate([(n * r).sum(axis=1), w * r.reshape(-1)])
        step = np.linalg.lstsq(a, rhs, rcond=None)[0]
        rot = rotation_from_vector(step[1:4])
        grow = 1.0 + step[0]
        sim = Similarity(grow * sim.scale, rot @ sim.rotation,
                         grow * rot @ (sim.translation - c) + c + step[4:])
    sim = best[1]
    return sim, sim.scale * surface.closest(sim.inverse().apply(samples))[0]


# ---------------------------------------------------------------- the face region


def face_frame(ibug):
    """Origin (the menton, iBUG 9) and unit axes (subject's left, up, forward) of a face
    from its iBUG landmarks (dict number -> (3,) point): left from the right eye's centre
    to the left's, up from the menton toward the eyes (made orthogonal to left), forward
    = left x up (Blender: +X x +Z = -Y, the way the face looks)."""
    eye_r = np.mean([ibug[i] for i in range(37, 43)], axis=0)
    eye_l = np.mean([ibug[i] for i in range(43, 49)], axis=0)
    left = (eye_l - eye_r) / np.linalg.norm(eye_l - eye_r)
    up = 0.5 * (eye_l + eye_r) - ibug[9]
    up -= (up @ left) * left
    up /= np.linalg.norm(up)
    return ibug[9], left, up, np.cross(left, up)


def face_mask(points, ibug, forehead=0.02):
    """Which points lie in the face region: above the menton (iBUG 9), at most
    ``forehead`` metres above the brows' mean height (iBUG 18-27), and in front of the
    jaw's top points (iBUG 1 and 17, in front of the ears). The same rule on the model's
    mean head and on a scan's own landmarks, so both measure the same anatomy."""
    origin, _, up, forward = face_frame(ibug)
    rel = np.asarray(points) - origin
    h, f = rel @ up, rel @ forward
    brow = np.mean([(ibug[i] - origin) @ up for i in range(18, 28)])
    ear = np.mean([(ibug[i] - origin) @ forward for i in (1, 17)])
    return (h >= 0) & (h <= brow + forehead) & (f >= ear)


#: The face's parts, by iBUG numbers: the landmark groups the benchmarks report, and
#: the part a point of the face belongs to by its nearest landmark (``face_parts``).
FACE_PARTS = {"jaw": range(1, 18), "brows": range(18, 28), "nose": range(28, 37),
              "eyes": range(37, 49), "mouth": range(49, 69)}


def face_parts(points, ibug):
    """Part name -> which of ``points`` (n, 3) lie nearest to one of its landmarks
    (``FACE_PARTS``; ``ibug`` dict number -> (3,) point): where on the face an error is,
    by the same rule on the model and on a scan."""
    numbers = [i for r in FACE_PARTS.values() for i in r if i in ibug]
    marks = np.array([ibug[i] for i in numbers])
    near = np.asarray(numbers)[cKDTree(marks).query(np.asarray(points, float))[1]]
    return {name: np.isin(near, list(r)) for name, r in FACE_PARTS.items()}


def model_ibug(model, vertices):
    """iBUG number -> (3,) point of ``vertices`` (the model's topology)."""
    return {int(e["ibug"]): vertices[int(e["vertex"])] for e in model.landmark_info
            if e.get("ibug") is not None}


def model_face_vertices(model):
    """Bool per vertex: the skin vertices in the face region of the mean head."""
    mask = np.zeros(model.n_vertices, bool)
    mask[model.skin] = face_mask(model.vertices[model.skin], model_ibug(model, model.vertices))
    return mask


# ---------------------------------------------------------------- out-of-model heads


def span_basis(model, local, vertices):
    """Columns (3n, K + 7) over ``vertices``: the identity modes, and a similarity's
    seven moves of the head ``local`` (translations, rotations, scale)."""
    x = local[vertices]
    n = len(x)
    cols = [model.identity.basis[:, vertices, :].reshape(model.identity.n_coeffs, -1)]
    for axis in np.eye(3):
        cols.append(np.tile(axis, n)[None])
        cols.append(np.cross(axis, x).reshape(1, -1))
    cols.append(x.reshape(1, -1))
    return np.concatenate(cols).T


def out_of_model_displacement(model, local, rng, rms_m, n_bumps=6, radius=(0.012, 0.03)):
    """A smooth displacement of every vertex (V, 3) that no identity combination and no
    similarity can express over the skin: ``n_bumps`` Gaussian bumps (centres on the
    face region of ``local``, each a fixed direction: the outward normal there, either
    sign; widths uniform in ``radius`` metres), their least-squares part in the span of
    the identity modes and the similarity moves over the skin subtracted (from all
    vertices, with the same coefficients), scaled to ``rms_m`` RMS over the face
    region's vertices."""
    face = model_face_vertices(model)
    normals = vertex_normals(local, part_triangles(model))
    centres = rng.choice(np.flatnonzero(face), size=n_bumps, replace=False)
    widths = rng.uniform(*radius, size=n_bumps)
    amps = rng.normal(size=n_bumps)
    d = np.zeros_like(local)
    for c, r, a in zip(centres, widths, amps, strict=True):
        g = np.exp(-((local - local[c]) ** 2).sum(axis=1) / (2.0 * r * r))
        d += a * g[:, None] * normals[c]
    skin = span_basis(model, local, model.skin)
    coef = np.linalg.lstsq(skin, d[model.skin].reshape(-1), rcond=None)[0]
    every = span_basis(model, local, np.arange(model.n_vertices))
    d -= (every @ coef).reshape(-1, 3)
    return d * (rms_m / np.sqrt((d[face] ** 2).sum(axis=1).mean()))


# ---------------------------------------------------------------- landmarks as people give them


@dataclass(frozen=True)
class Placement:
    """How a person places landmarks on one case: each landmark's fixed definition bias
    and its random noise (``bias_px`` and ``noise_px``: RMS lengths of 2-D offsets, so
    together about the 3-8 px by which real landmarks miss a perfect fit's landmark
    vertices), and the
    traced outline's noise (``contour_noise_px`` per coordinate, as ``make_case``)."""

    bias_px: float
    noise_px: float
    contour_noise_px: float

    @classmethod
    def draw(cls, rng, bias_px=(3.0, 5.0), noise_px=(3.0, 6.0), contour_noise_px=(1.0, 2.0)):
        return cls(float(rng.uniform(*bias_px)), float(rng.uniform(*noise_px)),
                   float(rng.uniform(*contour_noise_px)))


def depth_of(camera, points):
    """Depth of points along a camera's viewing direction, metres (orthographic too)."""
    if hasattr(camera, "depth"):
        return camera.depth(points)
    return points @ camera.rotation[2]


def visible(world, triangles, camera, normals, points=None, min_cos=0.0, tolerance=0.003):
    """Bool per point (default: every vertex): seen by ``camera``. The point's normal faces
    the camera (cosine above ``min_cos``), it falls inside the image, and no nearer part of
    the mesh covers it (a z-buffer at image resolution, slack ``tolerance`` metres plus what
    the slope allows within two pixels)."""
    x = world if points is None else points
    w, h = camera.size
    corner = world[triangles].reshape(-1, 3)
    buf = depth_buffer(camera.project(corner).reshape(-1, 3, 2),
                       depth_of(camera, corner).reshape(-1, 3), w, h)
    px = camera.project(x)
    inside = (px >= 0).all(axis=1) & (px[:, 0] < w) & (px[:, 1] < h)
    g = np.clip(np.floor(px).astype(int), 0, [w - 1, h - 1])
    cos = np.einsum("ij,ij->i", normals, camera.toward_camera(x))
    pixel = 1.0 / camera.pixels_per_metre(x)  # metres per pixel
    slope = np.minimum(np.sqrt(np.maximum(1.0 - cos**2, 0.0)) / np.maximum(cos, 1e-3), 20.0)
    near = depth_of(camera, x) <= buf[g[:, 1], g[:, 0]] + tolerance + 2.0 * pixel * slope
    return (cos > min_cos) & inside & near


def apparent_outline(world, triangles, camera, vertices, max_cos=0.2, outline=None):
    """Pixels (n, 2) where a person sees the head's outline in a photo: the visible
    ``vertices`` whose surface turns nearly edge-on to the camera (normal cosine below
    ``max_cos``: the cheek's and jaw's turn against the neck or the background), plus the
    traced outer outline when given."""
    normals = vertex_normals(world, triangles)[vertices]
    seen = visible(world, triangles, camera, normals, world[vertices], min_cos=0.0)
    cos = np.einsum("ij,ij->i", normals, camera.toward_camera(world[vertices]))
    px = camera.project(world[vertices][seen & (cos < max_cos)])
    return px if outline is None else np.vstack([px, outline])


def slide_on_outline(nominal, spacing, outline, rng, reach_px=25.0):
    """An outline landmark as a person places it: on the outline near its nominal pixel
    (the nearest outline point), moved along the outline uniformly within +-half of
    ``spacing``, the distance to its nearer neighbour (its own stretch; 2-15 px), and
    snapped back onto the outline. None when no outline point lies within
    ``reach_px`` (the landmark has no outline there)."""
    d = np.linalg.norm(outline - nominal, axis=1)
    i = int(np.argmin(d))
    if d[i] > reach_px:
        return None
    q0 = outline[i]
    near = outline[np.linalg.norm(outline - q0, axis=1) <= 6.0]
    if len(near) < 2:
        return q0
    tangent = np.linalg.svd(near - near.mean(axis=0))[2][0]
    half = float(np.clip(0.5 * spacing, 2.0, 15.0))
    target = q0 + rng.uniform(-half, half) * tangent
    return outline[int(np.argmin(np.linalg.norm(outline - target, axis=1)))]


def place_landmarks(names, nominal, placement, rng, outline=None, ibug=None):
    """Landmarks as a person gives them: (placed dict name -> (2,), names that had no
    outline near them). ``nominal`` (n, 2) are the true projections. An outline landmark
    (``ibug[name]`` in ``OUTLINE_IBUG``) goes on ``outline`` (see
    :func:`slide_on_outline`; its slide is its definition bias); the others get a fixed
    2-D bias; all get the random noise."""
    nominal = np.asarray(nominal, dtype=np.float64)
    ibug = ibug or {}
    chain = {ibug[n]: p for n, p in zip(names, nominal, strict=True)
             if ibug.get(n) in OUTLINE_IBUG}
    out, missed = {}, []
    for name, p in zip(names, nominal, strict=True):
        bias = rng.normal(size=2) * placement.bias_px / np.sqrt(2.0)
        noise = rng.normal(size=2) * placement.noise_px / np.sqrt(2.0)
        number = ibug.get(name)
        placed = None
        if number in OUTLINE_IBUG and outline is not None and len(outline):
            gaps = [np.linalg.norm(chain[j] - p) for j in (number - 1, number + 1) if j in chain]
            placed = slide_on_outline(p, min(gaps) if gaps else 10.0, outline, rng)
            if placed is None:
                missed.append(name)
        out[name] = (p + bias if placed is None else placed) + noise
    return out, missed


# ---------------------------------------------------------------- synthetic realistic heads


@dataclass
class RealisticTruth:
    """What a realistic synthetic case shows.

    Attributes
    ----------
    local_vertices : ndarray, (V, 3), metres
        The true head's neutral shape (identity + displacement, no expression): what a fit
        should recover, and what it is scored against.
    displacement_mm : float
        RMS of the out-of-model displacement over the face region's vertices.
    expression : dict
        {expression key: weight} of the head in the photos (empty: neutral).
    placement : Placement
    landmark_rms_px : float
        RMS distance of the given landmarks from the true projections of their vertices.
    missed_outline : list of str
        Outline landmarks placed as inner ones (no outline near them; "view/name").
    cameras : dict of str -> OrthographicCamera
    """

    local_vertices: np.ndarray
    displacement_mm: float
    expression: dict
    placement: Placement
    landmark_rms_px: float
    missed_outline: list
    cameras: dict = field(default_factory=dict)


def _camera(rng, cam_name, size, skin_world, fill=(0.75, 0.9)):
    """An orthographic photo framing the skin as ``make_case`` frames it: a random scale
    making the head fill ``fill`` of the height (and fit the width) and a random offset."""
    w, h = size
    rot = ORTHO_VIEWS[cam_name]
    a = skin_world @ rot[:2].T
    lo, hi = a.min(axis=0), a.max(axis=0)
    scale = min(rng.uniform(*fill) * h / (hi[1] - lo[1]), 0.95 * w / (hi[0] - lo[0]))
    corner = rng.uniform(0.2, 0.8, size=2) * (np.array([w, h]) - scale * (hi - lo))
    return OrthographicCamera(rot, scale, corner - scale * lo, size, cam_name)


def make_realistic_case(model, seed, expression=None, displacement_mm=(1.5, 3.0),
                        rotation_deg=5.0, image_height=1024, contour_points=100,
                        placement=None, front_outline=False, three_quarter=None):
    """A realistic synthetic case: an out-of-model head, photographed front and right
    profile (orthographic, 1024 px high, 3:4), landmarks as people give them; or from two
    three-quarter angles (``three_quarter``).

    Parameters
    ----------
    model : HeadModel
    seed : int
    expression : str, optional
        A key of ``EXPRESSIONS`` (weights drawn in its ranges); None: neutral.
    displacement_mm : (float, float)
        Range of the out-of-model displacement's RMS over the face.
    placement : Placement, optional
        How the landmarks are placed instead of the drawn one (the same head, cameras and
        outline stretches otherwise), e.g. ``Placement(0, 0, 0)``: exactly.
    front_outline : bool or str
        Trace the front photo's outline too (the head's silhouette there, as a
        segmentation would give it), with the profile's tracing noise; "face": only its
        stretch on the subject's right below the brows (the one skin run a photo of a
        person with hair shows on the person's edge).
    three_quarter : str, optional
        Photograph the head as james' photos are taken instead (``THREE_QUARTER``: two
        pinhole photos, 1200 x 1600 px, 1.5 m away, 30 degrees from the front on the
        subject's right and 21 on the left, cameras left for the fit to calibrate), the
        visible iBUG landmarks given, and trace of each photo's outline "none", the far
        "cheek" (temple to chin: what a photo of a person with hair shows as skin on the
        person's edge) or the whole "head" (a bald person).

    Returns
    -------
    case : LandmarkCase
    truth : RealisticTruth
    """
    rng = np.random.default_rng(seed)
    coeffs = rng.normal(size=model.identity.n_coeffs)
    identity = model.identity.instance(coeffs)
    rms = 1e-3 * float(rng.uniform(*displacement_mm))
    local = identity + out_of_model_displacement(model, identity, rng, rms)
    weights = {}
    if expression is not None:
        weights = {k: float(rng.uniform(*r)) for k, r in EXPRESSIONS[expression].items()}
    shown = local + model.expression_offsets(weights)
    rot = random_rotation(rng, rotation_deg)
    world = float(rng.uniform(0.95, 1.05)) * shown @ rot.T + rng.uniform(-0.01, 0.01, size=3)
    drawn = Placement.draw(rng)  # drawn either way, so the rest of the case stays the same
    placement = drawn if placement is None else placement

    if three_quarter is not None:
        views, cams, offsets, missed = _three_quarter_views(model, world, placement, rng,
                                                            three_quarter, contour_points)
    else:
        views, cams, offsets, missed = _front_profile_views(
            model, world, placement, rng, seed, image_height, contour_points, front_outline)
    truth = RealisticTruth(local, 1e3 * rms, weights, placement,
                           float(np.sqrt(np.mean(np.square(offsets)))), missed, cams)
    return LandmarkCase(views, "<realistic>"), truth


def _front_profile_views(model, world, placement, rng, seed, image_height, contour_points,
                         front_outline):
    """The front and right profile photos of ``make_realistic_case``: (views, cameras,
    landmark offsets, missed outline landmarks)."""
    h = int(image_height)
    size = (int(round(0.75 * h)), h)
    skin_tris = part_triangles(model)
    ibug = {e["name"]: int(e["ibug"]) for e in model.landmark_info if e.get("ibug")}
    views, cams, offsets, missed = {}, {}, [], []
    for view in ("front", "right"):
        cam = _camera(rng, f"orthographic-{view}", size, world[model.skin])
        cams[view] = cam
        names = [e["name"] for e in model.landmark_info if view in e.get("views", ())]
        contour = None
        traced = trace_silhouette(model, world, cam, skin_tris)
        if view == "front":
            outline = apparent_outline(world, skin_tris, cam, model.skin, outline=traced)
        else:
            names = [n for n in names if ibug.get(n) not in OUTLINE_IBUG
                     or ibug[n] in PROFILE_OUTLINE_IBUG]
            outline = traced
        if view == "right" or front_outline:
            drawn = traced
            if view == "front" and front_outline == "face":
                # the one skin run on the person's edge that a photo of a person with
                # hair shows (``solver detect`` keeps one run): the subject's right side
                drawn = _face_side(model, world, cam, traced, -1.0)
            contour = resample_polyline(drawn, contour_points)
            noise = rng.normal(size=contour.shape) if view == "right" \
                else np.random.default_rng([seed, 1]).normal(size=contour.shape)
            contour = np.clip(contour + placement.contour_noise_px * noise, 0.0, size)
        nominal = cam.project(world[[model.landmarks[n] for n in names]])
        placed, miss = place_landmarks(names, nominal, placement, rng, outline, ibug)
        missed += [f"{view}/{n}" for n in miss]
        pts = {n: np.clip(p, 0.0, size) for n, p in placed.items()}
        offsets += [np.linalg.norm(pts[n] - q) for n, q in zip(names, nominal, strict=True)]
        views[view] = View(name=view, image=None, size=size,
                           camera=OrthographicCamera.nominal(f"orthographic-{view}", size),
                           points=pts, contour=contour)
    return views, cams, offsets, missed


#: ``make_realistic_case(three_quarter=...)``'s photos: name -> degrees from the front
#: (positive: on the subject's right), as james' two photos are taken.
THREE_QUARTER = {"three_quarter_right": 30.0, "three_quarter_left": -21.0}
#: What of a three-quarter photo's outline is traced.
THREE_QUARTER_OUTLINES = ("none", "cheek", "head")


def _face_side(model, world, camera, traced, sign, to_chin=False):
    """The points of a traced outline (n, 2) on one side of the nose tip in the photo
    (``sign`` +1: beyond it along the image's u, -1: before it) below the brows' height,
    and with ``to_chin`` above the chin's: the face's side alone."""
    at = model.landmarks
    brow = camera.project(world[[at["brow_outer_left"], at["brow_outer_right"]]])[:, 1].min()
    nose, chin = camera.project(world[[at["nose_tip"], at["chin_bottom"]]])
    keep = (sign * (traced[:, 0] - nose[0]) > 0) & (traced[:, 1] > brow)
    if to_chin:
        keep &= traced[:, 1] < chin[1]
    return traced[keep]


def _three_quarter_views(model, world, placement, rng, outline, contour_points,
                         size=(1200, 1600), distance=1.5, f_px=6400.0):
    """The three-quarter photos of ``make_realistic_case``: (views, cameras, landmark
    offsets, missed outline landmarks)."""
    if outline not in THREE_QUARTER_OUTLINES:
        raise ValueError(f"three_quarter: one of {THREE_QUARTER_OUTLINES}, got {outline!r}")
    skin_tris = part_triangles(model)
    ibug = {e["name"]: int(e["ibug"]) for e in model.landmark_info if e.get("ibug")}
    at = model.landmarks
    target = world[at["nasion"]] + np.array([0.0, 0.05, -0.03])  # inside the head
    views, cams, offsets, missed = {}, {}, [], []
    for name, yaw in THREE_QUARTER.items():
        a = np.radians(yaw)
        cam = PinholeCamera.look_at(target + distance * np.array([-np.sin(a), -np.cos(a), 0.0]),
                                    target, size, f_px=f_px)
        cams[name] = cam
        names = [n for n in visible_landmarks(model, world, cam, triangles=skin_tris)
                 if n in ibug]
        traced = trace_silhouette(model, world, cam, skin_tris)
        contour = None
        noise = rng.normal(size=(contour_points, 2))  # drawn either way: the same landmarks
        if outline != "none":
            drawn = traced if outline == "head" else \
                _face_side(model, world, cam, traced, np.sign(yaw), to_chin=True)  # far side
            contour = resample_polyline(drawn, contour_points)
            contour = np.clip(contour + placement.contour_noise_px * noise, 0.0, size)
        seen = apparent_outline(world, skin_tris, cam, model.skin, outline=traced)
        nominal = cam.project(world[[at[n] for n in names]])
        placed, miss = place_landmarks(names, nominal, placement, rng, seen, ibug)
        missed += [f"{name}/{n}" for n in miss]
        pts = {n: np.clip(p, 0.0, size) for n, p in placed.items()}
        offsets += [np.linalg.norm(pts[n] - q) for n, q in zip(names, nominal, strict=True)]
        views[name] = View(name=name, image=None, size=size, camera=None, points=pts,
                           contour=contour, camera_hints={"kind": "pinhole"})
    return views, cams, offsets, missed


# ---------------------------------------------------------------- the real scan "james"

#: Environment variable naming the folder that holds ``james/`` (default: ``shared/realdata``
#: beside the checkout).
REALDATA_ENV = "HEADRECON_REALDATA"


def james_folder(root):
    """Where the scan "james" is looked for: ``$HEADRECON_REALDATA/james``, else
    ``<root>/../shared/realdata/james`` (``root``: the checkout)."""
    env = os.environ.get(REALDATA_ENV)
    base = Path(env) if env else Path(root).resolve().parent / "shared" / "realdata"
    return base / "james"


def jpeg_size(path):
    """(width, height) of a JPEG from its start-of-frame segment."""
    data = Path(path).read_bytes()
    i = 2
    while i + 9 < len(data):
        if data[i] != 0xFF:
            raise ValueError(f"{path}: not a JPEG segment at byte {i}")
        marker = data[i + 1]
        length = struct.unpack(">H", data[i + 2:i + 4])[0]
        if marker in (0xC0, 0xC1, 0xC2, 0xC3, 0xC5, 0xC6, 0xC7, 0xC9, 0xCA, 0xCB, 0xCD,
                      0xCE, 0xCF):
            height, width = struct.unpack(">HH", data[i + 5:i + 9])
            return width, height
        i += 2 + length
    raise ValueError(f"{path}: no JPEG frame header found")


def read_obj(path):
    """(vertices (n, 3), triangles (T, 3), texture coordinates (m, 2), the texture
    coordinate of each triangle corner (T, 3)) of a triangulated OBJ file, read with the
    solver's OBJ reader."""
    mesh = solver_read_obj(path)
    if (mesh.face_loop_total != 3).any():
        bad = int(mesh.face_loop_total[mesh.face_loop_total != 3][0])
        raise ValueError(f"{path}: a face with {bad} corners; expected triangles")
    return (mesh.positions, mesh.loop_vertex.reshape(-1, 3), mesh.uvs,
            mesh.loop_uv.reshape(-1, 3))


def obj_to_blender(points):
    """OBJ axes (Y up, front +Z) to Blender's: (x, y, z) -> (x, -z, y)."""
    p = np.asarray(points, dtype=np.float64)
    return np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=1)


def _ring(cycle, left, up):
    """A closed landmark contour (indices in its cyclic order) in iBUG order: the
    rightmost point (least ``left``), the upper arc toward the leftmost point, the
    leftmost point, then the lower arc back (iBUG's eyes and lips all run this way)."""
    n = len(cycle)
    lo, hi = int(np.argmin(left[cycle])), int(np.argmax(left[cycle]))
    one = [cycle[(lo + i) % n] for i in range(1, (hi - lo) % n)]
    two = [cycle[(lo - i) % n] for i in range(1, (lo - hi) % n)]
    upper, lower = (one, two) if np.mean(up[one]) > np.mean(up[two]) else (two, one)
    return [cycle[lo]] + upper + [cycle[hi]] + lower[::-1]


def _cycles(indices, edges):
    """The closed chains among ``indices`` (connected by ``edges``), each in its order."""
    nb = {i: [] for i in indices}
    for a, b in edges:
        if a in nb and b in nb:
            nb[a].append(b)
            nb[b].append(a)
    out, seen = [], set()
    for start in indices:
        if start in seen:
            continue
        chain, prev, cur = [start], None, start
        seen.add(start)
        while True:
            nxt = [j for j in nb[cur] if j != prev and j not in seen]
            if not nxt:
                break
            prev, cur = cur, nxt[0]
            chain.append(cur)
            seen.add(cur)
        out.append(chain)
    return out


def ibug_numbers(points, groups, edges):
    """The iBUG number of each of 68 face landmarks given in label groups (menpo's LJSON:
    "chin", two eyes, two eyebrows, "nose", "mouth"; the sides of "l" and "r" unknown), from
    the geometry alone.

    The face's axes come from side-free parts (up: from the chin group's middle point to
    the eyes; forward: toward the nose; the subject's left = up x forward, as in Blender's
    axes); then the eye and brow groups are told apart by that left axis, the chin runs
    from the subject's right (iBUG 1), the brows from right to left, the nose bridge top
    down, the nostrils right to left, and each eye and lip contour as :func:`_ring`.

    Returns
    -------
    ndarray of int, shape (68,)
        iBUG number (1-68) of each point.
    """
    p = np.asarray(points, dtype=np.float64)
    by_size = {}
    for name, idx in groups.items():
        by_size.setdefault((("brow" in name, "eye" in name), len(idx)), []).append(list(idx))
    chin = groups["chin"]
    eyes = by_size[((False, True), 6)]
    brows = by_size[((True, True), 5)]
    nose, mouth = list(groups["nose"]), list(groups["mouth"])
    e1, e2 = (p[e].mean(axis=0) for e in eyes)
    across = (e2 - e1) / np.linalg.norm(e2 - e1)
    up = 0.5 * (e1 + e2) - p[chin[len(chin) // 2]]
    up -= (up @ across) * across
    up /= np.linalg.norm(up)
    normal = np.cross(across, up)
    forward = normal if (p[nose] - 0.5 * (e1 + e2)).mean(axis=0) @ normal > 0 else -normal
    left = np.cross(up, forward)
    lc, uc = p @ left, p @ up
    number = np.zeros(len(p), dtype=int)
    run = list(chin) if lc[chin[0]] < lc[chin[-1]] else list(chin)[::-1]
    number[run] = np.arange(1, 18)
    right_first = sorted(brows, key=lambda g: lc[g].mean())
    number[sorted(right_first[0], key=lambda i: lc[i])] = np.arange(18, 23)
    number[sorted(right_first[1], key=lambda i: lc[i])] = np.arange(23, 28)
    by_height = sorted(nose, key=lambda i: -uc[i])
    number[by_height[:4]] = np.arange(28, 32)
    number[sorted(by_height[4:], key=lambda i: lc[i])] = np.arange(32, 37)
    eye_r, eye_l = sorted(eyes, key=lambda g: lc[g].mean())
    number[_ring(_cycles(eye_r, edges)[0], lc, uc)] = np.arange(37, 43)
    number[_ring(_cycles(eye_l, edges)[0], lc, uc)] = np.arange(43, 49)
    outer, inner = sorted(_cycles(mouth, edges), key=len, reverse=True)
    number[_ring(outer, lc, uc)] = np.arange(49, 61)
    number[_ring(inner, lc, uc)] = np.arange(61, 69)
    if sorted(number) != list(range(1, 69)):
        raise ValueError("landmarks: the groups do not make the 68 iBUG points")
    return number


@dataclass
class Scan:
    """A textured face scan in metres, Blender axes.

    Attributes
    ----------
    vertices : ndarray, (n, 3)
    triangles : ndarray, (T, 3)
    ibug : dict of int -> ndarray (3,)
        The 68 landmarks by iBUG number.
    photos : dict of str -> (vertex indices (m,), pixels (m, 2), size (w, h))
        Each photo of the texture and the vertex <-> pixel pairs it gives (vertices with
        one texture coordinate only: the seam's doubled ones disagree with the photos).
    corner_uv : ndarray, (T, 3, 2), optional
        Texture coordinates of each triangle's corners (0..1, v up).
    texture : Path, optional
        The texture image.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    ibug: dict
    photos: dict
    corner_uv: np.ndarray | None = None
    texture: Path | None = None

    @property
    def landmark_array(self):
        """The landmarks as (68, 3), iBUG order."""
        return np.array([self.ibug[i] for i in range(1, 69)])


def load_scan(folder, name="james"):
    """The scan ``<folder>/<name>.obj`` (mm), its landmarks ``<name>.ljson`` (mm, mapped to
    iBUG numbers by :func:`ibug_numbers`) and its texture ``<name>.jpg``'s two halves as
    photos "photo_a" (left half) and "photo_b" (right half)."""
    folder = Path(folder)
    v, tri, uv, tri_uv = read_obj(folder / f"{name}.obj")
    vertices = obj_to_blender(v) / 1000.0
    lj = json.loads((folder / f"{name}.ljson").read_text())["groups"]["LJSON"]
    pts = obj_to_blender(lj["landmarks"]["points"]) / 1000.0
    groups = {g["label"]: g["mask"] for g in lj["labels"]}
    number = ibug_numbers(pts, groups, lj["landmarks"]["connectivity"])
    width, height = jpeg_size(folder / f"{name}.jpg")
    pairs = np.unique(np.stack([tri.ravel(), tri_uv.ravel()], axis=1), axis=0)
    single = np.bincount(pairs[:, 0], minlength=len(vertices)) == 1
    pairs = pairs[single[pairs[:, 0]]]
    px = np.stack([uv[pairs[:, 1], 0] * width, (1.0 - uv[pairs[:, 1], 1]) * height], axis=1)
    half = width // 2
    photos = {}
    for photo, in_half, x0 in (("photo_a", px[:, 0] < half, 0), ("photo_b", px[:, 0] >= half,
                                                                  half)):
        photos[photo] = (pairs[in_half, 0], px[in_half] - [x0, 0.0], (half, height))
    return Scan(vertices, tri, {int(k): p for k, p in zip(number, pts, strict=True)}, photos,
                uv[tri_uv], folder / f"{name}.jpg")


@dataclass
class Calibration:
    """A photo's DLT camera from its vertex <-> pixel pairs, and how well it fits them."""

    camera: DLTCamera
    rms_px: float
    median_px: float
    max_px: float
    used: int
    pairs: int


def scan_photo_halves(folder, name="james"):
    """The scan's two real photos, the halves of its texture ``<name>.jpg``:
    {"photo_a": left half, "photo_b": right half}, each (H, W, 3) uint8 RGB."""
    from PIL import Image

    image = np.asarray(Image.open(Path(folder) / f"{name}.jpg").convert("RGB"))
    half = image.shape[1] // 2
    return {"photo_a": image[:, :half], "photo_b": image[:, half:2 * half]}


def calibrate(scan, photo, reject=4.0):
    """The 11-parameter DLT of one photo from its pairs, once refitted without the pairs
    farther than ``reject`` times the median residual (and 2 px) from the first fit."""
    verts, px, size = scan.photos[photo]
    x = scan.vertices[verts]
    first = fit_dlt(x, px, size)
    r = np.linalg.norm(first.residuals, axis=1)
    keep = r <= max(reject * np.median(r), 2.0)
    fit = fit_dlt(x, px, size, weights=keep.astype(float))
    r = np.linalg.norm(fit.residuals, axis=1)[keep]
    return Calibration(fit.camera, float(np.sqrt(np.mean(r**2))), float(np.median(r)),
                       float(r.max()), int(keep.sum()), len(keep))


def oriented_normals(vertices, triangles, ibug):
    """Vertex normals of a scan, turned to point out of the face (by the nose)."""
    n = vertex_normals(vertices, triangles)
    _, _, _, forward = face_frame(ibug)
    tip = int(np.argmin(np.linalg.norm(vertices - ibug[31], axis=1)))
    return n if n[tip] @ forward > 0 else -n


def boundary_vertices(triangles, n):
    """Bool per vertex: on the mesh's open boundary (:func:`boundary_edges`)."""
    out = np.zeros(n, bool)
    out[boundary_edges(triangles).ravel()] = True
    return out


def scan_landmarks(scan, camera, min_cos=0.0):
    """The scan's landmarks a photo shows (iBUG numbers, ascending) and their pixels: the
    normal of the nearest scan vertex faces the camera and the mesh does not cover them."""
    normals = oriented_normals(scan.vertices, scan.triangles, scan.ibug)
    pts = scan.landmark_array
    nearest = cKDTree(scan.vertices).query(pts)[1]
    seen = visible(scan.vertices, scan.triangles, camera, normals[nearest], pts, min_cos)
    numbers = [i + 1 for i in np.flatnonzero(seen)]
    return numbers, camera.project(pts[seen])


def scan_cases(scan, cameras, placement_seed=7000):
    """The scan's photos as cases: name -> LandmarkCase. Landmarks: the scan's 68
    projected through each photo's calibrated camera (those it shows), as ``ibugNN``;
    "projected" exactly, "as people give them" placed as :func:`place_landmarks` places
    them (outline landmarks on the scan's apparent outline in that photo, away from the
    scan's cut edge). Cameras: self-calibrated pinholes (``{"kind": "pinhole"}``, nothing
    else known) or the calibrated DLTs (kept)."""
    rng = np.random.default_rng(placement_seed)
    placement = Placement.draw(rng)
    inner = np.flatnonzero(~boundary_vertices(scan.triangles, len(scan.vertices)))
    given = {}
    for photo, cam in cameras.items():
        numbers, px = scan_landmarks(scan, cam)
        names = [f"ibug{i:02d}" for i in numbers]
        outline = apparent_outline(scan.vertices, scan.triangles, cam, inner)
        placed, _ = place_landmarks(names, px, placement, rng, outline,
                                    {n: i for n, i in zip(names, numbers, strict=True)})
        w, h = cam.size
        given[photo] = {"projected": dict(zip(names, px, strict=True)),
                        "as people give them": {n: np.clip(p, 0.0, [w, h])
                                                for n, p in placed.items()}}
    cases = {}
    for points in ("projected", "as people give them"):
        for kind in ("pinhole", "DLT"):
            views = {}
            for photo, cam in cameras.items():
                if kind == "DLT":
                    views[photo] = View(photo, None, cam.size, cam, given[photo][points],
                                        calibrated=True)
                else:
                    views[photo] = View(photo, None, cam.size, None, given[photo][points],
                                        camera_hints={"kind": "pinhole"})
            cases[f"{kind}, {points}"] = LandmarkCase(views, "<james>")
    return cases, placement


def scan_in_model_axes(scan):
    """The scan moved into the model's frame: menton at the origin, the subject's left
    +X, up +Z, looking along -Y (Blender's front), by its own landmarks (a Scan)."""
    origin, left, up, forward = face_frame(scan.ibug)
    rot = np.array([left, -forward, up])
    return Scan((scan.vertices - origin) @ rot.T, scan.triangles,
                {k: (p - origin) @ rot.T for k, p in scan.ibug.items()}, scan.photos,
                scan.corner_uv, scan.texture)


def boundary_edges(triangles):
    """Vertex pairs (E, 2) of a mesh's open boundary (edges of one triangle only)."""
    e = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]],
                                triangles[:, [2, 0]]]), axis=1)
    uniq, count = np.unique(e, axis=0, return_counts=True)
    return uniq[count == 1]


def scan_render_cases(scan, placement_seed=7100, image_height=1024, contour_points=100):
    """The scan photographed as the fit's users photograph a head: an exact front and an
    exact right profile (orthographic, 1024 px high, 3:4, framed as the synthetic cases),
    the profile's outline traced from the scan's silhouette (its cut edges left out). The
    landmarks are the scan's own 68 (``ibugNN``) where a photo shows them, the profile
    without the jaw's outline points but the menton (as the synthetic cases); "projected"
    exactly with the outline exact, "as people give them" placed by
    :func:`place_landmarks` (outline points on the front's apparent outline) with the
    outline's noise; and the front as people give them with the profile's traced outline
    alone (no landmark there, as when only a silhouette was found). Returns (name ->
    LandmarkCase, the scan in model axes, Placement, the cameras that took the photos:
    view name -> OrthographicCamera)."""
    rng = np.random.default_rng(placement_seed)
    placement = Placement.draw(rng)
    moved = scan_in_model_axes(scan)
    world, tris = moved.vertices, moved.triangles
    normals = oriented_normals(world, tris, moved.ibug)
    lm = moved.landmark_array
    nearest = cKDTree(world).query(lm)[1]
    inner = np.flatnonzero(~boundary_vertices(tris, len(world)))
    cut = boundary_edges(tris)
    h = int(image_height)
    size = (int(round(0.75 * h)), h)
    given = {"projected": {}, "as people give them": {}}
    cams = {}
    for view in ("front", "right"):
        cam = cams[view] = _camera(rng, f"orthographic-{view}", size, world)
        seen = visible(world, tris, cam, normals[nearest], lm, 0.0)
        numbers = [i + 1 for i in np.flatnonzero(seen)]
        contour = {}
        if view == "front":
            outline = apparent_outline(world, tris, cam, inner)
        else:
            numbers = [i for i in numbers
                       if i not in OUTLINE_IBUG or i in PROFILE_OUTLINE_IBUG]
            outline = trace_outline(world, tris, cam, cut)
            exact = resample_polyline(outline, contour_points)
            contour = {"projected": exact, "as people give them": np.clip(
                exact + placement.contour_noise_px * rng.normal(size=exact.shape), 0.0, size)}
        names = [f"ibug{i:02d}" for i in numbers]
        nominal = cam.project(lm[np.array(numbers) - 1])
        placed, _ = place_landmarks(names, nominal, placement, rng, outline,
                                    dict(zip(names, numbers, strict=True)))
        for points, pts in (("projected", dict(zip(names, nominal, strict=True))),
                            ("as people give them", placed)):
            given[points][view] = View(
                view, None, size, OrthographicCamera.nominal(f"orthographic-{view}", size),
                {n: np.clip(p, 0.0, size) for n, p in pts.items()},
                contour=contour.get(points))
    cases = {f"front + profile, {points}": LandmarkCase(views, "<james rendered>")
             for points, views in given.items()}
    people = given["as people give them"]
    side = people["right"]
    cases["front as people give them, profile outline only"] = LandmarkCase(
        {"front": people["front"], "right": View("right", None, side.size, side.camera, {},
                                                  contour=side.contour)}, "<james rendered>")
    return cases, moved, placement, cams


def render_scan(scan, camera, background=0.5):
    """A photo of a textured scan through an orthographic camera: (H, W, 3) float in
    [0, 1], the nearest triangle per pixel (a z-buffer) coloured by its texture at the
    pixel (nearest texel), ``background`` elsewhere. No shading: the texture is the
    scanner's photos, lit as they were."""
    from PIL import Image

    with Image.open(scan.texture) as im:
        tex = np.asarray(im.convert("RGB"), dtype=np.float32) / 255.0
    w, h = camera.size
    corner = scan.vertices[scan.triangles]
    px = camera.project(corner.reshape(-1, 3)).reshape(-1, 3, 2)
    depth = depth_of(camera, corner.reshape(-1, 3)).reshape(-1, 3)
    pixel, tri, bary = rasterize(px, w, h)
    z = np.einsum("nk,nk->n", bary, depth[tri])
    order = np.lexsort((z, pixel))
    first = order[np.r_[True, pixel[order][1:] != pixel[order][:-1]]]
    uv = np.einsum("nk,nkc->nc", bary[first], scan.corner_uv[tri[first]])
    th, tw = tex.shape[:2]
    col = np.clip((uv[:, 0] * tw).astype(int), 0, tw - 1)
    row = np.clip(((1.0 - uv[:, 1]) * th).astype(int), 0, th - 1)
    out = np.full((h * w, 3), background, np.float32)
    out[pixel[first]] = tex[row, col]
    return out.reshape(h, w, 3)


def detected_front_case(scan_cases_, moved, front_camera, detector):
    """The rendered front photo (taken by ``front_camera``, as :func:`scan_render_cases`
    gives it) with its landmarks found by the face detector (``detector``: a
    ``solver.detect.Detector``) and their uncertainty and depth as ``solver detect`` gives
    them, and
    the profile's traced outline alone: (LandmarkCase, the front photo) or (None, photo)
    when no face is found."""
    base = scan_cases_["front + profile, projected"]
    front, side = base.views["front"], base.views["right"]
    photo = render_scan(moved, front_camera)
    face = detector.detect(photo)
    if face is None or not face.is_face:
        return None, photo
    sigma = point_uncertainty(face)
    pts = {f"ibug{i + 1:02d}": p for i, p in enumerate(face.ibug)}
    kept = [i for i, s in sigma.items() if s is not None]
    given = {f"ibug{i:02d}": sigma[i] for i in kept}
    names = load_landmark_set().ibug
    depth = detected_depth(face, [names[i] for i in kept])
    depth = {f"ibug{i:02d}": depth[names[i]] for i in kept}
    views = {"front": View("front", None, front.size, front.camera, pts,
                           uncertainty=given, depth=depth),
             "right": View("right", None, side.size, side.camera, {},
                           contour=side.contour)}
    return LandmarkCase(views, "<james rendered, detected>"), photo


# ---------------------------------------------------------------- the oracle


def oracle_local(model, cloud, start=None, face_only=False):
    """The model's identity registered to the true surface in 3-D (``register`` on the
    skin, from ``start``, a Similarity model -> cloud, or register's own start): the best
    head the model can represent there, as local vertices (V, 3), and register's fit.
    ``face_only``: only the face region's vertices are matched (the cloud is a face scan
    that also holds parts the region leaves out)."""
    kw = {}
    if start is not None:
        kw = dict(scale=start.scale, rotation=start.rotation, translation=start.translation)
    if face_only:
        kw["weights"] = model_face_vertices(model)[model.skin].astype(float)
    fit = register(model.identity.take(model.skin), cloud, **kw)
    return model.identity.instance(fit.coeffs), fit


def landmark_start(model, local, ibug):
    """Similarity mapping a head (model topology) onto landmarks given by iBUG number."""
    mine = model_ibug(model, local)
    keys = sorted(set(mine) & set(ibug))
    return similarity_procrustes(np.array([mine[k] for k in keys]),
                                 np.array([ibug[k] for k in keys]))


def landmark_fit_3d(model, ibug, noise_mm, numbers=None, rounds=10):
    """The model's identity fitted to landmarks given exactly in 3-D (no photos): the most
    any fit from these landmarks can say about the head, when their definitions are the
    model's landmark vertices' up to isotropic noise.

    Parameters
    ----------
    model : HeadModel
    ibug : dict of int -> ndarray, shape (3,), metres
        The landmarks by iBUG number (any frame: a similarity is fitted with the shape).
    noise_mm : float
        Standard deviation assumed for each landmark coordinate, millimetres: the prior's
        weight against the landmarks (the posterior mean for coefficients ~ N(0, I)).
    numbers : iterable of int, optional
        The iBUG numbers used (default: every one the model and ``ibug`` share).

    Returns
    -------
    ndarray, shape (V, 3)
        The fitted head, local vertices (the model's frame).
    """
    vertex = {int(e["ibug"]): int(e["vertex"]) for e in model.landmark_info
              if e.get("ibug") is not None}
    keys = sorted(set(vertex) & set(ibug) if numbers is None
                  else set(numbers) & set(vertex) & set(ibug))
    idx = np.array([vertex[k] for k in keys])
    target = np.array([ibug[k] for k in keys], dtype=np.float64)
    lin = model.identity
    a = lin.basis[:, idx].reshape(lin.n_coeffs, -1).T  # (3n, K) metres per sigma
    lam2 = (1e-3 * float(noise_mm)) ** 2
    c = np.zeros(lin.n_coeffs)
    for _ in range(rounds):  # alternate the similarity and the (linear) shape
        sim = similarity_procrustes(lin.instance(c)[idx], target)
        local = (target - sim.translation) @ sim.rotation / sim.scale
        r = (local - lin.mean[idx]).reshape(-1)
        c = np.linalg.solve(a.T @ a + lam2 * np.eye(lin.n_coeffs), a.T @ r)
    return lin.instance(c)
