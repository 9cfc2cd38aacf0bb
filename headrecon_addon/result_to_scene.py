"""A FitResult written into the scene: shape keys, transform, baked texture and
uncertainty on the head; the residual list (landmarks and the passpoint checks) and the
markers' colours; the perspective photos' cameras lined up with the fitted ones.

Calibration residuals: every view with passpoints is checked on its own by the solver's
``check_passpoints`` (seed 000 §5-6: each view's DLT from its passpoints, leave-one-out
suspects); its passpoints' residuals join the landmark residuals in the list, suspects
first.
"""

import bpy
import numpy as np
from mathutils import Matrix

from . import (
    landmarks,
    material,
    photo_cameras,
    photos,
    reference_head,
    scene_collections,
    shape_keys,
)
from .data import Transaction
from .solver_link import check_passpoints

UNCERTAINTY_COLOR = "fit_uncertainty"
UNCERTAINTY_MM = "fit_uncertainty_mm"
BAKED = "headrecon_baked"  # custom property on baked texture images


def calibration_checks(case):
    """Passpoint check of every view with passpoints (``check_passpoints`` per view, so
    one view that cannot be checked does not hide the others).

    Returns
    -------
    checks : dict of str -> (list of str, PasspointCheck)
        Per view: its passpoint names (the order of the check's arrays) and the check.
    notes : list of str
        Views that could not be checked, and the checks' own notes.
    """
    checks, notes = {}, []
    for name, view in case.views.items():
        if not view.passpoints:
            continue
        try:
            names, xyz, uv = case.passpoint_arrays(name)
            check = check_passpoints(xyz, {name: uv}, names, sizes={name: view.size})
        except ValueError as e:
            notes.append(f"view {name!r}: passpoints not checked: {e}")
            continue
        checks[name] = (names, check)
        notes += check.notes
    return checks, notes


def similarity_matrix(result):
    m = np.eye(4)
    m[:3, :3] = result.scale * np.asarray(result.rotation, dtype=np.float64)
    m[:3, 3] = np.asarray(result.translation, dtype=np.float64)
    return Matrix(m.tolist())


def skin_group_tiles(model):
    """UDIM tile of each skin material group, e.g. {"Face": 1001, "Head": 1002}."""
    out = {}
    first_uv = model.loop_uv[model.face_loop_start]
    tile = (1001 + np.floor(first_uv[:, 0]) + 10 * np.floor(first_uv[:, 1])).astype(int)
    for p, part in enumerate(model.part_names):
        group = material.part_group(part)
        if group in material.SKIN_GROUPS and group not in out:
            t = tile[model.face_part == p]
            if t.size:
                out[group] = int(np.bincount(t - 1001).argmax() + 1001)
    return out


def write_textures(head, model, textures, iris=None):
    """Put baked tiles (dict tile -> (S, S, 3)) into the head's skin materials (packed
    into the .blend when it is saved, so the file carries its texture), and ``iris`` (3,)
    sRGB, the irises' colour read off the photos (``iris_colour``), into its eyes."""
    if iris is not None:
        eyes = reference_head.part_material(head, "Eyes")
        if eyes is not None:
            material.set_iris_colour(eyes, iris)
    images = []
    for group, tile in skin_group_tiles(model).items():
        if tile not in textures:
            continue
        mat = reference_head.part_material(head, group)
        if mat is None:
            continue
        old = material.skin_texture(mat)
        reuse = old if old is not None and old.get(BAKED) and old.users <= 1 else None
        img = photos.array_to_image(textures[tile], f"{head.name} {group} Texture", reuse)
        img[BAKED] = True  # packed when the file is saved (pack_baked_textures): PNG-encoding
        material.set_skin_texture(mat, img)  # it here would slow every fit down
        images.append(img)
    return images


def write_uncertainty(mesh, mm):
    """The fit's per-vertex uncertainty as a colour attribute (ramp) and raw millimetres."""
    mm = np.asarray(mm, dtype=np.float64)
    rgba, vmax = material.uncertainty_colors(mm)
    attr = mesh.color_attributes.get(UNCERTAINTY_COLOR)
    if attr is not None and (attr.data_type != "FLOAT_COLOR" or attr.domain != "POINT"):
        mesh.color_attributes.remove(attr)
        attr = None
    if attr is None:
        attr = mesh.color_attributes.new(UNCERTAINTY_COLOR, "FLOAT_COLOR", "POINT")
    attr.data.foreach_set("color", rgba.ravel())
    raw = mesh.attributes.get(UNCERTAINTY_MM)
    if raw is None:
        raw = mesh.attributes.new(UNCERTAINTY_MM, "FLOAT", "POINT")
    raw.data.foreach_set("value", mm.astype(np.float32))
    mesh.color_attributes.active_color = mesh.color_attributes[UNCERTAINTY_COLOR]
    return vmax


def fit_method(result):
    """The approach that made ``result``: for a "combined" fit the one that won (the
    solver's ``info["approach"]``), not the method requested."""
    return str(result.info.get("approach", result.method))


def residual_rows(result, calibration=None):
    """The residual list's rows: (rank, pixels, view, name, kind, message), sorted: flagged
    passpoints (suspects) first, then flagged landmarks and those the fit down-weighted as
    misplaced (its noise estimate), then the rest; worst first."""
    rows = []
    down_weighted = result.info.get("noise", {}).get("down_weighted", {})
    for view, r in result.residuals.items():
        flagged = set(r.flagged)
        down = down_weighted.get(view, {})
        for name, px in zip(r.names, np.asarray(r.pixels, dtype=np.float64), strict=True):
            message = (f"the fit gave it {100 * down[name]:.0f} % of a landmark's weight: "
                       "it sits far from where the others put the head" if name in down else "")
            rows.append((1 if name in flagged or name in down else 2, float(px), view, name,
                         "LANDMARK", message))
    for view, (names, check) in (calibration or {}).items():
        suspects = {s.name: s for s in check.suspects if s.view == view}
        px = np.asarray(check.residuals[view], dtype=np.float64)
        for name, r in zip(names, px, strict=True):
            s = suspects.get(name)
            rows.append((0 if s else 2, float(r), view, name, "PASSPOINT",
                         s.message if s else ""))
    rows.sort(key=lambda t: (t[0], -t[1]))
    return rows


def update_residuals(scene, result, calibration=None):
    """Fill the residual list (see ``residual_rows``) and colour landmarks and passpoints.
    Cheap enough for every live refit: rows are rewritten in place, a marker's material
    only changes when its flag does."""
    rows = residual_rows(result, calibration)
    props = scene.headrecon
    items = props.residuals
    if len(items) != len(rows):
        items.clear()
        for _ in rows:
            items.add()
        props.residual_index = -1
    for item, (rank, px, view, name, kind, message) in zip(items, rows, strict=True):
        item.view, item.landmark, item.pixels, item.flagged = view, name, px, rank < 2
        item.kind, item.message = kind, message
    by_view = {}
    for rank, px, view, name, kind, _ in rows:
        by_view.setdefault((view, kind), {})[name] = (rank < 2, px)
    for plane in photos.photo_planes(scene):
        for kind in landmarks.MARKER_ROLES:
            res = by_view.get((plane.headrecon.view, kind), {})
            for name, obj in landmarks.marker_objects(plane, kind).items():
                flagged, px = res.get(name, (False, -1.0))
                if obj.headrecon.flagged != flagged:
                    landmarks.set_landmark_state(obj, flagged, px)
                else:
                    obj.headrecon.residual_px = px


def apply_result(scene, model, result, textures=None, head=None, name=None, calibration=None,
                 notes=None, iris=None):
    """Write a FitResult into the scene: shape keys, transform, texture, uncertainty,
    residuals, landmark colours; photo planes lined up with the fitted cameras (a
    perspective photo's Blender camera set to its fitted camera, whose parameters become
    the view's stored camera: exported, and the next fit's starting guess).

    Parameters
    ----------
    scene : bpy.types.Scene
    model : HeadModel
    result : FitResult
    textures : dict of int -> ndarray (S, S, 3), optional
        Baked tiles (``bake_fit_texture``).
    iris : ndarray (3,), optional
        The irises' colour read off the photos (``iris_colour``), sRGB in [0, 1].
    head : bpy.types.Object, optional
        Default: the scene's head; one is made (and linked) if there is none.
    name : str, optional
        Name of a head made here (default "HeadRecon Head").
    calibration : dict, optional
        Passpoint checks (``calibration_checks``) for the residual list.
    notes : list, optional
        Gets what showing the cameras dropped or could not do (one line per view).

    Returns
    -------
    bpy.types.Object
        The head.
    """
    head = head or scene.headrecon.head
    if head is not None and not reference_head.is_head(head):
        head = None
    with Transaction():
        created = head is None
        if created:
            head = reference_head.new_head_object(model, name or reference_head.HEAD_NAME)
        try:
            shape_keys.write_fit_keys(head, model, result)
        except Exception:
            if not created:
                shape_keys.remove_fit_keys(head)
            raise
        if textures or iris is not None:
            write_textures(head, model, textures or {}, iris)
        head.headrecon.uncertainty_max_mm = write_uncertainty(head.data, result.uncertainty)
        if created:
            scene_collections.link(scene, head)
    scene.headrecon.head = head
    head.matrix_world = similarity_matrix(result)
    head.headrecon.fit_method = fit_method(result)
    head.headrecon.fit_rms_px = result.rms_px()
    update_residuals(scene, result, calibration)
    centre = result.world_vertices[model.skin].mean(axis=0)
    for plane in photos.photo_planes(scene):
        view = plane.headrecon.view
        cam = result.cameras.get(view)
        perspective = getattr(cam, "kind", None) in photo_cameras.PERSPECTIVE_KINDS
        if cam is None or perspective != photos.is_perspective(plane):
            continue
        try:
            shown = photos.place_plane(plane, cam, centre=centre)
        except ValueError as e:  # a camera Blender cannot show: the fit itself stands
            shown = [f"camera not shown: {e}"]
        else:
            if perspective:  # (kept only when shown: a re-import must show it too)
                photos.store_fitted_camera(plane, cam)
        if notes is not None:
            notes += [f"view {view!r}: {w}" for w in shown]
    return head


def pack_baked_textures():
    """Pack baked textures that are not packed, or changed since (they exist only in
    memory until then)."""
    for img in bpy.data.images:
        if img.get(BAKED) and img.has_data and (img.packed_file is None or img.is_dirty):
            img.pack()
