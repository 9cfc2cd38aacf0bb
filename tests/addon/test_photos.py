"""A photo plane lines up with its camera; photos load upright with their EXIF focal
length, several at once sorted into views (by name, face or shape; bpy module, background)."""

import numpy as np
import pytest
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


def _photo_jpeg(path, size, orientation=None, focal_35mm=None, seed=0):
    """A JPEG of stored ``size`` (w, h): a grey photo with a white square in its stored
    top-left corner, with EXIF Orientation and FocalLengthIn35mmFilm when given."""
    from solver.io import exif
    from tests.solver.io.exif_jpeg import jpeg, tiff

    w, h = size
    pixels = np.full((h, w, 3), 60 + 20 * seed, np.uint8)
    pixels[:16, :16] = 255
    ifd0 = [(exif.ORIENTATION, 3, [orientation])] if orientation else []
    sub = [(exif.FOCAL_35MM, 3, [focal_35mm])] if focal_35mm else None
    path.write_bytes(jpeg(tiff(ifd0, sub) if ifd0 or sub else None, pixels=pixels))
    return path


def test_load_photos_sorts_several_files_into_views(scene, tmp_path):
    import bpy

    from headrecon_addon import photos

    # a portrait phone photo stored sideways (orientation 6) and a wide one: the upright
    # portrait is the front, the wide one the profile
    _photo_jpeg(tmp_path / "IMG_1.jpg", (96, 64), orientation=6)
    _photo_jpeg(tmp_path / "IMG_2.jpg", (128, 96), seed=1)
    assert bpy.ops.headrecon.load_photo(
        directory=str(tmp_path), files=[{"name": "IMG_2.jpg"}, {"name": "IMG_1.jpg"}],
        camera_view=photos.AUTO) == {"FINISHED"}
    front, side = photos.find_plane(scene, "front"), photos.find_plane(scene, "side")
    assert front is not None and side is not None and len(photos.photo_planes(scene)) == 2
    assert photos.photo_source(front.headrecon.image) == str(tmp_path / "IMG_1.jpg")
    assert tuple(front.headrecon.image_size) == (64, 96)  # upright
    assert tuple(front.headrecon.image.size) == (64, 96)
    assert front.headrecon.camera_view == "orthographic-front"
    assert side.headrecon.camera_view == "orthographic-right"
    # the white corner, stored top-left, is top-right once turned 90° clockwise
    arr = photos.image_to_array(front.headrecon.image)
    assert arr[:12, -12:, :3].min() > 0.9 and arr[:12, :12, :3].max() < 0.5
    assert front.headrecon.image.packed_file is not None  # saved with the .blend
    # the landmarks file names the photo's own file, and reads back upright
    from headrecon_addon import scene_to_case

    d = scene_to_case.view_dict_from_plane(front, tmp_path)
    assert d["image"] == "IMG_1.jpg" and d["size"] == [64, 96]
    # a second load of the same file reuses the upright copy
    n_images = len(bpy.data.images)
    assert photos.load_image(tmp_path / "IMG_1.jpg") == front.headrecon.image
    assert len(bpy.data.images) == n_images


def test_a_file_of_an_older_version_keeps_its_photo_as_stored(scene, tmp_path):
    from headrecon_addon import photos

    _photo_jpeg(tmp_path / "old.jpg", (96, 64), orientation=6)
    # landmarks placed on the stored pixels (96 x 64): loaded as stored
    assert tuple(photos.load_image(tmp_path / "old.jpg", (96, 64)).size) == (96, 64)
    assert tuple(photos.load_image(tmp_path / "old.jpg", (64, 96)).size) == (64, 96)


def test_a_perspective_photo_takes_its_focal_length_from_exif(scene, tmp_path):
    import bpy

    from headrecon_addon import photos

    _photo_jpeg(tmp_path / "phone.jpg", (120, 90), focal_35mm=26)
    assert bpy.ops.headrecon.load_photo(filepath=str(tmp_path / "phone.jpg"),
                                        projection="PERSPECTIVE") == {"FINISHED"}
    plane = photos.photo_planes(scene)[0]
    # 26 mm by the diagonal of a 4:3 photo is 27.0 mm across its long side
    assert photos.lens_hint(plane) == pytest.approx(27.0)
    assert plane.headrecon.lens_from_exif and plane.headrecon.lens_mm == pytest.approx(27.0)
    assert "27 mm" in photos.camera_label(plane)
    assert photos.camera_object(plane).data.lens > 0
    # the artist's value overrides it, and the shown camera follows
    plane.headrecon.lens_mm = 50.0
    assert photos.lens_hint(plane) == pytest.approx(50.0)
    assert not plane.headrecon.lens_from_exif
    assert "50 mm" in photos.camera_label(plane)
    # a focal length given in the operator wins over the EXIF
    assert bpy.ops.headrecon.load_photo(filepath=str(tmp_path / "phone.jpg"), view="p2",
                                        projection="PERSPECTIVE", lens_mm=85.0) == {"FINISHED"}
    p2 = photos.find_plane(scene, "p2")
    assert photos.lens_hint(p2) == pytest.approx(85.0) and not p2.headrecon.lens_from_exif
    # an orthographic photo has no focal length to set
    assert bpy.ops.headrecon.load_photo(filepath=str(tmp_path / "phone.jpg"), view="front",
                                        projection="ORTHOGRAPHIC") == {"FINISHED"}
    front = photos.find_plane(scene, "front")
    assert front.headrecon.lens_mm == 0.0 and photos.lens_hint(front) is None
    # ... but the fit reads its EXIF lens, to say the photo was taken too close for one
    from headrecon_addon.scene_to_case import case_for_fit, export_landmarks

    case = case_for_fit(scene)
    assert case.views["front"].camera_hints == {"lens_mm": pytest.approx(27.0, abs=0.05)}
    assert case.views["p2"].camera_hints["lens_mm"] == pytest.approx(85.0)
    export_landmarks(scene, tmp_path / "out.json")  # not a file's business
    assert "camera_hints" not in (doc := (tmp_path / "out.json").read_text()) \
        and doc.count("lens_mm") == 2  # the two perspective views' own


def test_a_photo_with_its_lens_in_exif_is_perspective_held_near_its_direction(scene,
                                                                              tmp_path):
    # by default (From the Photo) a camera's photo is fitted with its lens, its camera held
    # near the view's direction (which follows the artist's Direction); one without EXIF
    # stays orthographic; the fit's case carries both
    import bpy

    from headrecon_addon import photos
    from headrecon_addon.scene_to_case import case_for_fit
    from solver import DIRECTION_SIGMA_DEG

    _photo_jpeg(tmp_path / "profile.jpg", (90, 120), focal_35mm=52)
    _photo_jpeg(tmp_path / "front.jpg", (90, 120), seed=1)
    assert bpy.ops.headrecon.load_photo(filepath=str(tmp_path / "profile.jpg"),
                                        camera_view="orthographic-right") == {"FINISHED"}
    assert bpy.ops.headrecon.load_photo(filepath=str(tmp_path / "front.jpg")) == {"FINISHED"}
    side, front = photos.find_plane(scene, "side"), photos.find_plane(scene, "front")
    assert photos.is_perspective(side) and not photos.is_perspective(front)
    # 52 mm by the diagonal of a 3:4 photo: 54.1 mm across its long side
    assert photos.lens_hint(side) == pytest.approx(54.1) and side.headrecon.lens_from_exif
    assert photos.camera_hints(side)["direction_prior"] == [90.0, DIRECTION_SIGMA_DEG]
    side.headrecon.camera_view = "orthographic-left"
    assert photos.camera_hints(side)["direction_prior"] == [-90.0, DIRECTION_SIGMA_DEG]
    case = case_for_fit(scene)
    assert case.views["side"].camera is None and case.views["front"].camera is not None
    assert case.views["side"].camera_hints["direction_prior"] == [-90.0, DIRECTION_SIGMA_DEG]


def test_an_exif_lens_no_camera_has_loads_the_photo_as_without_one(scene, tmp_path):
    import bpy

    from headrecon_addon import photos

    _photo_jpeg(tmp_path / "odd.jpg", (90, 120), focal_35mm=1)
    photo = photos.load_photo(tmp_path / "odd.jpg")
    assert photo.lens_mm() is None
    assert photo.problem == ("odd.jpg: its EXIF gives a 1 mm lens (36 mm equivalent), "
                             "outside 2..5000 mm; the photo is used as if it gave none")
    assert bpy.ops.headrecon.load_photo(filepath=str(tmp_path / "odd.jpg")) == {"FINISHED"}
    assert not photos.is_perspective(photos.find_plane(scene, "front"))


def test_bad_exif_loads_the_photo_as_stored_with_one_line(scene, tmp_path):
    import bpy

    from headrecon_addon import photos
    from tests.addon.support import snapshot
    from tests.solver.io.exif_jpeg import jpeg

    path = tmp_path / "broken exif.jpg"
    path.write_bytes(jpeg(b"MM\x00*\x00\x00\xff\xff", size=(40, 30)))
    photo = photos.load_photo(path)
    assert tuple(photo.image.size) == (40, 30) and photo.exif is None
    assert photo.problem.startswith("broken exif.jpg: EXIF not read")
    assert bpy.ops.headrecon.load_photo(filepath=str(path), projection="PERSPECTIVE",
                                        view="p") == {"FINISHED"}
    assert photos.lens_hint(photos.find_plane(scene, "p")) is None
    # one missing file among several: nothing is loaded
    before = snapshot()
    with pytest.raises(RuntimeError, match="missing.jpg: photo not found"):
        bpy.ops.headrecon.load_photo(directory=str(tmp_path), camera_view=photos.AUTO,
                                     files=[{"name": "broken exif.jpg"},
                                            {"name": "missing.jpg"}])
    assert snapshot() == before


def test_load_photos_sorts_photos_whose_names_say_nothing_by_the_face(sample, scene, tmp_path):
    # two photos of one shape: by shape the first would be the front; the faces say the
    # first is a right profile and the second the front
    import shutil

    import bpy

    from headrecon_addon import photos
    from solver.paths import DETECTOR_DIR

    if not (DETECTOR_DIR / "face_landmark.tflite").is_file():
        pytest.skip(f"detector models missing in {DETECTOR_DIR}: run ./run detector")
    folder, _ = sample
    shutil.copy(folder / "side.png", tmp_path / "IMG_1.png")
    shutil.copy(folder / "front.png", tmp_path / "IMG_2.png")
    assert bpy.ops.headrecon.load_photo(
        directory=str(tmp_path), files=[{"name": "IMG_1.png"}, {"name": "IMG_2.png"}],
        camera_view=photos.AUTO) == {"FINISHED"}
    front, side = photos.find_plane(scene, "front"), photos.find_plane(scene, "side")
    assert photos.photo_source(front.headrecon.image) == str(tmp_path / "IMG_2.png")
    assert photos.photo_source(side.headrecon.image) == str(tmp_path / "IMG_1.png")
    assert side.headrecon.camera_view == "orthographic-right"


def test_detector_pixels_are_clamped_srgb_and_read_once(scene):
    """The detector reads a photo as sRGB in [0, 1], row 0 at the top: an 8-bit image as
    stored, a float image (linear light) encoded, values beyond [0, 1] clamped, the alpha
    of a photo with transparent pixels (a cut-out) kept beside the colour; a job
    that reads a photo twice gets the same read-only array back."""
    import bpy

    from headrecon_addon import photos

    linear = np.array([[-0.5, 0.0, 0.002], [0.18, 1.0, 2.0]], np.float32)  # (h=2, w=3)
    img = bpy.data.images.new("hdr", 3, 2, float_buffer=True)
    rgba = np.ones((2, 3, 4), np.float32)
    rgba[..., :3] = linear[..., None]
    img.pixels.foreach_set(rgba[::-1].ravel())  # Blender's rows run bottom-up
    px = photos.detector_pixels(img)
    assert px.shape == (2, 3, 3) and px.dtype == np.float32 and px.flags.c_contiguous
    expect = np.clip(linear, 0.0, 1.0)
    expect = np.where(expect <= 0.0031308, 12.92 * expect, 1.055 * expect ** (1 / 2.4) - 0.055)
    assert np.allclose(px[..., 1], expect, atol=1e-6) and px.min() >= 0.0
    assert px[1, 2, 0] == pytest.approx(1.0) and px[0, 0, 0] == 0.0
    byte = bpy.data.images.new("ldr", 3, 2)
    byte.pixels.foreach_set(rgba[::-1].clip(0, 1).ravel())
    assert np.allclose(photos.detector_pixels(byte)[..., 2], np.clip(linear, 0, 1), atol=1 / 255)
    assert photos.detector_pixels(byte).shape == (2, 3, 3)  # opaque: no alpha
    rgba[0, 1, 3] = 0.0                        # a cut-out: its alpha goes to the detector
    cut = bpy.data.images.new("cut", 3, 2, alpha=True)
    cut.pixels.foreach_set(rgba[::-1].clip(0, 1).ravel())
    px_cut = photos.detector_pixels(cut)
    assert px_cut.shape == (2, 3, 4) and px_cut[0, 1, 3] == 0.0 and px_cut[1, 2, 3] == 1.0
    assert np.allclose(px_cut[..., 2], np.clip(linear, 0, 1), atol=1 / 255)
    read = {}
    first = photos.detector_pixels(img, read)
    assert photos.detector_pixels(img, read) is first and not first.flags.writeable
    assert np.array_equal(first, px) and set(read) == {"hdr"}
