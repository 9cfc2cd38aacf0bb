"""HeadRecon: front and profile photos to a 3D head with its identity in shape keys.

The extension's root. Inside Blender this package is ``bl_ext.<repo>.headrecon``; the
add-on lives in ``headrecon_addon/`` and the solver in ``solver/`` (both subpackages).

The add-on is imported when Blender calls ``register``, not when this package is
imported: pytest imports the repository root as a package while collecting the tests,
and that must stay free of bpy and of a second copy of the solver.
"""


def register():
    from .headrecon_addon import register as _register

    _register()


def unregister():
    from .headrecon_addon import unregister as _unregister

    _unregister()
