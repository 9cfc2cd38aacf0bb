"""A constrained perspective (pinhole) camera for self-calibration on a head.

A full DLT (solver/dlt.py) has 11 free parameters: focal lengths in u and v, skew, the
principal point, rotation and centre. Fitted to the landmarks of one head, whose depth is
shallow against the camera distance, those parameters trade off against each other: at
2 m with 2 px of landmark noise the DLT's camera centre is off by about 10 cm. Photos from
real cameras have square pixels, no skew and a principal point near the image centre, so
this camera keeps only

- the focal length ``f`` in pixels (one for u and v),
- the principal point (default the image centre, fixed unless ``free_principal_point``),
- the rotation ``R`` (world -> camera, rows u axis, v axis, viewing direction: OpenCV, as
  in solver/cameras.py) and the centre ``C`` (metres, world),
- optionally one radial distortion term ``k1`` (fixed at 0 unless given or ``free_k1``),

and ``refit`` estimates 7 unknowns (log f, a rotation increment, the centre) by
Levenberg-Marquardt on the reprojection error. Projection (normalised coordinates
``p = (x_c / z_c, y_c / z_c)`` of the camera-frame point ``R (X - C)``)::

    pixel = principal_point + f * p * (1 + k1 * |p|^2)

``k1`` is the forward (OpenCV-style) radial term on normalised coordinates, so projection
is explicit; the DLT's lens terms are written on observed pixels (seed 000 eq. 7), so
``to_dlt`` fits those to this model over the image and checks the fit.

What the constraints buy, and what they cannot (92 landmarks of the head model, 50 mm
equivalent, 1 px noise): they remove the principal point / skew / aspect freedom, so the
camera's pose across the viewing direction and its projection of points it was not fitted
to improve (docs/DECISIONS.md). The
camera's *distance* is another matter: a head is shallow, so focal length and distance
trade off (a dolly zoom changes the image of a head only through its depth variation of
about 15 %). With the focal length free the distance is as uncertain as the DLT's
(Cramer-Rao standard deviation about 9 cm at 2 m, 1 cm at 1 m), the error lying along the
viewing direction with ``dZ / Z = -df / f``. With the focal length known (EXIF;
``free_focal=False``) or given a tight ``focal_prior`` the distance follows from the
head's image size: a few millimetres at 2 m.

Blender conversions go through solver/blender_camera.py's K, R, C functions, which own all
Blender camera conventions. A rotation with determinant -1 (a camera seen in a mirror,
solver/mirror.py) is allowed everywhere except where Blender cannot represent it.
"""

import numpy as np

from ..errors import as_points
from ..geometry import check_orthonormal, rotation_between, rotation_from_vector, skew
from .base import Camera, correspondences, register, toward_centre, unit_scale
from .blender import blender_to_krc, krc_to_blender
from .dlt import DLTCamera, fit_dlt

#: sensor size (mm) across the longer image side that ``lens_mm`` refers to (full frame)
SENSOR_MM = 36.0
#: default plausible focal range for refits, mm equivalent on a 36 mm sensor (phone wide
#: angle to long portrait tele)
DEFAULT_FOCAL_RANGE_MM = (20.0, 200.0)
#: fewest weighted points for which ``refit`` frees the focal length (and principal point);
#: below it (4 or 5 points) only the pose is estimated
FREE_FOCAL_POINTS = 6
#: fewest weighted points for which ``refit`` frees k1 (when ``free_k1``)
FREE_K1_POINTS = 8

# Soft priors, relative to "1 px of error on every point": the focal range penalty is a
# near-hard wall (10 % outside the range costs as much as 10 px on every point); a free
# principal point 10 % of the image side off centre, or |k1| = 0.2, costs 1 px everywhere.
_FOCAL_WALL = 100.0
_PP_SIGMA = 0.1
_K1_SIGMA = 0.2
# points closer than this to the camera plane (metres) count as behind it
_MIN_DEPTH = 1e-6
# below this ratio of the 2nd to the 1st singular value of the centred points they are a line
_COLLINEAR_RATIO = 1e-3
# below this ratio of the 3rd to the 1st the weak-perspective start also tries a plane
_PLANAR_RATIO = 0.1


def pixel_by_camera_point(xc, focal_px, k1=0.0):
    """d(pixel)/d(camera-frame point) of a pinhole camera with radial term k1.

    Parameters
    ----------
    xc : ndarray, shape (n, 3), metres
        Points in the camera frame (depth > 0).
    focal_px : float
    k1 : float

    Returns
    -------
    g : ndarray, shape (n, 2, 3), pixels per metre
    p : ndarray, shape (n, 2)
        Normalised image coordinates x/z, y/z.
    """
    z = xc[:, 2]
    p = xc[:, :2] / z[:, None]
    dp = np.zeros((len(xc), 2, 3))  # d p / d x_c
    dp[:, 0, 0] = 1.0 / z
    dp[:, 1, 1] = 1.0 / z
    dp[:, :, 2] = -p / z[:, None]
    if k1 == 0.0:
        return focal_px * dp, p
    rho2 = (p * p).sum(axis=1)
    dd = (2.0 * focal_px * k1) * p[:, :, None] * p[:, None, :]  # d pixel / d p
    dd[:, 0, 0] += focal_px * (1.0 + k1 * rho2)
    dd[:, 1, 1] += focal_px * (1.0 + k1 * rho2)
    return np.einsum("nij,njk->nik", dd, dp), p


@register("pinhole")
class PinholeCamera(Camera):
    """Perspective camera with square pixels, no skew and few unknowns.

    Parameters
    ----------
    focal_px : float
        Focal length in pixels (the same for u and v).
    rotation : array_like, shape (3, 3)
        World -> camera rotation, rows (u axis, v axis, viewing direction); determinant +1,
        or -1 for a mirrored camera.
    centre : array_like, shape (3,), metres
        Camera centre in world coordinates.
    size : (int, int)
        Image width and height in pixels.
    principal_point : array_like, shape (2,), pixels, optional
        Default the image centre (w / 2, h / 2).
    k1 : float
        Radial distortion on normalised coordinates (0: none).
    free_principal_point : bool
        ``refit`` estimates the principal point too (weakly determined by a shallow head;
        a soft prior keeps it near the image centre).
    free_k1 : bool
        ``refit`` estimates k1 too (with at least 8 points; a soft prior keeps it small).
    free_focal : bool
        ``refit`` estimates the focal length (with at least 6 points). False when it is
        known (EXIF): then the distance is fixed by the head's image size, which a free
        focal length leaves weakly determined (see the module docstring).
    focal_prior : (float, float) or None
        (lens_mm, relative standard deviation) of a Gaussian prior on the focal length for
        ``refit`` (e.g. (50, 0.03) from EXIF data of uncertain crop factor).
    focal_range_mm : (float, float) or None
        Plausible focal lengths, mm equivalent on a 36 mm sensor: ``refit`` is walled in to
        this range (smoothly), which keeps shallow scenes, where focal length and distance
        trade off, well posed. None: no prior.
    direction_prior : (float, float) or None
        (yaw_deg, sigma_deg): a Gaussian prior on the camera's viewing direction in the
        head's frame, held level at this yaw (the camera's direction from the face's front,
        toward the subject's right positive: 0 a front photo, +-90 a profile), for the
        fit's joint steps: a front or profile photo says where its camera stood, which a
        profile's few points in one plane (the midline) cannot.
    """

    #: four non-collinear points fix the pose (with the focal length kept)
    min_refit_points = 4
    perspective = True
    moves_rigidly = True

    def __init__(self, focal_px, rotation, centre, size, principal_point=None, k1=0.0, *,
                 free_principal_point=False, free_k1=False,
                 focal_range_mm=DEFAULT_FOCAL_RANGE_MM, free_focal=True, focal_prior=None,
                 direction_prior=None):
        try:
            w, h = (int(size[0]), int(size[1]))
        except (TypeError, IndexError, ValueError):
            raise ValueError(f"camera (pinhole): size must be (width, height), got {size!r}") \
                from None
        if w <= 0 or h <= 0:
            raise ValueError(f"camera (pinhole): size must be positive, got {size!r}")
        self.size = (w, h)
        try:
            f = float(focal_px)
        except (TypeError, ValueError):
            f = np.nan
        if not (np.isfinite(f) and f > 0):
            raise ValueError(f"camera (pinhole): focal_px must be positive, got {focal_px!r}")
        self.focal_px = f
        self.rotation = check_orthonormal(rotation, "camera (pinhole): rotation")
        c = np.asarray(centre, dtype=np.float64).reshape(-1)
        if c.shape != (3,) or not np.isfinite(c).all():
            raise ValueError(f"camera (pinhole): centre must be 3 finite numbers, got {centre!r}")
        self.centre = c
        if principal_point is None:
            principal_point = (w / 2.0, h / 2.0)
        pp = np.asarray(principal_point, dtype=np.float64).reshape(-1)
        if pp.shape != (2,) or not np.isfinite(pp).all():
            raise ValueError("camera (pinhole): principal_point must be 2 finite numbers, "
                             f"got {principal_point!r}")
        self.principal_point = pp
        try:
            k = float(k1)
        except (TypeError, ValueError):
            k = np.nan
        if not np.isfinite(k):
            raise ValueError(f"camera (pinhole): k1 must be a finite number, got {k1!r}")
        self.k1 = k
        self.free_principal_point = bool(free_principal_point)
        self.free_k1 = bool(free_k1)
        if focal_range_mm is not None:
            lo, hi = (float(v) for v in focal_range_mm)
            if not (0 < lo < hi and np.isfinite(hi)):
                raise ValueError("camera (pinhole): focal_range_mm must be (min, max) with "
                                 f"0 < min < max, got {focal_range_mm!r}")
            focal_range_mm = (lo, hi)
        self.focal_range_mm = focal_range_mm
        self.free_focal = bool(free_focal)
        if focal_prior is not None:
            mm, sigma = (float(v) for v in focal_prior)
            if not (np.isfinite(mm) and mm > 0 and np.isfinite(sigma) and sigma > 0):
                raise ValueError("camera (pinhole): focal_prior must be (lens_mm, relative "
                                 f"sigma), both positive, got {focal_prior!r}")
            focal_prior = (mm, sigma)
        self.focal_prior = focal_prior
        if direction_prior is not None:
            try:
                yaw, sigma = (float(v) for v in direction_prior)
            except (TypeError, ValueError):
                yaw = sigma = np.nan
            if not (np.isfinite(yaw) and np.isfinite(sigma) and sigma > 0):
                raise ValueError("camera (pinhole): direction_prior must be (yaw_deg, "
                                 f"sigma_deg), sigma positive, got {direction_prior!r}")
            direction_prior = (yaw, sigma)
        self.direction_prior = direction_prior

    # ---- construction helpers

    def _options(self):
        return {"free_principal_point": self.free_principal_point, "free_k1": self.free_k1,
                "focal_range_mm": self.focal_range_mm, "free_focal": self.free_focal,
                "focal_prior": self.focal_prior, "direction_prior": self.direction_prior}

    def replaced(self, focal_px=None, rotation=None, centre=None, principal_point=None, k1=None):
        """A copy with the given parameters replaced (same size and options).

        Parameters
        ----------
        focal_px : float, optional
        rotation : array_like, shape (3, 3), optional
        centre : array_like, shape (3,), metres, optional
        principal_point : array_like, shape (2,), pixels, optional
        k1 : float, optional

        Returns
        -------
        PinholeCamera
        """
        return PinholeCamera(
            self.focal_px if focal_px is None else focal_px,
            self.rotation if rotation is None else rotation,
            self.centre if centre is None else centre, self.size,
            self.principal_point if principal_point is None else principal_point,
            self.k1 if k1 is None else k1, **self._options())

    @staticmethod
    def px_per_mm(size):
        """Pixels per millimetre of focal length for a 36 mm sensor across the longer side."""
        return max(float(size[0]), float(size[1])) / SENSOR_MM

    @classmethod
    def look_at(cls, centre, target, size, *, f_px=None, lens_mm=None, up=(0.0, 0.0, 1.0),
                principal_point=None, k1=0.0, **options):
        """Camera at ``centre`` looking at ``target`` with ``up`` pointing up in the image.

        Parameters
        ----------
        centre, target : array_like, shape (3,), metres
        size : (int, int)
            Image width and height in pixels.
        f_px : float, optional
            Focal length in pixels; or give
        lens_mm : float, optional
            Focal length in mm equivalent on a 36 mm sensor across the longer image side.
        up : array_like, shape (3,)
            World direction that appears up (-v) in the image (default +Z); must not be
            parallel to the viewing direction.
        principal_point, k1, **options
            As the class (``free_principal_point``, ``free_k1``, ``free_focal``,
            ``focal_prior``, ``focal_range_mm``).

        Returns
        -------
        PinholeCamera
        """
        if (f_px is None) == (lens_mm is None):
            raise ValueError("look_at: give exactly one of f_px and lens_mm")
        if f_px is None:
            f_px = float(lens_mm) * cls.px_per_mm(size)
        c = np.asarray(centre, dtype=np.float64).reshape(3)
        fwd = np.asarray(target, dtype=np.float64).reshape(3) - c
        if not np.linalg.norm(fwd) > 0:
            raise ValueError("look_at: target coincides with centre")
        fwd /= np.linalg.norm(fwd)
        right = np.cross(fwd, np.asarray(up, dtype=np.float64).reshape(3))
        if np.linalg.norm(right) < 1e-9:
            raise ValueError("look_at: up is parallel to the viewing direction")
        right /= np.linalg.norm(right)
        rot = np.array([right, np.cross(fwd, right), fwd])  # v = fwd x right points down
        return cls(f_px, rot, c, size, principal_point, k1, **options)

    # ---- derived quantities

    @property
    def lens_mm(self):
        """Focal length in mm equivalent on a 36 mm sensor across the longer image side."""
        return self.focal_px / self.px_per_mm(self.size)

    @property
    def intrinsics(self):
        """K, shape (3, 3), pixels: [[f, 0, cx], [0, f, cy], [0, 0, 1]]."""
        return np.array([[self.focal_px, 0.0, self.principal_point[0]],
                         [0.0, self.focal_px, self.principal_point[1]], [0.0, 0.0, 1.0]])

    @property
    def matrix(self):
        """The 3x4 projection matrix K R [I | -C] (without k1), third row the depth."""
        r = self.rotation
        return self.intrinsics @ np.hstack([r, (-r @ self.centre)[:, None]])

    @property
    def is_mirrored(self):
        """True for a camera seen in a mirror (rotation with determinant -1)."""
        return bool(np.linalg.det(self.rotation) < 0)

    def decompose(self):
        """(K, R, C) like ``DLTCamera.decompose``: copies of intrinsics, rotation, centre."""
        return self.intrinsics, self.rotation.copy(), self.centre.copy()

    # ---- projection

    def to_camera(self, points):
        """World points in the camera frame (u axis, v axis, depth): (n, 3) -> (n, 3) m."""
        x = as_points(points, "points")
        return (x - self.centre) @ self.rotation.T

    def depth(self, points):
        """Depth along the viewing direction, (n, 3) metres -> (n,) metres (> 0 in front)."""
        return self.to_camera(points)[:, 2]

    def toward_camera(self, points):
        """Unit vectors from each point toward the camera centre: (n, 3) -> (n, 3)."""
        return toward_centre(self.centre, points)

    def project(self, points):
        """Pixel of each world point: (n, 3) metres -> (n, 2) pixels."""
        xc = self.to_camera(points)
        p = xc[:, :2] / xc[:, 2:3]
        g = 1.0 + self.k1 * (p * p).sum(axis=1)
        return self.principal_point + self.focal_px * p * g[:, None]

    def jacobian(self, points):
        """d(pixel)/d(point), analytic: (n, 3) -> (n, 2, 3), pixels per metre."""
        g, _ = pixel_by_camera_point(self.to_camera(points), self.focal_px, self.k1)
        return g @ self.rotation

    def undistort(self, pixels):
        """Pixels as the camera without k1 would see them: (n, 2) -> (n, 2) pixels.

        Inverts ``rho (1 + k1 rho^2)`` on the normalised radius by Newton's method.
        """
        q = as_points(pixels, "pixels", dim=2)
        if self.k1 == 0.0:
            return q
        m = (q - self.principal_point) / self.focal_px
        ro = np.linalg.norm(m, axis=1)
        r = ro.copy()
        for _ in range(30):
            d = 1.0 + 3.0 * self.k1 * r * r
            step = (r * (1.0 + self.k1 * r * r) - ro) / np.where(np.abs(d) > 1e-12, d, 1e-12)
            r -= step
            if np.abs(step).max(initial=0.0) < 1e-14:
                break
        scale = np.where(ro > 0, r / np.where(ro > 0, ro, 1.0), 1.0)
        return self.principal_point + self.focal_px * m * scale[:, None]

    def back_project(self, pixels):
        """Viewing rays of pixels: origins (n, 3) metres (the centre), unit directions (n, 3)
        pointing away from the camera."""
        q = self.undistort(pixels)
        d = np.column_stack([(q - self.principal_point) / self.focal_px, np.ones(len(q))])
        d = d @ self.rotation  # camera -> world (R orthogonal)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return np.broadcast_to(self.centre, d.shape).copy(), d

    # ---- DLT and Blender

    def _corner_radius(self):
        """Largest distance from the principal point to an image corner, pixels."""
        w, h = self.size
        corners = np.array([[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]])
        return float(np.linalg.norm(corners - self.principal_point, axis=1).max())

    def to_dlt(self, tolerance_px=0.05):
        """The same camera as a DLTCamera (``P = K R [I | -C]``).

        Without k1 the projection is identical (to rounding). With k1 the DLT's radial lens
        terms b12..b14 (seed 000 eq. 7, written on observed pixels) are fitted to this
        camera's distortion along the radius out to the farthest image corner.

        Parameters
        ----------
        tolerance_px : float, pixels
            Largest pixel difference inside the image accepted for the k1 conversion.

        Returns
        -------
        DLTCamera

        Raises
        ------
        ValueError
            k1 that the DLT lens terms cannot match within ``tolerance_px`` (or that folds
            the image).
        """
        if self.k1 == 0.0:
            return DLTCamera(self.matrix, self.size)
        f, k1 = self.focal_px, self.k1
        r_max = 1.05 * self._corner_radius()
        # observed radius (px) -> ideal radius (px): invert f rho (1 + k1 rho^2) = r_obs
        r_obs = np.linspace(0.0, r_max, 200)
        # k1 < 0: the radius map rho (1 + k1 rho^2) peaks at rho* = 1 / sqrt(-3 k1), where it
        # reaches 2/3 rho*; beyond that observed radius the image folds back
        if k1 < 0 and r_max / f >= (2.0 / 3.0) / np.sqrt(-3.0 * k1):
            raise ValueError(f"camera (pinhole): k1 = {k1:.4g} folds the image inside its "
                             "corners; it has no DLT form")
        ideal = self.undistort(np.column_stack([self.principal_point[0] + r_obs,
                                                np.full_like(r_obs, self.principal_point[1])]))
        r_ideal = ideal[:, 0] - self.principal_point[0]
        # r_obs - r_ideal = b12 r^3 + b13 r^5 + b14 r^7 (r = r_obs), solved in units of r_max
        t = r_obs / r_max
        a = np.column_stack([t**3, t**5, t**7]) * r_max
        sol, *_ = np.linalg.lstsq(a, r_obs - r_ideal, rcond=None)
        err = np.abs(a @ sol - (r_obs - r_ideal)).max()
        if err > tolerance_px:
            raise ValueError(f"camera (pinhole): k1 = {k1:.4g} differs from the DLT lens "
                             f"terms by up to {err:.3g} px (> tolerance_px {tolerance_px})")
        b = sol / np.array([r_max**2, r_max**4, r_max**6])
        return DLTCamera(self.matrix, self.size, [b[0], b[1], b[2], 0.0, 0.0],
                         self.principal_point)

    @classmethod
    def from_krc(cls, K, R, C, size, principal_point="centre", k1=0.0, **options):
        """The nearest pinhole camera to ``K R [I | -C]``.

        The focal length is the geometric mean of K's fx and fy; skew is dropped. With
        ``principal_point="centre"`` (or given coordinates) the camera is turned so that
        the ray K put at that pixel stays there, which keeps the image content in place.

        Parameters
        ----------
        K : array_like, shape (3, 3), pixels
        R : array_like, shape (3, 3)
        C : array_like, shape (3,), metres
        size : (int, int)
        principal_point : "centre", "keep" or array_like (2,)
            The image centre, K's own principal point, or these pixel coordinates.
        k1 : float
        **options
            As the class (``free_focal``, ``focal_prior``, ``focal_range_mm``, ...).

        Returns
        -------
        PinholeCamera
        """
        k = np.asarray(K, dtype=np.float64).reshape(3, 3)
        if not (np.isfinite(k).all() and k[2, 2] > 0):
            raise ValueError("K: must be finite with K[2, 2] > 0")
        k = k / k[2, 2]
        fx, fy = k[0, 0], k[1, 1]
        if not (fx > 0 and fy > 0):
            raise ValueError(f"K: focal lengths must be positive, got fx={fx}, fy={fy}")
        r = check_orthonormal(R, "R")
        if isinstance(principal_point, str):
            if principal_point == "keep":
                target = k[:2, 2].copy()
            elif principal_point == "centre":
                target = np.array([size[0] / 2.0, size[1] / 2.0])
            else:
                raise ValueError("principal_point: must be 'centre', 'keep' or (cx, cy), got "
                                 f"{principal_point!r}")
        else:
            target = np.asarray(principal_point, dtype=np.float64).reshape(2)
        # the ray that K puts at the target pixel becomes the new viewing direction
        ray = np.linalg.solve(k, [target[0], target[1], 1.0])
        ray /= np.linalg.norm(ray)
        rot = rotation_between(ray, np.array([0.0, 0.0, 1.0])) @ r
        return cls(np.sqrt(fx * fy), rot, C, size, target, k1, **options)

    @classmethod
    def from_dlt(cls, camera, principal_point="centre", **options):
        """The nearest pinhole camera to a DLT camera (decomposed into K R C, projected onto
        square pixels without skew; see ``from_krc``).

        The DLT's first radial term becomes k1 = b12 f^2 (first order); the other lens terms
        are dropped.

        Parameters
        ----------
        camera : DLTCamera
        principal_point : "centre", "keep" or array_like (2,)
        **options
            As the class (``free_focal``, ``focal_prior``, ``focal_range_mm``, ...).

        Returns
        -------
        PinholeCamera
        """
        if not isinstance(camera, DLTCamera):
            raise ValueError(f"camera: expected a DLTCamera, got {type(camera).__name__}")
        k, r, c = camera.decompose()
        f = np.sqrt(k[0, 0] * k[1, 1])
        k1 = float(camera.distortion[0]) * f * f if camera.has_distortion else 0.0
        return cls.from_krc(k, r, c, camera.size, principal_point, k1, **options)

    def to_blender(self, sensor_size=SENSOR_MM, allow_flip=False):
        """Blender camera settings (``blender_camera.krc_to_blender``); a warning is added
        when k1 is dropped (Blender cameras have no lens distortion)."""
        out = krc_to_blender(self.intrinsics, self.rotation, self.centre, self.size,
                             sensor_size, allow_flip)
        if self.k1 != 0.0:
            out["warnings"].append(f"lens distortion k1 = {self.k1:.4g} dropped: Blender "
                                   "cameras have none; undistort the photo to match exactly")
        return out

    @classmethod
    def from_blender(cls, params, **options):
        """Camera of Blender camera settings (``blender_camera.blender_to_krc``).

        Raises
        ------
        ValueError
            Non-square pixels (pixel_aspect_x != pixel_aspect_y), or what
            ``blender_to_krc`` raises.
        """
        k, r, c, size = blender_to_krc(params)
        if abs(k[0, 0] / k[1, 1] - 1.0) > 1e-9:
            raise ValueError("blender camera: pixel_aspect_x and pixel_aspect_y differ; a "
                             "pinhole camera has square pixels (use a DLT camera)")
        return cls(k[0, 0], r, c, size, k[:2, 2], **options)

    # ---- serialisation

    def to_dict(self):
        """JSON form. ``lens_mm`` (36 mm equivalent) is for information; ``focal_px`` rules."""
        return {"kind": self.kind, "focal_px": self.focal_px,
                "principal_point": self.principal_point.tolist(),
                "rotation": self.rotation.tolist(), "centre": self.centre.tolist(),
                "size": list(self.size), "k1": self.k1, "lens_mm": self.lens_mm,
                "free_principal_point": self.free_principal_point, "free_k1": self.free_k1,
                "focal_range_mm": None if self.focal_range_mm is None
                else list(self.focal_range_mm), "free_focal": self.free_focal,
                "focal_prior": None if self.focal_prior is None else list(self.focal_prior),
                "direction_prior": None if self.direction_prior is None
                else list(self.direction_prior)}

    @classmethod
    def from_dict(cls, d):
        """Inverse of ``to_dict``. Without ``focal_px``, ``lens_mm`` (36 mm equivalent) is
        used; ``principal_point`` defaults to the image centre, ``k1`` to 0."""
        if not isinstance(d, dict):
            raise ValueError(f"camera (pinhole): expected an object, got {type(d).__name__}")
        for key in ("rotation", "centre", "size"):
            if key not in d:
                raise ValueError(f"camera (pinhole): missing field {key!r}")
        if "focal_px" in d:
            f = d["focal_px"]
        elif "lens_mm" in d:
            try:
                f = float(d["lens_mm"]) * cls.px_per_mm(d["size"])
            except (TypeError, ValueError, IndexError):
                raise ValueError("camera (pinhole): lens_mm and size must be numbers") \
                    from None
        else:
            raise ValueError("camera (pinhole): missing field 'focal_px' (or 'lens_mm')")
        try:
            return cls(f, d["rotation"], d["centre"], d["size"], d.get("principal_point"),
                       d.get("k1", 0.0),
                       free_principal_point=d.get("free_principal_point", False),
                       free_k1=d.get("free_k1", False),
                       focal_range_mm=d.get("focal_range_mm", DEFAULT_FOCAL_RANGE_MM),
                       free_focal=d.get("free_focal", True),
                       focal_prior=d.get("focal_prior"),
                       direction_prior=d.get("direction_prior"))
        except (TypeError, ValueError) as e:
            msg = str(e)
            if not msg.startswith("camera (pinhole)"):
                msg = f"camera (pinhole): {msg}"
            raise ValueError(msg) from None

    def __repr__(self):
        return (f"PinholeCamera(f={self.focal_px:.1f} px ({self.lens_mm:.1f} mm), "
                f"size={self.size}, centre={np.round(self.centre, 4).tolist()})")

    # ---- self-calibration

    # ---- the joint step of the fit (see Camera.parameter_modes)

    def parameter_fields(self, points, focal=True):
        """Pixel fields (6 or 7, n, 2) of the parameters at world points (n, 3): a rotation
        increment in the camera frame (``R <- rot(w) R``, radians, 3), the centre (metres,
        3) and, with ``focal``, the log focal length (k1 included)."""
        x = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        rot = self.rotation
        xc = (x - self.centre) @ rot.T
        f, k1 = self.focal_px, self.k1
        g, p = pixel_by_camera_point(xc, f, k1)
        rho2 = (p * p).sum(axis=1)
        by_rot = -np.einsum("nij,njk->nik", g, skew(xc))  # x_c += w x x_c
        by_centre = -g @ rot
        out = [by_rot[:, :, i] for i in range(3)] + [by_centre[:, :, i] for i in range(3)]
        if focal:
            out.append(f * p * (1.0 + k1 * rho2)[:, None])
        return np.stack(out)

    def focal_free(self, n_points):
        """Whether the fit moves the focal length (as ``refit`` does: ``free_focal`` and at
        least FREE_FOCAL_POINTS points)."""
        return bool(self.free_focal) and n_points >= FREE_FOCAL_POINTS

    def log_focal_prior(self, n_points):
        if not self.focal_free(n_points) or self.focal_prior is None:
            return None
        mm, sigma = self.focal_prior
        return float(np.log(mm * self.px_per_mm(self.size))), float(sigma)

    def direction_offset(self):
        """(offset (2,), sigma) of ``direction_prior``: the prior direction's tangent offsets
        from the optical axis across the image's u and v axes (radians for small angles),
        and its standard deviation in radians; None without one."""
        if self.direction_prior is None:
            return None
        yaw, sigma = (np.radians(v) for v in self.direction_prior)
        d = self.rotation @ np.array([np.sin(yaw), np.cos(yaw), 0.0])
        z = max(float(d[2]), 0.1)  # a camera looking away: its offsets stay finite
        return d[:2] / z, float(sigma)

    def prior_cost(self, n_points):
        """The cost of the camera's priors at its parameters (the ``lambda2^2 c^2`` of its
        prior modes at ``lambda2`` 1): the focal length's and the direction's."""
        total = 0.0
        focal = self.log_focal_prior(n_points)
        if focal is not None:
            total += ((np.log(self.focal_px) - focal[0]) / focal[1]) ** 2
        direction = self.direction_offset()
        if direction is not None:
            total += float((direction[0] ** 2).sum()) / direction[1] ** 2
        return float(total)

    def parameter_modes(self, points, centre_points, n_points, prior_weight, mode_pixels):
        """Rotation, centre and (when free) log focal length; a focal prior is the prior of
        its mode: one unit is ``sigma * prior_weight`` in log f and the mode starts at the
        camera's distance from the prior, so the shape-ICP's ``lambda2^2 c^2`` is exactly
        the prior's cost. A direction prior is the prior of the turns about the image's u
        and v axes alike (``R <- rot(w) R`` moves the prior direction's offsets (a, b) to
        (a + w_v, b - w_u))."""
        fields = self.parameter_fields(points, self.focal_free(n_points))
        units, start = unit_scale(fields, mode_pixels)
        prior = np.zeros(len(fields), bool)
        focal = self.log_focal_prior(n_points)
        if focal is not None and prior_weight > 0:
            units[6] = focal[1] * prior_weight
            start[6] = (np.log(self.focal_px) - focal[0]) / units[6]
            prior[6] = True
        direction = self.direction_offset()
        if direction is not None and prior_weight > 0:
            (a, b), sigma = direction
            units[:2] = sigma * prior_weight
            start[0], start[1] = -b / units[0], a / units[1]
            prior[:2] = True
        return fields, units, start, prior

    def depth_axis(self, points):
        """The optical axis toward the camera, (n, 3): the depth a face mesh detector gives
        is measured across its crop, not along each point's ray (for a mirror pair 6 cm
        apart, 5 degrees off the axis, the rays' difference alone is 5 mm)."""
        n = np.asarray(points).reshape(-1, 3).shape[0]
        return np.broadcast_to(-self.rotation[2], (n, 3)).copy()

    def parameter_motions(self, points):
        """The rotation's and centre's motions (6, n, 3) (:meth:`parameter_fields`' first
        six): ``R <- rot(w) R`` sees ``x`` where the old camera sees ``x + (R^T w) x (x -
        c)``, a centre moved by ``d`` where it sees ``x - d``."""
        x = np.asarray(points, dtype=np.float64).reshape(-1, 3) - self.centre
        turn = np.cross(self.rotation[:, None, :], x[None, :, :])  # row k: R^T e_k
        shift = np.broadcast_to(-np.eye(3)[:, None, :], (3, len(x), 3))
        return np.concatenate([turn, shift])

    def stepped(self, delta):
        """Moved by ``delta`` (6 or 7,) in the order of :meth:`parameter_fields`; the focal
        length is kept inside ``focal_range_mm``."""
        f = self.focal_px
        if len(delta) > 6:
            f = f * float(np.exp(np.clip(delta[6], -1.0, 1.0)))
            if self.focal_range_mm is not None:
                ppm = self.px_per_mm(self.size)
                f = float(np.clip(f, self.focal_range_mm[0] * ppm,
                                  self.focal_range_mm[1] * ppm))
        return self.replaced(focal_px=f, rotation=rotation_from_vector(delta[:3]) @ self.rotation,
                             centre=self.centre + delta[3:6])

    def pose_only(self):
        return PinholeCamera.with_pose_of(self, free_focal=False, focal_range_mm=None)

    def mirrored(self, plane):
        centre = plane.reflect_points(self.centre[None, :])[0]
        return self.replaced(rotation=self.rotation @ plane.matrix, centre=centre)

    def as_dlt(self):
        """The DLT of this camera (a lens term the DLT cannot match is dropped)."""
        try:
            return self.to_dlt()
        except ValueError:
            return self.replaced(k1=0.0).to_dlt()

    @classmethod
    def with_pose_of(cls, camera, **options):
        """A pinhole camera with the intrinsics and pose of the perspective ``camera`` and
        ``options`` (as the class's): a pinhole camera's copy; a DLT's K R C with K's own
        principal point (its lens terms dropped).

        Raises
        ------
        ValueError
            A mirrored DLT (no pinhole camera has its rotation), or another kind.
        """
        if isinstance(camera, PinholeCamera):
            return cls(camera.focal_px, camera.rotation, camera.centre, camera.size,
                       camera.principal_point, camera.k1, **options)
        if isinstance(camera, DLTCamera):
            k, r, c = camera.decompose()
            if np.linalg.det(r) < 0:
                raise ValueError("camera (dlt): a mirrored camera has no pinhole pose")
            return cls.from_krc(k, r, c, camera.size, principal_point="keep", **options)
        raise ValueError(f"expected a perspective camera, got {type(camera).__name__}")

    def refit(self, points, pixels, weights=None):
        """Re-estimate focal length, rotation and centre from 3-D points and their pixels.

        Levenberg-Marquardt on the weighted reprojection error over (log f, rotation
        increment, centre), plus the principal point when ``free_principal_point`` and k1
        when ``free_k1``. Starts: this camera when every point is in front of it; a DLT-11
        fit (``fit_dlt``) projected onto the constraints (6 or more points); weak-
        perspective (affine) estimates. The best result wins; the other starts are skipped
        when the result from this camera is as good as the DLT's own residual predicts
        (its cost within 1.5 times the DLT's cost scaled by the degrees of freedom), which
        is the usual case inside a fit's alternation.

        With 4 or 5 points only the pose is estimated (focal length, principal point and k1
        kept); k1 needs 8 points. The focal length is walled in to ``focal_range_mm`` and
        pulled toward ``focal_prior`` when one is set.

        Parameters
        ----------
        points : array_like, shape (n, 3), metres
            World points, at least 4 with non-zero weight, not all on one line.
        pixels : array_like, shape (n, 2), pixels
        weights : array_like, shape (n,), optional
            Non-negative weight of each pair (default 1); 0 leaves a pair out. Read as
            inverse pixel variances (1: 1 px standard deviation) by ``focal_prior``.

        Returns
        -------
        PinholeCamera
            Same size and options.

        Raises
        ------
        ValueError
            Too few weighted points, collinear points, mismatched shapes, NaN, or no camera
            found with every point in front of it.
        """
        x, q, w = correspondences(points, pixels, weights, self.min_refit_points)
        used = w > 0
        x, q, w = x[used], q[used], w[used]
        centred = x - np.average(x, axis=0, weights=w)
        sv = np.linalg.svd(centred, compute_uv=False)
        if sv[0] == 0.0 or sv[1] / sv[0] < _COLLINEAR_RATIO:
            raise ValueError(f"points: the {len(x)} weighted points lie on one line; a camera "
                             "refit needs points spread in two directions at least")
        n = len(x)
        free = {"f": self.free_focal and n >= FREE_FOCAL_POINTS,
                "pp": self.free_principal_point and n >= FREE_FOCAL_POINTS,
                "k1": self.free_k1 and n >= FREE_K1_POINTS}
        problem = _RefitProblem(self, x, q, w, free)
        best = problem.solve(self) if problem.in_front(self) else None

        dlt = None
        if n >= FREE_FOCAL_POINTS and sv[2] / sv[0] >= _COLLINEAR_RATIO:
            try:
                dlt = fit_dlt(x, q, self.size, weights=w)
            except ValueError:  # degenerate layout for 11 parameters: other starts remain
                dlt = None
        if best is not None and dlt is not None:
            dlt_cost = float((w * (dlt.residuals**2).sum(axis=1)).sum())
            dof = max(2 * n - 11, 1)
            expected = dlt_cost * (2 * n - problem.n_params) / dof
            if best[1] <= 1.5 * expected + 1e-12 * w.sum():
                return problem.camera_of(best[0])

        starts = []
        if dlt is not None and dlt.camera.is_mirrored == self.is_mirrored:
            start = PinholeCamera.from_dlt(dlt.camera, self.principal_point)
            starts.append(self.replaced(problem.clamp_focal(start.focal_px), start.rotation,
                                     start.centre))
        starts.extend(self._weak_perspective_starts(x, q, w, sv, problem))
        for start in starts:
            result = problem.solve(start)
            if result is not None and (best is None or result[1] < best[1]):
                best = result
        if best is None:
            raise ValueError("points: no camera found that sees every weighted point in front "
                             "of it (check that the points match the pixels)")
        return problem.camera_of(best[0])

    def _weak_perspective_starts(self, x, q, w, sv, problem):
        """Scaled-orthographic estimates of the pose (the focal length kept): an affine
        camera fitted to normalised image coordinates, its rows made orthonormal; for
        (nearly) planar points also the two mirror-image solutions of the plane."""
        f = problem.clamp_focal(self.focal_px)
        m = (self.undistort(q) - self.principal_point) / f
        xm = np.average(x, axis=0, weights=w)
        mm = np.average(m, axis=0, weights=w)
        sw = np.sqrt(w)[:, None]
        a_rows, *_ = np.linalg.lstsq((x - xm) * sw, (m - mm) * sw, rcond=1e-6)
        affines = [a_rows.T]  # (2, 3): m - mm ~ A (X - xm)
        if sv[2] / sv[0] < _PLANAR_RATIO:
            _, _, vt = np.linalg.svd((x - xm) * sw, full_matrices=False)
            e = vt[:2]  # in-plane axes; vt[2] the plane normal
            b = affines[0] @ e.T  # (2, 2): the rows' in-plane parts
            # out-of-plane parts (s, t) making the rows orthogonal and of equal length:
            # (s + i t)^2 = |b1|^2 - |b0|^2 - 2i b0.b1, two opposite solutions
            z = np.sqrt(complex(b[1] @ b[1] - b[0] @ b[0], -2.0 * (b[0] @ b[1])))
            for sgn in (1.0, -1.0):
                out = np.array([sgn * z.real, sgn * z.imag])
                affines.append(b @ e + out[:, None] * vt[2])
        sign = -1.0 if self.is_mirrored else 1.0
        starts = []
        for a in affines:
            u, s, vt = np.linalg.svd(a, full_matrices=False)
            if not s[0] > 0:
                continue
            r12 = u @ vt
            rot = np.vstack([r12, sign * np.cross(r12[0], r12[1])])
            depth = 2.0 / (s[0] + s[1])  # mean depth of the points: 1 / scale
            centre = xm - rot.T @ (depth * np.array([mm[0], mm[1], 1.0]))
            cam = self.replaced(f, rot, centre)
            if problem.in_front(cam):
                starts.append(cam)
        return starts


class _RefitProblem:
    """The least-squares problem of ``PinholeCamera.refit``: weighted reprojection residuals
    plus soft priors, over log f, a rotation increment (left, in the camera frame), the
    centre and optionally the principal point and k1.

    It works on bare parameter tuples ``(f, R, C, pp, k1)`` (no camera objects in the
    loop, whose constructor checks would dominate the cost of a step)."""

    def __init__(self, camera, x, q, w, free):
        self.camera = camera
        self.x, self.q = x, q
        self.sw = np.sqrt(w)
        self.free = free
        total = float(np.sqrt(w.sum()))
        self.wall = _FOCAL_WALL * total
        rng = camera.focal_range_mm
        if rng is None or not free["f"]:
            self.log_range = None
        else:
            s = camera.px_per_mm(camera.size)
            self.log_range = (np.log(rng[0] * s), np.log(rng[1] * s))
        self.prior = None
        if free["f"] and camera.focal_prior is not None:
            mm, sigma = camera.focal_prior
            self.prior = (np.log(mm * camera.px_per_mm(camera.size)), 1.0 / sigma)
        self.pp_scale = total / (_PP_SIGMA * max(camera.size))
        self.k1_scale = total / _K1_SIGMA
        self.centre_px = np.array([camera.size[0] / 2.0, camera.size[1] / 2.0])
        self.n_params = 6 + free["f"] + 2 * free["pp"] + free["k1"]

    @staticmethod
    def state(cam):
        return (cam.focal_px, cam.rotation, cam.centre, cam.principal_point, cam.k1)

    def camera_of(self, s):
        return self.camera.replaced(*s)

    def clamp_focal(self, f):
        """``f`` moved into the focal range when f is free (else the camera's own f)."""
        if not self.free["f"]:
            return self.camera.focal_px
        if self.log_range is None:
            return float(f)
        return float(np.exp(np.clip(np.log(f), *self.log_range)))

    def in_front(self, cam):
        return bool((cam.depth(self.x) > _MIN_DEPTH).all())

    def residuals(self, s, with_jacobian=True):
        """Residual vector (2n + priors,) and its Jacobian (., n_params) at state ``s``, or
        (None, None) when a point is behind the camera."""
        f, rot, centre, pp, k1 = s
        xc = (self.x - centre) @ rot.T
        z = xc[:, 2]
        if not (z > _MIN_DEPTH).all():
            return None, None
        p = xc[:, :2] / z[:, None]
        rho2 = (p * p).sum(axis=1)
        proj = pp + f * p * (1.0 + k1 * rho2)[:, None]
        res = [((proj - self.q) * self.sw[:, None]).reshape(-1)]
        lf = np.log(f)
        wall = 0.0
        if self.log_range is not None:
            lo, hi = self.log_range
            res.append([self.wall * (max(0.0, lf - hi) + min(0.0, lf - lo))])
            wall = self.wall if (lf > hi or lf < lo) else 0.0
        if self.prior is not None:
            res.append([self.prior[1] * (lf - self.prior[0])])
        if self.free["pp"]:
            res.append(self.pp_scale * (pp - self.centre_px))
        if self.free["k1"]:
            res.append([self.k1_scale * k1])
        r = np.concatenate(res)
        if not with_jacobian:
            return r, None
        n = len(self.x)
        g, _ = pixel_by_camera_point(xc, f, k1)
        cols = [-np.einsum("nij,njk->nik", g, skew(xc)),  # x_c += omega x x_c
                -g @ rot]  # centre
        if self.free["f"]:
            cols.append((proj - pp)[:, :, None])  # d / d log f
        if self.free["pp"]:
            cols.append(np.broadcast_to(np.eye(2), (n, 2, 2)))
        if self.free["k1"]:
            cols.append((f * p * rho2[:, None])[:, :, None])
        j = (np.concatenate(cols, axis=2) * self.sw[:, None, None]).reshape(2 * n, -1)
        rows = [j]
        col = 6
        if self.free["f"]:
            if self.log_range is not None:
                row = np.zeros((1, self.n_params))
                row[0, col] = wall
                rows.append(row)
            if self.prior is not None:
                row = np.zeros((1, self.n_params))
                row[0, col] = self.prior[1]
                rows.append(row)
            col += 1
        if self.free["pp"]:
            row = np.zeros((2, self.n_params))
            row[0, col] = row[1, col + 1] = self.pp_scale
            rows.append(row)
            col += 2
        if self.free["k1"]:
            row = np.zeros((1, self.n_params))
            row[0, col] = self.k1_scale
            rows.append(row)
        return r, np.vstack(rows)

    def step(self, s, delta):
        """The state moved by a parameter step ``delta`` (n_params,)."""
        f, rot, centre, pp, k1 = s
        rot = rotation_from_vector(delta[0:3]) @ rot
        centre = centre + delta[3:6]
        col = 6
        if self.free["f"]:
            f = f * np.exp(np.clip(delta[col], -2.0, 2.0))
            col += 1
        if self.free["pp"]:
            pp = pp + delta[col:col + 2]
            col += 2
        if self.free["k1"]:
            k1 = k1 + delta[col]
        return f, rot, centre, pp, k1

    def solve(self, start, max_iter=100, tol=1e-10):
        """Levenberg-Marquardt (Marquardt's diagonal scaling, each step an augmented least
        squares solved by SVD) from camera ``start``. Returns (state, cost) or None."""
        s = self.state(start)
        r, j = self.residuals(s)
        if r is None:
            return None
        cost = float(r @ r)
        lam = 1e-3
        zeros = np.zeros(self.n_params)
        for _ in range(max_iter):
            d = np.sqrt((j * j).sum(axis=0))
            d = np.where(d > 0, d, 1.0)
            jtr = j.T @ r
            while True:
                a = np.vstack([j, np.diag(np.sqrt(lam) * d)])
                delta = np.linalg.lstsq(a, np.concatenate([-r, zeros]), rcond=None)[0]
                trial = self.step(s, delta)
                r_new, _ = self.residuals(trial, with_jacobian=False)
                if r_new is not None and float(r_new @ r_new) < cost:
                    break
                lam *= 10.0
                if lam > 1e12:
                    return s, cost
            new_cost = float(r_new @ r_new)
            s = trial
            done = cost - new_cost <= tol * cost or abs(delta @ jtr) <= tol * cost
            cost = new_cost
            lam = max(lam / 10.0, 1e-9)
            if done:
                break
            r, j = self.residuals(s)
        return s, cost
