"""HeadRecon's Blender layer: panels, operators and scene data around the solver.

``register`` / ``unregister`` are what the extension root (the repository's
``__init__.py``) exposes to Blender; tests and the headless script call them directly.

Importing the package does not import bpy: the Blender modules are imported by
``register``, ``CLASSES`` or the first use of one of them (``headrecon_addon.panels``).
A batch's Dask workers import ``batch_cluster`` from here to drive a fitting process;
importing bpy there as well cost each of them about 1 s of CPU and 256 MB for nothing.
"""

import importlib

#: The modules whose Blender classes are registered, in registration order.
_CLASS_MODULES = ("properties", "reference_head", "photos", "plane_removal", "landmark_ops",
                  "detect_ops", "fit_ops", "result_ops", "texture_ops", "panels")
#: The modules with app handlers (added by ``register``, removed by ``unregister``).
_HANDLER_MODULES = ("live_refit", "plane_removal", "landmarks")


def _classes():
    """The Blender classes to register, in order (their modules imported, with bpy)."""
    return tuple(cls for m in _CLASS_MODULES
                 for cls in importlib.import_module(f".{m}", __name__).CLASSES)


def __getattr__(name):
    """``CLASSES`` and the Blender modules, imported (with bpy) on first use."""
    if name == "CLASSES":
        return _classes()
    if name in _CLASS_MODULES or name in _HANDLER_MODULES:
        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def is_registered():
    import bpy

    return hasattr(bpy.types.Scene, "headrecon") and hasattr(bpy.types, "HEADRECON_OT_fit")


def register():
    import bpy

    from . import landmarks, live_refit, plane_removal, properties

    for cls in _classes():
        bpy.utils.register_class(cls)
    properties.register_properties()
    live_refit.register_handlers()
    plane_removal.register_handlers()
    landmarks.register_handlers()


def unregister():
    import bpy

    from . import landmarks, live_refit, plane_removal, properties

    landmarks.unregister_handlers()
    plane_removal.unregister_handlers()
    live_refit.unregister_handlers()
    properties.unregister_properties()
    for cls in reversed(_classes()):
        bpy.utils.unregister_class(cls)
