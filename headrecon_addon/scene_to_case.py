"""The scene read into the solver's plain data: the photo planes and their markers as a
LandmarkCase (and a landmarks file), the scene's settings as FitOptions, the photos as
pixel arrays, and whether there are enough landmarks to fit.

The file format is the solver's: reading and writing go through the solver's
``parse_landmarks`` / ``save_landmarks`` only.
"""

import json
import os
from pathlib import Path

from . import landmarks, photos
from .solver_link import (
    CURRENT_VERSION,
    FORMAT,
    MIN_LANDMARKS_TOTAL,
    FitOptions,
    camera_class,
    count_problems,
    landmarks_needed,
    orthographic_lenses,
    parse_landmarks,
    save_landmarks,
)


def _image_ref(image, base_dir):
    """Path of a photo for the file: relative to ``base_dir`` when possible."""
    source = photos.photo_source(image)
    if source is None:
        return None
    path = Path(source)
    if base_dir is None:
        return str(path)
    try:
        return Path(os.path.relpath(path, base_dir)).as_posix()
    except ValueError:  # another drive (Windows)
        return str(path)


def view_dict_from_plane(plane, base_dir=None):
    """A photo plane as a view of the landmarks file (its JSON form): size, photo,
    camera, the landmark and contour pixels and the detected landmarks' uncertainty from
    the scene (and their depth); every other key as the imported file had it
    (``view_json``)."""
    (w, h), _ = photos.plane_size(plane)
    props = plane.headrecon
    d = json.loads(props.view_json) if props.view_json else {}
    if props.camera_json:
        d["camera"] = json.loads(props.camera_json)
    elif not isinstance(d.get("camera"), dict):  # (a dict here: hints, camera unknown)
        d["camera"] = props.camera_view
    image = _image_ref(props.image, base_dir)
    if image is None:
        d.pop("image", None)
    else:
        d["image"] = image
    d["size"] = [w, h]
    d["points"] = {k: list(v) for k, v in landmarks.landmark_pixels(plane).items()}
    uncertainty = landmarks.landmark_uncertainty(plane)  # detected points, as detected
    if uncertainty:
        d["uncertainty"] = uncertainty
    else:
        d.pop("uncertainty", None)
    depth = landmarks.landmark_depth(plane)  # of the points still as detected
    if depth:
        d["depth"] = depth
    else:
        d.pop("depth", None)
    passpoints = landmarks.landmark_pixels(plane, "PASSPOINT")
    if passpoints:
        d["passpoints"] = {k: list(v) for k, v in passpoints.items()}
    else:
        d.pop("passpoints", None)
    contour = landmarks.contour_pixels(plane)
    if contour is None:
        d.pop("contour", None)
    else:
        d["contour"] = contour.tolist()
    return d


def case_dict_from_scene(scene, base_dir=None):
    """The scene's photos and landmarks as a landmarks document (a dict).

    Raises
    ------
    ValueError
        No photo planes, or two planes claim one view name.
    """
    planes = photos.photo_planes(scene)
    if not planes:
        raise ValueError("the scene has no photos: load a front and a profile photo first")
    views = {}
    for plane in planes:
        v = plane.headrecon.view
        if v in views:
            raise ValueError(f"view {v!r}: two photo planes claim it ({plane.name!r} and "
                             f"another); rename one view")
        views[v] = view_dict_from_plane(plane, base_dir)
    doc = {"format": FORMAT, "version": CURRENT_VERSION, "views": views}
    if scene.headrecon.case_json:
        doc.update(json.loads(scene.headrecon.case_json))
    return doc


def case_from_scene(scene, base_dir=None, source=None):
    """The scene's photos and landmarks as a LandmarkCase, checked by the solver's own
    parser (as work in progress: without the fit's landmark count floor).

    Parameters
    ----------
    base_dir : path-like, optional
        Folder photo paths are written relative to (absolute paths when None).
    source : str, optional
        Name for messages and for resolving photos (default: a file in ``base_dir``).

    Raises
    ------
    ValueError
        No photos, two planes with one view name, or what the parser finds (a landmark
        dragged off its photo, ...), naming view and landmark.
    """
    doc = case_dict_from_scene(scene, base_dir)
    if source is None:
        source = str(Path(base_dir) / "scene.json") if base_dir is not None else "<scene>"
    return parse_landmarks(doc, source, for_fit=False)


def case_for_fit(scene):
    """``case_from_scene`` for a fit: an orthographic photo whose EXIF gives its lens also
    carries it (``orthographic_lenses``), so the fit warns when the photo was taken too
    close for a parallel projection (read from the files, so not on every live refit)."""
    case = case_from_scene(scene)
    orthographic_lenses(case, {p.headrecon.view: photos.photo_source(p.headrecon.image)
                               for p in photos.photo_planes(scene)})
    return case


def export_landmarks(scene, path):
    """Write the scene's landmarks to ``path`` (atomically, validated by the solver)."""
    path = Path(path)
    case = case_from_scene(scene, base_dir=path.resolve().parent, source=str(path))
    save_landmarks(case, path)
    return case


def options_from_props(props, progress=None):
    """FitOptions from the scene's settings (``Scene.headrecon``)."""
    return FitOptions(method=props.method, n_identity=props.n_identity,
                      n_regional=props.n_regional, lambda1=props.lambda1,
                      lambda2=props.lambda2, prior=props.prior,
                      landmark_weight=props.landmark_weight,
                      exact_landmarks=props.exact_landmarks, progress=progress)


def photo_arrays(scene):
    """Pixels of each view's real photo (not stand-ins): dict view -> (H, W, 4) float32."""
    out = {}
    for plane in photos.photo_planes(scene):
        img = plane.headrecon.image
        if img is None or img.get(photos.PLACEHOLDER) or img.size[0] == 0:
            continue
        out[plane.headrecon.view] = photos.image_to_array(img)
    return out


def placed_and_needed(scene):
    """Landmarks placed and landmarks needed per view, by the solver's rule
    (``landmarks_needed``) on what the views of the scene's case say: the camera kind
    (its ``min_refit_points``), ``calibrated`` (kept), passpoints, ``mirror_of`` and a
    profile's traced outline.

    Returns
    -------
    used, needed : dict of str -> int
        View name -> landmarks placed, and -> landmarks its fit needs.
    """
    used, needed = {}, {}
    for plane in photos.photo_planes(scene):
        view = plane.headrecon.view
        cls = camera_class(photos.camera_kind(plane))
        extra = json.loads(plane.headrecon.view_json) if plane.headrecon.view_json else {}
        used[view] = len(landmarks.landmark_objects(plane))
        needed[view] = landmarks_needed(
            cls.min_refit_points if cls is not None else 0,
            kept=extra.get("calibrated") is True,
            passpoints=bool(landmarks.passpoint_objects(plane)),
            mirror=photos.mirror_of(plane) is not None,
            outline=landmarks.contour_pixels(plane) is not None
            and photos.camera_kind(plane) == "orthographic"
            and photos.view_kind(plane) != "front")
    return used, needed


def fit_problem(scene):
    """Why the scene cannot be fitted yet (a sentence for the artist), or None."""
    if not photos.photo_planes(scene):
        return "Load a front and a profile photo first"
    used, needed = placed_and_needed(scene)
    problems = count_problems(used, needed)
    few = [view for view, _ in problems if view is not None]
    if few:
        counts = ", ".join(f"{v} ({used[v]})" for v in few)
        needs = {needed[v] for v in few}
        if len(needs) == 1:
            return f"Too few landmarks on {counts}: place at least {needs.pop()} per photo"
        return (f"Too few landmarks on {counts}: place at least "
                + ", ".join(f"{needed[v]} on {v}" for v in few))
    if problems:
        return (f"Too few landmarks ({sum(used.values())}): place at least "
                f"{MIN_LANDMARKS_TOTAL} in all")
    return None
