"""Cameras: how a photo sees the world. One module per kind (orthographic, DLT, pinhole),
all behind the one interface of ``base.Camera``, so the fit, the texture bake and the
landmarks file never branch on the kind; the rest is computed from cameras (triangulation,
a mirror, passpoint checks, the parallel-projection check, Blender's camera)."""

from .base import Camera, camera_class, camera_from_dict, camera_kinds, is_side_camera
from .dlt import DLTCamera, fit_dlt
from .orthographic import ORTHO_VIEWS, VIEW_YAW_DEG, OrthographicCamera
from .pinhole import PinholeCamera

__all__ = ["ORTHO_VIEWS", "VIEW_YAW_DEG", "Camera", "DLTCamera", "OrthographicCamera",
           "PinholeCamera", "camera_class", "camera_from_dict", "camera_kinds", "fit_dlt",
           "is_side_camera"]
