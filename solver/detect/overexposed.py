"""How much of a detected face the photo clipped to white (overexposed). No colour is left
there: the texture shows the skin white, and the outline's colour rules cannot tell the
face's edge from a white wall. Above a share the report says so, so that the artist can
take the photo again in softer light."""

import numpy as np

from ..eyes import EYE_OPENINGS
from ..geometry import inside_polygon
from ..photo_colour import SKIN_WHITE, sample_photo

#: The report speaks of an overexposed face above this share of its skin clipped white.
#: Measured (docs/DECISIONS.md, "An overexposed face"): the rendered heads lit by a window
#: from one side 13-14 %, in the studio's soft light 0 %, james' two photos 0 %.
OVEREXPOSED_SHARE = 0.05
#: The face's skin is sampled on a grid of this many columns across its width.
GRID = 40
#: The face's outline, iBUG numbers in order: the jaw, then the brows back across.
FACE = tuple(range(1, 18)) + tuple(range(27, 17, -1))
#: What is not skin inside it: the eyes and the lips' outer line.
HOLES = (*(tuple(eye) for eye in EYE_OPENINGS), tuple(range(49, 61)))


def clipped_share(image, face):
    """The share of ``face``'s skin that ``image`` (H, W, 3) float in [0, 1] shows white
    in every channel (``photo_colour.SKIN_WHITE``): grid points inside the jaw and the
    brows (``FACE``) but in neither eye nor the lips (``HOLES``). ``face`` is a front or
    three-quarter ``DetectedFace`` (its iBUG points, px). 0.0 where no grid point falls
    on the face."""
    ibug = np.asarray(face.ibug, float)
    outline = ibug[np.array(FACE) - 1]
    lo, hi = outline.min(axis=0), outline.max(axis=0)
    step = max((hi[0] - lo[0]) / GRID, 1.0)
    u, v = np.meshgrid(np.arange(lo[0], hi[0], step), np.arange(lo[1], hi[1], step))
    grid = np.column_stack([u.ravel(), v.ravel()])
    skin = inside_polygon(grid, outline)
    for hole in HOLES:
        skin &= ~inside_polygon(grid, ibug[np.array(hole) - 1])
    h, w = image.shape[:2]
    grid = grid[skin & (grid[:, 0] >= 0) & (grid[:, 0] <= w - 1) & (grid[:, 1] >= 0)
                & (grid[:, 1] <= h - 1)]
    if not len(grid):
        return 0.0
    return float(np.mean(sample_photo(image, grid).min(axis=1) >= SKIN_WHITE))


def overexposed_note(face):
    """What the report says of a face whose skin the photo clipped white
    (``DetectedFace.clipped`` over ``OVEREXPOSED_SHARE``), a phrase, or None."""
    if face.clipped <= OVEREXPOSED_SHARE:
        return None
    return (f"{100 * face.clipped:.0f} % of the face is clipped to white (overexposed): "
            "the texture has no skin colour there and the outline may miss the face's edge; "
            "softer light or a shorter exposure keeps it")
