"""The one place the add-on reaches the solver.

Inside Blender the extension is the package ``bl_ext.<repo>.headrecon`` and the solver is
its sibling subpackage (``from .. import solver``). In a checkout run as plain Python
(tests, ``python -m headrecon_addon.headless``) ``headrecon_addon`` and ``solver`` are both
top-level packages and the relative import fails with "attempted relative import beyond
top-level package"; then the absolute import is the right one. Any other ImportError (a
missing scipy, a broken solver module) is re-raised so it is not mistaken for this case.
"""

import importlib

_MODULES = ("cameras.blender", "cameras.calib_errors", "cameras", "cameras.dlt",
            "fitting.fit", "io.landmarks_file", "model.head_model", "cameras.pinhole",
            "fitting.result", "texture.bake")


try:
    from .. import solver
except ImportError as e:  # top-level headrecon_addon (a checkout): the solver is top-level too
    if "beyond top-level package" not in str(e):
        raise
    solver = importlib.import_module("solver")

_mods = {name: importlib.import_module(f"{solver.__name__}.{name}") for name in _MODULES}

blender_camera = _mods["cameras.blender"]
calib_errors = _mods["cameras.calib_errors"]
cameras = _mods["cameras"]
dlt = _mods["cameras.dlt"]
fit = _mods["fitting.fit"]
landmarks_file = _mods["io.landmarks_file"]
model = _mods["model.head_model"]
pinhole = _mods["cameras.pinhole"]
result = _mods["fitting.result"]
texture = _mods["texture.bake"]

# What the add-on uses, by name.
ORTHO_VIEWS = cameras.ORTHO_VIEWS
OrthographicCamera = cameras.OrthographicCamera
camera_from_dict = cameras.camera_from_dict
DLTCamera = dlt.DLTCamera
fit_dlt = dlt.fit_dlt
PinholeCamera = pinhole.PinholeCamera
check_passpoints = calib_errors.check_passpoints
FitOptions = fit.FitOptions
fit_head = fit.fit_head
refit_landmarks = fit.refit_landmarks
View = landmarks_file.View
LandmarkCase = landmarks_file.LandmarkCase
parse_landmarks = landmarks_file.parse_landmarks
load_landmarks = landmarks_file.load_landmarks
landmarks_to_dict = landmarks_file.landmarks_to_dict
save_landmarks = landmarks_file.save_landmarks
load_landmark_set = landmarks_file.load_landmark_set
camera_to_json = landmarks_file.camera_to_json
camera_from_json = landmarks_file.camera_from_json
HeadModel = model.HeadModel
load_model = model.load_model
FitResult = result.FitResult
bake_texture = texture.bake_texture
bake_fit_texture = texture.bake_fit_texture
uv_raster = texture.uv_raster
uv_tiles = texture.uv_tiles
orthographic_uvs = texture.orthographic_uvs

__all__ = [
    "ORTHO_VIEWS", "DLTCamera", "FitOptions", "FitResult", "HeadModel", "LandmarkCase",
    "OrthographicCamera", "PinholeCamera", "View", "bake_fit_texture", "bake_texture",
    "blender_camera", "camera_from_dict", "camera_from_json", "camera_to_json",
    "check_passpoints", "fit_dlt", "fit_head", "landmarks_to_dict", "load_landmark_set",
    "load_landmarks", "load_model", "orthographic_uvs", "parse_landmarks", "refit_landmarks",
    "save_landmarks", "solver", "uv_raster", "uv_tiles",
]
