"""Where the add-on's objects go in the Outliner: one "HeadRecon" collection in the scene,
the head in it, and sub-collections "Photos" (photo planes), "Landmarks" (landmarks,
passpoints, contours) and "Cameras" (the perspective photos' Blender cameras).

The collections are found by a custom property, not by name, so an artist may rename or
move objects and collections freely; and nothing else relies on them: every object is
found by its ``Object.headrecon`` role (scenes made before the collections existed keep
working, their objects where they were).
"""

import bpy

KEY = "headrecon_collection"  # custom property on the collections: which one it is
ROOT = "root"
ROOT_NAME = "HeadRecon"
SUBS = {"photos": "Photos", "landmarks": "Landmarks", "cameras": "Cameras"}
# Object.headrecon.role -> sub-collection (None: the HeadRecon collection itself)
ROLE_SUB = {"HEAD": None, "PHOTO": "photos", "LANDMARK": "landmarks",
            "PASSPOINT": "landmarks", "CONTOUR": "landmarks", "CAMERA": "cameras"}


def _child(parent, kind):
    return next((c for c in parent.children if c.get(KEY) == kind), None)


def _new(parent, kind, name):
    coll = bpy.data.collections.new(name)
    coll[KEY] = kind
    parent.children.link(coll)
    return coll


def root_collection(scene, create=True):
    """The scene's "HeadRecon" collection (made when missing and ``create``), or None."""
    root = _child(scene.collection, ROOT)
    if root is None and create:
        root = _new(scene.collection, ROOT, ROOT_NAME)
    return root


def collection_for(scene, role, create=True):
    """The collection new objects of ``role`` (``Object.headrecon.role``) go into: a
    sub-collection of "HeadRecon" (the collection itself for the head and other roles)."""
    root = root_collection(scene, create)
    sub = ROLE_SUB.get(role)
    if root is None or sub is None:
        return root
    coll = _child(root, sub)
    if coll is None and create:
        coll = _new(root, sub, SUBS[sub])
    return coll


def link(scene, obj):
    """Link ``obj`` into its role's collection of ``scene`` (once)."""
    coll = collection_for(scene, obj.headrecon.role)
    if obj.name not in coll.objects:
        coll.objects.link(obj)


def link_tree(scene, obj):
    """Link ``obj`` and its children (recursively), each into its role's collection: a
    view's camera, plane and markers at once."""
    link(scene, obj)
    for child in obj.children:
        link_tree(scene, child)


def link_like(obj, other):
    """Link ``obj`` into its role's collection of every scene ``other`` is in (a marker
    made for a plane already in a scene; nothing when ``other`` is in none yet, as a view
    is linked whole once built)."""
    for scene in other.users_scene:
        link(scene, obj)
