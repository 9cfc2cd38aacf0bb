"""A photo plane lines up with its camera (bpy module, background)."""

import numpy as np
from mathutils import Vector


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
