"""Cameras: how a photo sees the world. One class per camera model, all with one interface,
so the fit, the texture bake and the landmarks file never branch on the kind of camera.

Conventions (all cameras): world in metres, Blender axes (Z up, face toward -Y, subject's
left +X). Pixels have their origin at the image's top-left corner, u to the right, v down.
A camera's ``rotation`` is world -> camera with rows (u axis, v axis, viewing direction),
the OpenCV convention, so 'depth' grows away from the camera.
"""

import importlib
from abc import ABC, abstractmethod

import numpy as np

from ..errors import as_points, as_weights

# kind -> class; filled by @register. Modules listed in _PLUGINS register further kinds
# (e.g. "dlt") and are imported on first lookup, so this module needs no import of them.
_KINDS = {}
_PLUGINS = ("dlt", "pinhole")


def register(kind):
    """Class decorator: make a Camera subclass constructible by ``camera_from_dict``."""

    def deco(cls):
        cls.kind = kind
        _KINDS[kind] = cls
        return cls

    return deco


def camera_kinds():
    """All registered camera kinds (including plug-in modules that import cleanly)."""
    _load_plugins()
    return sorted(_KINDS)


def camera_from_dict(d):
    """Build a camera from its JSON form (``{"kind": ..., ...}``)."""
    _load_plugins()
    kind = d.get("kind") if isinstance(d, dict) else None
    if kind not in _KINDS:
        raise ValueError(f"camera: unknown kind {kind!r}; known: {', '.join(sorted(_KINDS))}")
    return _KINDS[kind].from_dict(d)


def _load_plugins():
    for name in _PLUGINS:
        try:
            importlib.import_module(f"{__package__}.{name}")
        except ModuleNotFoundError as e:  # plug-in not written yet in this checkout
            if e.name != f"{__package__}.{name}":
                raise


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

    def reprojection_error(self, points, pixels):
        """Pixel distance between ``project(points)`` and ``pixels``: (n,) pixels."""
        px = as_points(pixels, "pixels", dim=2)
        return np.linalg.norm(self.project(points) - px, axis=1)


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


# Nominal orientations of the orthographic views (rows: u axis, v axis, viewing direction).
ORTHO_VIEWS = {
    # camera in front, looking at the face (+Y); subject's left (+X) on the image's right
    "orthographic-front": np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),
    # camera at the subject's right (-X) looking +X; the face (-Y) points to the image's right
    "orthographic-right": np.array([[0, -1.0, 0], [0, 0, -1], [1, 0, 0]]),
    # camera at the subject's left (+X) looking -X; the face points to the image's left
    "orthographic-left": np.array([[0, 1.0, 0], [0, 0, -1], [-1, 0, 0]]),
}


class OrthographicCamera(Camera):
    """Scaled orthographic (parallel) projection: pixel = scale * R[:2] @ X + offset.

    Its free parameters are a 2-D similarity of the image: ``scale``, ``offset`` and a
    rotation about the viewing direction (in-plane). ``refit`` re-estimates exactly these,
    keeping the viewing direction, because a single parallel projection cannot tell an
    out-of-plane turn of the camera from a turn of the head (the fit's head rotation owns
    that).

    Parameters
    ----------
    rotation : ndarray, shape (3, 3)
        World -> camera rotation (rows u, v, viewing direction).
    scale : float
        Pixels per metre.
    offset : ndarray, shape (2,)
        Pixel position of the world origin.
    size : (int, int)
        Image width and height in pixels.
    view : str
        Name of the nominal view this camera started from (a key of ORTHO_VIEWS).
    """

    def __init__(self, rotation, scale, offset, size, view="orthographic-front"):
        self.rotation = np.asarray(rotation, dtype=np.float64).reshape(3, 3)
        self.scale = float(scale)
        self.offset = np.asarray(offset, dtype=np.float64).reshape(2)
        self.size = (int(size[0]), int(size[1]))
        self.view = view

    @classmethod
    def nominal(cls, view, size, scale=None, offset=None):
        """The ideal camera of an ``orthographic-*`` view: the head (about 0.3 m tall)
        filling about 80 % of the image height, centred, unless scale/offset are given."""
        if view not in ORTHO_VIEWS:
            raise ValueError(f"camera: unknown view {view!r}; known: {', '.join(ORTHO_VIEWS)}")
        w, h = size
        if scale is None:
            scale = 0.8 * h / 0.3
        if offset is None:
            offset = (w / 2.0, h / 2.0)
        return cls(ORTHO_VIEWS[view], scale, offset, size, view)

    min_refit_points = 2

    def project(self, points):
        x = as_points(points, "points")
        return self.scale * x @ self.rotation[:2].T + self.offset

    @property
    def in_plane_angle(self):
        """Rotation of the image about the viewing direction relative to the nominal view,
        radians; positive turns the u axis toward +v (clockwise on screen, v points down)."""
        base = ORTHO_VIEWS.get(self.view)
        if base is None:
            return 0.0
        m = self.rotation[:2] @ base[:2].T  # 2x2 in-plane rotation (if the view axis agrees)
        return float(np.arctan2(m[1, 0], m[0, 0]))

    def refit(self, points, pixels, weights=None):
        """Re-estimate scale, in-plane rotation and offset (a weighted 2-D similarity
        between the points' current image-plane coordinates and ``pixels``).

        Parameters
        ----------
        points : array_like, shape (n, 3), metres
        pixels : array_like, shape (n, 2), pixels
        weights : array_like, shape (n,), optional

        Returns
        -------
        OrthographicCamera
            Same viewing direction, new scale / in-plane rotation / offset.

        Raises
        ------
        ValueError
            Fewer than 2 (weighted) pairs, mismatched shapes, NaN, or points whose
            projections coincide (the similarity is undetermined).
        """
        from ..procrustes import similarity_procrustes

        x, q, w = correspondences(points, pixels, weights, self.min_refit_points)
        a = x @ self.rotation[:2].T  # image-plane coordinates in metres
        try:
            sim = similarity_procrustes(a, q, w)
        except ValueError as e:
            raise ValueError(f"camera refit ({self.view}): {e}") from None
        rot = self.rotation.copy()
        rot[:2] = sim.rotation @ self.rotation[:2]
        return OrthographicCamera(rot, sim.scale, sim.translation, self.size, self.view)

    def jacobian(self, points):
        n = np.asarray(points).shape[0]
        return np.broadcast_to(self.scale * self.rotation[:2], (n, 2, 3)).copy()

    def to_camera(self, points):
        return as_points(points, "points") @ self.rotation.T

    def toward_camera(self, points):
        n = np.asarray(points).shape[0]
        return np.broadcast_to(-self.rotation[2], (n, 3)).copy()

    def to_dict(self):
        return {"kind": self.kind, "view": self.view, "rotation": self.rotation.tolist(),
                "scale": self.scale, "offset": self.offset.tolist(), "size": list(self.size)}

    @classmethod
    def from_dict(cls, d):
        try:
            return cls(d["rotation"], d["scale"], d["offset"], d["size"],
                       d.get("view", "orthographic-front"))
        except KeyError as e:
            raise ValueError(f"camera ({cls.kind}): missing field {e.args[0]!r}") from None


register("orthographic")(OrthographicCamera)
