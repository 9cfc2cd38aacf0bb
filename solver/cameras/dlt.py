"""Direct Linear Transformation (DLT) cameras: any pinhole camera, calibrated from passpoints.

Seed 000 (Mössner 1992, "3D-Filmauswertung bei mitgeschwenkter und gezoomter Kamera") and
seed 004 (Mielke 2020, DLT in numpy). The 11 DLT parameters b1..b11 map a world point
(X, Y, Z) to a pixel (x, y) (seed 000 eq. 1)::

    x = (b1 X + b2 Y + b3 Z + b4) / (b9 X + b10 Y + b11 Z + 1)
    y = (b5 X + b6 Y + b7 Z + b8) / (b9 X + b10 Y + b11 Z + 1)

i.e. the 3x4 matrix P = [[b1 b2 b3 b4], [b5 b6 b7 b8], [b9 b10 b11 1]] of a projective
camera. The extended DLT (eq. 6-8) adds five lens terms b12..b16 to the *observed* pixel::

    x = (eq. 1) + dx,   y = (eq. 1) + dy
    u = x - x0,  v = y - y0,  r = u^2 + v^2            (r is the squared radius)
    dx = u (b12 r + b13 r^2 + b14 r^3) + b15 (r + 2 u^2) + 2 b16 u v
    dy = v (b12 r + b13 r^2 + b14 r^3) + 2 b15 u v + b16 (r + 2 v^2)

so b12..b14 are the radial (symmetric) and b15, b16 the tangential (decentering) terms of
Brown's model, written on the observed coordinates: a pixel is undistorted explicitly
(``x - dx(x)``, eq. 15) and projecting a point needs a short Newton solve. The coefficients
are stored in pixel units (b12 in px^-2, b13 in px^-4, b14 in px^-6, b15 and b16 in px^-1).

Distortion centre (x0, y0): seed 000 eq. 8 / 12a divide (b1 b9 + b2 b10 + b3 b11 + b4) by
(b9^2 + b10^2 + b11^2 + 1). That is the image of the world point (b9, b10, b11), so it moves
with the choice of world origin and scale (it is near the principal point only when the
origin is near the passpoints and far from the camera). The default here is the principal
point (b1 b9 + b2 b10 + b3 b11) / (b9^2 + b10^2 + b11^2), the same expression without the
b4 and 1 terms (Karara and Marzan's principal point), which does not depend on the world
frame; ``distortion_centre="eq8"`` follows the seed's formula literally in the scaled frame.
Either way the centre used is stored with the camera, so a saved camera is one fixed model.

Conventions: world in metres (Blender axes), pixels continuous with (0, 0) at the image's
top-left corner, u right, v down. The camera frame is OpenCV style: rows of ``R`` are the
u axis, the v axis and the viewing direction; depth grows away from the camera. A camera
seen in a flat mirror (solver/mirror.py) is a valid DLT camera whose rotation has
determinant -1; everything here works for it.

Numerics (seed 000 §4): the least-squares problems are solved in a scaled frame (object
points centred on their centroid and scaled to unit RMS radius, image points mapped to
[-1, 1] by eq. 22), by SVD (``numpy.linalg.lstsq``), never by the normal equations (whose
error grows with the square of the condition number, eq. 23). The condition number
kappa(A) of eq. 19 is reported for the scaled and for the unscaled system.
"""

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from ..errors import as_points
from .base import Camera, correspondences, register, toward_centre, unit_scale

#: fewest passpoints for the 11- and 16-parameter DLT (seed 000 §2)
MIN_POINTS = {11: 6, 16: 8}

# Below this ratio of the centred passpoints' smallest to largest singular value the points
# are taken to lie in one plane (thickness under 0.1 % of their extent).
_COPLANAR_RATIO = 1e-3
# The scaled system is rank deficient (degenerate passpoint layout) above this condition.
_MAX_CONDITION = 1e8
# The condition number above which the fit warns (seed 000 §4 saw < 200 after scaling).
_WARN_CONDITION = 1e4


@dataclass
class DLTScaling:
    """The scaled frame of seed 000 §4 in which the least squares are solved.

    Attributes
    ----------
    centroid : ndarray, shape (3,), metres
        Object-space origin of the scaled frame (the passpoints' centroid, or zeros when
        ``centre_object=False``).
    object_scale : float, 1/metres
        Scaled object coordinates are ``(X - centroid) * object_scale``.
    image_min, image_max : float, pixels
        b_min and b_max of eq. 22: pixel coordinates in this range map to [-1, 1].
    """

    centroid: np.ndarray
    object_scale: float
    image_min: float
    image_max: float

    @property
    def image_factor(self):
        """s in x_scaled = s x + t (eq. 22), 1/pixels."""
        return 2.0 / (self.image_max - self.image_min)

    @property
    def image_shift(self):
        """t in x_scaled = s x + t (eq. 22)."""
        return -2.0 * self.image_min / (self.image_max - self.image_min) - 1.0

    def image_matrix(self):
        """3x3 homogeneous map pixels -> scaled image coordinates."""
        s, t = self.image_factor, self.image_shift
        return np.array([[s, 0.0, t], [0.0, s, t], [0.0, 0.0, 1.0]])

    def object_matrix(self):
        """4x4 homogeneous map world (metres) -> scaled object coordinates."""
        t = np.eye(4)
        t[:3, :3] *= self.object_scale
        t[:3, 3] = -self.object_scale * self.centroid
        return t


@dataclass
class DLTFit:
    """Outcome of a DLT calibration (``fit_dlt``).

    Attributes
    ----------
    camera : DLTCamera
    requested : int
        11 or 16: the model asked for.
    n_params : int
        11 or 16: the model delivered (11 when DLT-16 fell back).
    residuals : ndarray, shape (n, 2), pixels
        Observed minus projected pixel of each passpoint.
    rms : float, pixels
        Root mean square of the residual lengths (over points with non-zero weight).
    condition : float
        kappa(A) (eq. 19) of the last scaled system solved.
    condition_unscaled : float
        kappa(A) of the 11-parameter system in the original units (what scaling avoids).
    iterations : int
        DLT-16 iterations done (eq. 12-14); 0 for DLT-11.
    converged : bool
        DLT-16 met the tolerance of eq. 14 (always True for DLT-11).
    fell_back : bool
        DLT-16 was asked for but DLT-11 is returned (seed 000 §2: "Im Falle des Versagens
        der Iteration nehme die 11 Parameter-Auswertung").
    reason : str
        Why it fell back ("" otherwise).
    warnings : list of str
    scaling : DLTScaling
    """

    camera: "DLTCamera"
    requested: int
    n_params: int
    residuals: np.ndarray
    rms: float
    condition: float
    condition_unscaled: float
    iterations: int
    converged: bool
    fell_back: bool
    reason: str
    scaling: DLTScaling
    warnings: list = field(default_factory=list)


# ----------------------------------------------------------------------------- distortion


def _distortion(pixels, coeffs, centre):
    """Correction (dx, dy) of eq. 7 at observed pixels: (n, 2) -> (n, 2) pixels."""
    k1, k2, k3, p1, p2 = coeffs
    u = pixels[:, 0] - centre[0]
    v = pixels[:, 1] - centre[1]
    r = u * u + v * v
    g = r * (k1 + r * (k2 + r * k3))
    dx = u * g + p1 * (r + 2.0 * u * u) + 2.0 * p2 * u * v
    dy = v * g + 2.0 * p1 * u * v + p2 * (r + 2.0 * v * v)
    return np.stack([dx, dy], axis=1)


def _distortion_jacobian(pixels, coeffs, centre):
    """d(dx, dy)/d(x, y) of eq. 7: (n, 2) -> (n, 2, 2), dimensionless."""
    k1, k2, k3, p1, p2 = coeffs
    u = pixels[:, 0] - centre[0]
    v = pixels[:, 1] - centre[1]
    r = u * u + v * v
    g = r * (k1 + r * (k2 + r * k3))
    dg = k1 + r * (2.0 * k2 + 3.0 * r * k3)  # dg/dr
    j = np.empty((len(pixels), 2, 2))
    cross = 2.0 * u * v * dg + 2.0 * p1 * v + 2.0 * p2 * u
    j[:, 0, 0] = g + 2.0 * u * u * dg + 6.0 * p1 * u + 2.0 * p2 * v
    j[:, 0, 1] = cross
    j[:, 1, 0] = cross
    j[:, 1, 1] = g + 2.0 * v * v * dg + 2.0 * p1 * u + 6.0 * p2 * v
    return j


def _correction_jacobian(pixels, coeffs, centre):
    """d(x - d(x))/dx, the correction of eq. 15 differentiated at observed pixels:
    (n, 2) -> (n, 2, 2), dimensionless. Its inverse maps ideal-pixel steps to observed ones
    (Newton's step of ``distort``, the chain rule of ``jacobian``)."""
    j = -_distortion_jacobian(pixels, coeffs, centre)
    j[:, 0, 0] += 1.0
    j[:, 1, 1] += 1.0
    return j


def _inv2(m):
    """Inverse of a stack of 2x2 matrices (n, 2, 2) and their determinants (n,)."""
    det = m[:, 0, 0] * m[:, 1, 1] - m[:, 0, 1] * m[:, 1, 0]
    inv = np.empty_like(m)
    inv[:, 0, 0] = m[:, 1, 1]
    inv[:, 1, 1] = m[:, 0, 0]
    inv[:, 0, 1] = -m[:, 0, 1]
    inv[:, 1, 0] = -m[:, 1, 0]
    return inv / det[:, None, None], det


# ----------------------------------------------------------------------------- the camera


@register("dlt")
class DLTCamera(Camera):
    """A projective (pinhole) camera given by a 3x4 DLT matrix, optionally with the five
    lens-distortion terms of the extended DLT (seed 000 eq. 6-8).

    Parameters
    ----------
    matrix : array_like, shape (3, 4)
        Maps homogeneous world points (metres) to homogeneous pixels. Its overall sign says
        which side is in front: a point is in front of the camera when
        ``matrix[2] @ (X, 1) > 0``. Any positive scale is allowed; it is normalised so the
        third row's first three entries have unit length, which makes
        ``matrix[2] @ (X, 1)`` the depth in metres along the viewing direction.
    size : (int, int)
        Image width and height in pixels.
    distortion : array_like, shape (5,), optional
        b12, b13, b14 (radial; px^-2, px^-4, px^-6) and b15, b16 (tangential; px^-1) of
        eq. 7, in pixel units. None or all zeros: the plain 11-parameter DLT.
    distortion_centre : array_like, shape (2,), pixels, optional
        (x0, y0) of eq. 8 that u, v are measured from. Default: the principal point.

    Notes
    -----
    ``parameters`` gives b1..b11 (or b1..b16) of eq. 1 / eq. 6, i.e. the matrix scaled so
    its bottom-right entry is 1; ``depth_sign`` is then the sign that makes that scaled
    matrix's third row positive in front (-1 only when the world origin lies behind the
    camera).
    """

    min_refit_points = MIN_POINTS[11]
    perspective = True

    def __init__(self, matrix, size, distortion=None, distortion_centre=None):
        p = np.asarray(matrix, dtype=np.float64)
        if p.shape != (3, 4) or not np.isfinite(p).all():
            raise ValueError(f"camera (dlt): matrix must be a finite 3x4 array, got {p.shape}")
        n3 = np.linalg.norm(p[2, :3])
        if n3 == 0.0 or np.linalg.matrix_rank(p[:, :3]) < 3:
            raise ValueError("camera (dlt): the matrix's left 3x3 block is singular (an "
                             "affine or degenerate camera); use an orthographic camera")
        self.matrix = p / n3
        try:
            self.size = (int(size[0]), int(size[1]))
        except (TypeError, IndexError, ValueError):
            raise ValueError(f"camera (dlt): size must be (width, height), got {size!r}") from None
        if distortion is None:
            distortion = np.zeros(5)
        k = np.asarray(distortion, dtype=np.float64).reshape(-1)
        if k.shape != (5,) or not np.isfinite(k).all():
            raise ValueError(f"camera (dlt): distortion must be 5 finite numbers, got {k.shape}")
        self.distortion = k
        if distortion_centre is None:
            distortion_centre = self.principal_point
        c = np.asarray(distortion_centre, dtype=np.float64).reshape(-1)
        if c.shape != (2,) or not np.isfinite(c).all():
            raise ValueError("camera (dlt): distortion_centre must be 2 finite numbers")
        self.distortion_centre = c
        m = self.matrix[:, :3]
        self._m_inv = np.linalg.inv(m)
        self._centre = -self._m_inv @ self.matrix[:, 3]
        self._decomposed = None

    # ---- construction helpers

    @classmethod
    def from_parameters(cls, parameters, size, distortion_centre=None, depth_sign=1):
        """Camera from the DLT parameters b1..b11 (eq. 1) or b1..b16 (eq. 6).

        Parameters
        ----------
        parameters : array_like, shape (11,) or (16,)
        size : (int, int)
        distortion_centre : array_like, shape (2,), optional
            (x0, y0) for 16 parameters; default the principal point.
        depth_sign : {1, -1}
            +1 when points in front of the camera have b9 X + b10 Y + b11 Z + 1 > 0 (the
            world origin is in front of the camera, the usual case).
        """
        b = np.asarray(parameters, dtype=np.float64).reshape(-1)
        if b.shape not in ((11,), (16,)):
            raise ValueError(f"camera (dlt): parameters must have 11 or 16 entries, got {b.size}")
        if depth_sign not in (1, -1):
            raise ValueError(f"camera (dlt): depth_sign must be 1 or -1, got {depth_sign!r}")
        p = np.array([b[0:4], b[4:8], [b[8], b[9], b[10], 1.0]]) * depth_sign
        dist = b[11:16] if b.size == 16 else None
        return cls(p, size, dist, distortion_centre)

    @classmethod
    def from_krc(cls, K, R, C, size, distortion=None, distortion_centre=None):
        """Camera ``P = K R [I | -C]`` from intrinsics, rotation and centre.

        Parameters
        ----------
        K : array_like, shape (3, 3)
            Upper-triangular intrinsics in pixels (fx, skew, cx; 0, fy, cy; 0, 0, 1).
        R : array_like, shape (3, 3)
            World -> camera rotation, rows (u axis, v axis, viewing direction); an improper
            rotation (det -1) gives a mirrored camera.
        C : array_like, shape (3,), metres
            Camera centre.
        size : (int, int)
        distortion, distortion_centre : see the class.
        """
        k = np.asarray(K, dtype=np.float64).reshape(3, 3)
        r = np.asarray(R, dtype=np.float64).reshape(3, 3)
        c = np.asarray(C, dtype=np.float64).reshape(3)
        if k[2, 2] <= 0:
            raise ValueError("camera (dlt): K[2, 2] must be positive")
        if not np.allclose(r @ r.T, np.eye(3), atol=1e-9):
            raise ValueError("camera (dlt): R is not orthonormal")
        p = k @ np.hstack([r, (-r @ c)[:, None]])
        return cls(p, size, distortion, distortion_centre)

    # ---- derived quantities

    @property
    def has_distortion(self):
        """True when any of b12..b16 is non-zero."""
        return bool(np.any(self.distortion != 0.0))

    @property
    def n_params(self):
        """16 with distortion terms, else 11."""
        return 16 if self.has_distortion else 11

    @property
    def centre(self):
        """Camera centre (projection centre), shape (3,), metres."""
        return self._centre.copy()

    @property
    def principal_point(self):
        """Where the viewing direction meets the image, shape (2,), pixels:
        (b1 b9 + b2 b10 + b3 b11, b5 b9 + b6 b10 + b7 b11) / (b9^2 + b10^2 + b11^2)."""
        m = self.matrix[:, :3]
        return m[:2] @ m[2] / (m[2] @ m[2])

    @property
    def is_mirrored(self):
        """True for a camera seen in a mirror (its rotation has determinant -1)."""
        return bool(np.linalg.det(self.matrix[:, :3]) < 0)

    @property
    def depth_sign(self):
        """+1 when the world origin is in front of the camera (see the class notes)."""
        return 1 if self.matrix[2, 3] >= 0 else -1

    @property
    def parameters(self):
        """b1..b11, or b1..b16 with distortion: shape (11,) or (16,).

        Raises ValueError when the world origin lies on the camera's principal plane
        (b-form needs P[2, 3] != 0); ``matrix`` always works.
        """
        p = self.matrix
        if abs(p[2, 3]) < 1e-12 * max(1.0, np.abs(p[:, 3]).max()):
            raise ValueError("camera (dlt): the world origin lies on the camera's principal "
                             "plane, so b1..b11 (which fix the last entry to 1) do not exist")
        b = (p / p[2, 3]).reshape(-1)[:11]
        return np.concatenate([b, self.distortion]) if self.has_distortion else b

    def decompose(self):
        """Intrinsics, rotation and centre with ``matrix ~ K R [I | -C]`` (RQ decomposition).

        Returns
        -------
        K : ndarray, shape (3, 3)
            Upper triangular, positive diagonal, ``K[2, 2] == 1``; pixels.
        R : ndarray, shape (3, 3)
            World -> camera, rows (u axis, v axis, viewing direction); determinant +1 for a
            real camera, -1 for a mirrored one.
        C : ndarray, shape (3,), metres
        """
        if self._decomposed is None:
            m = self.matrix[:, :3]
            k, r = scipy.linalg.rq(m)
            d = np.sign(np.diag(k))
            d[d == 0] = 1.0
            k = k * d[None, :]
            r = d[:, None] * r
            k = k / k[2, 2]
            self._decomposed = (k, r, self._centre.copy())
        k, r, c = self._decomposed
        return k.copy(), r.copy(), c.copy()

    @property
    def rotation(self):
        """World -> camera rotation of ``decompose`` (rows u, v, viewing direction)."""
        return self.decompose()[1]

    # ---- projection

    def depth(self, points):
        """Depth along the viewing direction, (n, 3) metres -> (n,) metres (> 0 in front)."""
        x = as_points(points, "points")
        return x @ self.matrix[2, :3] + self.matrix[2, 3]

    def project_ideal(self, points):
        """Pixels without lens distortion (eq. 1): (n, 3) metres -> (n, 2) pixels."""
        x = as_points(points, "points", min_count=0)
        h = x @ self.matrix[:, :3].T + self.matrix[:, 3]
        return h[:, :2] / h[:, 2:3]

    def distort(self, ideal, tol=1e-9, max_iter=30):
        """Observed pixels whose correction (eq. 15) gives ``ideal``: solves
        ``x - d(x) = ideal`` by Newton's method (the model of eq. 6 is written on observed
        coordinates, so this direction is implicit).

        Parameters
        ----------
        ideal : array_like, shape (n, 2), pixels
        tol : float, pixels
        max_iter : int

        Returns
        -------
        ndarray, shape (n, 2), pixels
        """
        q = np.asarray(ideal, dtype=np.float64).reshape(-1, 2)
        if not self.has_distortion:
            return q.copy()
        x = q.copy()
        for _ in range(max_iter):
            f = x - _distortion(x, self.distortion, self.distortion_centre) - q
            if np.abs(f).max(initial=0.0) <= tol:
                break
            inv, _ = _inv2(_correction_jacobian(x, self.distortion, self.distortion_centre))
            x = x - np.einsum("nij,nj->ni", inv, f)
        return x

    def undistort(self, pixels):
        """Ideal (distortion-free) pixels of observed ones, eq. 15: x - dx, y - dy.

        Parameters
        ----------
        pixels : array_like, shape (n, 2), pixels

        Returns
        -------
        ndarray, shape (n, 2), pixels
        """
        q = as_points(pixels, "pixels", dim=2)
        if not self.has_distortion:
            return q
        return q - _distortion(q, self.distortion, self.distortion_centre)

    def project(self, points):
        """Pixel of each world point, with lens distortion: (n, 3) metres -> (n, 2) pixels."""
        return self.distort(self.project_ideal(points))

    def jacobian(self, points):
        """d(pixel)/d(point), analytic: (n, 3) -> (n, 2, 3), pixels per metre.

        Without distortion ``(M[:2] - p M[2]) / w``; with it the implicit-function rule
        ``(I - dd/dx)^-1`` times that, evaluated at the observed pixel.
        """
        x = as_points(points, "points")
        m = self.matrix[:, :3]
        h = x @ m.T + self.matrix[:, 3]
        q = h[:, :2] / h[:, 2:3]
        jac = (m[None, :2, :] - q[:, :, None] * m[None, 2:3, :]) / h[:, 2, None, None]
        if not self.has_distortion:
            return jac
        obs = self.distort(q)
        inv, _ = _inv2(_correction_jacobian(obs, self.distortion, self.distortion_centre))
        return np.einsum("nij,njk->nik", inv, jac)

    def to_camera(self, points):
        """World points in the camera frame (u axis, v axis, depth): (n, 3) -> (n, 3) metres."""
        x = as_points(points, "points")
        _, r, c = self.decompose()
        return (x - c) @ r.T

    def toward_camera(self, points):
        """Unit vectors from each point toward the camera centre: (n, 3) -> (n, 3)."""
        return toward_centre(self._centre, points)

    def back_project(self, pixels):
        """Viewing rays of pixels (after undistortion, eq. 15).

        Parameters
        ----------
        pixels : array_like, shape (n, 2), pixels

        Returns
        -------
        origins : ndarray, shape (n, 3), metres
            The camera centre, repeated.
        directions : ndarray, shape (n, 3)
            Unit vectors pointing away from the camera (depth increases along them).
        """
        q = self.undistort(pixels)
        h = np.column_stack([q, np.ones(len(q))])
        d = h @ self._m_inv.T  # depth component 1 (third row of M has unit length)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return np.broadcast_to(self._centre, d.shape).copy(), d

    def transformed(self, h):
        """The camera that sees ``X`` where this one sees ``H X``: matrix ``P H``.

        Parameters
        ----------
        h : array_like, shape (4, 4)
            Homogeneous world transform (e.g. the reflection in a mirror plane).

        Returns
        -------
        DLTCamera
            Same size and lens distortion (intrinsics are shared).
        """
        hm = np.asarray(h, dtype=np.float64).reshape(4, 4)
        return DLTCamera(self.matrix @ hm, self.size, self.distortion, self.distortion_centre)

    # ---- the joint step of the fit (see Camera.parameter_modes)

    def parameter_fields(self, points):
        """Pixel fields (12, n, 2) of the 12 entries of the matrix (lens terms left out) at
        world points (n, 3)."""
        x = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        pm = self.matrix
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

    def parameter_modes(self, points, centre_points, n_points, prior_weight, mode_pixels):
        """The directions of the matrix that move the points (the 11 of a DLT: the overall
        scale is left out), refitted after the step."""
        f = self.parameter_fields(points)
        flat = f.reshape(len(f), -1)
        _, sv, vt = np.linalg.svd(flat, full_matrices=False)
        keep = sv > 1e-9 * sv[0]
        f = vt[keep].reshape(-1, f.shape[1], 2)
        return (f, *unit_scale(f, mode_pixels), np.zeros(len(f), bool))

    def mirrored(self, plane):
        return self.transformed(plane.homogeneous)

    def as_dlt(self):
        return self

    # ---- fitting

    def refit(self, points, pixels, weights=None):
        """Recalibrate from correspondences (e.g. the head model's landmark vertices and
        their pixels, for self-calibration): same size and same model (11 or 16 params).

        Parameters
        ----------
        points : array_like, shape (n, 3), metres
        pixels : array_like, shape (n, 2), pixels
        weights : array_like, shape (n,), optional
            Non-negative weight per pair (each pair's two equations are multiplied by its
            square root).

        Returns
        -------
        DLTCamera
            A 16-parameter camera falls back to 11 parameters like ``fit_dlt`` (fewer
            than 8 points, or the iteration does not converge); use ``fit_dlt`` to see why.

        Raises
        ------
        ValueError
            Fewer than 6 weighted points, coplanar points, or a degenerate layout.
        """
        return fit_dlt(points, pixels, self.size, n_params=self.n_params, weights=weights).camera

    # ---- serialisation

    def to_dict(self):
        """JSON form: kind, size and b1..b11 (b1..b16 plus ``distortion_centre``)."""
        d = {"kind": self.kind, "size": list(self.size)}
        try:
            d["parameters"] = self.parameters.tolist()
            d["depth_sign"] = self.depth_sign
        except ValueError:  # origin on the principal plane: store the matrix itself
            d["matrix"] = self.matrix.tolist()
            if self.has_distortion:
                d["distortion"] = self.distortion.tolist()
        if self.has_distortion:
            d["distortion_centre"] = self.distortion_centre.tolist()
        return d

    @classmethod
    def from_dict(cls, d):
        """Inverse of ``to_dict`` (accepts ``parameters`` or ``matrix``)."""
        if not isinstance(d, dict):
            raise ValueError(f"camera (dlt): expected an object, got {type(d).__name__}")
        if "size" not in d:
            raise ValueError("camera (dlt): missing field 'size'")
        centre = d.get("distortion_centre")
        try:
            if "parameters" in d:
                return cls.from_parameters(d["parameters"], d["size"], centre,
                                           int(d.get("depth_sign", 1)))
            if "matrix" in d:
                return cls(d["matrix"], d["size"], d.get("distortion"), centre)
        except (TypeError, ValueError) as e:
            msg = str(e)
            if not msg.startswith("camera (dlt)"):
                msg = f"camera (dlt): {msg}"
            raise ValueError(msg) from None
        raise ValueError("camera (dlt): missing field 'parameters' (or 'matrix')")

    def __repr__(self):
        return (f"DLTCamera(n_params={self.n_params}, size={self.size}, "
                f"centre={np.round(self._centre, 4).tolist()})")


# ----------------------------------------------------------------------------- calibration


def _check_not_coplanar(x):
    centred = x - x.mean(axis=0)
    s = np.linalg.svd(centred, compute_uv=False)
    if s[0] == 0.0 or s[2] / s[0] < _COPLANAR_RATIO:
        thick = s[2] / np.sqrt(len(x))
        extent = s[0] / np.sqrt(len(x))
        raise ValueError(
            f"points: the {len(x)} passpoints lie in one plane (RMS thickness {thick:.3g} m "
            f"against an extent of {extent:.3g} m); the DLT needs passpoints spread in depth "
            "(at least 6, no 4 of them in one plane)")


def _scaling(x, q, used, image_range, centre_object):
    xu = x[used]
    centroid = xu.mean(axis=0) if centre_object else np.zeros(3)
    rms = np.sqrt(((xu - centroid) ** 2).sum(axis=1).mean())
    if image_range is None:
        bmin, bmax = float(q[used].min()), float(q[used].max())
    else:
        bmin, bmax = (float(v) for v in image_range)
    if not bmax > bmin:
        raise ValueError(f"pixels: image range [{bmin}, {bmax}] is empty (all passpoints at "
                         "one pixel?)")
    return DLTScaling(centroid, 1.0 / rms, bmin, bmax)


def _dlt11_rows(xs, qs):
    """A and r of eq. 10 for scaled points: (n, 3), (n, 2) -> (2n, 11), (2n,)."""
    n = len(xs)
    a = np.zeros((n, 2, 11))
    a[:, 0, 0:3] = xs
    a[:, 0, 3] = 1.0
    a[:, 0, 8:11] = -qs[:, 0:1] * xs
    a[:, 1, 4:7] = xs
    a[:, 1, 7] = 1.0
    a[:, 1, 8:11] = -qs[:, 1:2] * xs
    return a.reshape(2 * n, 11), qs.reshape(2 * n)


def _dlt16_rows(xs, qs, b, centre_rule):
    """A^(k), r^(k) of eq. 13 and the centre (x0, y0) of eq. 12a used, in scaled units."""
    m1, m2, m3 = b[0:3], b[4:7], b[8:11]
    if centre_rule == "eq8":
        ell = 1.0 / (m3 @ m3 + 1.0)
        x0 = (m1 @ m3 + b[3]) * ell
        y0 = (m2 @ m3 + b[7]) * ell
    else:
        ell = 1.0 / (m3 @ m3)
        x0 = (m1 @ m3) * ell
        y0 = (m2 @ m3) * ell
    a_i = 1.0 / (xs @ m3 + 1.0)  # eq. 12b
    u = qs[:, 0] - x0
    v = qs[:, 1] - y0
    r = u * u + v * v
    n = len(xs)
    a = np.zeros((n, 2, 16))
    xa = xs * a_i[:, None]
    a[:, 0, 0:3] = xa
    a[:, 0, 3] = a_i
    a[:, 0, 8:11] = -qs[:, 0:1] * xa
    a[:, 1, 4:7] = xa
    a[:, 1, 7] = a_i
    a[:, 1, 8:11] = -qs[:, 1:2] * xa
    a[:, 0, 11] = u * r
    a[:, 0, 12] = u * r**2
    a[:, 0, 13] = u * r**3
    a[:, 0, 14] = r + 2.0 * u * u
    a[:, 0, 15] = 2.0 * u * v
    a[:, 1, 11] = v * r
    a[:, 1, 12] = v * r**2
    a[:, 1, 13] = v * r**3
    a[:, 1, 14] = 2.0 * u * v
    a[:, 1, 15] = r + 2.0 * v * v
    rhs = (qs * a_i[:, None]).reshape(2 * n)
    return a.reshape(2 * n, 16), rhs, np.array([x0, y0])


def _solve(a, r, sw):
    """Weighted least squares by SVD; returns solution and kappa(A) (eq. 19)."""
    sol, _, rank, s = np.linalg.lstsq(a * sw[:, None], r * sw, rcond=None)
    cond = np.inf if s[-1] == 0 else float(s[0] / s[-1])
    return sol, cond, rank


def _to_world(b, scaling, x, used):
    """Scaled-frame b1..b11 -> DLT matrix in pixels/metres, oriented so the passpoints are
    in front (positive depth)."""
    ps = np.array([b[0:4], b[4:8], [b[8], b[9], b[10], 1.0]])
    p = np.linalg.solve(scaling.image_matrix(), ps) @ scaling.object_matrix()
    w = x[used] @ p[2, :3] + p[2, 3]
    if np.median(w) < 0:
        p = -p
        w = -w
    return p, w


def fit_dlt(points, pixels, size, n_params=11, weights=None, image_range=None,
            centre_object=True, distortion_centre="principal", tol=1e-9, itmax=10):
    """Calibrate a DLT camera from passpoints (seed 000 §2 and §4).

    Parameters
    ----------
    points : array_like, shape (n, 3), metres
        Passpoints in world coordinates: at least 6 (8 for 16 parameters), not coplanar.
    pixels : array_like, shape (n, 2), pixels
        Where each passpoint is seen.
    size : (int, int)
        Image width and height in pixels (stored with the camera).
    n_params : {11, 16}
        11: eq. 1 solved by eq. 10-11. 16: eq. 6-8 by the iteration of eq. 12-14, falling
        back to 11 (with ``fell_back`` and ``reason``) when it fails.
    weights : array_like, shape (n,), optional
        Non-negative weight per passpoint; 0 leaves a point out.
    image_range : (float, float), optional
        (b_min, b_max) of eq. 22; default the passpoints' pixel range (one range for u and
        v, so the scaling is isotropic and the distortion model keeps its circles).
    centre_object : bool
        Move the object origin to the passpoints' centroid (seed 000 §4). False keeps the
        given origin (still scaled), which gives exactly the plain least-squares DLT of the
        unscaled equations (e.g. seed 004's numbers); the two differ slightly because eq. 9
        weighs each equation by its point's denominator relative to the origin's.
    distortion_centre : {"principal", "eq8"}
        How (x0, y0) of eq. 12a is computed for 16 parameters (see the module docstring).
    tol : float
        Eq. 14: stop when ||b^(k) - b^(k-1)|| < tol * ||b^(k)|| (scaled frame).
    itmax : int
        Most DLT-16 iterations (film3d's default is 10).

    Returns
    -------
    DLTFit

    Raises
    ------
    ValueError
        Too few passpoints, coplanar passpoints, rank-deficient layout, mismatched shapes,
        or non-finite input.
    """
    if n_params not in (11, 16):
        raise ValueError(f"n_params: must be 11 or 16, got {n_params!r}")
    if int(itmax) < 1:
        raise ValueError(f"itmax: must be at least 1, got {itmax!r}")
    if distortion_centre not in ("principal", "eq8"):
        raise ValueError(f"distortion_centre: must be 'principal' or 'eq8', "
                         f"got {distortion_centre!r}")
    x, q, w = correspondences(points, pixels, weights, MIN_POINTS[11], what="the DLT",
                              unit="passpoints (not all in one plane)")
    used = w > 0
    _check_not_coplanar(x[used])
    scaling = _scaling(x, q, used, image_range, centre_object)
    xs = (x - scaling.centroid) * scaling.object_scale
    qs = q * scaling.image_factor + scaling.image_shift
    sw = np.repeat(np.sqrt(w), 2)

    a, r = _dlt11_rows(xs, qs)
    b11, cond, rank = _solve(a, r, sw)
    if rank < 11 or cond > _MAX_CONDITION:
        raise ValueError(
            f"points: the passpoint layout is degenerate for the DLT (rank {rank} of 11, "
            f"condition {cond:.3g}); e.g. all but one point in one plane or all on a few "
            "lines: add passpoints spread in depth")
    a_raw, r_raw = _dlt11_rows(x, q)
    cond_raw = float(np.linalg.cond(a_raw * sw[:, None]))
    warnings = []
    if cond > _WARN_CONDITION:
        warnings.append(f"condition number {cond:.3g} of the scaled DLT system is large: "
                        "the passpoints barely determine the camera")

    p11, depth = _to_world(b11, scaling, x, used)
    if (depth <= 0).any():
        warnings.append(f"{int((depth <= 0).sum())} passpoint(s) fall behind the fitted "
                        "camera: check the passpoints")
    cam11 = DLTCamera(p11, size)

    fit = None
    reason = ""
    iterations = 0
    converged = True
    if n_params == 16:
        if np.count_nonzero(used) < MIN_POINTS[16]:
            reason = (f"DLT-16 needs at least {MIN_POINTS[16]} passpoints, got "
                      f"{np.count_nonzero(used)}")
        else:
            fit, reason, iterations, converged = _fit16(
                xs, qs, sw, b11, scaling, x, used, size, distortion_centre, tol, itmax)
    if fit is None:
        cam, n_used, cond16 = cam11, 11, cond
    else:
        cam, cond16 = fit
        n_used = 16
    res = q - cam.project(x)
    rms = float(np.sqrt((res[used] ** 2).sum(axis=1).mean()))
    return DLTFit(cam, n_params, n_used, res, rms, cond16, cond_raw, iterations,
                  converged, n_params == 16 and n_used == 11, reason, scaling, warnings)


def _fit16(xs, qs, sw, b11, scaling, x, used, size, centre_rule, tol, itmax):
    """The iteration of eq. 12-14 in the scaled frame. Returns ((camera, kappa) or None,
    reason, iterations, converged)."""
    b = np.concatenate([b11, np.zeros(5)])
    centre = None
    cond = np.inf
    converged = False
    k = 0
    for k in range(1, itmax + 1):
        a, r, centre = _dlt16_rows(xs, qs, b, centre_rule)
        b_new, cond, rank = _solve(a, r, sw)
        if not np.isfinite(b_new).all():
            return None, f"DLT-16 iteration {k} produced non-finite parameters", k, False
        if rank < 16 or cond > 1e12:
            return (None, f"DLT-16 system is rank deficient at iteration {k} (rank {rank}, "
                    f"condition {cond:.3g}): the passpoints do not determine the lens terms",
                    k, False)
        step = np.linalg.norm(b_new - b)
        b = b_new
        if step < tol * np.linalg.norm(b):
            converged = True
            break
    if not converged:
        return (None, f"DLT-16 did not converge in {itmax} iterations (last step "
                f"{step:.3g} > tolerance {tol:.3g} x |b|)", k, False)
    # back to pixel units: u_scaled = s u, r_scaled = s^2 r (module docstring)
    s = scaling.image_factor
    dist = b[11:16] * np.array([s**2, s**4, s**6, s, s])
    centre_px = (centre - scaling.image_shift) / s
    p, _ = _to_world(b[:11], scaling, x, used)
    cam = DLTCamera(p, size, dist, centre_px)
    # the model must stay invertible (x -> x - d(x) must not fold) at the passpoints
    obs = qs[used]
    jd = _distortion_jacobian(obs, b[11:16], centre)
    det = (1 - jd[:, 0, 0]) * (1 - jd[:, 1, 1]) - jd[:, 0, 1] * jd[:, 1, 0]
    if (det <= 0).any():
        return (None, "DLT-16 lens terms fold the image at some passpoints (the correction "
                "is not invertible there)", k, True)
    return (cam, cond), "", k, True
