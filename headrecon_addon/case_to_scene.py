"""A LandmarkCase read into the scene: one photo plane per view (with its Blender camera
for a perspective photo), its landmarks (those with an uncertainty as detected ones),
passpoints and contour, and the case's top-level keys; importing a landmarks file builds it
all or nothing.
"""

import json

import bpy

from . import landmarks, photos, scene_collections
from .data import Transaction
from .solver_link import MIN_PASSPOINTS, fit_dlt, landmarks_to_dict, load_landmarks

# The keys of a view the scene holds as its own data (the plane, its photo, camera and
# markers); the rest of the view is kept as the file had it (``view_json``).
_EDITED = ("image", "size", "points", "contour", "camera", "passpoints", "uncertainty",
           "depth")


def store_case_level(scene, case):
    """Remember the case's top-level keys besides the views (passpoints, x- keys)."""
    doc = landmarks_to_dict(case)
    rest = {k: v for k, v in doc.items() if k not in ("format", "version", "views")}
    scene.headrecon.case_json = json.dumps(rest) if rest else ""


def placeholder_image(view, size):
    """A plain grey image standing in for a view whose file names no photo."""
    w, h = size
    img = bpy.data.images.new(f"HeadRecon {view} (no photo)", int(w), int(h), alpha=False)
    img.generated_color = (0.5, 0.5, 0.5, 1.0)
    img[photos.PLACEHOLDER] = True
    return img


def build_view_planes(case, images, centre=(0.0, 0.0, 0.0)):
    """Photo planes with their landmarks, passpoints and contours for every view of
    ``case``, with a Blender camera for each perspective photo (not linked to a scene: link
    ``photos.view_root(plane)``). ``images``: dict view -> bpy Image."""
    planes = []
    for name, view in case.views.items():
        img = images[name]
        if tuple(img.size) != tuple(view.size):
            raise ValueError(f"view {name!r}: the photo {img.name!r} is "
                             f"{img.size[0]}x{img.size[1]} pixels but the landmarks file "
                             f"says {view.size[0]}x{view.size[1]}")
        vd = view.to_dict()  # the file's form: a camera keeps its numbers as read
        keep = {k: v for k, v in vd.items() if k not in _EDITED}
        hints, shown = None, None
        if view.camera is None:
            keep["camera"] = hints = vd["camera"]  # the fit computes this camera
            shown = passpoint_camera(case, name)
        plane = photos.new_photo_plane(
            img, name, photos.nearest_view(view.camera or shown, name), camera=view.camera,
            centre=centre, hints=hints, shown=shown)
        planes.append(plane)
        if view.camera is not None and not isinstance(vd["camera"], str):
            plane.headrecon.camera_json = json.dumps(vd["camera"])
        plane.headrecon.view_json = json.dumps(keep) if keep else ""
        for lm, uv in view.points.items():
            if lm in view.uncertainty:  # a detector's point (shown as detected)
                landmarks.place_detected(plane, lm, uv, view.uncertainty[lm],
                                         view.depth.get(lm))
            else:
                landmarks.place_landmark(plane, lm, uv)
        for pp, uv in view.passpoints.items():
            landmarks.place_landmark(plane, pp, uv, "PASSPOINT")
        if view.contour is not None and len(view.contour):
            landmarks.set_contour(plane, view.contour)
    return planes


def passpoint_camera(case, view):
    """The DLT camera of a view's passpoints (what the fit starts from for a camera to be
    computed), or None when they cannot give one (too few, coplanar, undefined)."""
    if len(case.views[view].passpoints) < MIN_PASSPOINTS:
        return None
    try:
        _, xyz, uv = case.passpoint_arrays(view)
        return fit_dlt(xyz, uv, case.views[view].size).camera
    except ValueError:
        return None


def load_case_images(case):
    """Each view's photo as a bpy Image (a grey placeholder for views without one).

    Raises ValueError naming the view and the file when a photo is missing or unreadable.
    """
    images = {}
    for name in case.views:
        path = case.image_path(name)
        if path is None:
            images[name] = placeholder_image(name, case.views[name].size)
            continue
        try:
            images[name] = photos.load_image(path, case.views[name].size)
        except ValueError as e:
            raise ValueError(f"{case.source}: view {name!r}: {e}") from None
    return images


def import_landmarks(context, path):
    """Read a landmarks file into the scene: one photo plane per view with its landmarks
    and contour; planes of the same views are replaced. All or nothing.

    Returns
    -------
    list of bpy.types.Object
        The new photo planes.

    Raises
    ------
    ValueError, OSError
        The file is unreadable or invalid, or a photo is missing (scene unchanged).
    """
    case = load_landmarks(path, for_fit=False)
    scene = context.scene
    with Transaction():
        images = load_case_images(case)
        centre = photos.head_centre(scene)
        planes = build_view_planes(case, images, centre)
        # Everything is built: now replace the old planes and link the new ones.
        for name in case.views:
            old = photos.find_plane(scene, name)
            if old is not None:
                photos.remove_objects(photos.view_objects(old))
        for plane in planes:
            scene_collections.link_tree(scene, photos.view_root(plane))
        store_case_level(scene, case)
    return planes
