"""The profile line's landmarks read off a profile photo's outline: nasion, nose tip,
subnasale, the lips, pogonion and menton, where the outline itself shows them (its dips,
its most forward points, the chin's corner). On a profile the face mesh is unreliable
(22-46 px median on the sample), while its outline is found to 1-2 px; named points on
it tell the fit where along the outline each feature sits, which the outline alone
leaves free. Rules and their measured errors: docs/DECISIONS.md ("A profile's landmarks
are read off its outline").
"""

import numpy as np

from .face_detection import KEYPOINTS
from .view_guess import MEDIAN_TO_SIGMA

#: Where the points are looked for, in the face's sizes (the detector box's width) of
#: arc length along the outline from the nose tip: up toward the forehead for the
#: nasion, down over the lips and chin for the rest.
UP_REACH = 0.6
DOWN_REACH = 1.0
#: An outline whose points lie further apart than this (median, fraction of the face's
#: size) is too coarse to show the lips: nothing is read off it.
MAX_SPACING = 0.02
#: A step between neighbouring outline points longer than this fraction of the face's
#: size is a gap (a beard, a hand or the photo's border hides the outline there): the
#: points are read off the unbroken piece that holds the nose tip only, so nothing beyond
#: a gap (a lip showing through a beard) is taken for the next feature down the face.
GAP = 0.03
#: The nose tip is the most forward point of the outline within this fraction of the
#: face's size of the face detector's nose keypoint (then followed on forward), and the
#: piece read is the one holding it: the keypoint is rough (on a black and white profile 39
#: px under the tip, by the subnasale, where the points under the nose zig-zag by a gap's
#: length onto the nostril's shadow), the tip is not.
TIP_REACH = 0.3
#: The outline is smoothed over this fraction of the face's size before the extremes
#: are read (a traced outline's 1-2 px noise makes no dip).
SMOOTH = 0.012
#: A dip or a bump counts when it is at least this fraction of the face's size deep or
#: high against its neighbours.
PROMINENCE = 0.006
#: The nasion's dip is looked for under the line from the nose tip that touches the
#: forehead at least this high above the tip (fraction of the face's size).
NASION_MIN_RISE = 0.12
#: The chin is looked for at least this far below the nose tip (fraction of the face's
#: size; the mean head's lower lip lies 0.34, its pogonion 0.46 below).
CHIN_MIN_DROP = 0.4
#: Lips that stand in front of that line (a receding chin, full lips) are touched first:
#: a point touched is a lip, not the chin, where the outline below it dips behind (the
#: sulcus under the lower lip) and comes forward again to a chin within this many face
#: sizes lower and at most ``CHIN_BEHIND`` further back (the throat, below the chin, lies
#: a quarter of the face's size and more behind it).
LIP_TO_CHIN = 0.3
CHIN_BEHIND = 0.15
#: ... the dip at least this many face sizes deep under the line from the lip to the chin
#: (about 3 mm: deeper than the bumps a busy background leaves under a chin), and that
#: line steeper than 45 degrees (the chin's underside, below its corner, runs back more
#: than down).
SULCUS = 0.02
#: The angle of the mean head's line from its nasion to its pogonion (their landmark
#: vertices) in profile, degrees forward of straight down: the face's frame is the one
#: where the nasion-to-chin line leans so.
FACE_LINE_DEG = 2.3
#: In an upright profile the line from the visible ear's tragion to the nose tip (the face
#: detector's keypoints) runs this many degrees above the face's forward direction (the
#: ten rendered heads' profiles -8.5 to +4.5, mean -4.1; docs/DECISIONS.md, "A profile
#: photo turned in its plane").
TRAGION_NOSE_DEG = -4.1
#: A profile whose tragion-to-nose line turns further than this from
#: ``TRAGION_NOSE_DEG`` is read in its own upright frame: the points' rules take the photo's
#: rows for the face's up and down (an upright profile's estimate strays up to 9 degrees).
#: A face whose eye line leans further is segmented upright (``outline.upright_angle``;
#: the rendered and real faces' eye lines lean 3 degrees at most).
MAX_TURN_DEG = 12.0
#: How far each point is moved along the outline from the feature read (fraction of the
#: face's size; away from the nose tip, the nose tip itself upward): the model's vertex
#: for the landmark lies there on average (``bench.bench_detect``).
ARC_SHIFT = {"nasion": 0.027, "nose_tip": 0.021, "subnasale": 0.0,
             "lip_upper_middle": -0.015, "mouth_middle": -0.009, "lip_lower_middle": 0.024,
             "pogonion": -0.062, "chin_bottom": 0.012}
#: The heights of the lips on the profile, a fraction of the nasion-to-menton height:
#: (mean, standard deviation) over 60 heads drawn from the model, turned up to 5 degrees
#: (their landmark vertices; ``bench.bench_detect --profile-line`` prints it again).
HEIGHT = {"lip_upper_middle": (0.568, 0.022), "mouth_middle": (0.640, 0.020),
          "lip_lower_middle": (0.733, 0.027)}
#: The nose tip's height on the same scale (0.321 +- 0.020 over the model's heads): where
#: the nasion is not seen (hair over the forehead, the frame of glasses), the lips are
#: placed by the nose tip and the menton.
TIP_HEIGHT = 0.321
#: The cost of leaving a lip out, in squared standard deviations of its height: a bump or
#: dip is taken for a lip only within 4 standard deviations of its mean height, where
#: taking it costs less (real faces lie further out than the model's heads: james'
#: stomion and lower lip 2.4 and 2.9 standard deviations off).
MISSING_COST = 16.0
#: Each point's median error, a fraction of the face's size: measured on 40 profiles of
#: heads drawn from the model, their outlines traced with 1 px noise, other heads than
#: those ``ARC_SHIFT`` was measured on (``bench.bench_detect --profile-line``).
MEDIAN_ERROR = {"nasion": 0.009, "nose_tip": 0.009, "subnasale": 0.006,
                "lip_upper_middle": 0.008, "mouth_middle": 0.015, "lip_lower_middle": 0.008,
                "pogonion": 0.015, "chin_bottom": 0.019}


def _arc(points):
    """Cumulative arc length (n,) of a polyline (n, 2)."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])


def _smooth(points, width):
    """The polyline resampled every pixel along its length and smoothed by a Gaussian of
    ``width`` px (its ends held)."""
    s = _arc(points)
    t = np.arange(0.0, s[-1], 1.0)
    p = np.stack([np.interp(t, s, points[:, 0]), np.interp(t, s, points[:, 1])], axis=1)
    r = max(int(3 * width), 1)
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / max(width, 1e-6)) ** 2)
    k /= k.sum()
    padded = np.concatenate([np.repeat(p[:1], r, axis=0), p, np.repeat(p[-1:], r, axis=0)])
    return np.stack([np.convolve(padded[:, i], k, mode="valid") for i in range(2)], axis=1)


def _extremes(signal, prominence, kind):
    """Indices of the local maxima (``kind`` "max") or minima ("min") of ``signal`` (n,)
    that stand at least ``prominence`` above (below) the lowest (highest) value between
    them and the nearest higher (lower) value on each side, or the ends."""
    x = np.asarray(signal, dtype=float)
    if kind == "min":
        x = -x
    n = len(x)
    out = []
    for i in range(1, n - 1):
        if not (x[i] >= x[i - 1] and x[i] > x[i + 1]):
            continue
        left = x[:i][::-1]
        higher = np.nonzero(left > x[i])[0]
        lmin = left[:higher[0]].min() if len(higher) else left.min()
        right = x[i + 1:]
        higher = np.nonzero(right > x[i])[0]
        rmin = right[:higher[0]].min() if len(higher) else right.min()
        if x[i] - max(lmin, rmin) >= prominence:
            out.append(i)
    return out


def profile_turn_deg(keypoints, side):
    """How far a profile photo shows the face turned in its plane, degrees (positive:
    counterclockwise as the photo shows it), from the face detector's ``keypoints`` (6, 2)
    px: the tragion-to-nose line against ``TRAGION_NOSE_DEG``; 0.0 within ``MAX_TURN_DEG``
    of upright, where the estimate is no better than the face's own build."""
    sign = 1.0 if side == "right" else -1.0
    k = np.asarray(keypoints, dtype=float)
    d = k[KEYPOINTS.index("nose_tip")] - k[KEYPOINTS.index(f"tragion_{side}")]
    turn = sign * (np.degrees(np.arctan2(-d[1], sign * d[0])) - TRAGION_NOSE_DEG)
    return float(turn) if abs(turn) > MAX_TURN_DEG else 0.0


def _turned(points, deg, centre):
    """``points`` (n, 2) px turned by ``deg`` degrees counterclockwise as a photo shows
    them (rows run down) about ``centre`` (2,)."""
    t = np.radians(deg)
    cos, sin = np.cos(t), np.sin(t)
    return centre + (np.asarray(points, dtype=float) - centre) @ np.array([[cos, -sin],
                                                                              [sin, cos]])


def profile_line_points(contour, side, face_size, nose_tip=None, turn_deg=0.0):
    """The profile line's landmarks on a profile photo's outline.

    Parameters
    ----------
    contour : ndarray (n, 2)
        The head's outline in the photo, px, in order along it (either way), covering the
        face from above the nasion to below the chin; where it has gaps (``GAP``), only
        its piece with the nose tip is read.
    side : {"right", "left"}
        The profile: a right profile's face looks toward +u, a left one's toward -u.
    face_size : float
        The face's size in the photo, px (the detector box's width).
    nose_tip : (float, float), optional
        Where the nose tip roughly is (the face detector's), px; default: the outline's
        most forward point.
    turn_deg : float
        How far the photo shows the face turned in its plane (:func:`profile_turn_deg`):
        the outline is read turned back upright, and the points given in the photo.

    Returns
    -------
    points : dict of str -> (float, float)
        Landmark name -> (u, v) px, for each the outline shows.
    uncertainty : dict of str -> float
        Landmark name -> standard deviation px.
    """
    c = np.asarray(contour, dtype=float)
    if c.ndim != 2 or c.shape[1] != 2 or len(c) < 8 or not face_size > 0 \
            or np.median(np.linalg.norm(np.diff(c, axis=0), axis=1)) > MAX_SPACING * face_size:
        return {}, {}
    if turn_deg:
        centre = c.mean(axis=0) if nose_tip is None else np.asarray(nose_tip, dtype=float)
        points, sigma = profile_line_points(_turned(c, -turn_deg, centre), side, face_size,
                                            None if nose_tip is None else centre)
        back = _turned(np.array(list(points.values())).reshape(-1, 2), turn_deg, centre)
        return {n: (float(u), float(v)) for n, (u, v) in zip(points, back, strict=True)}, sigma
    sign = 1.0 if side == "right" else -1.0
    c = _piece_with_tip(c, sign, face_size, nose_tip)
    if len(c) < 8:
        return {}, {}
    p = _smooth(c, SMOOTH * face_size)
    q = np.stack([sign * p[:, 0], p[:, 1]], axis=1)  # (forward, down) px
    if nose_tip is None:
        tip = int(np.argmax(q[:, 0]))
    else:
        near = _most_forward_near(p, q[:, 0], nose_tip, face_size)
        if near is None:
            return {}, {}
        tip = _climbed(q[:, 0], near)
    s = _arc(p)
    up, down, step = _stretches(q, s, tip, face_size)
    nasion = _nasion(q, up, face_size)
    chin = _chin_tangent(q, down, face_size)
    found = {} if nasion is None else {"nasion": nasion}
    if nasion is not None and chin is not None:
        # the face's own frame: its nasion-to-chin line turned as the mean head's is
        d = q[chin] - q[nasion]
        tilt = np.arctan2(d[0], d[1]) - np.radians(FACE_LINE_DEG)
        cos, sin = np.cos(tilt), np.sin(tilt)
        q = q @ np.array([[cos, sin], [-sin, cos]])
    found["nose_tip"] = _tip(q, tip, up, down, face_size)
    found.update(_lower_face(q, down, found.get("nasion"), face_size))
    # each point moved along the outline to where the model's vertex for it lies on average
    upward = ("nasion", "nose_tip")
    found = {n: int(np.clip(i + (-step if n in upward else step)
                            * round(ARC_SHIFT[n] * face_size), 0, len(p) - 1))
             for n, i in found.items()}
    points = {n: (float(p[i, 0]), float(p[i, 1])) for n, i in found.items()}
    return points, {n: round(MEDIAN_ERROR[n] * face_size * MEDIAN_TO_SIGMA, 3)
                    for n in points}


def _piece_with_tip(c, sign, face_size, nose_tip):
    """The unbroken piece of the outline ``c`` (n, 2) (no step longer than ``GAP`` of the
    face's size) that holds the nose tip: the most forward point (``sign`` +1 a right
    profile, -1 a left one) within ``TIP_REACH`` of ``nose_tip`` if given (else the point
    nearest it), else the most forward one."""
    cut = np.flatnonzero(np.linalg.norm(np.diff(c, axis=0), axis=1) > GAP * face_size) + 1
    if not len(cut):
        return c
    forward = sign * c[:, 0]
    if nose_tip is None:
        at = int(np.argmax(forward))
    else:
        at = _most_forward_near(c, forward, nose_tip, face_size)
        if at is None:
            at = int(np.argmin(np.linalg.norm(c - np.asarray(nose_tip, dtype=float), axis=1)))
    k = int(np.searchsorted(cut, at, side="right"))
    bounds = np.concatenate([[0], cut, [len(c)]])
    return c[bounds[k]:bounds[k + 1]]


def _most_forward_near(points, forward, nose_tip, face_size):
    """The index of the most forward of ``points`` (n, 2) px (``forward`` (n,)) within
    ``TIP_REACH`` of the face's size of ``nose_tip``, or None where none is."""
    near = np.linalg.norm(points - np.asarray(nose_tip, dtype=float), axis=1) \
        < TIP_REACH * face_size
    return int(np.argmax(np.where(near, forward, -np.inf))) if near.any() else None


def _climbed(forward, i):
    """From index ``i`` along the outline the way it goes forward (``forward`` (n,)) as
    long as it does: a nose tip guessed too far up the nose (the face detector's keypoint
    on a bearded profile lay above the nasion) leaves the most forward point near it on
    the dorsum, the edge of what it searched."""
    n = len(forward)
    for step in (1, -1):
        while 0 <= i + step < n and forward[i + step] > forward[i]:
            i += step
    return i


def _stretches(q, s, tip, face_size):
    """Indices of the outline up from the nose tip toward the forehead and down from it
    over the lips and chin (each starting at the tip), each as far as its reach."""
    # down the face is the way the outline goes lower (where it ends, its last point)
    ahead = min(int(np.searchsorted(s, s[tip] + 0.3 * face_size)), len(q) - 1)
    behind = max(int(np.searchsorted(s, s[tip] - 0.3 * face_size)), 0)
    step = 1 if q[ahead, 1] > q[behind, 1] else -1

    def stretch(direction, reach):
        idx = np.arange(tip, len(q)) if direction > 0 else np.arange(tip, -1, -1)
        return idx[np.abs(s[idx] - s[tip]) <= reach * face_size]

    return stretch(-step, UP_REACH), stretch(step, DOWN_REACH), step


def _deepest_under(q, idx, a, b):
    """The index among ``idx`` (between the ends ``a`` and ``b``) lying furthest behind the
    line from ``q[a]`` to ``q[b]``, and that depth px."""
    t = q[b] - q[a]
    n = np.array([t[1], -t[0]]) / max(np.linalg.norm(t), 1e-9)
    if n[0] > 0:
        n = -n
    depth = (q[idx] - q[a]) @ n
    k = int(np.argmax(depth))
    return idx[k], float(depth[k])


def _touched_from_tip(q, stretch, direction, min_height):
    """Where in ``stretch`` (indices from the nose tip, ``stretch[0]``) the line from the
    tip touches the outline beyond ``min_height`` px above (``direction`` -1) or below (+1)
    it: the point most forward per height from the tip; None without such points."""
    tip = stretch[0]
    height = direction * (q[stretch, 1] - q[tip, 1])
    ok = height > min_height
    if not ok.any():
        return None
    slope = np.where(ok, (q[stretch, 0] - q[tip, 0]) / np.maximum(height, 1e-9), -np.inf)
    return int(np.argmax(slope))


def _nasion(q, up, face_size):
    """The nasion: the deepest point under the line from the nose tip that touches the
    forehead (so a forehead sloping back still leaves its dip), or None."""
    touch = _touched_from_tip(q, up, -1, NASION_MIN_RISE * face_size)
    if not touch:
        return None
    idx, depth = _deepest_under(q, up[1:touch], up[0], up[touch])
    return idx if depth >= PROMINENCE * face_size else None


def _chin_tangent(q, down, face_size):
    """The chin's point touched by the line from the nose tip (Ricketts' E-line): among
    the points well below the lips, the one most forward per height below the tip, or
    where that is a lip standing out in front of the chin, the chin below it
    (:func:`_chin_below_lip`); None when the outline does not turn back behind that line
    below it (no chin)."""
    k = _touched_from_tip(q, down, 1, CHIN_MIN_DROP * face_size)
    if k is None or not 0 < k < len(down) - 1:
        return None
    # a chin: the outline turns back under it, behind the line
    _, depth = _deepest_under(q, down[k + 1:], down[0], down[k])
    if depth < PROMINENCE * face_size:
        return None
    while (lower := _chin_below_lip(q, down, k, face_size)) is not None:
        k = lower
    return down[k]


def _chin_below_lip(q, down, k, face_size):
    """The position in ``down`` of a chin below the point ``down[k]`` that the line from
    the nose tip touched, when that point is a lip (``LIP_TO_CHIN``, ``CHIN_BEHIND``): the
    lower end of the first edge of the outline's front hull below it that spans a dip of
    the outline (the sulcus), the outline turning back behind that edge under its end;
    else None."""
    drop = q[down, 1] - q[down[k], 1]
    back = q[down[k], 0] - q[down, 0]
    idx = np.flatnonzero((np.arange(len(down)) >= k) & (drop <= LIP_TO_CHIN * face_size)
                         & (back <= CHIN_BEHIND * face_size))
    hull = _front_hull(q[down[idx]], idx)
    for a, b in zip(hull[:-1], hull[1:], strict=True):
        edge_back = q[down[a], 0] - q[down[b], 0]
        edge_drop = q[down[b], 1] - q[down[a], 1]
        if b <= a + 1 or b >= len(down) - 1 or edge_back > edge_drop:
            continue                # no points between, or the chin's underside
        _, sulcus = _deepest_under(q, down[a + 1:b], down[a], down[b])
        if sulcus >= SULCUS * face_size:
            _, under = _deepest_under(q, down[b + 1:], down[a], down[b])
            return int(b) if under >= PROMINENCE * face_size else None
    return None


def _front_hull(points, idx):
    """The vertices (their ``idx``, in order down the face) of the hull of ``points``
    (m, 2) (forward, down) on the face's front: the chain from the highest point to the
    lowest that no point lies in front of."""
    order = np.argsort(points[:, 1], kind="stable")
    chain = []
    for i in order:
        while len(chain) >= 2:
            (f0, d0), (f1, d1) = points[chain[-2]], points[chain[-1]]
            f2, d2 = points[i]
            # the middle point lies behind the line from the first to the new one: drop it
            if (f1 - f0) * (d2 - d0) - (d1 - d0) * (f2 - f0) <= 0:
                chain.pop()
            else:
                break
        chain.append(int(i))
    return [int(idx[i]) for i in chain]


def _tip(q, tip, up, down, face_size):
    """The nose tip: the most forward point (in the face's frame) near the first guess."""
    near = np.concatenate([up[::-1], down[1:]])
    near = near[np.linalg.norm(q[near] - q[tip], axis=1) < 0.1 * face_size]
    return int(near[np.argmax(q[near, 0])])


def _lower_face(q, down, nasion, face_size):
    """Subnasale, lips, pogonion and menton on the stretch ``down`` (indices from the nose
    tip down over the chin) of the outline ``q`` (forward, down) in the face's frame. The
    lips are the bumps and the dip between them whose heights (from the nasion down to the
    menton) lie nearest the mean head's, so a lip that makes no bump is left out rather
    than another taken for it."""
    prom = PROMINENCE * face_size
    chin = _chin_tangent(q, down, face_size)
    if chin is None:
        return {}
    k = int(np.nonzero(down == chin)[0][0])
    found = {"pogonion": chin}
    fwd = q[down, 0]
    corners = [i for i in _extremes(fwd + q[down, 1], prom, "max") if i > k]
    if not corners:
        return found
    found["chin_bottom"] = down[corners[0]]
    bottom = q[down[corners[0]], 1]
    # the heights from the nasion (0) to the menton (1); without the nasion, from where
    # the nose tip's height puts it
    top = q[nasion, 1] if nasion is not None else \
        q[down[0], 1] - TIP_HEIGHT / (1 - TIP_HEIGHT) * (bottom - q[down[0], 1])
    height = bottom - top
    if height <= 0:
        return found
    t = (q[down, 1] - top) / height
    bumps = [b for b in _extremes(fwd[:k], prom, "max") if b > 0]
    dips = _extremes(fwd[:k], prom, "min")
    lips = _label_lips(t, bumps, dips)
    found.update({n: down[i] for n, i in lips.items()})
    # subnasale: the deepest point under the line from the nose tip to the upper lip (or
    # where the mean head's upper lip would be)
    upper = lips.get("lip_upper_middle")
    if upper is None:
        upper = int(np.argmin(np.abs(t[:k] - HEIGHT["lip_upper_middle"][0])))
    if upper > 1:
        found["subnasale"], _ = _deepest_under(q, down[1:upper], down[0], down[upper])
    return found


def _label_lips(t, bumps, dips):
    """{name: index} of the upper lip, stomion and lower lip among the ``bumps`` and
    ``dips`` (indices, in order down the outline) by their heights ``t`` (fraction of the
    nasion-to-menton height): the assignment in order down the face nearest the mean
    head's heights (``HEIGHT``), each left out where taking it would cost more
    (``MISSING_COST``)."""
    def options(name, pool):
        mean, sd = HEIGHT[name]
        return [None] + [i for i in pool if ((t[i] - mean) / sd) ** 2 < MISSING_COST]

    best, best_cost = {}, np.inf
    for ls in options("lip_upper_middle", bumps):
        for st in options("mouth_middle", dips):
            for li in options("lip_lower_middle", bumps):
                chosen = [(n, i) for n, i in (("lip_upper_middle", ls), ("mouth_middle", st),
                                              ("lip_lower_middle", li)) if i is not None]
                order = [i for _, i in chosen]
                if order != sorted(set(order)):
                    continue
                cost = sum(((t[i] - HEIGHT[n][0]) / HEIGHT[n][1]) ** 2 for n, i in chosen)
                cost += MISSING_COST * (3 - len(chosen))
                if cost < best_cost:
                    best, best_cost = dict(chosen), cost
    return best
