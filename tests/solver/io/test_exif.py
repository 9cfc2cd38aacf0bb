"""The EXIF reader (solver/io/exif.py) on JPEG bytes built here: orientation and focal
length in both byte orders, the 36 mm equivalent, and bad EXIF that must not crash."""

import io
import struct

import numpy as np
import pytest

from solver.io import exif
from tests.solver.io.exif_jpeg import jpeg, tiff


@pytest.mark.parametrize("order", ["<", ">"])
def test_orientation_and_focal_length_in_both_byte_orders(order):
    data = jpeg(tiff([(exif.ORIENTATION, 3, [6])],
                     [(exif.FOCAL_LENGTH, 5, [(42, 10)]), (exif.FOCAL_35MM, 3, [26]),
                      (exif.FOCAL_PLANE_X_RES, 5, [(4032000, 5600)]),
                      (exif.FOCAL_PLANE_Y_RES, 5, [(3024000, 4200)]),
                      (exif.FOCAL_PLANE_UNIT, 3, [4]),
                      (exif.PIXEL_X, 4, [4032]), (exif.PIXEL_Y, 3, [3024])], order))
    e = exif.parse_exif(data)
    assert e.orientation == 6
    assert e.focal_length_mm == pytest.approx(4.2)
    assert e.focal_35mm == 26
    assert e.focal_plane_resolution == pytest.approx((720.0, 720.0))
    assert e.focal_plane_unit_mm == 1.0
    assert e.pixel_size == (4032, 3024)


def test_lens_36mm_from_the_35mm_equivalent_and_from_the_sensor():
    # 3:2: the diagonal equivalent is the long-side one
    assert exif.Exif(focal_35mm=50).lens_36mm((6000, 4000)) == pytest.approx(50.0)
    # 4:3 (a phone): 26 mm by the diagonal is 27.0 mm across the long side
    assert exif.Exif(focal_35mm=26).lens_36mm((4032, 3024)) == pytest.approx(27.04, abs=0.01)
    assert exif.Exif(focal_35mm=26).lens_36mm((3024, 4032)) == pytest.approx(27.04, abs=0.01)
    # a 5.6 x 4.2 mm sensor (720 px/mm) and a 4.2 mm lens: 4.2 * 36 / 5.6 = 27 mm
    e = exif.Exif(focal_length_mm=4.2, focal_plane_resolution=(720.0, 720.0),
                  focal_plane_unit_mm=1.0, pixel_size=(4032, 3024))
    assert e.lens_36mm((4032, 3024)) == pytest.approx(27.0)
    # the sensor read from the photo's size when EXIF gives no pixel dimensions
    e = exif.Exif(focal_length_mm=4.2, focal_plane_resolution=(720.0, 720.0),
                  focal_plane_unit_mm=1.0)
    assert e.lens_36mm((4032, 3024)) == pytest.approx(27.0)
    assert exif.Exif(focal_length_mm=4.2).lens_36mm((4032, 3024)) is None  # no sensor size
    assert exif.Exif().lens_36mm((4032, 3024)) is None


def test_no_exif_is_none():
    assert exif.parse_exif(jpeg()) is None
    assert exif.parse_exif(b"\x89PNG\r\n\x1a\n" + b"\0" * 20) is None
    e = exif.parse_exif(jpeg(tiff([(exif.ORIENTATION, 3, [1])])))
    assert e == exif.Exif()  # no EXIF sub-IFD: upright, no focal length


@pytest.mark.parametrize("bad", [
    lambda t: t[:10],  # cut inside IFD0
    lambda t: b"XX" + t[2:],  # no byte order
    lambda t: t[:2] + b"\x2b\x00" + t[4:],  # not TIFF's 42
    lambda t: t[:4] + struct.pack("<I", 10 ** 6) + t[8:],  # IFD0 past the end
    lambda t: t[:8] + struct.pack("<H", 5000) + t[10:],  # absurd entry count
])
def test_corrupt_exif_raises_in_parse_and_never_in_read(bad, tmp_path):
    good = tiff([(exif.ORIENTATION, 3, [6])], [(exif.FOCAL_35MM, 3, [26])])
    data = jpeg(bad(good))
    with pytest.raises(ValueError):
        exif.parse_exif(data)
    path = tmp_path / "bad photo.jpg"
    path.write_bytes(data)
    got, problem = exif.read_photo_exif(path)
    assert got is None
    assert problem.startswith("bad photo.jpg: EXIF not read") and "\n" not in problem


def test_a_segment_running_past_the_end_is_an_error():
    data = jpeg(tiff([(exif.ORIENTATION, 3, [3])]))
    with pytest.raises(ValueError, match="past the end"):
        exif.parse_exif(data[:30])


def test_read_photo_exif_of_a_missing_file_names_it(tmp_path):
    got, problem = exif.read_photo_exif(tmp_path / "gone.jpg")
    assert got is None and problem.startswith("gone.jpg: EXIF not read")


def test_entries_of_the_wrong_type_fall_back_or_raise_value_error():
    # orientation as a rational, no values, a unit that is a fraction: defaults
    e = exif.parse_exif(jpeg(tiff([(exif.ORIENTATION, 5, [(13, 2)])],
                                  [(exif.FOCAL_PLANE_X_RES, 5, [(720, 1)]),
                                   (exif.FOCAL_PLANE_Y_RES, 5, [(720, 1)]),
                                   (exif.FOCAL_PLANE_UNIT, 5, [(7, 2)])])))
    assert e.orientation == 1 and e.focal_plane_unit_mm == 25.4
    e = exif.parse_exif(jpeg(tiff([(exif.ORIENTATION, 3, [])])))
    assert e.orientation == 1
    # the sub-directory pointer as a rational with a zero denominator
    data = tiff([(exif.EXIF_IFD, 5, [(8, 0)])])
    with pytest.raises(ValueError, match="pointer"):
        exif.parse_exif(jpeg(data))


def test_odd_values_fall_back():
    # an orientation outside 1-8 is upright; a zero denominator is no focal length
    e = exif.parse_exif(jpeg(tiff([(exif.ORIENTATION, 3, [9])],
                                  [(exif.FOCAL_LENGTH, 5, [(50, 0)])])))
    assert e.orientation == 1 and e.focal_length_mm is None


@pytest.mark.parametrize("orientation", range(1, 9))
def test_orient_agrees_with_pillow(orientation, tmp_path):
    from PIL import Image, ImageOps

    rng = np.random.default_rng(orientation)
    stored = np.repeat(np.repeat(rng.integers(0, 256, (3, 4, 3), dtype=np.uint8), 16, 0), 16, 1)
    data = jpeg(tiff([(exif.ORIENTATION, 3, [orientation])]), pixels=stored)
    e = exif.parse_exif(data)
    assert e.orientation == orientation
    img = Image.open(io.BytesIO(data))
    as_stored = np.asarray(img)
    upright = np.asarray(ImageOps.exif_transpose(img))
    ours = exif.orient(as_stored, orientation)
    assert ours.shape == upright.shape
    assert ours.shape[1::-1] == exif.oriented_size(as_stored.shape[1::-1], orientation)
    np.testing.assert_array_equal(ours, upright)


def test_random_damage_never_raises_anything_but_value_error():
    good = jpeg(tiff([(exif.ORIENTATION, 3, [6])],
                     [(exif.FOCAL_LENGTH, 5, [(42, 10)]), (exif.FOCAL_35MM, 3, [26]),
                      (exif.FOCAL_PLANE_X_RES, 5, [(4032000, 5600)]),
                      (exif.PIXEL_X, 4, [4032])], ">"))
    start = good.index(b"Exif")
    rng = np.random.default_rng(7)
    outcomes = set()
    for _ in range(2000):
        data = bytearray(good)
        for _ in range(rng.integers(1, 6)):
            data[rng.integers(start, start + 120)] = rng.integers(0, 256)
        if rng.random() < 0.2:
            data = data[:rng.integers(0, start + 120)]
        try:
            got = exif.parse_exif(bytes(data))
        except ValueError:
            outcomes.add("error")
            continue
        outcomes.add("none" if got is None else "exif")
        if got is not None:
            assert 1 <= got.orientation <= 8
            got.lens_36mm((4032, 3024))  # whatever was read, no exception
    assert {"error", "exif"} <= outcomes
