"""The orthographic camera: a photo taken from far away, a parallel projection with its own
scale, in-plane rotation and offset (the thesis' front and profile photos)."""

import numpy as np

from ..errors import as_points
from .base import Camera, correspondences, register

# Nominal orientations of the orthographic views (rows: u axis, v axis, viewing direction).
ORTHO_VIEWS = {
    # camera in front, looking at the face (+Y); subject's left (+X) on the image's right
    "orthographic-front": np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),
    # camera at the subject's right (-X) looking +X; the face (-Y) points to the image's right
    "orthographic-right": np.array([[0, -1.0, 0], [0, 0, -1], [1, 0, 0]]),
    # camera at the subject's left (+X) looking -X; the face points to the image's left
    "orthographic-left": np.array([[0, 1.0, 0], [0, 0, -1], [-1, 0, 0]]),
}
#: Each view's yaw: the camera's direction from the face's front, degrees, toward the
#: subject's right positive (``PinholeCamera.direction_prior``'s).
VIEW_YAW_DEG = {"orthographic-front": 0.0, "orthographic-right": 90.0,
                "orthographic-left": -90.0}


@register("orthographic")
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

    @classmethod
    def turned(cls, view, size, yaw_deg):
        """The nominal camera of ``view`` (``nominal``) looking from ``yaw_deg`` instead
        (degrees from the face's front, toward the subject's right positive, level: the
        views' own yaws are ``VIEW_YAW_DEG``): a side photo taken short of a profile."""
        t = np.radians(float(yaw_deg))
        rotation = np.array([[np.cos(t), -np.sin(t), 0.0], [0.0, 0.0, -1.0],
                             [np.sin(t), np.cos(t), 0.0]])
        cam = cls.nominal(view, size)
        return cls(rotation, cam.scale, cam.offset, size, view)

    min_refit_points = 2

    def project(self, points):
        x = as_points(points, "points", min_count=0)
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


