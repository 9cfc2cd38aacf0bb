"""Synthetic landmark cases with a known answer, for tests and benchmarks.

A head is drawn from the model (identity coefficients ~ N(0, 1)), posed by a random
similarity and photographed by orthographic cameras, each with its own scale, offset (and
optionally in-plane tilt), like two photos taken separately. Its landmarks are the
projections of the landmark vertices a view can see (``views`` in assets/landmarks.json)
plus Gaussian noise; a side view also gets the traced head outline: the silhouette of the
projected skin, rasterised at image resolution, traced along its outer boundary, the bottom
cut of the neck left out (a person tracing a photo follows the head, not the mesh's end).
"""

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .cameras import ORTHO_VIEWS, OrthographicCamera
from .landmarks_file import LandmarkCase, View
from .raster import rasterize

# Moore neighbourhood in clockwise order on screen (rows run down): W, NW, N, NE, E, SE, S, SW.
_MOORE = np.array([(0, -1), (-1, -1), (-1, 0), (-1, 1), (0, 1), (1, 1), (1, 0), (1, -1)])


@dataclass
class SyntheticTruth:
    """What the synthetic photos show.

    Attributes
    ----------
    identity_coeffs : ndarray, shape (K,)
        Coefficients of the head (standard deviations; K = all modes of the model).
    local_vertices : ndarray, shape (V, 3), metres
        ``model.identity.instance(identity_coeffs)``.
    scale : float
    rotation : ndarray, shape (3, 3)
        Local -> world.
    translation : ndarray, shape (3,), metres
    cameras : dict of str -> OrthographicCamera
        The cameras that took the photos.
    pixels : dict of str -> dict of str -> ndarray (2,)
        Noise-free projection of every landmark placed in each view.
    contour : dict of str -> ndarray (n, 2)
        Noise-free traced outline of each side view (before subsampling noise).
    """

    identity_coeffs: np.ndarray
    local_vertices: np.ndarray
    scale: float
    rotation: np.ndarray
    translation: np.ndarray
    cameras: dict
    pixels: dict = field(default_factory=dict)
    contour: dict = field(default_factory=dict)

    @property
    def world_vertices(self):
        """Posed head, shape (V, 3), metres."""
        return self.scale * self.local_vertices @ self.rotation.T + self.translation


def random_rotation(rng, max_deg):
    """Rotation about a uniformly random axis by an angle uniform in [0, max_deg] degrees."""
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    angle = np.radians(rng.uniform(0.0, max_deg))
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)


def _view_camera_name(view):
    name = view if view.startswith("orthographic-") else f"orthographic-{view}"
    if name not in ORTHO_VIEWS:
        raise ValueError(f"views: unknown view {view!r}; use front, right or left")
    return name


def _landmark_side(view):
    """Key of a view in the ``views`` list of assets/landmarks.json."""
    return _view_camera_name(view)[len("orthographic-"):]


def make_case(model, rng=None, *, noise_px=1.0, rotation_deg=5.0, image_height=1024,
              views=("front", "right"), coeffs=None, coeff_scale=1.0, in_plane_deg=0.0,
              contour=True, contour_points=100, contour_noise_px=None, aspect=0.75,
              fill=(0.75, 0.9)):
    """A synthetic case: landmarks (and a profile contour) of a random head.

    Parameters
    ----------
    model : HeadModel
    rng : numpy.random.Generator or int or None
        Random source or seed.
    noise_px : float
        Standard deviation of the Gaussian noise added to each landmark coordinate, pixels.
    rotation_deg : float
        Largest rotation of the head (random axis), degrees.
    image_height : int
        Photo height in pixels; the width is ``aspect * image_height``.
    views : sequence of str
        Views to photograph: "front", "right", "left" (the view's name in the case).
    coeffs : array_like, shape (K,), optional
        The head's identity coefficients (default: standard normal times ``coeff_scale``).
    coeff_scale : float
        Spread of the sampled coefficients (1: the model's distribution).
    in_plane_deg : float
        Largest tilt of each camera about its viewing direction, degrees (0: upright).
    contour : bool
        Trace the outline in side views.
    contour_points : int
        Points of the subsampled outline.
    contour_noise_px : float, optional
        Noise of the outline points (default ``noise_px``).
    aspect : float
        Image width / height.
    fill : (float, float)
        Range of the fraction of the image height the head's projection fills.

    Returns
    -------
    case : LandmarkCase
    truth : SyntheticTruth
    """
    rng = np.random.default_rng(rng)
    if noise_px < 0 or rotation_deg < 0:
        raise ValueError("noise_px and rotation_deg: must be >= 0")
    if not views:
        raise ValueError("views: at least one view is needed")
    ident = model.identity
    k = ident.n_coeffs
    if coeffs is None:
        c = coeff_scale * rng.normal(size=k)
    else:
        c = np.zeros(k)
        given = np.asarray(coeffs, dtype=np.float64).reshape(-1)
        if len(given) > k:
            raise ValueError(f"coeffs: at most {k} values, got {len(given)}")
        c[:len(given)] = given
    local = ident.instance(c)
    rot = random_rotation(rng, rotation_deg)
    scale = float(rng.uniform(0.95, 1.05))
    trans = rng.uniform(-0.01, 0.01, size=3)
    world = scale * local @ rot.T + trans
    cnoise = noise_px if contour_noise_px is None else contour_noise_px

    h = int(image_height)
    w = int(round(aspect * h))
    skin_tris = _skin_triangles(model)
    case_views, cams, clean, outlines = {}, {}, {}, {}
    for view in views:
        cam_name = _view_camera_name(view)
        side = _landmark_side(view)
        cam = _random_camera(rng, cam_name, (w, h), world[model.skin], fill, in_plane_deg)
        cams[view] = cam
        names = [e["name"] for e in model.landmark_info if side in e.get("views", ())]
        verts = np.array([model.landmarks[n] for n in names], dtype=np.int64)
        px = cam.project(world[verts])
        clean[view] = dict(zip(names, px, strict=True))
        noisy = px + noise_px * rng.normal(size=px.shape)
        noisy = np.clip(noisy, 0.0, [w, h])
        outline = None
        if contour and side in ("right", "left"):
            traced = trace_silhouette(model, world, cam, skin_tris)
            outlines[view] = traced
            outline = resample_polyline(traced, contour_points)
            outline = np.clip(outline + cnoise * rng.normal(size=outline.shape), 0.0, [w, h])
        case_views[view] = View(name=view, image=None, size=(w, h),
                                camera=OrthographicCamera.nominal(cam_name, (w, h)),
                                points=dict(zip(names, noisy, strict=True)), contour=outline)
    truth = SyntheticTruth(c, local, scale, rot, trans, cams, clean, outlines)
    return LandmarkCase(case_views, "<synthetic>"), truth


def _random_camera(rng, cam_name, size, skin_world, fill, in_plane_deg):
    """Orthographic camera with a random scale, offset and tilt that keeps the whole skin
    inside the image."""
    w, h = size
    base = ORTHO_VIEWS[cam_name]
    tilt = np.radians(rng.uniform(-in_plane_deg, in_plane_deg))
    q = np.array([[np.cos(tilt), -np.sin(tilt)], [np.sin(tilt), np.cos(tilt)]])
    rot = base.copy()
    rot[:2] = q @ base[:2]
    a = skin_world @ rot[:2].T  # image-plane metres
    lo, hi = a.min(axis=0), a.max(axis=0)
    scale = rng.uniform(*fill) * h / (hi[1] - lo[1])
    scale = min(scale, 0.95 * w / (hi[0] - lo[0]))
    ext = scale * (hi - lo)
    room = np.array([w, h]) - ext
    corner = rng.uniform(0.2, 0.8, size=2) * room
    offset = corner - scale * lo
    return OrthographicCamera(rot, scale, offset, size, cam_name)


def _skin_triangles(model):
    """Triangles (T, 3) of the skin parts (face, head and neck)."""
    tri_vertex, _, tri_face = model.triangles()
    skin = np.zeros(model.n_vertices, bool)
    skin[model.skin] = True
    return tri_vertex[skin[tri_vertex].all(axis=1)]


def _neck_cut_vertices(model, triangles):
    """Vertices of the skin's open boundary loop at the bottom of the neck."""
    e = np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]])
    e = np.sort(e, axis=1)
    uniq, count = np.unique(e, axis=0, return_counts=True)
    # Fan triangulation adds diagonals inside polygons; they are used twice like any inner
    # edge, so edges used once are exactly the boundary.
    border = uniq[count == 1]
    n = model.n_vertices
    g = coo_matrix((np.ones(len(border)), (border[:, 0], border[:, 1])), shape=(n, n))
    _, label = connected_components(g, directed=False)
    bverts = np.unique(border)
    lowest = bverts[np.argmin(model.vertices[bverts, 2])]
    return bverts[label[bverts] == label[lowest]], border


def trace_silhouette(model, world, camera, triangles=None):
    """Outer outline of the projected skin, neck cut removed, in drawing order.

    Parameters
    ----------
    model : HeadModel
    world : ndarray, shape (V, 3), metres
        Posed vertices.
    camera : OrthographicCamera
    triangles : ndarray, shape (T, 3), optional
        Skin triangles (computed when not given).

    Returns
    -------
    ndarray, shape (n, 2), pixels
        From the front of the neck over the face and skull to the back of the neck, one
        point per boundary pixel, moved half a pixel outward so it sits on the edge of the
        silhouette rather than on the centres of its outermost pixels.
    """
    tris = _skin_triangles(model) if triangles is None else triangles
    w, h = camera.size
    px = camera.project(world)
    pixel, _, _ = rasterize(px[tris], w, h)
    mask = np.zeros(h * w, bool)
    mask[pixel] = True
    mask = mask.reshape(h, w)
    loop = _moore_trace(mask)  # (n, 2) as (row, col)
    pts = loop[:, ::-1] + 0.5  # pixel centres as (u, v)
    # Outward normals from the neighbours along the loop; flip where they point inside.
    tangent = np.roll(pts, -2, axis=0) - np.roll(pts, 2, axis=0)
    normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
    probe = np.floor(pts + 1.5 * normal).astype(int)
    probe = np.clip(probe, 0, [w - 1, h - 1])
    normal[mask[probe[:, 1], probe[:, 0]]] *= -1.0
    pts = pts + 0.5 * normal
    # Leave out the neck's cut: outline points near the projected boundary loop there.
    neck, border = _neck_cut_vertices(model, tris)
    is_neck = np.zeros(model.n_vertices, bool)
    is_neck[neck] = True
    seg = border[is_neck[border[:, 0]] & is_neck[border[:, 1]]]
    near = _distance_to_segments(pts, px[seg[:, 0]], px[seg[:, 1]]) <= 2.0
    keep = _longest_cyclic_run(~near)
    out = pts[keep]
    # Start at the end toward the face (drawing order of the profile chain).
    forward = camera.rotation[:2] @ np.array([0.0, -1.0, 0.0])
    if out[0] @ forward < out[-1] @ forward:
        out = out[::-1]
    return out


def _moore_trace(mask):
    """Outer boundary of the 8-connected component holding the first set pixel (raster
    order) of a boolean image, as (row, col) pixels in order (Moore-neighbour tracing)."""
    h, w = mask.shape
    pad = np.zeros((h + 2, w + 2), bool)
    pad[1:-1, 1:-1] = mask
    flat = np.flatnonzero(pad)
    if flat.size == 0:
        raise ValueError("silhouette: the projected head covers no pixel")
    start = (int(flat[0] // (w + 2)), int(flat[0] % (w + 2)))
    out = [start]
    cur = start
    back = 0  # index into _MOORE of the (empty) neighbour we came from: west of the start
    first_step = None
    for _ in range(8 * pad.size):
        for i in range(1, 9):
            d = (back + i) % 8
            r, c = cur[0] + _MOORE[d][0], cur[1] + _MOORE[d][1]
            if pad[r, c]:
                # The neighbour checked just before d is empty: it becomes the backtrack,
                # expressed relative to the new pixel.
                pr, pc = cur[0] + _MOORE[(d - 1) % 8][0], cur[1] + _MOORE[(d - 1) % 8][1]
                nxt = (r, c)
                back = _direction(nxt, (pr, pc))
                break
        else:  # isolated pixel
            break
        if first_step is None:
            first_step = nxt
        elif cur == start and nxt == first_step:
            break
        cur = nxt
        out.append(cur)
    loop = np.array(out[:-1] if len(out) > 1 and out[-1] == start else out)
    return loop - 1


def _direction(frm, to):
    d = (to[0] - frm[0], to[1] - frm[1])
    for i, m in enumerate(_MOORE):
        if m[0] == d[0] and m[1] == d[1]:
            return i
    raise ValueError("moore trace: pixels are not neighbours")


def _distance_to_segments(p, a, b):
    """Distance of each point (n, 2) to the nearest of the segments a-b (m, 2)."""
    if len(a) == 0:
        return np.full(len(p), np.inf)
    ab = b - a
    ll = np.maximum((ab * ab).sum(1), 1e-12)
    t = np.clip(((p[:, None, :] - a[None]) * ab[None]).sum(2) / ll[None], 0.0, 1.0)
    d = p[:, None, :] - (a[None] + t[..., None] * ab[None])
    return np.sqrt((d * d).sum(2)).min(axis=1)


def _longest_cyclic_run(flags):
    """Indices of the longest run of True in a cyclic boolean array, in order."""
    n = len(flags)
    if flags.all():
        return np.arange(n)
    if not flags.any():
        raise ValueError("silhouette: nothing left once the neck cut is removed")
    shift = int(np.flatnonzero(~flags)[0])
    f = np.roll(flags, -shift)  # starts with False: runs do not wrap
    edges = np.diff(np.concatenate([[0], f.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    i = int(np.argmax(ends - starts))
    return (np.arange(starts[i], ends[i]) + shift) % n


def resample_polyline(points, n):
    """``n`` points evenly spaced by arc length along a polyline (ends kept), (n, 2)."""
    p = np.asarray(points, dtype=np.float64)
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    t = np.linspace(0.0, s[-1], int(n))
    return np.stack([np.interp(t, s, p[:, 0]), np.interp(t, s, p[:, 1])], axis=1)
