"""The camera interface every kind implements, the registry of kinds, and the checks their
refits share, so the fit, the texture bake and the landmarks file never branch on a kind.

Conventions (all cameras): world in metres, Blender axes (Z up, face toward -Y, subject's
left +X). Pixels have their origin at the image's top-left corner, u to the right, v down.
A camera's ``rotation`` is world -> camera with rows (u axis, v axis, viewing direction),
the OpenCV convention, so 'depth' grows away from the camera.
"""

from abc import ABC, abstractmethod

import numpy as np

from ..errors import as_points, as_weights

# kind -> class; filled by @register as each kind's module is imported (the package's
# __init__ imports them all).
_KINDS = {}


def register(kind):
    """Class decorator: make a Camera subclass constructible by ``camera_from_dict``."""

    def deco(cls):
        cls.kind = kind
        _KINDS[kind] = cls
        return cls

    return deco


def camera_kinds():
    """All registered camera kinds."""
    return sorted(_KINDS)


def camera_class(kind):
    """The Camera class registered for ``kind``, or None."""
    return _KINDS.get(kind)


def camera_from_dict(d):
    """Build a camera from its JSON form (``{"kind": ..., ...}``)."""
    kind = d.get("kind") if isinstance(d, dict) else None
    if kind not in _KINDS:
        raise ValueError(f"camera: unknown kind {kind!r}; known: {', '.join(sorted(_KINDS))}")
    return _KINDS[kind].from_dict(d)


def unit_scale(fields, mode_pixels):
    """Units (P,) that make each pixel field (P, n, 2) move its points by ``mode_pixels``
    pixels RMS per unit of coefficient, and zero starts (P,)."""
    rms = np.sqrt((fields**2).sum(axis=2).mean(axis=1))
    return mode_pixels / np.maximum(rms, 1e-12), np.zeros(len(fields))


class Camera(ABC):
    """Interface every camera implements. ``size`` is (width, height) in pixels.

    ``refit`` lets the fit re-estimate a camera's own free parameters from 3-D points and
    the pixels they should land on, so the fit alternates "head given cameras" and
    "cameras given head" without knowing any camera's parametrisation. The base class
    treats a camera as calibrated (nothing free); kinds with free parameters override it
    and set ``min_refit_points``.
    """

    kind = "abstract"
    #: fewest point/pixel pairs ``refit`` needs (0: the camera has no free parameters).
    min_refit_points = 0
    #: a central projection (rays through one centre), as pinhole and DLT cameras are
    perspective = False
    #: The joint step moves this camera's turn as the rigid motion it is
    #: (``parameter_motions``), so rows on a point's depth see it.
    moves_rigidly = False

    @abstractmethod
    def project(self, points):
        """Pixel coordinates of world points: (n, 3) metres -> (n, 2) pixels."""

    @abstractmethod
    def jacobian(self, points):
        """d(pixel)/d(point) at each point: (n, 3) -> (n, 2, 3), pixels per metre."""

    @abstractmethod
    def to_camera(self, points):
        """World points in this camera's frame (u, v, depth axes): (n, 3) -> (n, 3)."""

    @abstractmethod
    def toward_camera(self, points):
        """Unit vectors from each point toward the camera: (n, 3) -> (n, 3). Texture
        blending weighs a surface by its normal's dot product with these."""

    @abstractmethod
    def to_dict(self):
        """JSON-ready parameters, including ``"kind"``."""

    @classmethod
    @abstractmethod
    def from_dict(cls, d):
        """Inverse of ``to_dict``."""

    def refit(self, points, pixels, weights=None):
        """The camera re-estimated so ``project(points)`` best matches ``pixels``.

        Parameters
        ----------
        points : array_like, shape (n, 3), metres
            World points (e.g. the fitted head's landmark vertices).
        pixels : array_like, shape (n, 2), pixels
            Where each point is seen in the photo.
        weights : array_like, shape (n,), optional
            Non-negative weight of each pair (default 1).

        Returns
        -------
        Camera
            A new camera of the same kind. This base version has no free parameters (a
            calibrated camera) and returns ``self`` after checking the input.
        """
        correspondences(points, pixels, weights, self.min_refit_points)
        return self

    def pixels_per_metre(self, points, scale=(1.0, 1.0)):
        """Pixels a metre spans at each world point, (n, 3) metres -> (n,) pixels per metre:
        the RMS length of the Jacobian's two rows, after scaling its u and v rows by
        ``scale`` (sx, sy), the image's pixels per camera pixel (a reduced photo)."""
        jac = np.asarray(self.jacobian(points), dtype=np.float64)
        jac = jac * np.asarray(scale, dtype=np.float64)[:, None]
        return np.sqrt((jac ** 2).sum(axis=(1, 2)) / 2.0)

    def reprojection_error(self, points, pixels):
        """Pixel distance between ``project(points)`` and ``pixels``: (n,) pixels."""
        px = as_points(pixels, "pixels", dim=2)
        return np.linalg.norm(self.project(points) - px, axis=1)

    # How the fit moves a camera inside one Gauss-Newton step of head and cameras
    # (solver/fitting/joint.py): pixel fields of its free parameters become extra modes
    # of the step, and after it the camera takes the step (``stepped``) or is refitted to
    # what the step predicted.

    def parameter_modes(self, points, centre_points, n_points, prior_weight, mode_pixels):
        """The camera's free parameters as modes of the joint step.

        Parameters
        ----------
        points : ndarray, shape (n, 3)
            World points the camera sees (a mirror view's points reflected).
        centre_points : ndarray, shape (m, 3)
            Points whose projections' mean a 2-D similarity turns and scales about (the
            view's landmarks).
        n_points : int
            Weighted landmarks the camera is seen through (decides a free focal length).
        prior_weight : float
            The shape prior's weight (lambda2): a mode with a real prior is scaled by it.
        mode_pixels : float
            Pixels one unit of a mode's coefficient should move the points.

        Returns
        -------
        fields : ndarray, shape (P, n, 2)
            Pixels per natural unit of each parameter.
        units : ndarray, shape (P,)
            Natural units per coefficient.
        start : ndarray, shape (P,)
            Coefficients now (non-zero only for a mode with a prior).
        prior : ndarray of bool, shape (P,)
            Modes whose prior is a real prior, not a negligible one.

        This base version is the 2-D similarity of the photo (shifts in u and v, a rotation
        and a scaling about the projection of ``centre_points``' mean, both one pixel at
        their RMS radius), which any camera can be refitted to.
        """
        p = self.project(points)
        d = p - self.project(centre_points).mean(axis=0)
        radius = max(float(np.sqrt((d * d).sum(1).mean())), 1e-9)
        fields = np.zeros((4, len(p), 2))
        fields[0, :, 0] = 1.0
        fields[1, :, 1] = 1.0
        fields[2] = np.stack([-d[:, 1], d[:, 0]], axis=1) / radius
        fields[3] = d / radius
        return fields, np.full(4, float(mode_pixels)), np.zeros(4), np.zeros(4, bool)

    def depth_axis(self, points):
        """Unit vectors (n, 3) along which a point's depth toward the camera is measured,
        as a face mesh detector gives it (across its crop, so along the camera's axis, not
        along each point's ray): this base version ``toward_camera``, which is that axis
        for a parallel projection."""
        return self.toward_camera(points)

    def parameter_motions(self, points):
        """The world motions (k, n, 3), metres per natural unit, of ``points`` (n, 3) that
        move their projections as the first k of :meth:`parameter_modes` do and keep each
        point's place relative to the camera (its depth too): a turn of the camera is the
        points turned the other way about it. None (this base version): the modes have no
        such motion (a 2-D similarity of the photo), and the joint step lifts their pixel
        fields across the image only."""
        return None

    def stepped(self, delta):
        """The camera moved by ``delta`` (P,) natural units of :meth:`parameter_modes`, or
        None: the fit then refits the camera to what the step predicted."""
        return None

    def log_focal_prior(self, n_points):
        """(log f0 in pixels, relative sigma) of a focal length the fit moves and a prior
        holds, seen through ``n_points`` landmarks; None for cameras without one."""
        return None

    def prior_cost(self, n_points):
        """The cost of the camera's own priors at its parameters, seen through ``n_points``
        landmarks (as the joint step's prior modes count it at ``lambda2`` 1); 0 for
        cameras without one."""
        return 0.0

    def pose_only(self):
        """A copy whose ``refit`` moves only what a start from the mean head should (a
        pinhole camera's pose; other kinds: the camera itself)."""
        return self

    def mirrored(self, plane):
        """This camera reflected in a mirror plane (seed 001 eq. 3.11-3.13): the camera of
        the mirror image. Only a central projection can place a mirror."""
        raise ValueError(f"a mirror view needs a perspective (pinhole or DLT) camera, got "
                         f"{type(self).__name__}: a parallel projection cannot place a mirror")

    def as_dlt(self):
        """This camera as a DLTCamera (perspective cameras only)."""
        raise ValueError(f"expected a perspective camera, got {type(self).__name__}")


def is_side_camera(camera, at=None):
    """True when ``camera`` looks along the world x axis (the head's left-right axis) at
    the point ``at`` (3,) (default the origin)."""
    p = np.zeros((1, 3)) if at is None else np.asarray(at, dtype=np.float64).reshape(1, 3)
    d = np.asarray(camera.toward_camera(p), dtype=np.float64).reshape(3)
    return abs(d[0]) > 0.7 * np.linalg.norm(d)


def toward_centre(centre, points):
    """Unit vectors from each point toward a camera centre, what ``toward_camera`` is for
    any camera with one (central projection): centre (3,), points (n, 3) metres -> (n, 3).
    A point at the centre gets a zero vector rather than NaN."""
    d = centre - as_points(points, "points")
    n = np.linalg.norm(d, axis=1, keepdims=True)
    return d / np.where(n > 0, n, 1.0)


def correspondences(points, pixels, weights=None, min_count=1, what="a camera refit",
                    unit="weighted points"):
    """Validated 3-D points and their pixels, for fitting a camera to them.

    Parameters
    ----------
    points : array_like, shape (n, 3), metres
    pixels : array_like, shape (n, 2), pixels
    weights : array_like, shape (n,), optional
        Non-negative; zero leaves a point out.
    min_count : int
        Fewest points with a non-zero weight.
    what, unit : str
        Name the fit and its points in the too-few message.

    Returns
    -------
    (points (n, 3), pixels (n, 2), weights (n,)) as float64
    """
    x = as_points(points, "points")
    q = as_points(pixels, "pixels", dim=2)
    if len(q) != len(x):
        raise ValueError(f"pixels: {len(q)} rows for {len(x)} points")
    w = as_weights(weights, len(x))
    if np.count_nonzero(w) < min_count:
        raise ValueError(f"points: {what} needs at least {min_count} {unit}, "
                         f"got {np.count_nonzero(w)}")
    return x, q, w
