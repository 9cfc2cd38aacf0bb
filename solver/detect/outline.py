"""The head's outline in a photo, as the fit wants a traced contour: the person's
segmentation's edge, moved onto the colour edge in the photo itself, and only the stretch
of skin that holds the face (hair and clothes cut off, the photo's border left out).

Steps (numbers in docs/DECISIONS.md, "The head's outline"):

1. the selfie segmentation (``segmentation.person_mask``) on a square around the face
   (turned upright with a face that leans in the photo: ``upright_angle``; a larger one
   where the head reaches its side or top), its 0.5 iso-line
   (``iso_line``) around the face: 1.2-1.7 px (median) from the true silhouette on the
   rendered photos, its map's pixel 3.4-3.8 photo pixels; what it took in of a busy
   background (many colours, changing every few pixels) taken out of it
   (``busy_background``);
2. each point moved along the outline's normal to where the photo's colour crosses
   halfway between the colours inside and outside (sub-pixel, on the photo itself; a
   rim of light along darker skin's edge is inside the edge, not the edge, and a band
   of light wider than that search, which the segmentation leaves out, is followed out
   to the background: ``wide_rim``);
   where a long stretch of it is straight, the segmentation took in something behind
   the head (a door, a frame: ``straight_stretches``), and what it took in of that
   thing's colour is taken out of the mask and the outline found again
   (``without_leaks``);
3. the colour just inside each point against the face's skin (sampled between the
   detector's keypoints: eyes, nose, mouth, ears): the outline is the run of skin that
   holds the face's front (the nose tip; a clipped highlight counts where skin lies on
   either side of it), so hair (on the forehead, the crown, the nape)
   and the collar or clothes below the neck end it; the photo's border and the segmented
   square's do not (nothing is seen beyond them): the outline goes on past them, the
   points there left out;
4. on a photo without colour (black and white), where skin cannot be told from clothes,
   the outline ends under the chin (``NECK_CUT``), is the face's run alone, and the fit
   gets only the points moved onto the photo's edge (``Outline.contour``);
5. an outline the segmentation is unsure of over most of it (``UNSURE_REFUSE``) is none,
   and so is a three-quarter view's that shows the face's side alone (``over_the_head``).
"""

from dataclasses import dataclass, field, replace

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from ..eyes import EYE_OPENINGS
from ..geometry import distance_to_segments, inside_polygon
from ..photo_colour import (
    chromaticity,
    has_colour,
    highlight_like,
    lit_skin_like,
    sample_photo,
    skin_colour,
    skin_like,
)
from .busy_background import without_busy_background
from .crop import Square
from .face_landmarks import eye_line_angle
from .iso_line import iso_lines
from .profile_line import MAX_TURN_DEG
from .segmentation import person_mask
from .view_guess import guess_view

#: Outline points every this many photo pixels (the fit weighs points by the outline
#: length they stand for, ``solver.io.contour.SPACING_PX``, so denser is not heavier).
SPACING_PX = 3.0
#: The square the segmentation sees: this many times the detector's box, centred on it.
SQUARE_SCALE = 2.5
#: Where the person reaches that square's side or top above the mouth (a profile's skull,
#: a head turned in the photo), it is segmented once more in one this many times larger,
#: moved toward that side by ``REGROW_SHIFT`` of the first one's size.
REGROW = 1.4
REGROW_SHIFT = 0.2
#: How far along the normal the photo's colour edge is looked for: this many map pixels
#: (the mask's own error, 1-2 px median, up to about 3 px, is under one map pixel of 3-4 px).
SEARCH_MAP_PX = 1.5
#: A rim of light along the edge (darker skin lit from the side, brighter than the
#: background): the outermost step along the normal (a colour change over ``STEP_PX``
#: photo pixels, a local peak at least ``STEP_SHARE`` of the largest) that falls from the
#: skin's colour lit, brighter than both the background and the skin further in. The rim
#: rises from the skin more steeply than it falls to the background (docs/DECISIONS.md,
#: "Darker skin").
STEP_PX = 1.0
STEP_SHARE = 0.5
#: A rim wider than the search (a face lit from the side: a clipped band up to 20 px wide
#: along a profile's forehead and nose, to which the segmentation gives a person
#: probability of 0.2-0.6, so its edge runs along the band's inner side): looked for as far
#: as this many map pixels out, taken where the segmentation's mean probability over it is
#: at least ``WIDE_RIM_P`` (past a head's edge on a plain wall it falls to 0 within a map
#: pixel or two) and it is brighter than the skin inside and the colour past it by
#: ``RIM_STEP`` (the sum of the three channels, in [0, 1] each; docs/DECISIONS.md, "A face
#: lit from one side").
WIDE_RIM_MAP_PX = 6.0
WIDE_RIM_P = 0.05
RIM_STEP = 0.15
#: ... and only along this many outline points in a row at least (``SPACING_PX`` apart:
#: 18 px), as a band of light runs along the edge (on the studio-lit renders a few points
#: alone, 2-6 a photo on a third of the profiles, had been moved).
WIDE_RIM_RUN = 6
#: The outline found must be at least this many times the face's size (the detector's
#: box) long: on james' front photo the only skin on the person's edge is a strip of neck
#: between hair and collar.
MIN_LENGTH = 1.0
#: Along the outline, a stretch shorter than this fraction of the face's size does not
#: cut the skin run (the lips' red on a profile: 30-40 px of james' 346-px face; a
#: highlight) and does not make one.
MIN_STRETCH = 0.12
#: Other runs of skin on the person's outline than the face's front's are kept where they
#: come this many face sizes near the face's centre: its other side, where hair on the
#: crown parts the two (a front photo). The front's run alone must be ``MIN_LENGTH`` long.
#: On a photo without colour no other run is kept: nothing tells it is skin (a white
#: collar, the neck behind a three-quarter face's ear).
NEAR_FACE = 1.0
#: A three-quarter view within ``SIDE_ONLY_YAW_DEG`` of the front (its guessed yaw) has
#: an outline only where it goes over the head: its points more than ``OVER_HEAD_HEIGHT``
#: eye-to-mouth distances above the eyes span ``OVER_HEAD_SPAN`` of the face's width
#: across it (rendered bald heads at 26-57 degrees: 0.82-1.41; with hair, and james' real
#: photos: 0.02 at most). The far cheek's side alone, with hair around it, took the fit
#: further from the truth there, on james and on rendered and out-of-model heads; farther
#: round (rendered heads with hair, read at 48-57 degrees) it brought the fit nearer
#: (docs/DECISIONS.md, "A three-quarter view's outline of the face's side alone").
OVER_HEAD_HEIGHT = 0.8
OVER_HEAD_SPAN = 0.5
SIDE_ONLY_YAW_DEG = 40.0
#: Outline points within an eye's contour or this close to it (fraction of the face's
#: size) are left out (``by_the_eyes``): on heads photographed 45 degrees round, the far
#: eye's cornea lies on the face's outline (docs/DECISIONS.md, "The far eye on a
#: three-quarter outline"; 0.03 left out more of the skin beside it).
EYE_MARGIN = 0.01
#: On a photo without colour (``photo_colour.has_colour``: black and white), where skin
#: cannot be told from clothes, the outline ends this many eye-to-mouth distances below
#: the mouth (along the line from the eyes to the mouth): about 2 cm under the chin.
NECK_CUT = 1.0
#: A stretch of the outline this many face sizes long that stays within ``STRAIGHT_TOL``
#: face sizes of a straight line is the edge of something behind the head (a door, a
#: frame, a shelf) that the segmentation took in: no head's outline is that straight
#: (docs/DECISIONS.md, "A straight edge beside the head") ...
STRAIGHT_LONG = 0.6
STRAIGHT_TOL = 0.0025
#: ... or within this many where the thing's colour is not the skin's (its chromaticity
#: at least ``LEAK_CHROMA`` from the face's): a wooden door's grain moves its edge by about
#: a pixel, while a skull's shaded back, as straight at this tolerance on some heads, is
#: the skin's colour.
STRAIGHT_TOL_COLOURED = 0.005
LEAK_CHROMA = 0.06
#: ... where it comes this many face sizes near the face's centre (farther off, the body
#: cut straight by the edge of a photo within the photo: a turned or a framed one).
STRAIGHT_NEAR = 1.0
#: What of that thing the segmentation took in is looked for within this many face
#: sizes of the straight stretch.
LEAK_REACH = 1.0
#: ... and is the map's pixels of its colour: within this many times its spread along the
#: straight stretch (at least ``LEAK_COLOUR``, RGB in [0, 1]) and nearer it than the
#: face's skin.
LEAK_SPREADS = 3.0
LEAK_COLOUR = 0.06
#: The segmentation is sure of the person's edge at an outline point where its person
#: probability ``SURE_REACH`` map pixels inside the point is at least ``SURE_P`` and as far
#: outside at most 1 - ``SURE_P`` ...
SURE_REACH = 3.0
SURE_P = 0.9
#: ... and where more than this share of the outline kept is not, it may have run into
#: the scene (a busy background, a door of the skin's colour): a warning asks for a check.
#: Measured on the rendered heads' photos: up to 2 % before a plain wall, 10 % in a room,
#: with hair, a beard or glasses, 23 % with a wooden door, 65 % on confetti
#: (docs/DECISIONS.md, "A busy background").
UNSURE_SHARE = 0.15
#: Where the segmentation is unsure of more than this share, the outline is none: on a black
#: and white photo with hair it ran across the face and the profile's points were read off
#: it (a head fitted 9.5 mm from the truth; docs/DECISIONS.md, "An outline the segmentation
#: is unsure of, a profile's rough nose keypoint, a grey photo's other runs").
UNSURE_REFUSE = 0.5


@dataclass
class Outline:
    """A head's outline found in a photo.

    Attributes
    ----------
    points : ndarray (n, 2)
        (u, v) photo pixels (continuous: pixel (r, c) covers [c, c + 1) × [r, r + 1)),
        in drawing order from the chin's side (on a profile: from the front of the neck
        over the chin, the face, the forehead and the skull toward the nape); where the
        photo's border cuts the head, the points beyond it are left out (a jump).
    refined : ndarray (n,) bool
        Moved onto a colour edge in the photo (else left on the segmentation's edge: too
        little contrast there).
    notes : list of str
        What ended the outline at each end ("hair, clothes or background", "the photo's
        border") and other facts for the report.
    colour : bool
        The photo has colour (``photo_colour.has_colour``).
    warnings : list of str
        What the user should check on this outline: a thing behind the head that the
        segmentation took in, left out of it (``without_leaks``); a busy background it
        took in, left out too (``busy_background``); an outline the
        segmentation is unsure of (``UNSURE_SHARE``).
    unsure : float
        The share of the points where the segmentation is unsure of the person's edge
        (:func:`edge_sure`).
    """

    points: np.ndarray
    refined: np.ndarray
    notes: list = field(default_factory=list)
    colour: bool = True
    warnings: list = field(default_factory=list)
    unsure: float = 0.0

    @property
    def contour(self):
        """The points the fit gets as the view's contour (n, 2) px: all of them; on a
        photo without colour only those moved onto its edge (the segmentation's own edge,
        where they stay, lies 7-9 px off there: docs/DECISIONS.md, "Photos as users give
        them, measured"). The profile line is read off all of them (``points``)."""
        return self.points if self.colour else self.points[self.refined]


def _closed_resample(points, spacing):
    """A closed polygon resampled every ``spacing`` along its length."""
    p = np.vstack([points, points[:1]])
    seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    n = max(int(s[-1] / spacing), 8)
    t = np.arange(n) * (s[-1] / n)
    return np.stack([np.interp(t, s, p[:, 0]), np.interp(t, s, p[:, 1])], axis=1)


def _normals(points, reach=2):
    """Outward unit normals of a closed polygon that runs clockwise on screen."""
    t = np.roll(points, -reach, axis=0) - np.roll(points, reach, axis=0)
    n = np.stack([t[:, 1], -t[:, 0]], axis=1)
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)


def refine_edge(image, points, normals, reach, passes=2, skin=None, rim=None):
    """Each point moved along its outward normal to where the photo's colour crosses
    halfway from the colour inside (the inner third of the search) to the colour outside
    (the outer third), the crossing nearest the point; then once more from there
    (``passes``), so an edge far from the point does not tint the colour taken as the
    other side's. With the face's ``skin`` colour (``photo_colour.skin_colour``), where a
    rim of light runs along the edge (:func:`_rim`), the colour inside is the rim's and
    the crossing the one nearest its outer step: the skin's further in would hold the
    crossing inside the rim.

    Parameters
    ----------
    image : ndarray (H, W, 3) float in [0, 1]
    points, normals : ndarray (n, 2)
    reach : float
        The search runs from -reach to +reach photo pixels along the normal.
    passes : int
    skin : tuple, optional
    rim : ndarray (n,) bool, optional
        Where a rim may be looked for (default everywhere): where the segmentation is sure
        of the person's edge (:func:`edge_sure`); where it is not, a bright colour past the
        edge may be the background's (a busy one).

    Returns
    -------
    points : ndarray (n, 2)
        Moved, or as given where no crossing is found or inside and outside differ by
        less than 0.05 (in [0, 1] RGB).
    refined : ndarray (n,) bool
    inside : ndarray (n, 3)
        The colour inside the outline (the mean of the search's inner third): what the
        skin test reads.
    """
    moved, ok, inside = _edge_pass(image, points, normals, reach, skin, rim)
    for _ in range(passes - 1):
        again, ok2, inside2 = _edge_pass(image, moved, normals, reach, skin, rim)
        moved = np.where((ok & ok2)[:, None], again, moved)
        inside = np.where(ok[:, None], inside2, inside)
    return moved, ok, inside


def _rim(col, inner, outside, skin, w, where=None):
    """Where a rim of light runs along the edge in the colours ``col`` (n, k, 3) sampled
    along each normal (of the points ``where`` (n,) bool, default all): the outermost
    strong step (a colour change over ``w`` samples, a local peak at least ``STEP_SHARE``
    of the largest) falls from a colour brighter than both the background (``outside``
    (n, 3)) and the colour further in (``inner``, which is the skin: a beard's edge has no
    rim), and that colour is the skin's lit (``lit_skin_like``: a bright patch of a busy
    background is not). Returns (rim (n,) bool, the step's first sample (n,)); no rim
    without ``skin``."""
    n = len(col)
    if skin is None:
        return np.zeros(n, bool), np.zeros(n, np.intp)
    change = np.linalg.norm(col[:, w:] - col[:, :-w], axis=2)   # (n, k - w)
    padded = np.pad(change, ((0, 0), (1, 1)), constant_values=-1.0)
    peak = (change >= padded[:, :-2]) & (change >= padded[:, 2:]) \
        & (change >= STEP_SHARE * change.max(axis=1, keepdims=True))
    outer = change.shape[1] - 1 - np.argmax(peak[:, ::-1], axis=1)
    lit = col[np.arange(n), outer]
    bright = lit.sum(1)
    rim = (bright > outside.sum(1)) & (bright > inner.sum(1)) & lit_skin_like(lit, skin) \
        & skin_like(inner, skin)
    return (rim if where is None else rim & where), outer


def _edge_pass(image, points, normals, reach, skin=None, where=None):
    per_px = 4                                                 # samples per photo pixel
    steps = np.linspace(-reach, reach, int(np.ceil(per_px * reach)) + 1)
    uv = points[:, None, :] + steps[None, :, None] * normals[:, None, :]
    col = sample_photo(image, uv)                              # (n, k, 3)
    k, rows = len(steps), np.arange(len(points))
    third = max(k // 3, 1)
    inner, outside = col[:, :third].mean(1), col[:, -third:].mean(1)
    w = max(int(round(STEP_PX * per_px)), 1)
    rim, outer = _rim(col, inner, outside, skin, w, where)
    # the colour inside: the rim's own there, else the inner third's
    diff = np.where(rim[:, None], col[rows, outer], inner) - outside
    contrast = np.linalg.norm(diff, axis=1)
    s = ((col - outside[:, None]) * diff[:, None]).sum(2) / np.maximum(contrast, 1e-9)[:, None] ** 2
    above = s >= 0.5
    cross = above[:, :-1] != above[:, 1:]                      # (n, k - 1)
    mid = (steps[:-1] + steps[1:]) / 2
    # the crossing nearest the rim's step, else nearest the point
    near = np.where(rim, (steps[outer] + steps[outer + w]) / 2, 0.0)
    dist = np.where(cross, np.abs(mid[None] - near[:, None]), np.inf)
    j = np.argmin(dist, axis=1)
    ok = np.isfinite(dist[rows, j]) & (np.linalg.norm(inner - outside, axis=1) >= 0.05)
    s0, s1 = s[rows, j], s[rows, j + 1]
    frac = np.clip((0.5 - s0) / np.where(s1 != s0, s1 - s0, 1.0), 0, 1)
    t = steps[j] + frac * (steps[j + 1] - steps[j])
    moved = np.where(ok[:, None], points + t[:, None] * normals, points)
    return moved, ok, inner


def between_keypoints(face, pairs):
    """Points on the middle half of the lines between the detector's keypoints of
    ``face`` (``pairs`` of indices into ``face_detection.KEYPOINTS``), nine per line,
    (9 len(pairs), 2) px: where the face's skin is sampled."""
    k = np.asarray(face.keypoints, float)
    t = np.linspace(0.25, 0.75, 9)[:, None]
    return np.concatenate([k[a] + t * (k[b] - k[a]) for a, b in pairs])


def face_skin(image, face, mask):
    """The face's skin colour: samples on the lines between the detector's keypoints
    (eye-mouth, nose-mouth, mouth-ear, eye-ear: cheeks and jaw), those inside the person.

    Returns
    -------
    chroma : ndarray (2,)
        Median r, g chromaticity (r / (r+g+b), g / (r+g+b)).
    spread : float
        Robust spread of the chromaticity (1.4826 × the median absolute deviation, at
        least 0.005).
    brightness : float
        Median r + g + b.
    warmth : float
        Median red share less blue share ((r - b) / (r + g + b)).
    """
    return skin_colour(_skin_samples(image, face, mask))


def _skin_samples(image, face, mask):
    """The photo's colours (m, 3) where :func:`face_skin` samples the face's skin."""
    pairs = [(0, 3), (1, 3), (2, 3), (3, 4), (3, 5), (0, 4), (1, 5), (2, 4), (2, 5)]
    pts = between_keypoints(face, pairs)
    pts = pts[mask.at(pts) >= 0.5]
    if len(pts) < 5:
        raise ValueError("no skin sampled between the face's keypoints")
    return sample_photo(image, pts)


def _runs(flags):
    """(start, end) index pairs (end exclusive, may pass n: cyclic) of the runs of True in
    a cyclic boolean array."""
    n = len(flags)
    if flags.all():
        return [(0, n)]
    shift = int(np.flatnonzero(~flags)[0])
    f = np.roll(flags, -shift).astype(np.int8)
    edges = np.diff(np.concatenate([[0], f, [0]]))
    return [(int(a) + shift, int(b) + shift)
            for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1),
                            strict=True)]


def between_skin(flags, skin):
    """Which of ``flags`` (n,) bool of a closed outline lie in a run of them with ``skin``
    (n,) bool at the points on either side: a highlight on the skull between its lit
    sides is skin, a clipped white collar below the neck is not."""
    out = np.zeros_like(flags)
    n = len(flags)
    if flags.all():
        return out
    for a, b in _runs(flags):
        if skin[(a - 1) % n] and skin[b % n]:
            out[np.arange(a, b) % n] = True
    return out


def _close_short_gaps(flags, shortest):
    """Flip runs (of either value) shorter than ``shortest`` points to their
    surroundings, short gaps first."""
    out = flags.copy()
    for value in (False, True):
        if out.all() or not out.any():
            break
        n = len(out)
        for a, b in _runs(out == value):
            if b - a < shortest:
                out[np.arange(a, b) % n] = not value
    return out


class UnsureEdge(ValueError):
    """The segmentation is unsure of the person's edge over ``UNSURE_REFUSE`` of the
    outline."""


def head_outline(image, face, network, spacing_px=SPACING_PX):
    """The head's outline in ``image`` (H, W, 3) float in [0, 1], for ``face`` (a
    :class:`~.detector.DetectedFace` with its keypoints and box).

    Past the photo's border the segmentation sees the photo's edges extended. Where the
    photo cuts the head tightly (the back and top of a profile's head cut off) those
    streaks of skin may leave it unsure of the whole edge; then it sees black there
    instead, as a photo's border looks to it, and that outline is taken if it is sure
    (docs/DECISIONS.md, "Photos cropped tightly").

    Parameters
    ----------
    network : Network
        The selfie segmentation model.
    spacing_px : float
        Photo pixels between outline points.

    Returns
    -------
    Outline

    Raises
    ------
    ValueError
        No person around the face, no skin on the person's edge, or an edge the
        segmentation is unsure of over ``UNSURE_REFUSE`` of it (the message names what is
        missing; the caller names the photo).
    """
    try:
        return _outline(image, face, network, spacing_px, "edge")
    except UnsureEdge as unsure:
        try:
            return _outline(image, face, network, spacing_px, "zero")
        except ValueError:
            raise unsure from None


def _outline(image, face, network, spacing_px, border):
    """:func:`head_outline` with the segmentation seeing ``border`` past the photo (as
    ``person_mask`` takes it); a square within the photo is never tried with "zero"."""
    box = np.asarray(face.box, float)
    centre = ((box[0] + box[2]) / 2, (box[1] + box[3]) / 2)
    angle = upright_angle(face)
    square = Square(centre, SQUARE_SCALE * float(max(box[2] - box[0], box[3] - box[1])),
                    angle)
    mask, busy = without_busy_background(person_mask(network, image, square, border))
    past = _reaching(mask, np.asarray(face.keypoints, float)[3])
    if past.any():                       # the head goes on past the square: a larger one
        shift = REGROW_SHIFT * square.size * past @ np.array([[-1, 0], [1, 0], [0, -1]])
        shift = shift @ np.stack(square.axes())
        square = Square(tuple(np.asarray(centre) + shift), REGROW * square.size, angle)
        mask, busy = without_busy_background(person_mask(network, image, square, border))
    if border != "edge" and _within(square, image):
        raise ValueError("the segmented square lies within the photo")  # the same mask
    nose = np.asarray(face.keypoints, float)[2]
    size = float(box[2] - box[0])
    loop, moved, refined, inside, skin_of_face = _edge(image, mask, face, spacing_px)
    on_photo = _seen(image, mask, loop, moved)
    taken_out = 0
    straight, sure = _straight_by_the_face(moved, on_photo, centre, size)
    if straight.any():
        mask, taken_out = without_leaks(image, mask, moved, straight,
                                        np.median(_skin_samples(image, face, mask), axis=0),
                                        LEAK_REACH * size, sure)
    if taken_out:
        loop, moved, refined, inside, skin_of_face = _edge(image, mask, face, spacing_px)
        on_photo = _seen(image, mask, loop, moved)
    colour = has_colour(skin_of_face)
    above = np.ones(len(moved), bool) if colour else _above_neck_cut(moved, face)
    skin = skin_like(inside, skin_of_face)
    skin |= between_skin(highlight_like(inside, skin_of_face) & ~skin, skin)
    shortest = max(int(round(MIN_STRETCH * size / spacing_px)), 1)
    skin = _close_short_gaps(skin, shortest)
    # off the photo nothing is seen: the head's outline goes on across the photo's border
    by_eye = by_the_eyes(moved, face)
    keep = (skin | ~on_photo | by_eye) & above
    if not (keep & on_photo).any():
        raise ValueError("no skin on the person's outline")
    front = int(np.argmin(np.linalg.norm(moved - nose, axis=1)))
    n = len(moved)
    run = next(((a, b) for a, b in _runs(keep) if a <= front < b or a <= front + n < b),
               None)
    if run is None:
        # the nose's point itself is not skin (a highlight; a beard on a front photo's
        # cheek): the nearest run long enough to be the face's (a strip of skin between
        # a beard and an ear is not), else the nearest
        runs = sorted(_runs(keep), key=lambda r: min(abs(r[0] - front), abs(r[1] - front)))
        run = next((r for r in runs if on_photo[np.arange(r[0], r[1]) % n].sum()
                    * spacing_px >= MIN_LENGTH * size), runs[0])
    idx = np.arange(run[0], run[1]) % n
    if len(idx) == n:
        if on_photo.all():
            raise ValueError("the person's outline is all skin: cannot tell where the neck "
                             "ends")
        idx = np.roll(idx, -int(np.flatnonzero(~on_photo)[-1]) - 1)  # from the border on
    seen = int(on_photo[idx].sum())
    if seen * spacing_px < MIN_LENGTH * size:
        raise ValueError(f"the skin on the person's outline near the face is "
                         f"{seen * spacing_px:.0f} px long, under {MIN_LENGTH:g} x the "
                         f"face's {size:.0f} px (hair or clothes around it): no outline")
    centre = np.asarray(centre, float)
    # the face's other side, where hair parts them (only colour tells that a run is skin)
    for a, b in _runs(keep) if colour else []:
        more = np.arange(a, b) % n
        if (a, b) != run and len(more) >= shortest and np.min(np.linalg.norm(
                moved[more] - centre, axis=1)) <= NEAR_FACE * size:
            idx = np.concatenate([idx, more])
    crossed = not on_photo[idx].all()
    idx = idx[on_photo[idx] & ~by_eye[idx]]
    if _short_three_quarter(face) and not over_the_head(moved[idx], face):
        raise ValueError("a three-quarter view's outline that shows the face's side alone, "
                         "not over the head (hair around the face): no outline, the fit is "
                         "nearer the truth without one in a view this close to the front")
    notes = [_end_note(i % n, skin, on_photo, above) for i in (idx[0] - 1, idx[-1] + 1)]
    # drawn from the chin's side: the mouth comes before the nose
    mouth = np.asarray(face.keypoints, float)[3]
    at = {name: int(np.argmin(np.linalg.norm(moved[idx] - p, axis=1)))
          for name, p in (("nose", nose), ("mouth", mouth))}
    if at["mouth"] > at["nose"]:
        idx, notes = idx[::-1], notes[::-1]
    notes = [f"starts at {notes[0]}", f"ends at {notes[1]}",
             f"{int(refined[idx].sum())} of {len(idx)} points moved onto a colour edge"]
    warnings = [f"the outline ran along a straight edge beside the face (a door, a frame, "
                f"a shelf behind the head): {taken_out * mask.pixel_size ** 2:.0f} px\u00b2 "
                "of it taken for the head were left out; check the outline there"] \
        if taken_out else []
    if busy:
        warnings.append(f"a busy background (its colours changing every few pixels) was "
                        f"taken for the person: {busy * mask.pixel_size ** 2:.0f} px\u00b2 of "
                        "it left out; check the outline there")
    if crossed:
        notes.append("the photo's border cuts the head: its outline goes on beyond it")
    if not colour:
        notes.append("the photo has no colour: the outline ends under the chin and the fit "
                     "gets only its points on an edge")
    unsure = float(np.mean(~edge_sure(mask, loop)[idx]))
    if unsure > UNSURE_REFUSE:
        raise UnsureEdge(f"the person's segmentation is unsure of the edge over "
                         f"{100 * unsure:.0f} % of the outline (over {100 * UNSURE_REFUSE:.0f}"
                         " %: a busy background, a black and white photo): no outline")
    if unsure > UNSURE_SHARE:
        warnings.append(f"the person's segmentation is unsure of the edge over "
                        f"{100 * unsure:.0f} % of the outline (a busy background, or "
                        "something of the skin's colour behind the head): check that the "
                        "outline follows the head")
    return Outline(moved[idx], refined[idx], notes, colour, warnings, unsure)


def upright_angle(face):
    """The angle (radians, as ``Square.angle`` takes it) that turns the segmented square
    upright with ``face`` where its eye keypoints lean more than ``MAX_TURN_DEG`` (a
    camera held askew: the segmentation model was trained on people upright); else 0,
    the photo's own rows. A profile keeps them: its turn read off the tragion-to-nose
    line took the ten rendered heads' outlines further off (docs/DECISIONS.md)."""
    if face.is_profile:
        return 0.0
    angle = eye_line_angle(face.keypoints)
    return angle if abs(np.degrees(angle)) > MAX_TURN_DEG else 0.0


def _within(square, image):
    """Whether ``square`` lies wholly inside ``image``'s pixels."""
    h, w = image.shape[:2]
    corners = square.to_photo(np.array([[0, 0], [1, 0], [0, 1], [1, 1]]), 1)
    return bool((corners >= 0).all() and (corners[:, 0] <= w).all()
                and (corners[:, 1] <= h).all())


def _edge(image, mask, face, spacing_px):
    """The person's outline around the ``face``'s nose in ``mask``: (the iso-line resampled
    every ``spacing_px``, it moved onto the photo's colour edge, which points were, their
    colours inside, as ``refine_edge`` with the face's skin colour; that colour,
    :func:`face_skin`)."""
    nose = np.asarray(face.keypoints, float)[2]
    loops = [mask.to_photo(line) for line in iso_lines(mask.probability)]
    loops = [p for p in loops if inside_polygon(nose, p)[0]] or loops[:1]
    if not loops or len(loops[0]) < 8:
        raise ValueError("no person found for an outline")
    loop = _closed_resample(loops[0], spacing_px)
    skin = face_skin(image, face, mask)
    normals = _normals(loop)
    moved, refined, inside = refine_edge(image, loop, normals, SEARCH_MAP_PX * mask.pixel_size,
                                         skin=skin, rim=edge_sure(mask, loop))
    moved, wide = wide_rim(image, mask, moved, normals, skin)
    return loop, moved, refined | wide, inside, skin


def wide_rim(image, mask, points, normals, skin):
    """Points (n, 2) moved out across a rim of light wider than the edge search. Along each
    point's normal, out to ``WIDE_RIM_MAP_PX`` map pixels, the photo's largest fall in
    brightness ends a band: where that band is the skin's colour lit
    (``photo_colour.lit_skin_like``), brighter than the skin inside the point and than the
    colour past the fall by ``RIM_STEP``, bright all the way out to the fall, and the
    segmentation gives it a mean person probability of at least ``WIDE_RIM_P`` (a bright
    wall past the head's edge it gives almost none), along ``WIDE_RIM_RUN`` consecutive
    points (``points`` in the outline's order) at least, the point goes to where the band
    falls halfway to the colour past it. Returns (points, which moved (n,) bool)."""
    n, rows = len(points), np.arange(len(points))
    step = 0.5
    k = int(WIDE_RIM_MAP_PX * mask.pixel_size / step)
    s = np.arange(1, k + 1) * step                                         # (k,)
    uv = points[:, None, :] + s[None, :, None] * normals[:, None, :]
    col = sample_photo(image, uv)                                          # (n, k, 3)
    prob = mask.at(uv.reshape(-1, 2)).reshape(n, k)
    inner = sample_photo(image, points[:, None, :] - np.array([1.0, 2.0, 3.0])[None, :, None]
                         * normals[:, None, :]).mean(1)
    w = max(int(round(STEP_PX / step)), 1)
    bright = col.sum(2)
    fall = bright[:, :-w] - bright[:, w:]                                  # (n, k - w)
    f = np.argmax(fall, axis=1)            # the band ends at sample f, the past from f + w
    # the band starts where the photo has risen from the skin at the point (within w
    # samples of it): up to there the colour is the edge's own, skin blurred into rim
    top = bright >= bright[rows, f][:, None] - RIM_STEP
    r = np.argmax(top, axis=1)
    ks = np.arange(k)[None, :]
    before = (ks >= r[:, None]) & (ks <= f[:, None])
    count = np.maximum(before.sum(1), 1)
    band = (col * before[..., None]).sum(1) / count[:, None]
    after = (ks >= (f + w)[:, None]) & (ks < (f + w + max(w, 2))[:, None])
    past = (col * after[..., None]).sum(1) / np.maximum(after.sum(1), 1)[:, None]
    contrast = band - past
    c2 = np.maximum((contrast ** 2).sum(1), 1e-12)
    share = ((col - past[:, None]) * contrast[:, None]).sum(2) / c2[:, None]  # 1 band, 0 past
    held = (prob * before).sum(1) / count
    rim = (f + w < k) & (after.sum(1) > 0) & (r <= 2 * w) & (f >= r + w) \
        & (band.sum(1) > inner.sum(1) + RIM_STEP) & (band.sum(1) > past.sum(1) + RIM_STEP) \
        & lit_skin_like(band, skin) & (held >= WIDE_RIM_P) \
        & np.all((share >= 0.5) | ~before, axis=1)
    # a band of light runs along the edge: a few points alone (a bright spot, a patch of
    # something behind the head) are none
    along = np.zeros(n, bool)
    for a, b in _runs(rim):
        along[np.arange(a, b) % n] = b - a >= WIDE_RIM_RUN
    rim &= along
    # the crossing: the first sample past halfway, from the fall on
    j = np.clip(f + 1 + np.argmax((share < 0.5)[rows[:, None], np.clip(
        f[:, None] + 1 + np.arange(w + 1)[None, :], 0, k - 1)], axis=1), 1, k - 1)
    s0, s1 = share[rows, j - 1], share[rows, j]
    frac = np.clip((s0 - 0.5) / np.where(s0 != s1, s0 - s1, 1.0), 0.0, 1.0)
    out = s[j - 1] + frac * step
    return np.where(rim[:, None], points + out[:, None] * normals, points), rim


def edge_sure(mask, loop):
    """Which points of the segmentation's iso-line ``loop`` (n, 2) photo px, clockwise,
    lie where it is sure of the person's edge (n,) bool: its probability ``SURE_REACH``
    map pixels inside is at least ``SURE_P`` and as far outside at most 1 - ``SURE_P``."""
    d = SURE_REACH * mask.pixel_size * _normals(loop)
    return (mask.at(loop - d) >= SURE_P) & (mask.at(loop + d) <= 1.0 - SURE_P)


def _seen(image, mask, loop, moved):
    """Which outline points (n,) bool lie on the photo and inside the segmented square
    (beyond them nothing is seen): ``loop`` the iso-line's, ``moved`` them on the edge."""
    h, w = image.shape[:2]
    return ((moved[:, 0] > 1) & (moved[:, 0] < w - 1) & (moved[:, 1] > 1)
            & (moved[:, 1] < h - 1)) & mask.inside(loop)


def _straight_by_the_face(points, seen, centre, size):
    """Which outline points (n,) bool lie on straight stretches of ``seen`` ones
    (``straight_stretches``, ``STRAIGHT_LONG`` of the face's ``size``) that come within
    ``STRAIGHT_NEAR`` face sizes of its ``centre``: (within ``STRAIGHT_TOL_COLOURED``,
    within ``STRAIGHT_TOL``)."""
    straight = straight_stretches(points, STRAIGHT_TOL_COLOURED * size,
                                  STRAIGHT_LONG * size, seen)
    for a, b in _runs(straight):
        run = np.arange(a, b) % len(points)
        if np.linalg.norm(points[run] - np.asarray(centre), axis=1).min() > STRAIGHT_NEAR * size:
            straight[run] = False
    sure = straight & straight_stretches(points, STRAIGHT_TOL * size, STRAIGHT_LONG * size,
                                         seen)
    return straight, sure


def straight_stretches(points, tol, length, seen):
    """Which points (n,) bool of a closed outline (n, 2), about evenly spaced, lie on a
    stretch of ``seen`` points at least ``length`` long (px, along it) that stays within
    ``tol`` px of the line between its ends (where the photo's border or the segmented
    square cuts the person, the outline runs straight along it: those are not seen)."""
    n = len(points)
    step = np.linalg.norm(np.roll(points, -1, axis=0) - points, axis=1)
    m = int(np.ceil(length / max(float(np.median(step)), 1e-9)))
    flags = np.zeros(n, bool)
    if m >= n:
        return flags
    idx = (np.arange(n)[:, None] + np.arange(m + 1)[None]) % n      # each window (n, m+1)
    w = points[idx]
    chord = w[:, -1] - w[:, 0]
    normal = np.stack([-chord[:, 1], chord[:, 0]], axis=1) \
        / np.maximum(np.linalg.norm(chord, axis=1, keepdims=True), 1e-9)
    off = np.abs(((w - w[:, :1]) * normal[:, None]).sum(axis=2)).max(axis=1)
    flags[idx[(off <= tol) & seen[idx].all(axis=1)].ravel()] = True
    return flags


def without_leaks(image, mask, points, straight, skin, reach, sure=None):
    """``mask`` without what it took in of the things whose straight edges ``straight``
    (n,) bool marks on its outline ``points`` (n, 2): for each run of them, the person's
    map pixels within ``reach`` photo px of it that have the thing's own colour (the
    median of the photo a little inside the run, ``LEAK_SPREADS`` times its spread, nearer
    it than the face's ``skin`` (3,) RGB), connected to the run. A run with no point
    marked ``sure`` (n,) bool (default: all are) counts only where the thing's
    chromaticity lies ``LEAK_CHROMA`` or more from the skin's. Returns (the mask, how many
    map pixels were taken out)."""
    n = mask.probability.shape[0]
    r, c = np.mgrid[0:n, 0:n]
    uv = mask.to_photo(np.stack([c.ravel(), r.ravel()], axis=1))
    colours = sample_photo(image, uv)
    person = mask.probability >= 0.5
    leak = np.zeros_like(person)
    inward = -_normals(points)
    depth = (SEARCH_MAP_PX + 2.0) * mask.pixel_size   # past the edge's blur and search
    for a, b in _runs(straight):
        idx = np.arange(a, b) % len(points)
        within = points[idx] + depth * inward[idx]
        own = sample_photo(image, within)
        thing = np.median(own, axis=0)
        if sure is not None and not sure[idx].any() and np.linalg.norm(
                chromaticity(thing) - chromaticity(skin)) < LEAK_CHROMA:
            continue
        spread = 1.4826 * np.median(np.linalg.norm(own - thing, axis=1))
        # its own colour: within its spread, and nearer it than the skin
        tol = min(max(LEAK_SPREADS * spread, LEAK_COLOUR), 0.5 * np.linalg.norm(skin - thing))
        near = (cKDTree(points[idx]).query(uv, distance_upper_bound=reach)[0]
                <= reach).reshape(n, n)
        like = person & near & (np.linalg.norm(colours - thing, axis=1) <= tol).reshape(n, n)
        labels, _ = ndimage.label(like)
        x, y = mask.to_map(within)
        seeds = labels[np.clip(np.round(y).astype(int), 0, n - 1),
                       np.clip(np.round(x).astype(int), 0, n - 1)]
        leak |= np.isin(labels, seeds[seeds > 0])
    # the map's pixels on the thing's own edge are of mixed colour: a strip a pixel wide
    # left beside what was taken out goes with it
    kept = person & ~leak
    leak |= kept & ~ndimage.binary_opening(kept) & ndimage.binary_dilation(leak, iterations=2)
    return (replace(mask, probability=np.where(leak, 0.0, mask.probability).astype(np.float32)),
            int(leak.sum()))


def _reaching(mask, mouth):
    """Whether the person reaches the segmented square's left, right and top edges (3,)
    bool; at the sides only above the ``mouth`` (below it the shoulders may)."""
    p = mask.probability >= 0.5
    x, y = mask.to_map(np.asarray(mouth, float)[None])
    rows = slice(0, int(np.clip(y[0], 0, p.shape[0])))
    return np.array([p[rows, 0].any(), p[rows, -1].any(), p[0].any()])


def over_the_head(points, face):
    """Whether an outline's ``points`` (n, 2) px go over the head of ``face`` (the
    detector's keypoints: its eyes, its mouth, its box): those more than
    ``OVER_HEAD_HEIGHT`` eye-to-mouth distances above the eyes span at least
    ``OVER_HEAD_SPAN`` of the face's width across the face."""
    k = np.asarray(face.keypoints, float)
    eyes = k[:2].mean(0)
    up = eyes - k[3]
    length = max(float(np.linalg.norm(up)), 1e-9)
    up = up / length
    d = np.asarray(points, float) - eyes
    high = d[d @ up > OVER_HEAD_HEIGHT * length]
    across = high @ np.array([up[1], -up[0]])
    return len(high) > 1 and float(np.ptp(across)) >= OVER_HEAD_SPAN * face.face_size


def by_the_eyes(points, face):
    """Which outline points (n, 2) px lie on or within ``EYE_MARGIN`` of the face's eyes
    (the mesh's iBUG eye contours; a face, not a profile): far round, the far eye's
    cornea stands out on the face's outline, and the head's mesh, without eyeballs, has
    no silhouette there. The outline goes on across them, as across the photo's border,
    and leaves them out."""
    points = np.asarray(points, float)
    out = np.zeros(len(points), bool)
    if face.is_profile or not len(points):
        return out
    for numbers in EYE_OPENINGS:
        eye = np.asarray(face.ibug, float)[np.array(numbers) - 1]
        gap = distance_to_segments(points, eye, np.roll(eye, -1, axis=0))
        out |= inside_polygon(points, eye) | (gap < EYE_MARGIN * face.face_size)
    return out


def _short_three_quarter(face):
    """Whether ``face`` is a three-quarter view within ``SIDE_ONLY_YAW_DEG`` of the front
    (``view_guess.guess_view``)."""
    guess = guess_view(face)
    return guess is not None and guess.name.startswith("three_quarter") \
        and abs(guess.yaw_deg) < SIDE_ONLY_YAW_DEG


def _above_neck_cut(points, face):
    """Whether each point (n, 2) lies above ``NECK_CUT`` (the detector's keypoints give
    the eyes, the mouth and which way is down the face)."""
    k = np.asarray(face.keypoints, float)
    down = k[3] - k[:2].mean(0)
    d = float(np.linalg.norm(down))
    return (points - k[3]) @ (down / max(d, 1e-9)) <= NECK_CUT * d


def _end_note(i, skin, on_photo, above):
    if not on_photo[i]:
        return "the photo's border (or the edge of the part of it segmented)"
    if not skin[i]:
        return "hair, clothes or background (not the face's skin)"
    return "the neck (no colour to tell skin from clothes by)" if not above[i] else "?"
