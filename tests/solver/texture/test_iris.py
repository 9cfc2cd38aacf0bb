"""The irises' colour read off the photos (solver/texture/iris.py): the colour painted in
the iris of a photo of the mean head, its highlight and pupil left out; nothing from a
profile, from closed eyes or off the photo; and the rendered sample's blue-grey eyes."""

from types import SimpleNamespace

import numpy as np
import pytest
from PIL import Image

from solver.cameras import OrthographicCamera
from solver.eyes import IRIS_RADIUS, IRIS_RANGES, PUPIL_RADIUS
from solver.texture.iris import MIN_SAMPLES, eye_openings, iris_colour, iris_samples

BROWN = np.array([0.42, 0.26, 0.14])
SKIN = np.array([0.80, 0.62, 0.52])


def _photo(model, vertices, view="orthographic-front", w=600, h=800):
    """A photo (h, w, 3) float of a head whose irises, seen from the front, are brown with
    a black pupil and a white highlight, over skin; and its camera."""
    cam = OrthographicCamera.nominal(view, (w, h))
    img = np.tile(SKIN, (h, w, 1))
    v, u = np.mgrid[0:h, 0:w] + 0.5
    for i0, i1 in IRIS_RANGES:
        cu, cv = OrthographicCamera.nominal("orthographic-front", (w, h)).project(
            vertices[i0:i1 + 1].mean(axis=0)[None])[0]
        r = np.hypot(u - cu, v - cv) / cam.scale
        img[r < IRIS_RADIUS] = BROWN
        img[r < PUPIL_RADIUS] = 0.02
        img[np.hypot(u - cu - 0.002 * cam.scale, v - cv + 0.002 * cam.scale)
            < 0.0008 * cam.scale] = 1.0
    return img, cam


def _result(vertices, cameras):
    return SimpleNamespace(local_vertices=vertices, world_vertices=vertices, cameras=cameras)


def test_the_iris_colour_is_read_where_the_lids_leave_it_open(model):
    img, cam = _photo(model, model.vertices)
    colour = iris_colour(model, _result(model.vertices, {"front": cam}), {"front": img})
    np.testing.assert_allclose(colour, BROWN, atol=0.02)
    # uint8 photos read as [0, 1]
    as_bytes = np.round(img * 255).astype(np.uint8)
    again = iris_colour(model, _result(model.vertices, {"front": cam}), {"front": as_bytes})
    np.testing.assert_allclose(again, BROWN, atol=0.02)
    # the lids hide part of the iris: fewer points are seen than lie on the ring
    seen = iris_samples(model, model.vertices, model.vertices, cam, img)
    assert MIN_SAMPLES <= len(seen) < 230


def test_no_colour_from_a_profile_closed_eyes_or_eyes_off_the_photo(model):
    img, cam = _photo(model, model.vertices)
    side = OrthographicCamera.nominal("orthographic-right", cam.size)
    assert iris_colour(model, _result(model.vertices, {"right": side}), {"right": img}) is None
    names = list(model.expression_names)
    shut = model.vertices + sum(model.expressions[names.index(n)]
                                for n in ("eyeBlink_L", "eyeBlink_R"))
    assert len(iris_samples(model, shut, shut, cam, img)) < MIN_SAMPLES
    assert iris_colour(model, _result(shut, {"front": cam}), {"front": img}) is None
    away = OrthographicCamera(cam.rotation, cam.scale, cam.offset + [0.0, 700.0], cam.size,
                              cam.view)
    assert iris_colour(model, _result(model.vertices, {"front": away}), {"front": img}) is None


def test_the_rendered_sample_s_eyes_read_blue_grey(sample, model):
    from solver import fit_head, load_landmarks

    folder, _ = sample
    case = load_landmarks(folder / "sample.json", known_names=model)
    result = fit_head(model, case)
    photos = {v: np.asarray(Image.open(folder / case.views[v].image).convert("RGB"))
              for v in case.views}
    colour = iris_colour(model, result, photos)
    if colour is None:
        pytest.fail("no iris colour read off the rendered sample")
    # the sample's eye material: a blue-grey iris, lighter than the pupil, not the skin's
    assert colour[2] > colour[0] + 0.04 and 0.2 < colour.mean() < 0.85, colour


def test_eye_openings_are_found_under_either_name_of_the_eye_landmarks(model):
    lms = model.landmark_set
    names = {n: lms.canonical(f"ibug{n:02d}") for n in range(37, 49)}
    px = {n: (100.0 + 10 * (n % 6), 200.0 + 7 * (n // 43)) for n in names}
    canonical = SimpleNamespace(points={names[n]: p for n, p in px.items()})
    aliased = SimpleNamespace(points={f"ibug{n:02d}": p for n, p in px.items()})
    a, b = eye_openings(model, canonical), eye_openings(model, aliased)
    assert a.shape == (2, 6, 2)
    np.testing.assert_array_equal(a, b)
    one_eye = SimpleNamespace(points={f"ibug{n:02d}": p for n, p in px.items() if n < 43})
    assert eye_openings(model, one_eye).shape == (1, 6, 2)
