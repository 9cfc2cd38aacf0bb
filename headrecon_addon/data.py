"""All-or-nothing changes to bpy.data: an operator builds inside ``Transaction()`` and, when
anything raises, every datablock made since it began is removed again, so a failed
operator leaves no half-made objects, meshes, materials or images behind."""

import bpy

# Removal order: users first, so the data they used is free to go.
_KINDS = ("objects", "meshes", "curves", "cameras", "materials", "images", "node_groups",
          "collections")


class Transaction:
    """Context manager: remove the datablocks created inside it if it exits by exception."""

    def __enter__(self):
        self.before = {k: {i.as_pointer() for i in getattr(bpy.data, k)} for k in _KINDS}
        return self

    def created(self, kind):
        """Datablocks of ``kind`` (e.g. "objects") made since the transaction began."""
        seen = self.before[kind]
        return [i for i in getattr(bpy.data, kind) if i.as_pointer() not in seen]

    def rollback(self):
        for kind in _KINDS:
            new = self.created(kind)
            if new:
                bpy.data.batch_remove(new)

    def __exit__(self, exc_type, exc, tb):
        if exc_type is not None:
            self.rollback()
        return False
