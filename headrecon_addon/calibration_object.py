"""The calibration object: the 3-D points (name -> metres) that the photos' passpoints
refer to, kept with the scene's case (the file's top-level ``passpoints``, in
``Scene.headrecon.case_json``) and edited from the panel."""

import json

import numpy as np

from . import landmarks, photos


def case_passpoints(scene):
    """The calibration object's passpoints of the scene's case: dict name -> [x, y, z]
    metres (from the imported file), in the file's order."""
    props = scene.headrecon
    return dict(json.loads(props.case_json).get("passpoints", {})) if props.case_json else {}


def set_case_passpoint(scene, name, xyz):
    """Define (or move) the calibration object's passpoint ``name`` at ``xyz`` (metres,
    Blender axes): the file's top-level ``passpoints``, written on export.

    Raises
    ------
    ValueError
        An empty name or a coordinate that is not a finite number (names the passpoint).
    """
    name = str(name).strip()
    if not name:
        raise ValueError("passpoint: give it a name")
    xyz = np.asarray(xyz, dtype=np.float64).reshape(-1)
    if xyz.shape != (3,) or not np.all(np.isfinite(xyz)):
        raise ValueError(f"passpoint {name!r}: expected 3 finite coordinates (metres), got "
                         f"{xyz.tolist()}")
    _write_case_passpoints(scene, {**case_passpoints(scene), name: [float(c) for c in xyz]})


def remove_case_passpoint(scene, name):
    """Forget the calibration object's passpoint ``name``.

    Raises
    ------
    ValueError
        It is not defined, or a photo still has it placed (names the views).
    """
    points = case_passpoints(scene)
    if name not in points:
        raise ValueError(f"passpoint {name!r}: not defined")
    used = [p.headrecon.view for p in photos.photo_planes(scene)
            if name in landmarks.passpoint_objects(p)]
    if used:
        raise ValueError(f"passpoint {name!r}: still placed on view(s) "
                         f"{', '.join(map(repr, used))}; remove it there first")
    del points[name]
    _write_case_passpoints(scene, points)


def _write_case_passpoints(scene, points):
    props = scene.headrecon
    rest = json.loads(props.case_json) if props.case_json else {}
    rest.pop("passpoints", None)
    if points:
        rest["passpoints"] = points
    props.case_json = json.dumps(rest) if rest else ""
