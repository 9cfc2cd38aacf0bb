"""The head's eyes and eyelashes: the eye attribute, a rendered eye, the lash texture
(bpy module, background)."""

import numpy as np
import pytest


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


def test_the_iris_takes_the_colour_read_off_the_photos(model, scene):
    from headrecon_addon import material, reference_head
    from solver.texture.shading import srgb_to_linear

    head = reference_head.new_head_object(model)
    scene.collection.objects.link(head)
    eyes = reference_head.part_material(head, "Eyes")
    ramp = eyes.node_tree.nodes[material.IRIS_NODE].color_ramp.elements
    np.testing.assert_allclose([tuple(e.color)[:3] for e in ramp], material.DEFAULT_IRIS,
                               atol=1e-6)
    brown = (0.45, 0.28, 0.15)
    assert material.set_iris_colour(eyes, brown)
    for e, k in zip(ramp, material.IRIS_SPREAD, strict=True):
        assert tuple(e.color)[:3] == pytest.approx(tuple(k * srgb_to_linear(brown)), abs=1e-5)
    # rendered: the iris is now brown, not blue-grey
    rgba, cam = _render_eyes(scene, head, model)
    attr = material.eye_attribute(model.vertices)
    u, v = np.round(cam.project(model.vertices[[23021 + int(np.argmax(
        attr[23021:23791]))]])[0]).astype(int)
    r_px = int(round(0.5 * (material.IRIS_RADIUS + material.PUPIL_RADIUS) * cam.scale))
    iris = rgba[v - 1:v + 2, u + r_px - 1:u + r_px + 2, :3].mean(axis=(0, 1))
    assert iris[0] > iris[2] + 0.05, iris
    # a material without the iris node (not the add-on's eye) is left as it is
    assert not material.set_iris_colour(reference_head.part_material(head, "Teeth"), brown)


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
