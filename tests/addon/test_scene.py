"""Add-on scene building without a fit: reference head, photo planes, landmarks, contour,
the place-landmarks logic, landmarks import/export (bpy module, background)."""

import json

import bpy
import numpy as np
import pytest
from mathutils import Vector

from tests.addon.support import addon, empty_scene, snapshot, synthetic_files, write_photo


@pytest.fixture(scope="module")
def files(model, tmp_path_factory):
    addon()
    return synthetic_files(model, tmp_path_factory.mktemp("scene"), seed=3)


@pytest.fixture
def scene():
    return empty_scene()


def test_reference_head(model, scene):
    assert bpy.ops.headrecon.add_head() == {"FINISHED"}
    head = scene.headrecon.head
    mesh = head.data
    assert head.headrecon.role == "HEAD" and head.name in scene.objects
    assert len(mesh.vertices) == model.n_vertices
    assert len(mesh.polygons) == model.face_loop_start.size
    co = np.empty(model.n_vertices * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    assert np.abs(co.reshape(-1, 3) - model.vertices).max() < 1e-6
    lv = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("vertex_index", lv)
    assert np.array_equal(lv, model.loop_vertex)
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    mesh.uv_layers["UVMap"].data.foreach_get("uv", uv)
    assert np.abs(uv.reshape(-1, 2) - model.loop_uv).max() < 1e-6
    # one material per part group, skin first; the eyes' faces use the eye material
    names = [m.get("headrecon_group") for m in mesh.materials]
    assert names[:2] == ["Face", "Head"] and "Eyes" in names and "Teeth" in names
    mi = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("material_index", mi)
    eye = model.part_names.index("Eyeball left")
    assert set(mi[model.face_part == eye]) == {names.index("Eyes")}
    # one vertex group per region, weights = region weights (to 1/1024)
    assert [g.name for g in head.vertex_groups] == list(model.region_names)
    for r in (0, len(model.region_names) - 1):
        g = head.vertex_groups[r]
        idx = np.flatnonzero(model.region_weights[r] > 0.001)
        sample = idx[:: max(1, idx.size // 500)]
        got = np.array([g.weight(int(i)) for i in sample])
        assert np.abs(got - model.region_weights[r, sample]).max() <= 0.5 / 1024 + 1e-6


def test_photo_plane_lines_up_with_its_camera(files, scene):
    from headrecon_addon import photos

    path, case, _ = files
    view = case.views["front"]
    img = photos.load_image(case.image_path("front"))
    plane = photos.new_photo_plane(img, "front", "orthographic-front")
    scene.collection.objects.link(plane)
    assert tuple(plane.headrecon.image_size) == view.size
    # pixels <-> plane space round trip
    uv = np.array([[0.0, 0.0], [view.size[0], view.size[1]], [123.25, 456.5]])
    assert np.abs(photos.pixels_from_local(plane, photos.local_from_pixels(plane, uv))
                  - uv).max() < 1e-9
    # a plane-space point, in the world, projects through the camera onto its pixel
    cam = photos.plane_camera(plane)
    xy = photos.local_from_pixels(plane, uv)
    world = np.array([plane.matrix_world @ Vector((x, y, 0.0)) for x, y in xy])
    assert np.abs(cam.project(world) - uv).max() < 1e-4
    # the photo stands behind the head (+Y for the front view), unlit
    assert plane.matrix_world.translation.y > 0.2
    mat = plane.data.materials[0]
    assert any(n.type == "EMISSION" for n in mat.node_tree.nodes)
    assert not any(n.type == "BSDF_PRINCIPLED" for n in mat.node_tree.nodes)


def test_place_landmarks_session_and_swap(files, scene, tmp_path):
    from headrecon_addon import landmarks, photos

    path, case, _ = files
    img = photos.load_image(case.image_path("right"))
    plane = photos.new_photo_plane(img, "side", "orthographic-right")
    scene.collection.objects.link(plane)
    session = landmarks.PlacementSession(plane)
    names = [d["name"] for d in session.definitions]
    assert names == [d["name"] for d in landmarks.landmark_definitions("right")]
    assert all("right" in d["views"] for d in session.definitions) and len(names) > 10
    assert session.current["name"] == names[0] and names[0] in session.header()

    def ray_to(uv):  # a view ray from in front of the photo through pixel uv
        xy = photos.local_from_pixels(plane, [uv])[0]
        target = plane.matrix_world @ Vector((xy[0], xy[1], 0.0))
        normal = (plane.matrix_world.to_3x3() @ Vector((0, 0, 1))).normalized()
        return target + normal * 2.0, -normal

    assert session.click(*ray_to((100.0, 200.0)))
    session.skip()  # names[1] stays unplaced
    assert session.click(*ray_to((300.5, 400.25)))
    assert not session.click(Vector((50, 0, 0)), Vector((0, 0, 1)))  # misses the photo
    px = landmarks.landmark_pixels(plane)
    assert list(px) == [names[0], names[2]]
    assert np.allclose(px[names[0]], (100.0, 200.0), atol=1e-3)
    assert np.allclose(px[names[2]], (300.5, 400.25), atol=1e-3)
    session.back()
    session.back()
    assert session.current["name"] == names[1]
    session.back()
    session.unplace()
    assert list(landmarks.landmark_pixels(plane)) == [names[2]]
    # landmarks are children of the plane: moving the plane moves them, pixels stay
    plane.location.x += 0.5
    assert np.allclose(landmarks.landmark_pixels(plane)[names[2]], (300.5, 400.25), atol=1e-3)
    # swapping the photo keeps the landmarks (same place relative to centre and height)
    other = tmp_path / "other.png"
    write_photo(other, (2 * img.size[0], 2 * img.size[1]), seed=9)
    bpy.ops.headrecon.load_photo(filepath=str(other), view="side",
                                 camera_view="orthographic-right")
    assert photos.find_plane(scene, "side") == plane
    assert plane.headrecon.image.filepath.endswith("other.png")
    assert np.allclose(landmarks.landmark_pixels(plane)[names[2]], (601.0, 800.5), atol=2e-3)
    assert len([o for o in scene.objects if photos.is_photo(o)]) == 1


def test_contour(files, scene):
    from headrecon_addon import landmarks, photos

    _, case, _ = files
    img = photos.load_image(case.image_path("right"))
    plane = photos.new_photo_plane(img, "right", "orthographic-right")
    scene.collection.objects.link(plane)
    assert landmarks.contour_pixels(plane) is None
    pts = np.array([[10.0, 20.0], [15.5, 30.25], [21.0, 45.0]])
    landmarks.set_contour(plane, pts)
    assert np.allclose(landmarks.contour_pixels(plane), pts, atol=1e-3)
    session = landmarks.ContourSession(plane)
    xy = photos.local_from_pixels(plane, [[30.0, 60.0]])[0]
    target = plane.matrix_world @ Vector((xy[0], xy[1], 0.0))
    normal = (plane.matrix_world.to_3x3() @ Vector((0, 0, 1))).normalized()
    assert session.click(target + normal, -normal)
    assert np.allclose(landmarks.contour_pixels(plane)[-1], (30.0, 60.0), atol=1e-3)
    session.undo_point()
    assert np.allclose(landmarks.contour_pixels(plane), pts, atol=1e-3)
    landmarks.set_contour(plane, np.zeros((0, 2)))
    assert landmarks.contour_object(plane) is None


def test_import_export_round_trip(files, scene, tmp_path):
    from solver.io import landmarks_file

    path, case, _ = files
    # keys the add-on does not edit travel through the scene untouched
    data = json.loads(path.read_text())
    data["version"] = 2
    data["x-tool"] = {"made by": "test"}
    data["views"]["front"]["calibrated"] = False
    data["views"]["front"]["x-note"] = "kept"
    path = path.parent / "case_v2.json"
    path.write_text(json.dumps(data))
    case = landmarks_file.load_landmarks(path)
    assert bpy.ops.headrecon.import_landmarks(filepath=str(path)) == {"FINISHED"}
    planes = [o for o in scene.objects if o.headrecon.role == "PHOTO"]
    assert sorted(p.headrecon.view for p in planes) == sorted(case.views)
    n_lm = sum(1 for o in scene.objects if o.headrecon.role == "LANDMARK")
    assert n_lm == case.n_points
    out = tmp_path / "sub" / "exported.json"
    out.parent.mkdir()
    assert bpy.ops.headrecon.export_landmarks(filepath=str(out)) == {"FINISHED"}
    again = landmarks_file.load_landmarks(out)
    assert _same(again, case)
    assert again.extra == {"x-tool": {"made by": "test"}}
    assert again.views["front"].calibrated is False
    assert again.views["front"].extra == {"x-note": "kept"}
    # image paths are rewritten relative to the new file and still find the photos
    for v in case.views:
        assert again.image_path(v).resolve() == case.image_path(v).resolve()
    # importing the export again replaces the planes (no duplicates) and keeps the points
    assert bpy.ops.headrecon.import_landmarks(filepath=str(out)) == {"FINISHED"}
    assert sum(1 for o in scene.objects if o.headrecon.role == "PHOTO") == len(case.views)
    assert sum(1 for o in scene.objects if o.headrecon.role == "LANDMARK") == n_lm


def _same(a, b):
    for v in b.views:
        pa, pb = a.views[v].points, b.views[v].points
        assert list(pa) == list(pb)
        assert np.allclose([pa[k] for k in pa], [pb[k] for k in pb], atol=1e-3)
        if b.views[v].contour is not None:
            assert np.allclose(a.views[v].contour, b.views[v].contour, atol=1e-3)
        assert a.views[v].camera.to_dict() == b.views[v].camera.to_dict()
    return True


def _bad_files(folder, good):
    data = json.loads(good.read_text())
    out = {}
    (folder / "bad_json.json").write_text("{ nope")
    out["not_json"] = (folder / "bad_json.json", "not valid JSON")
    d = json.loads(json.dumps(data))
    first = next(iter(d["views"]))
    d["views"][first]["points"]["nose_tipp"] = [10, 10]
    (folder / "bad_unknown.json").write_text(json.dumps(d))
    out["unknown"] = (folder / "bad_unknown.json", "nose_tipp")
    d = json.loads(json.dumps(data))
    last = list(d["views"])[-1]
    d["views"][last]["image"] = "missing_photo.png"
    (folder / "bad_missing.json").write_text(json.dumps(d))
    out["missing"] = (folder / "bad_missing.json", "missing_photo.png")
    d = json.loads(json.dumps(data))
    w, h = d["views"][last]["size"]
    d["views"][last]["size"] = [w + 2, h + 2]
    (folder / "bad_size.json").write_text(json.dumps(d))
    out["size"] = (folder / "bad_size.json", "pixels")
    out["absent"] = (folder / "bad_absent.json", "no such file")
    return out


def test_bad_landmarks_file_leaves_scene_unchanged(files, scene):
    from headrecon_addon import landmarks

    path, _, _ = files
    bpy.ops.headrecon.import_landmarks(filepath=str(path))  # a scene with work in it
    before = snapshot()
    # next to the good file, so its photos' relative paths resolve
    for key, (bad, words) in _bad_files(path.parent, path).items():
        with pytest.raises((ValueError, OSError)) as err:
            landmarks.import_landmarks(bpy.context, bad)
        assert words in str(err.value), key
        assert snapshot() == before, key
        # the operator reports the error and cancels, also leaving everything as it was
        with pytest.raises(RuntimeError, match="Error"):
            bpy.ops.headrecon.import_landmarks(filepath=str(bad))
        assert snapshot() == before, key


def test_poll_messages(scene):
    # Operators that cannot run say why (poll_message_set); background ops raise with it.
    with pytest.raises(RuntimeError, match="Load a front and a profile photo"):
        bpy.ops.headrecon.fit()
    with pytest.raises(RuntimeError, match="no photos with landmarks"):
        bpy.ops.headrecon.export_landmarks(filepath="/tmp/never.json")


def _render_eyes(scene, head, model, lash_alpha=None):
    """A small Cycles render of the subject's right eye from the front (no photo planes,
    plain light): (h, w, 4) float32 and the camera. ``lash_alpha``: replace the lash
    shader's alpha by this constant (None keeps the shader)."""
    from solver.cameras import ORTHO_VIEWS, OrthographicCamera
    from tools import render_util as ru

    lashes = next(m for m in head.data.materials if m["headrecon_group"] == "Eyelashes")
    bsdf = next(n for n in lashes.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    if lash_alpha is not None:
        for link in list(bsdf.inputs["Alpha"].links):
            lashes.node_tree.links.remove(link)
        bsdf.inputs["Alpha"].default_value = lash_alpha
    size = (96, 64)
    ru.configure_cycles(scene, size, samples=8, denoise=False)
    right_eye = model.vertices[23021:24591].mean(axis=0)
    rot = ORTHO_VIEWS["orthographic-front"]
    scale = 2800.0  # px per metre: the eye ~ 80 px wide
    cam = OrthographicCamera(rot, scale, np.array(size) / 2 - scale * (rot[:2] @ right_eye),
                             size, "orthographic-front")
    if scene.world is None:
        ru.studio_lighting(right_eye, **ru.PREVIEW_LIGHTING)
    return ru.render_rgba(ru.add_ortho_camera(cam, name="Eye camera")), cam


def test_eyes_and_lashes(model, scene):
    from headrecon_addon import material, reference_head

    head = reference_head.new_head_object(model)
    scene.collection.objects.link(head)
    # the eye material's attribute: 1 on each eye's axis, 0 off the sclera's front
    attr = np.empty(model.n_vertices, np.float32)
    head.data.attributes[material.EYE_ATTRIBUTE].data.foreach_get("value", attr)
    np.testing.assert_array_equal(attr, material.eye_attribute(model.vertices))
    for (s0, s1), (i0, i1) in zip(material.SCLERA_RANGES, material.IRIS_RANGES, strict=True):
        front = attr[s0:s1 + 1]
        assert front.max() > 0.97 and (front == 0).mean() > 0.3  # the back half is 0
        assert not attr[i0:i1 + 1].any()
    assert not attr[:material.SCLERA_RANGES[0][0]].any() and not attr[model.skin].any()
    # the eyeball's faces use the eye shader, which reads that attribute
    eyes = next(m for m in head.data.materials if m["headrecon_group"] == "Eyes")
    names = {n.attribute_name for n in eyes.node_tree.nodes if n.type == "ATTRIBUTE"}
    assert names == {material.EYE_ATTRIBUTE}
    # rendered: a dark pupil inside a blue-grey iris inside a light sclera ...
    rgba, cam = _render_eyes(scene, head, model)
    pupil_vertex = 23021 + int(np.argmax(attr[23021:23791]))
    u, v = np.round(cam.project(model.vertices[[pupil_vertex]])[0]).astype(int)
    pupil = rgba[v - 1:v + 2, u - 1:u + 2, :3].mean(axis=(0, 1))
    r_px = int(round(0.5 * (material.IRIS_RADIUS + material.PUPIL_RADIUS) * cam.scale))
    iris = rgba[v - 1:v + 2, u + r_px - 1:u + r_px + 2, :3].mean(axis=(0, 1))
    sclera_px = int(round(1.6 * material.IRIS_RADIUS * cam.scale))
    sclera = rgba[v - 1:v + 2, u - sclera_px - 1:u - sclera_px + 2, :3].mean(axis=(0, 1))
    # (the pupil shows the bright world in the wet coat, so it is dark grey, not black)
    assert pupil.mean() < 0.5 * sclera.mean() and pupil.mean() < iris.mean() - 0.15, pupil
    assert iris[2] > iris[0] + 0.05 and iris.mean() < sclera.mean() - 0.05, (iris, sclera)
    assert sclera.min() > 0.45, sclera
    # ... and the upper lashes a dark fringe that lets the light through between strands:
    # over the strips' footprint (where opaque strips would change the image), darker than
    # no lashes and much lighter than opaque strips
    without = _render_eyes(scene, head, model, lash_alpha=0.0)[0][:v, :, :3].mean(axis=2)
    slabs = _render_eyes(scene, head, model, lash_alpha=1.0)[0][:v, :, :3].mean(axis=2)
    footprint = without - slabs > 0.1  # above the pupil: the upper lid's strips
    assert footprint.sum() > 100
    lashes = rgba[:v, :, :3].mean(axis=2)
    cover = (without - lashes)[footprint] / (without - slabs)[footprint]  # 0 clear, 1 opaque
    assert 0.05 < cover.mean() < 0.6, cover.mean()
    assert np.percentile(cover, 90) > 0.25 and np.median(cover) < 0.4  # dense at the lid


def test_eyelash_texture():
    from headrecon_addon import material

    n = 512
    a = material.eyelash_alpha(n)
    assert a.shape == (n, n) and a.dtype == np.float32 and a.min() >= 0 and a.max() <= 1
    v = 1.0 - (np.arange(n) + 0.5) / n  # texel rows, top first
    strip = np.floor(6 * v)
    root = (np.mod(6 * v, 1) - material.LASH_STRIP_TIP) / (
        material.LASH_STRIP_ROOT - material.LASH_STRIP_TIP)  # 0 at the tips, 1 at the lid
    eye = slice(0, n // 2)  # u in [0, 0.5): one eye's strips, along the whole lid
    upper, lower = (strip >= 3) & (root > 0) & (root < 1), (strip < 3) & (root > 0) & (root < 1)
    # strands: near the lid a row crosses one lash after another, clear in between
    row = a[np.flatnonzero(upper & (np.abs(root - 0.9) < 0.02))[0], eye]
    starts = np.count_nonzero((row[1:] > 0.3) & (row[:-1] <= 0.3))
    assert 25 <= starts <= material.LASH_STRANDS
    assert (row < 0.05).mean() > 0.3
    # dense at the lid, fading toward the tips; the lower lid lighter
    near_lid = a[upper & (root > 0.75)][:, eye].mean()
    near_tip = a[upper & (root < 0.25)][:, eye].mean()
    assert near_lid > 2.5 * near_tip > 0
    assert a[lower][:, eye].mean() < 0.7 * a[upper][:, eye].mean()
    assert a[upper][:, eye].mean() < 0.3  # strands, not a slab
