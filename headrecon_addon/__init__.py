"""HeadRecon's Blender layer: panels, operators and scene data around the solver.

``register`` / ``unregister`` are what the extension root (the repository's
``__init__.py``) exposes to Blender; tests and the headless script call them directly.
"""

import bpy

from . import (
    detect_ops,
    fit_ops,
    landmark_ops,
    landmarks,
    live_refit,
    panels,
    photos,
    plane_removal,
    properties,
    reference_head,
    result_ops,
    texture_ops,
)

CLASSES = (*properties.CLASSES, *reference_head.CLASSES, *photos.CLASSES,
           *plane_removal.CLASSES, *landmark_ops.CLASSES, *detect_ops.CLASSES, *fit_ops.CLASSES,
           *result_ops.CLASSES, *texture_ops.CLASSES, *panels.CLASSES)

_register_classes, _unregister_classes = bpy.utils.register_classes_factory(CLASSES)


def is_registered():
    return hasattr(bpy.types.Scene, "headrecon") and hasattr(bpy.types, "HEADRECON_OT_fit")


def register():
    _register_classes()
    properties.register_properties()
    live_refit.register_handlers()
    plane_removal.register_handlers()
    landmarks.register_handlers()


def unregister():
    landmarks.unregister_handlers()
    plane_removal.unregister_handlers()
    live_refit.unregister_handlers()
    properties.unregister_properties()
    _unregister_classes()
