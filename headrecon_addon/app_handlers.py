"""Blender's application handlers (``bpy.app.handlers``): each added once, removed wholly."""

import bpy


def add(pairs):
    """Append each (handler list name, function) of ``pairs`` unless it is there already
    (a second ``register`` must not run a handler twice)."""
    for kind, fn in pairs:
        handlers = getattr(bpy.app.handlers, kind)
        if fn not in handlers:
            handlers.append(fn)


def remove(pairs):
    """Remove every occurrence of each (handler list name, function) of ``pairs``."""
    for kind, fn in pairs:
        handlers = getattr(bpy.app.handlers, kind)
        while fn in handlers:
            handlers.remove(fn)
