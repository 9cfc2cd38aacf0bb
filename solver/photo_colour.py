"""Colours in a photo: bilinear samples, and whether a colour is the face's skin (the rule
the outline detection ends the head's outline by, ``detect/outline.py``, and the bake
leaves clothes out by, ``texture/clothes.py``; measured in docs/DECISIONS.md, "The
head's outline" and "Clothes end the outline: skin is warm").
"""

import numpy as np

#: A point's colour counts as skin within these bounds of the face's: chromaticity
#: distance in robust spreads of the face's, but at least ``SKIN_CHROMA`` (light at a
#: silhouette washes skin out toward white: 0.06 on the sample's neck and skull, where
#: its shirt is 0.085-0.09 away and james' white collar 0.096-0.13); brightness within a
#: factor (the shade under the sample's chin is 0.43 of the face's, james' dark hair
#: 0.01-0.25).
SKIN_SPREADS = 4.0
SKIN_CHROMA = 0.075
SKIN_BRIGHTNESS = 3.0
#: Skin is warm: its red share exceeds its blue share by at least this fraction of the
#: face's own excess (the sample's face 0.09-0.10, its shade under the ear 0.12, skin
#: washed out by the light 0.02, on darker skin 0.15-0.19 of the face's; its grey-blue
#: shirt -0.04 to -0.06 and a white collar -0.01, both within ``SKIN_CHROMA`` of the
#: face), unless a channel is clipped (a highlight on the skull is plain white: no colour
#: is left to tell; docs/DECISIONS.md, "Darker skin").
SKIN_WARMTH = 0.1
#: Skin in shade (a face lit from one side, by a window: its far side 0.2-0.33 of the face's
#: brightness between the keypoints, which the lit side sets) is darker than
#: ``SKIN_BRIGHTNESS`` allows but keeps the skin's colour closely: down to 1 /
#: ``SHADE_BRIGHTNESS`` of the face's brightness a colour is skin where its chromaticity
#: lies within ``SHADE_CHROMA`` of the face's and its warmth is at least ``SHADE_WARMTH``
#: of the face's (docs/DECISIONS.md, "A face lit from one side").
SHADE_BRIGHTNESS = 5.0
SHADE_CHROMA = 0.025
SHADE_WARMTH = 0.5
SKIN_CLIPPED = 0.99
#: A colour this near white in every channel is a highlight too (a clipped one a little
#: blurred: 0.988 on the sample's skull under a 2 px blur; a white collar in the light
#: 0.88-0.96).
SKIN_WHITE = 0.97
#: A photo whose face's skin is less warm than this has no colour to tell skin by (a
#: black-and-white photo: 0; the rendered faces 0.09-0.12, james 0.19-0.20).
MIN_COLOUR = 0.02
#: A photo is stretched to its own white by at most this factor (a photo of the night);
#: a channel whose white is this near full scale is left as it is; and one channel is
#: stretched at most ``MAX_CAST`` times more than another.
MAX_STRETCH = 10.0
NEAR_WHITE = 0.98
MAX_CAST = 1.5


def sample_photo(image, uv):
    """Bilinear colours of ``image`` (H, W, C) at continuous photo points ``uv``
    (..., 2), the photo's border extended."""
    h, w = image.shape[:2]
    x = np.clip(uv[..., 0] - 0.5, 0, w - 1)
    y = np.clip(uv[..., 1] - 0.5, 0, h - 1)
    x0 = np.minimum(np.floor(x).astype(int), w - 2)
    y0 = np.minimum(np.floor(y).astype(int), h - 2)
    fx, fy = (x - x0)[..., None], (y - y0)[..., None]
    return ((image[y0, x0] * (1 - fx) + image[y0, x0 + 1] * fx) * (1 - fy)
            + (image[y0 + 1, x0] * (1 - fx) + image[y0 + 1, x0 + 1] * fx) * fy)


def chromaticity(colours):
    """The red and green shares of each colour's sum (..., 2) of colours (..., 3): its hue
    and saturation, not its light."""
    return _chroma_brightness(colours)[0]


def _chroma_brightness(colours):
    total = np.maximum(colours.sum(-1), 1e-3)
    return colours[..., :2] / total[..., None], total


def _warmth(colours):
    """Red share less blue share (n,) of colours (n, 3)."""
    return (colours[..., 0] - colours[..., 2]) / np.maximum(colours.sum(-1), 1e-3)


def skin_colour(colours):
    """The skin colour :func:`skin_like` compares with, from samples (n, 3) of skin:
    (median chromaticity (2,), its robust spread, median brightness, median warmth), as
    ``detect.outline.face_skin`` returns it."""
    chroma, bright = _chroma_brightness(colours)
    centre = np.median(chroma, axis=0)
    spread = 1.4826 * np.median(np.linalg.norm(chroma - centre, axis=1))
    return (centre, max(float(spread), 0.005), float(np.median(bright)),
            float(np.median(_warmth(colours))))


def has_colour(skin):
    """Whether the face's skin (:func:`skin_colour`) has a colour :func:`skin_like` can
    tell skin from clothes and hair by (``MIN_COLOUR``)."""
    return skin[3] >= MIN_COLOUR


def lit_skin_of(lit, skin):
    """Whether the skin colour ``lit`` (:func:`skin_colour`, e.g. of one cheek) is ``skin``
    in a stronger light that :func:`skin_like` does not take in: brighter, with a colour
    to tell (``MIN_COLOUR``), its chromaticity within the tolerance of ``skin``'s, and its
    median colour not ``skin_like`` (a window's light washes the lit cheek out toward
    white, clips it, and makes it five times the shaded one's brightness)."""
    chroma, bright = lit[0], lit[2]
    median = np.append(chroma, 1.0 - chroma.sum()) * bright
    return bright > skin[2] and has_colour(lit) \
        and float(np.linalg.norm(chroma - skin[0])) <= _chroma_tolerance(skin[1]) \
        and not skin_like(median[None], skin, clipped=False)[0]


def lighter_than_skin(colours, skin):
    """Whether each colour (n, 3) is brighter than the face's skin (:func:`skin_colour`):
    what a white or light collar is, and a jaw's shade or dark hair is not."""
    return _chroma_brightness(colours)[1] > skin[2]


def white_point(image):
    """The photo's white (3,): the brightest value each channel reaches over the photo (H,
    W, 3 or more) floats, its 99.9th percentile (a few hot pixels do not set it). Clipped
    highlights and white things are white in the scene: a photo darkened after it was
    taken has its white below 1 in every channel, one with a colour cast in some."""
    return np.percentile(image[::4, ::4, :3].reshape(-1, 3), 99.9, axis=0)


def stretched_to_white(image):
    """``image`` (H, W, 3) float32 in [0, 1] stretched to its white (:func:`white_point`),
    as it was shot (docs/DECISIONS.md, "Photos as users give them, measured"). Where some
    channel reaches full scale (a white thing, a clipped highlight), the others are
    stretched to it: a colour cast taken out. Where none does (a photo darkened, or one
    whose brightest things are coloured, such as skin), all by one factor: its colours
    kept."""
    white = np.maximum(white_point(image), 1.0 / MAX_STRETCH)
    if white.max() < NEAR_WHITE:
        white = np.full(3, white.max())
    else:
        white = np.where(white >= NEAR_WHITE, 1.0, np.maximum(white, white.max() / MAX_CAST))
    if (white >= 1.0).all():
        return image
    out = image * (1.0 / white).astype(np.float32)
    return np.minimum(out, 1.0, out=out)


def skin_like(colours, skin, clipped=True):
    """Whether each colour (n, 3) is the face's skin (:func:`skin_colour`) in chromaticity
    (within ``SKIN_SPREADS``, at least ``SKIN_CHROMA``), brightness (within a factor
    ``SKIN_BRIGHTNESS``) and warmth (``SKIN_WARMTH``, or with ``clipped`` a channel at
    ``SKIN_CLIPPED`` or all at ``SKIN_WHITE``: a highlight has no colour left to tell); or
    in shade, darker, where its colour is the skin's more closely (``SHADE_BRIGHTNESS``)."""
    centre, spread, bright, warmth = skin
    chroma, b = _chroma_brightness(colours)
    off = np.linalg.norm(chroma - centre, axis=1)
    heat = _warmth(colours)
    warm = heat >= SKIN_WARMTH * warmth
    if clipped:
        warm |= _clipped(colours)
    lit = (off <= _chroma_tolerance(spread)) & warm & (b >= bright / SKIN_BRIGHTNESS)
    shade = (off <= SHADE_CHROMA) & (heat >= SHADE_WARMTH * warmth) \
        & (b >= bright / SHADE_BRIGHTNESS)
    return (lit | shade) & (b <= bright * SKIN_BRIGHTNESS)


def highlight_like(colours, skin):
    """Whether each colour (n, 3) may be a highlight on the face's skin (:func:`skin_colour`):
    clipped (a channel at ``SKIN_CLIPPED`` or all at ``SKIN_WHITE``) and :func:`lit_skin_like`,
    at any brightness. On darker skin a highlight is further from the skin's colour than
    ``SKIN_CHROMA``, so :func:`skin_like` cannot take it in; a clipped white thing (a
    collar) is such a colour too, so only where skin lies on either side of it is it skin
    (``detect.outline``)."""
    return _clipped(colours) & lit_skin_like(colours, skin)


def lit_skin_like(colours, skin):
    """Whether each colour (n, 3) has a chromaticity between the face's skin's
    (:func:`skin_colour`) and white, within the tolerance of :func:`skin_like`: the skin's
    colour plus a white light's, as on a highlight or a rim of light along its edge."""
    centre, spread = skin[0], skin[1]
    chroma, _ = _chroma_brightness(colours)
    towards = np.full(2, 1.0 / 3.0) - centre
    t = np.clip((chroma - centre) @ towards / max(float(towards @ towards), 1e-12), 0.0, 1.0)
    off = np.linalg.norm(chroma - centre - t[:, None] * towards, axis=1)
    return off <= _chroma_tolerance(spread)


def _chroma_tolerance(spread):
    """How far from the face's chromaticity a colour may lie (``SKIN_SPREADS`` of its
    ``spread``, at least ``SKIN_CHROMA``)."""
    return max(SKIN_SPREADS * spread, SKIN_CHROMA)


def _clipped(colours):
    return (colours.max(-1) >= SKIN_CLIPPED) | (colours.min(-1) >= SKIN_WHITE)
