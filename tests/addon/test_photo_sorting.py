"""Several photos sorted into views (headrecon_addon/photo_sorting.py): by file name, by
the detector's hook, then by shape."""

import pytest

from headrecon_addon.photo_sorting import (
    FRONT,
    LEFT,
    RIGHT,
    direction_from_name,
    sort_photos,
)


def test_names_say_the_direction():
    assert direction_from_name("IMG_0042_profile_left.jpg") == LEFT
    assert direction_from_name("anna-Side.JPG") == RIGHT
    assert direction_from_name("anna_right.png") == RIGHT
    assert direction_from_name("Front.jpeg") == FRONT
    assert direction_from_name("IMG_0042.jpg") is None
    assert direction_from_name("inside.jpg") is None  # whole words only


def test_shapes_give_the_front_and_the_profile():
    # unnamed: the narrowest is the front, the widest the profile, others fronts
    photos = [("a.jpg", (1000, 1000)), ("b.jpg", (800, 1000)), ("c.jpg", (1200, 1000))]
    assert sort_photos(photos) == [FRONT, FRONT, RIGHT]
    # alike: the first is the front
    assert sort_photos([("a.jpg", (600, 800)), ("b.jpg", (600, 800))]) == [FRONT, RIGHT]
    # a name wins over the shape
    assert sort_photos([("front.jpg", (1200, 800)), ("b.jpg", (600, 800))]) == [FRONT, RIGHT]
    assert sort_photos([("left.jpg", (1200, 800)), ("b.jpg", (1300, 800))]) == [LEFT, FRONT]


def test_what_the_scene_has_is_not_asked_for_again():
    assert sort_photos([("a.jpg", (1200, 800))], taken={FRONT}) == [RIGHT]
    assert sort_photos([("a.jpg", (600, 800))], taken={LEFT}) == [FRONT]
    assert sort_photos([("a.jpg", (1200, 800))], taken={FRONT, RIGHT}) == [FRONT]
    assert sort_photos([]) == []


def test_the_detector_hook_decides_before_the_shape():
    asked = []

    def face(i):
        asked.append(i)
        return LEFT if i == 1 else None

    photos = [("front.jpg", (600, 800)), ("b.jpg", (600, 800)), ("c.jpg", (700, 800))]
    assert sort_photos(photos, face_direction=face) == [FRONT, LEFT, FRONT]
    assert asked == [1, 2]  # never for a photo its name places
    with pytest.raises(ValueError, match="face_direction"):
        sort_photos([("b.jpg", (600, 800))], face_direction=lambda i: "up")
