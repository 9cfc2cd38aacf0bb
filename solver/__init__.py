"""HeadRecon's solver: pure numpy/scipy, never imports bpy.

Everything here takes and returns plain arrays (metres, Blender axes: Z up, the face
looks toward -Y, the subject's left is +X) so the Blender add-on, the command line and
the tests share one code path. Modules use relative imports only, so the package works
both as the top-level ``solver`` of a checkout and as ``<extension>.solver`` inside
Blender.

What the add-on, the command line and the tools use is imported here, by name; the
subpackages are ``cameras`` (one module per camera kind, and what is computed from
cameras), ``model`` (the statistical head model), ``fitting`` (the fit), ``io`` (files),
``texture`` and ``detect`` (automatic landmarks).
"""

from .cameras import (
    ORTHO_VIEWS,
    VIEW_YAW_DEG,
    Camera,
    OrthographicCamera,
    camera_class,
    camera_from_dict,
)
from .cameras.blender import blender_to_krc, dlt_to_blender
from .cameras.calib_errors import check_passpoints
from .cameras.dlt import DLTCamera, fit_dlt
from .cameras.pinhole import PinholeCamera
from .cores import usable_cores
from .detect.detected_case import face_landmarks
from .detect.detector import DetectedFace, Detector, face_notes
from .detect.view_guess import POINTS_YAW_MIN, ViewGuess, guess_view, placed, points_yaw_deg
from .fitting.engine import forget_fit_subsets
from .fitting.fit import FitOptions, fit_head, prepare_fit, refit_landmarks
from .fitting.options import FIT_METHODS
from .fitting.result import FitResult, ViewResidual
from .io.camera_json import camera_from_json, camera_to_json, is_nominal
from .io.case import LandmarkCase, View
from .io.case_check import MIN_PASSPOINTS, check_case
from .io.exif import Exif, orient, oriented_size, read_photo_exif
from .io.landmark_counts import (
    MIN_LANDMARKS_PER_VIEW,
    MIN_LANDMARKS_TOTAL,
    count_problems,
    landmarks_needed,
)
from .io.landmark_set import load_landmark_set
from .io.landmarks_file import (
    CURRENT_VERSION,
    FORMAT,
    LandmarksError,
    landmarks_to_dict,
    load_landmarks,
    parse_landmarks,
    save_landmarks,
)
from .io.photo_lens import (
    DIRECTION_SIGMA_DEG,
    lens_hints,
    orthographic_lenses,
    plausible_lens,
)
from .model.head_model import HeadModel, load_model
from .texture.bake import (
    CLOTHES_MODES,
    SHADING_MODES,
    BakeOptions,
    bake_fit_texture,
    bake_texture,
)
from .texture.iris import iris_colour
from .texture.uvs import orthographic_uvs, uv_raster, uv_tiles

__all__ = [
    "CLOTHES_MODES", "CURRENT_VERSION", "DIRECTION_SIGMA_DEG", "FIT_METHODS", "FORMAT",
    "MIN_LANDMARKS_PER_VIEW", "MIN_LANDMARKS_TOTAL", "MIN_PASSPOINTS", "ORTHO_VIEWS",
    "POINTS_YAW_MIN",
    "SHADING_MODES", "VIEW_YAW_DEG",
    "BakeOptions", "Camera", "DLTCamera",
    "DetectedFace", "Detector", "Exif", "FitOptions", "FitResult", "HeadModel",
    "LandmarkCase", "LandmarksError", "OrthographicCamera", "PinholeCamera", "View",
    "ViewGuess", "ViewResidual", "bake_fit_texture", "bake_texture", "blender_to_krc",
    "camera_class", "camera_from_dict", "camera_from_json", "camera_to_json", "check_case",
    "check_passpoints", "count_problems", "dlt_to_blender", "face_landmarks",
    "face_notes", "fit_dlt", "fit_head", "forget_fit_subsets",
    "guess_view", "iris_colour", "is_nominal", "landmarks_needed", "landmarks_to_dict",
    "load_landmark_set",
    "load_landmarks", "load_model", "lens_hints", "orient", "oriented_size",
    "orthographic_lenses", "placed", "plausible_lens", "points_yaw_deg",
    "orthographic_uvs", "prepare_fit",
    "parse_landmarks", "read_photo_exif", "refit_landmarks", "save_landmarks",
    "usable_cores", "uv_raster", "uv_tiles",
]
