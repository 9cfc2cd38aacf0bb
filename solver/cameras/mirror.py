"""One camera and a flat mirror: the face and its mirror image in one photo.

Seed 001 (Hashimoto 1984), chapter 3. A mirror image is a second view of the head whose
camera is the real camera reflected in the mirror plane. With n the mirror's unit normal
and G any point on the mirror:

- M = I - 2 n n^T is the reflection (eq. 3.12); the virtual camera centre is
  F2 = G + M (F1 - G) (eq. 3.11) and a ray toward a mirrored image point, reflected, is
  u2 = M u2' (eq. 3.13). The intrinsics (and lens distortion) are shared.
- As a DLT camera the mirrored view is ``P H`` with H the 4x4 reflection: a valid
  projective camera whose rotation has determinant -1 (``DLTCamera.is_mirrored``). It maps
  a physical point to where its mirror image appears, so it can be used as just another
  view, e.g. self-calibrated by ``DLTCamera.refit`` from the head's landmarks.

The mirror's normal comes from the photo itself (§3.2.2), so the mirror may move between
shots: for a point P and its mirror image P', the segment P P' is perpendicular to the
mirror, so the plane through the camera centre, P and P' contains the normal, and that
plane's normal A = p x p' (p, p' the unit viewing rays toward P and P', eq. 3.8) lies in
the mirror plane. Two pairs give n = A1 x A2 / |A1 x A2| (eq. 3.9); with more pairs n is the
direction most nearly perpendicular to all A_i, the right singular vector of the stacked
A_i with the smallest singular value (each A_i weighted by its length, the sine of the
angle between its rays, so nearly parallel pairs count little). The sign makes n face the
camera: (G - F) . n < 0 (eq. 3.10), tested with the mirrored rays, which all hit the mirror
in front of the camera.

The normal fixes the mirror's orientation, not its distance: scaling the whole scene about
the camera centre leaves every ray in place. The distance comes from a point on the mirror
(G, as in the seed) or a known length between two landmarks.

Points are the midpoint of the common perpendicular of the direct and the reflected ray
(eq. 3.5-3.7, ``solver.triangulate.ray_midpoint``); the perpendicular's length (the gap)
is a per-landmark check.

A mirror swaps left and right: what looks like a left eye in the mirror image is the
reflection of the right eye. ``mirror_name`` maps a label read off the mirror image to the
physical landmark.
"""

import re
from dataclasses import dataclass

import numpy as np

from ..errors import as_points
from .dlt import DLTCamera
from .triangulate import ray_midpoint

# iBUG-68 numbers of left/right symmetric landmarks; the rest (9, 28-31, 34, 52, 58, 63,
# 67) lie on the midline and map to themselves.
_IBUG_PAIRS = [(1, 17), (2, 16), (3, 15), (4, 14), (5, 13), (6, 12), (7, 11), (8, 10),
               (18, 27), (19, 26), (20, 25), (21, 24), (22, 23),
               (32, 36), (33, 35),
               (37, 46), (38, 45), (39, 44), (40, 43), (41, 48), (42, 47),
               (49, 55), (50, 54), (51, 53), (56, 60), (57, 59),
               (61, 65), (62, 64), (66, 68)]
#: iBUG-68 number -> number of its mirror partner (itself on the midline)
IBUG_MIRROR = {i: i for i in range(1, 69)}
for _a, _b in _IBUG_PAIRS:
    IBUG_MIRROR[_a], IBUG_MIRROR[_b] = _b, _a

_IBUG_NAME = re.compile(r"^(ibug)(\d+)$", re.IGNORECASE)
_SWAP = {"left": "right", "right": "left", "Left": "Right", "Right": "Left",
         "LEFT": "RIGHT", "RIGHT": "LEFT"}


def mirror_name(name):
    """The landmark whose mirror image carries the label ``name``.

    ``ibugNN`` maps to its iBUG-68 partner (keeping the zero padding); otherwise every
    underscore-separated ``left``/``right`` token is swapped (``eye_outer_left`` ->
    ``eye_outer_right``, ``jaw_right_1`` -> ``jaw_left_1``); midline names map to
    themselves.

    Parameters
    ----------
    name : str

    Returns
    -------
    str

    Raises
    ------
    ValueError
        An ``ibug`` number outside 1..68.
    """
    m = _IBUG_NAME.match(name)
    if m:
        num = int(m.group(2))
        if num not in IBUG_MIRROR:
            raise ValueError(f"landmark {name!r}: iBUG-68 numbers run from 1 to 68")
        return f"{m.group(1)}{IBUG_MIRROR[num]:0{len(m.group(2))}d}"
    return "_".join(_SWAP.get(tok, tok) for tok in name.split("_"))


def mirror_names(points):
    """Relabel the landmarks read off a mirror image: ``{mirror_name(k): v}``.

    Parameters
    ----------
    points : dict of str -> (u, v)

    Returns
    -------
    dict of str -> (u, v)
    """
    out = {}
    for k, v in points.items():
        out[mirror_name(k)] = v
    return out


def pair_mirrored(direct, mirrored):
    """Landmarks seen both directly and in the mirror, matched physically.

    Parameters
    ----------
    direct : dict of str -> (u, v), pixels
        Labels on the direct image of the face.
    mirrored : dict of str -> (u, v), pixels
        Labels on the mirror image, as they look (a left eye there is the right eye).

    Returns
    -------
    names : list of str
        Physical landmarks seen in both, in ``direct``'s order.
    direct_pixels, mirrored_pixels : ndarray, shape (k, 2), pixels
    """
    phys = mirror_names(mirrored)
    names = [k for k in direct if k in phys]
    d = np.array([direct[k] for k in names], dtype=np.float64).reshape(-1, 2)
    m = np.array([phys[k] for k in names], dtype=np.float64).reshape(-1, 2)
    return names, d, m


@dataclass(frozen=True)
class MirrorPlane:
    """A flat mirror: points X with ``normal . X == offset``.

    Attributes
    ----------
    normal : ndarray, shape (3,)
        Unit normal facing the camera (seed 001 eq. 3.10).
    offset : float, metres
    """

    normal: np.ndarray
    offset: float

    @classmethod
    def from_point_normal(cls, point, normal):
        """Plane through ``point`` (G, metres) with ``normal`` (normalised here)."""
        n = np.asarray(normal, dtype=np.float64).reshape(3)
        length = np.linalg.norm(n)
        if not np.isfinite(length) or length == 0:
            raise ValueError("mirror: normal must be a finite non-zero vector")
        n = n / length
        g = np.asarray(point, dtype=np.float64).reshape(3)
        return cls(n, float(n @ g))

    @property
    def point(self):
        """The point of the mirror nearest the world origin (a G), shape (3,), metres."""
        return self.offset * self.normal

    @property
    def matrix(self):
        """M = I - 2 n n^T (eq. 3.12), shape (3, 3)."""
        return np.eye(3) - 2.0 * np.outer(self.normal, self.normal)

    @property
    def homogeneous(self):
        """4x4 reflection X -> M X + 2 offset n (its own inverse)."""
        h = np.eye(4)
        h[:3, :3] = self.matrix
        h[:3, 3] = 2.0 * self.offset * self.normal
        return h

    def reflect_points(self, points):
        """G + M (X - G) (eq. 3.11): (n, 3) metres -> (n, 3) metres."""
        x = as_points(points, "points")
        return x - 2.0 * (x @ self.normal - self.offset)[:, None] * self.normal

    def reflect_directions(self, directions):
        """M d (eq. 3.13): (n, 3) -> (n, 3)."""
        d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
        return d - 2.0 * (d @ self.normal)[:, None] * self.normal

    def signed_distance(self, points):
        """normal . X - offset: (n, 3) -> (n,) metres, positive on the camera's side."""
        return as_points(points, "points") @ self.normal - self.offset

    # The fit moves a plane by three parameters: the tilt of its normal along two axes
    # (radians) and its offset (metres).

    def axes(self):
        """Two unit vectors completing the normal to an orthonormal frame: the tilt axes."""
        normal = self.normal
        a = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        e1 = np.cross(normal, a)
        e1 /= np.linalg.norm(e1)
        return e1, np.cross(normal, e1)

    def fields(self, real, points):
        """Pixel fields (3, n, 2) of the mirror images of ``points`` (n, 3) seen by the real
        camera ``real``, per unit tilt of the normal along :meth:`axes` (radians) and per
        metre of offset (see :meth:`moved`)."""
        x = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        n = self.normal
        e1, e2 = self.axes()
        dist = x @ n - self.offset
        jac = np.asarray(real.jacobian(self.reflect_points(x)), dtype=np.float64)
        d = np.empty((3, len(x), 3))  # d(reflected point) / d(parameter)
        for j, e in enumerate((e1, e2)):
            d[j] = -2.0 * ((x @ e)[:, None] * n + dist[:, None] * e)
        d[2] = 2.0 * n
        return np.einsum("kij,pkj->pki", jac.reshape(len(x), 2, 3), d)

    def moved(self, step):
        """The plane moved by ``step`` (3,): the normal tilted by step[0] along the first of
        :meth:`axes` and step[1] along the second, offset + step[2] metres."""
        n = self.normal
        e1, e2 = self.axes()
        m = n + step[0] * e1 + step[1] * e2
        return MirrorPlane(m / np.linalg.norm(m), float(self.offset + step[2]))

    def refit(self, real, points, pixels, weights, iterations=10):
        """The plane that best maps ``points`` (n, 3) onto ``pixels`` (n, 2) through the
        real camera, from this one (Gauss-Newton on tilt and offset, weighted squared
        pixels; a step that does not lower the cost is halved).

        Returns
        -------
        MirrorPlane
        """
        x = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        q = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        w = np.asarray(weights, dtype=np.float64).reshape(-1)
        plane = self
        if np.count_nonzero(w) < 2:
            return plane

        def cost(pl):
            r = q - real.project(pl.reflect_points(x))
            return float(w @ (r * r).sum(axis=1)), r

        c0, r = cost(plane)
        for _ in range(iterations):
            jac = plane.fields(real, x)  # (3, n, 2)
            a = np.einsum("pni,qni,n->pq", jac, jac, w)
            b = np.einsum("pni,ni,n->p", jac, r, w)
            try:
                step = np.linalg.solve(a + 1e-12 * np.trace(a) * np.eye(3), b)
            except np.linalg.LinAlgError:
                break
            for _ in range(6):
                cand = plane.moved(step)
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


def mirror_normal(direct_rays, mirrored_rays):
    """The mirror's unit normal from viewing rays of landmark pairs (eq. 3.8-3.10).

    Parameters
    ----------
    direct_rays : array_like, shape (k, 3)
        Directions from the camera centre toward each landmark (need not be unit).
    mirrored_rays : array_like, shape (k, 3)
        Directions from the camera centre toward the same landmark's mirror image.

    Returns
    -------
    normal : ndarray, shape (3,)
        Unit normal facing the camera.
    residual : ndarray, shape (k,), radians
        Angle by which each pair's A_i = p x p' leaves the mirror plane (0 when exact).

    Raises
    ------
    ValueError
        Fewer than 2 pairs, or pairs that do not fix the normal (all A_i parallel, e.g.
        all landmarks on one line through the mirror's normal).
    """
    p = np.asarray(direct_rays, dtype=np.float64).reshape(-1, 3)
    q = np.asarray(mirrored_rays, dtype=np.float64).reshape(-1, 3)
    if p.shape != q.shape:
        raise ValueError(f"mirror: {len(p)} direct rays but {len(q)} mirrored rays")
    if len(p) < 2:
        raise ValueError(f"mirror: the normal needs at least 2 landmarks seen directly and "
                         f"in the mirror, got {len(p)}")
    p = p / np.linalg.norm(p, axis=1, keepdims=True)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    a = np.cross(p, q)  # eq. 3.8
    _, s, vt = np.linalg.svd(a, full_matrices=False)
    if s[0] == 0 or s[1] < 1e-6 * s[0]:
        raise ValueError("mirror: the landmark pairs do not fix the mirror's normal (their "
                         "planes through the camera all coincide); use landmarks spread "
                         "over the face")
    n = vt[-1]
    if (q @ n).mean() > 0:  # eq. 3.10: the mirror lies on the -n side of the camera
        n = -n
    length = np.linalg.norm(a, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        res = np.arcsin(np.clip(np.abs(a @ n) / length, 0.0, 1.0))
    return n, np.where(length > 0, res, np.nan)


def reflected_camera(camera, plane):
    """The camera that sees the mirror image: ``P H`` (module docstring).

    Parameters
    ----------
    camera : DLTCamera
    plane : MirrorPlane

    Returns
    -------
    DLTCamera
        Centre F2 (eq. 3.11), same intrinsics and distortion, ``is_mirrored`` True.
    """
    if not isinstance(camera, DLTCamera):
        raise ValueError(f"mirror: needs a DLT camera, got {type(camera).__name__}")
    return camera.transformed(plane.homogeneous)


def triangulate_mirror(camera, plane, direct_pixels, mirrored_pixels):
    """Landmarks from their direct and mirrored pixels (eq. 3.5-3.7, 3.11, 3.13).

    Parameters
    ----------
    camera : DLTCamera
    plane : MirrorPlane
    direct_pixels, mirrored_pixels : array_like, shape (k, 2), pixels

    Returns
    -------
    points : ndarray, shape (k, 3), metres
        Midpoints of the common perpendiculars.
    gaps : ndarray, shape (k,), metres
        Lengths of the common perpendiculars.
    """
    f1, u1 = camera.back_project(direct_pixels)
    _, u2p = camera.back_project(mirrored_pixels)
    f2 = plane.reflect_points(camera.centre[None, :])  # eq. 3.11
    u2 = plane.reflect_directions(u2p)  # eq. 3.13
    mid, gap, _, _ = ray_midpoint(f1, u1, f2, u2)
    return mid, gap


@dataclass
class MirrorFit:
    """Result of ``estimate_mirror``.

    Attributes
    ----------
    plane : MirrorPlane
    names : list of str
    points : ndarray, shape (k, 3), metres
        Triangulated landmarks (eq. 3.7).
    gaps : ndarray, shape (k,), metres
        Ray gaps (per-landmark check).
    normal_residual : ndarray, shape (k,), radians
        How far each pair's A_i leaves the fitted mirror plane.
    mirrored_camera : DLTCamera
    """

    plane: MirrorPlane
    names: list
    points: np.ndarray
    gaps: np.ndarray
    normal_residual: np.ndarray
    mirrored_camera: DLTCamera


def estimate_mirror(camera, direct_pixels, mirrored_pixels, names=None,
                    point_on_mirror=None, known_length=None):
    """Mirror plane and landmarks from one photo of the face and its mirror image.

    Parameters
    ----------
    camera : DLTCamera
        The calibrated real camera.
    direct_pixels : array_like, shape (k, 2), pixels
        Landmarks seen directly.
    mirrored_pixels : array_like, shape (k, 2), pixels
        The same physical landmarks in the mirror (relabel with ``pair_mirrored``).
    names : sequence of str, length k, optional
    point_on_mirror : array_like, shape (3,), metres, optional
        G of eq. 3.11 (e.g. a marked point on the mirror's surface).
    known_length : (str, str, float), optional
        Two landmark names and their distance in metres; used when G is not given.

    Returns
    -------
    MirrorFit

    Raises
    ------
    ValueError
        Neither or both of ``point_on_mirror`` and ``known_length``; too few pairs; a
        degenerate layout; unknown names.
    """
    if (point_on_mirror is None) == (known_length is None):
        raise ValueError("mirror: give exactly one of point_on_mirror (a point G on the "
                         "mirror) and known_length (name, name, metres): the normal alone "
                         "leaves the mirror's distance open")
    d = as_points(direct_pixels, "direct_pixels", dim=2, min_count=2)
    m = as_points(mirrored_pixels, "mirrored_pixels", dim=2, min_count=2)
    if len(d) != len(m):
        raise ValueError(f"mirrored_pixels: {len(m)} rows for {len(d)} direct pixels")
    names = [f"#{i}" for i in range(len(d))] if names is None else [str(s) for s in names]
    if len(names) != len(d):
        raise ValueError(f"names: {len(names)} names for {len(d)} landmarks")
    f1 = camera.centre
    _, u1 = camera.back_project(d)
    _, u2p = camera.back_project(m)
    n, resid = mirror_normal(u1, u2p)
    if point_on_mirror is not None:
        plane = MirrorPlane.from_point_normal(point_on_mirror, n)
        if plane.signed_distance(f1[None, :])[0] <= 0:
            raise ValueError("mirror: the camera is behind the mirror given by "
                             "point_on_mirror and the landmarks' normal")
    else:
        a, b, length = known_length
        try:
            ia, ib = names.index(a), names.index(b)
        except ValueError:
            raise ValueError(f"known_length: landmarks {a!r} and {b!r} must both be among "
                             "the paired landmarks") from None
        if not float(length) > 0:
            raise ValueError(f"known_length: distance must be positive, got {length!r}")
        unit = MirrorPlane(n, float(n @ f1) - 1.0)  # mirror 1 m from the camera
        pts, _ = triangulate_mirror(camera, unit, d[[ia, ib]], m[[ia, ib]])
        l1 = np.linalg.norm(pts[0] - pts[1])
        if not l1 > 0:
            raise ValueError(f"known_length: {a!r} and {b!r} triangulate to one point")
        plane = MirrorPlane(n, float(n @ f1) - float(length) / l1)
    pts, gaps = triangulate_mirror(camera, plane, d, m)
    return MirrorFit(plane, names, pts, gaps, resid, reflected_camera(camera, plane))
