"""Clothes in a photo: what it shows below the chin that is not skin and reaches the
photo's bottom edge (a collar, a shirt, a jacket), and the light collar rising from there
up the neck's sides and back. The model's neck goes on under them, so
the bake would paint the shirt onto the neck; left out, the neck there gets the smooth
fill from the skin around it.

Skin is told by the rule the outline detection uses (``photo_colour.skin_like``),
against the skin of the fitted head's cheeks in the same photo. A photo without colour
(``photo_colour.has_colour``: black and white) cannot tell them: there everything from
``BELOW_CHIN_M`` under the chin down is left out.
"""

import numpy as np
import scipy.ndimage as ndi

from ..photo_colour import (
    has_colour,
    lighter_than_skin,
    lit_skin_of,
    sample_photo,
    skin_colour,
    skin_like,
)

#: Cheeks: the skin nearest the point halfway between two iBUG landmarks (nose wing and
#: jaw, per side); the skin vertices within ``CHEEK_RADIUS_M`` of it give the photo's skin
#: colour.
CHEEKS = ((32, 4), (36, 14))
CHEEK_RADIUS_M = 0.012
#: Clothes begin at least this far below the menton (the jaw's own shade stays).
BELOW_CHIN_M = 0.015
#: A collar rises above the chin's line at the neck's sides and back (a photo from the side
#: or three-quarters shows it there): from the clothes below, what is not skin and lighter
#: than the face's skin counts up to the lower of these landmarks (a jaw's shade and the
#: nape's hair are darker, so a dark collar above the line stays).
RISES_TO = ("ear_lobe_right", "ear_lobe_left")
#: Pixels the clothes are grown by: their edge against the skin is a blend of both.
GROW_PX = 2
#: Fewest cheek samples the skin colour is taken from; fewer leave the photo as it is (a
#: cheek's own colour: its share of them).
MIN_SKIN_SAMPLES = 20


def clothes_mask(model, world, camera, image, scale=(1.0, 1.0)):
    """Pixels of ``image`` (H, W, 3 or 4, floats in [0, 1]) that show clothes, (H, W)
    bool; None when the photo shows too little of the cheeks to tell skin.

    ``world`` (V, 3) is the fitted head in world space and ``camera`` its camera in this
    photo; ``scale`` (sx, sy) maps the camera's pixels to the image's (a reduced photo).
    """
    world = np.asarray(world, dtype=np.float64)
    sx, sy = scale
    to_image = np.array([sx, sy])
    skin = world[np.asarray(model.skin, dtype=np.intp)]
    inside = np.array([(world[model.landmark_vertex(f"ibug{a:02d}")]
                        + world[model.landmark_vertex(f"ibug{b:02d}")]) / 2.0
                       for a, b in CHEEKS])  # below the cheek: on the chord between them
    to_skin = np.linalg.norm(skin[:, None] - inside[None], axis=2)  # (n, 2)
    centres = skin[np.argmin(to_skin, axis=0)]  # the cheeks' surface points
    to_centres = np.linalg.norm(skin[:, None] - centres[None], axis=2)
    h, w = image.shape[:2]
    projected = camera.project(skin) * to_image  # the skin in the image, once
    on = (to_centres.min(axis=1) <= CHEEK_RADIUS_M) & (projected[:, 0] >= 0) \
        & (projected[:, 0] < w) & (projected[:, 1] >= 0) & (projected[:, 1] < h)
    if on.sum() < MIN_SKIN_SAMPLES:
        return None
    rgb = image[..., :3]
    reference = skin_colour(sample_photo(rgb, projected[on]))
    references = [reference] + _lit_cheek(rgb, projected, on, to_centres.argmin(axis=1),
                                          reference)
    chin = world[model.landmark_vertex("chin_bottom")]
    px_per_m = camera.pixels_per_metre(chin[None], to_image)[0]
    top = camera.project(chin[None])[0, 1] * sy + BELOW_CHIN_M * px_per_m
    lobes = camera.project(world[[model.landmark_vertex(n) for n in RISES_TO]])[:, 1] * sy
    # Only where the head is, from its ear lobes to the photo's bottom edge: the bake
    # samples nothing else.
    u = projected[:, 0]
    r0 = int(np.clip(np.ceil(top), 0, h))
    r1 = int(np.clip(np.ceil(lobes.max()), 0, r0))
    c0 = int(np.clip(np.floor(u.min()) - GROW_PX - 1, 0, w))
    c1 = int(np.clip(np.ceil(u.max()) + GROW_PX + 2, 0, w))
    clothes = np.zeros((h, w), bool)
    if r0 >= h or c1 <= c0:
        return clothes
    if not has_colour(reference):
        clothes[r0:, c0:c1] = True
        return clothes
    # each pixel's colour over its 3 x 3 neighbourhood: single noisy pixels tell nothing
    smooth = ndi.uniform_filter(rgb[r1:, c0:c1], size=(3, 3, 1), mode="nearest")
    # a white shirt's highlights are clipped too: below the chin no clipped colour is skin
    flat = smooth.reshape(-1, 3)
    candidate = ~np.logical_or.reduce([skin_like(flat, r, clipped=False)
                                       for r in references]).reshape(smooth.shape[:2])
    above = smooth[:r0 - r1]  # the rows a collar rises into
    candidate[:r0 - r1] &= lighter_than_skin(above.reshape(-1, 3), reference).reshape(
        above.shape[:2])
    labels, _ = ndi.label(candidate, structure=np.ones((3, 3), bool))
    bottom = np.unique(labels[-1][labels[-1] > 0])
    found = np.isin(labels, bottom)
    clothes[r1:, c0:c1] = ndi.binary_dilation(found, iterations=GROW_PX) if GROW_PX \
        else found
    return clothes


def _lit_cheek(rgb, projected, on, cheek, reference):
    """[the skin colour of the cheek in the stronger light] where it is the face's skin
    lit more (``photo_colour.lit_skin_of``: a window at one side washes that half of the
    face and neck out beyond the skin's tolerance), else []. ``projected`` (n, 2): the
    skin's pixels; ``on``: those of a cheek in the photo; ``cheek``: which cheek each is
    nearest."""
    lit = [skin_colour(sample_photo(rgb, projected[on & (cheek == k)]))
           for k in range(len(CHEEKS))
           if (on & (cheek == k)).sum() >= MIN_SKIN_SAMPLES // len(CHEEKS)]
    lit = [c for c in lit if lit_skin_of(c, reference)]
    return [max(lit, key=lambda c: c[2])] if lit else []
