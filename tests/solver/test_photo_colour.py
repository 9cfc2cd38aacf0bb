"""Colours in a photo (solver/photo_colour.py): skin told from clothes and hair, lit or
shaded, against the face's skin colour; a bilinear sample between pixels."""

import numpy as np
import pytest

from solver.photo_colour import (
    chromaticity,
    has_colour,
    highlight_like,
    lighter_than_skin,
    lit_skin_like,
    lit_skin_of,
    sample_photo,
    skin_colour,
    skin_like,
    stretched_to_white,
    white_point,
)

SKIN = (np.array([0.396, 0.323]), 0.015, 2.49, 0.10)  # the sample's face, as face_skin gives it
# the same face as the full-size render's detector gives it: a wider spread, within which
# the grey-blue shirt's chromaticity falls
SKIN_WIDE = (np.array([0.3836, 0.3288]), 0.0192, 2.607, 0.097)


def test_skin_lit_or_shaded_is_skin_and_clothes_hair_collar_are_not():
    colours = np.array([
        [0.95, 0.78, 0.69],     # the face
        [1.00, 1.00, 0.93],     # skin washed out by the light at the silhouette
        [0.45, 0.35, 0.31],     # skin in the shade under the chin
        [0.42, 0.44, 0.47],     # the sample's shirt
        [0.05, 0.04, 0.03],     # dark hair
        [0.88, 0.96, 0.91],     # a white collar
    ])
    assert skin_like(colours, SKIN).tolist() == [True, True, True, False, False, False]
    # the shirt is within the wider spread's chromaticity, but cold (more blue than red)
    assert skin_like(colours, SKIN_WIDE).tolist() == [True, True, True, False, False, False]
    # a clipped highlight has no colour left: skin, unless clipped colours are not asked
    # for (below the chin a clipped white is a shirt's, clothes.py)
    white = np.array([[1.0, 1.0, 1.0]])
    assert skin_like(white, SKIN).tolist() == [True]
    # a clipped highlight blurred a little is white still; a white collar is not so white
    blurred = np.array([[0.988, 0.988, 0.988], [0.88, 0.96, 0.91]])
    assert skin_like(blurred, SKIN).tolist() == [True, False]
    assert skin_like(white, SKIN, clipped=False).tolist() == [False]


def test_skin_in_deep_shade_is_skin_where_it_keeps_the_skin_s_colour_closely():
    # a face lit from one side (``tools.make_sample --light window``): its far side a
    # quarter as bright as the face between the keypoints, the skin's colour kept
    colour = np.array([SKIN[0][0], SKIN[0][1], 1.0 - SKIN[0].sum()])  # brightness 1
    shade = colour * SKIN[2] / np.array([[4.0], [6.0]])
    assert skin_like(shade, SKIN).tolist() == [True, False]  # darker than a fifth: not
    # as dark, but hair a little redder, a grey, or a colour off toward the shirt's: not
    hair = np.array([0.45, 0.33, 0.22]) * SKIN[2] / 4.0
    grey = np.full(3, SKIN[2] / 12.0)
    cold = np.array([0.37, 0.33, 0.30]) * SKIN[2] / 4.0
    assert skin_like(np.array([hair, grey, cold]), SKIN).tolist() == [False, False, False]
    # lit, the same colours are within the skin's wider tolerance
    assert skin_like(np.array([hair, cold]) * 2.0, SKIN).tolist() == [True, True]


# a darker face (``tools.make_sample --skin dark``, as face_skin gives it): its chromaticity
# further from white than SKIN_CHROMA
SKIN_DARK = (np.array([0.4128, 0.3176]), 0.0153, 1.285, 0.142)


def test_a_highlight_on_darker_skin_may_be_one_a_clipped_colour_off_its_way_to_white_not():
    colours = np.array([
        [1.0, 1.0, 1.0],        # the skull's highlight: clipped white
        [1.0, 0.80, 0.66],      # its rim: the skin's colour and the light's, clipped red
        [0.42, 0.29, 0.22],     # the face itself (not clipped: no highlight)
        [0.3, 0.6, 1.0],        # something clipped and blue
        [1.0, 0.95, 0.3],       # something clipped and yellow
    ])
    assert highlight_like(colours, SKIN_DARK).tolist() == [True, True, False, False, False]
    # white is too far from this skin's colour to be skin by itself (a white collar is
    # white too: the outline takes a highlight in only between skin)
    assert skin_like(colours, SKIN_DARK).tolist() == [False, True, True, False, False]
    # the light along its silhouette washes it out to a seventh of its warmth, not clipped;
    # a white collar (no warmth) and a grey-blue shirt stay out
    edge = np.array([[0.90, 0.85, 0.85], [0.88, 0.96, 0.91], [0.42, 0.44, 0.47]])
    assert skin_like(edge, SKIN_DARK).tolist() == [True, False, False]


def test_skin_lit_by_a_white_light_is_between_its_colour_and_white_clipped_or_not():
    face = np.array([0.42, 0.29, 0.22])
    lit = np.array([face + t * (1.0 - face) for t in (0.0, 0.3, 0.6, 1.0)])
    others = np.array([[0.59, 0.78, 0.47],     # a green patch behind the head
                       [0.3, 0.6, 1.0],        # something blue
                       [0.95, 0.85, 0.25]])    # something yellow, as bright as the rim
    assert lit_skin_like(lit, SKIN_DARK).all()
    assert not lit_skin_like(others, SKIN_DARK).any()
    # a highlight is such a colour, clipped
    both = np.vstack([lit, others])
    assert (highlight_like(both, SKIN_DARK)
            == lit_skin_like(both, SKIN_DARK) & (both.max(1) >= 0.99)).all()


def test_a_cheek_in_a_window_s_light_is_the_skin_lit_where_the_skin_rule_misses_it():
    shaded = skin_colour(np.array([[0.223, 0.175, 0.157]] * 5))  # the cheek in shade
    window = skin_colour(np.array([[1.0, 1.0, 0.906]] * 5))      # the other, clipped
    assert not skin_like(np.array([[1.0, 1.0, 0.906]]), shaded, clipped=False)[0]
    assert lit_skin_of(window, shaded)
    assert not lit_skin_of(shaded, window)                       # darker: not lit
    assert not lit_skin_of(skin_colour(np.array([[0.45, 0.35, 0.31]] * 5)), shaded)  # taken in
    assert not lit_skin_of(skin_colour(np.array([[0.95, 0.95, 0.95]] * 5)), shaded)  # no colour
    assert not lit_skin_of(skin_colour(np.array([[0.42, 0.44, 0.47]] * 5)), shaded)  # shirt


def test_a_white_collar_is_lighter_than_the_skin_a_shade_or_hair_is_not():
    colours = np.array([
        [0.88, 0.96, 0.91],     # a white collar
        [0.45, 0.35, 0.31],     # skin in the shade under the chin
        [0.05, 0.04, 0.03],     # dark hair
        [0.95, 0.78, 0.69],     # the face itself: no lighter than its own colour
    ])
    assert lighter_than_skin(colours, SKIN).tolist() == [True, False, False, False]


def test_the_skin_colour_is_the_samples_median_and_spread():
    colours = np.array([[0.9, 0.6, 0.5]] * 8 + [[0.2, 0.2, 0.8]])  # one blue outlier
    centre, spread, bright, warmth = skin_colour(colours)
    np.testing.assert_allclose(centre, [0.45, 0.30])
    assert spread == 0.005  # none among the eight: the least spread
    assert bright == pytest.approx(2.0) and warmth == pytest.approx(0.2)


def test_a_sample_between_pixels_is_their_blend():
    image = np.zeros((4, 4, 3))
    image[:, 2:] = 1.0  # pixels 2 and 3 of each row, centred on 2.5 and 3.5
    got = sample_photo(image, np.array([[2.0, 1.5], [2.5, 1.5], [0.0, 0.0]]))
    np.testing.assert_allclose(got, [[0.5] * 3, [1.0] * 3, [0.0] * 3])


def test_a_black_and_white_photo_has_no_colour_to_tell_skin_by():
    face = np.array([[0.95, 0.78, 0.69], [0.80, 0.62, 0.55], [0.90, 0.74, 0.66]])
    assert has_colour(skin_colour(face))
    grey = face.mean(1, keepdims=True).repeat(3, axis=1)
    assert not has_colour(skin_colour(grey))
    # skin under a cold light keeps some warmth
    assert has_colour(skin_colour(face * [0.9, 1.0, 1.05]))


def test_a_photo_s_white_is_its_brightest_per_channel_not_a_few_hot_pixels():
    image = np.full((200, 200, 3), 0.2)
    image[:40, :40] = (0.5, 0.45, 0.4)           # a white highlight under a warm cast, dark
    image[100, 100] = 1.0                         # a hot pixel
    np.testing.assert_allclose(white_point(image), [0.5, 0.45, 0.4])


def test_a_photo_is_stretched_to_its_white_its_colours_kept_unless_a_white_is_cast():
    rng = np.random.default_rng(2)
    scene = rng.uniform(0.1, 0.7, (200, 200, 3)).astype(np.float32)
    scene[:30, :30] = 1.0                                  # something white
    # darkened after the shot: back as it was
    np.testing.assert_allclose(stretched_to_white(scene * 0.5), scene, rtol=1e-3)
    # a cool cast on it: the white is white again, the rest with it
    cool = scene * np.float32([0.85, 1.0, 1.0])
    np.testing.assert_allclose(stretched_to_white(cool), scene, rtol=1e-3)
    # no white in it, its brightest things warm (skin): one factor, its colours kept
    warm = scene[30:] * np.float32([0.8, 0.62, 0.5])
    out = stretched_to_white(warm)
    np.testing.assert_allclose(out / out.max(), warm / warm.max(), rtol=1e-3)
    assert out.max() == pytest.approx(1.0, abs=0.01)
    # a photo already at full scale is the same array
    assert stretched_to_white(scene) is scene


def test_chromaticity_is_a_colour_s_hue_and_saturation_not_its_light():
    skin = np.array([1.0, 0.84, 0.73])
    np.testing.assert_allclose(chromaticity(skin), chromaticity(0.6 * skin))  # in shade
    np.testing.assert_allclose(chromaticity(np.full((2, 3), 0.5)), np.full((2, 2), 1 / 3))
    wood = np.array([0.65, 0.44, 0.26])
    assert np.linalg.norm(chromaticity(wood) - chromaticity(skin)) > 0.06
