"""The place-landmarks and draw-contour logic on a photo plane (bpy module, background)."""

import bpy
import numpy as np
from mathutils import Vector

from tests.addon.support import write_photo


def test_place_landmarks_session_and_swap(files, scene, tmp_path):
    from headrecon_addon import landmark_ops, landmarks, photos

    path, case, _ = files
    img = photos.load_image(case.image_path("right"))
    plane = photos.new_photo_plane(img, "side", "orthographic-right")
    scene.collection.objects.link(plane)
    session = landmark_ops.PlacementSession(plane)
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
    from headrecon_addon import landmark_ops, landmarks, photos

    _, case, _ = files
    img = photos.load_image(case.image_path("right"))
    plane = photos.new_photo_plane(img, "right", "orthographic-right")
    scene.collection.objects.link(plane)
    assert landmarks.contour_pixels(plane) is None
    pts = np.array([[10.0, 20.0], [15.5, 30.25], [21.0, 45.0]])
    landmarks.set_contour(plane, pts)
    assert np.allclose(landmarks.contour_pixels(plane), pts, atol=1e-3)
    session = landmark_ops.ContourSession(plane)
    xy = photos.local_from_pixels(plane, [[30.0, 60.0]])[0]
    target = plane.matrix_world @ Vector((xy[0], xy[1], 0.0))
    normal = (plane.matrix_world.to_3x3() @ Vector((0, 0, 1))).normalized()
    assert session.click(target + normal, -normal)
    assert np.allclose(landmarks.contour_pixels(plane)[-1], (30.0, 60.0), atol=1e-3)
    session.undo_point()
    assert np.allclose(landmarks.contour_pixels(plane), pts, atol=1e-3)
    # a detected outline across hair or the photo's border: drawn as its parts, read back
    # whole, in order; a point added by hand goes on the last part
    parted = np.vstack([pts, pts[-1] + [200.0, 0.0] + np.arange(4)[:, None] * [3.0, 4.0]])
    landmarks.set_contour(plane, parted)
    obj = landmarks.contour_object(plane)
    assert [len(sp.points) for sp in obj.data.splines] == [3, 4]
    assert np.allclose(landmarks.contour_pixels(plane), parted, atol=1e-3)
    landmarks.add_contour_point_local(plane, xy)
    assert [len(sp.points) for sp in obj.data.splines] == [3, 5]
    landmarks.remove_last_contour_point(plane)
    landmarks.remove_last_contour_point(plane)
    assert [len(sp.points) for sp in obj.data.splines] == [3, 3]
    landmarks.set_contour(plane, np.zeros((0, 2)))
    assert landmarks.contour_object(plane) is None
