"""The profile line's landmarks read off a profile's outline (solver/detect/profile_line.py),
on profiles of heads drawn from the model: their silhouettes traced with 1 px noise, a
point every 3 px as the detected outline gives them, the truth their landmark vertices'
projections."""

import numpy as np
import pytest

from solver.detect.profile_line import (
    MAX_SPACING,
    MAX_TURN_DEG,
    profile_line_points,
    profile_turn_deg,
)
from solver.synthetic import make_case, resample_polyline

NAMES = ("nasion", "nose_tip", "subnasale", "lip_upper_middle", "mouth_middle",
         "lip_lower_middle", "pogonion", "chin_bottom")
#: The detector box's width over the nasion-to-menton distance on the rendered sample.
FACE_PER_HEIGHT = 1.215


def _profile(model, seed, view="right", spacing=3.0, noise=1.0):
    """(outline (n, 2), exact landmark pixels, face size px) of a head's profile."""
    _, truth = make_case(model, np.random.default_rng(seed), noise_px=0.0, views=(view,))
    traced = np.asarray(truth.contour[view])
    length = np.sum(np.linalg.norm(np.diff(traced, axis=0), axis=1))
    n = int(length / spacing)
    rng = np.random.default_rng(seed + 1)
    outline = resample_polyline(traced, n) + noise * rng.normal(size=(n, 2))
    exact = truth.pixels[view]
    size = FACE_PER_HEIGHT * np.linalg.norm(exact["nasion"] - exact["chin_bottom"])
    return outline, exact, size


def _errors(points, exact, size):
    return {n: np.linalg.norm(np.subtract(p, exact[n])) / size for n, p in points.items()}


@pytest.mark.parametrize("view", ["right", "left"])
def test_the_profile_line_s_points_lie_where_the_model_s_vertices_do(model, view):
    errors = {n: [] for n in NAMES}
    for seed in range(4100, 4106):
        outline, exact, size = _profile(model, seed, view)
        points, sigma = profile_line_points(outline, view, size, exact["nose_tip"] + 5.0)
        assert {"nasion", "nose_tip", "subnasale", "pogonion", "chin_bottom"} <= set(points)
        assert set(sigma) == set(points) and all(0 < s < 0.05 * size for s in sigma.values())
        for n, e in _errors(points, exact, size).items():
            errors[n].append(e)
    found = [n for n in NAMES if errors[n]]
    assert all(len(errors[n]) >= 5 for n in found), errors
    # each point within 3 % of the face's size in the median, none beyond 8 %
    assert all(np.median(errors[n]) < 0.03 for n in found), errors
    assert max(max(e) for e in errors.values()) < 0.08, errors


def test_the_outline_s_direction_and_side_do_not_matter(model):
    outline, exact, size = _profile(model, 4120)
    right, _ = profile_line_points(outline, "right", size)
    backward, _ = profile_line_points(outline[::-1], "right", size)
    mirrored, _ = profile_line_points(outline * [-1.0, 1.0] + [2000.0, 0.0], "left", size)
    assert set(right) == set(backward) == set(mirrored) and len(right) >= 6
    for n, p in right.items():
        assert np.linalg.norm(np.subtract(backward[n], p)) < 1.5, n
        assert np.linalg.norm(np.subtract(mirrored[n], (2000.0 - p[0], p[1]))) < 1e-6, n


def _turn(points, deg, centre):
    """``points`` turned ``deg`` degrees counterclockwise as a photo shows them."""
    t = np.radians(deg)
    d = np.asarray(points, float) - centre
    return centre + np.column_stack([np.cos(t) * d[:, 0] + np.sin(t) * d[:, 1],
                                     -np.sin(t) * d[:, 0] + np.cos(t) * d[:, 1]])


@pytest.mark.parametrize("view, deg", [("right", 25.0), ("left", -25.0)])
def test_a_profile_turned_in_the_photo_is_read_upright(model, view, deg):
    """A profile photo turned by 25 degrees, its face looking up, read with its turn: the
    points of the upright profile, turned; read as if upright, the rows no longer the
    face's up and down, some are far off (a face looking down is read well either way)."""
    centre = np.array([500.0, 500.0])
    right_turns, errors = [], []
    for seed in range(4100, 4104):
        outline, exact, size = _profile(model, seed, view)
        upright, _ = profile_line_points(outline, view, size, exact["nose_tip"])
        turned = _turn(outline, deg, centre)
        tip = _turn(exact["nose_tip"][None], deg, centre)[0]
        points, _ = profile_line_points(turned, view, size, tip, deg)
        assert set(points) == set(upright)
        for n, p in upright.items():
            assert np.linalg.norm(points[n] - _turn(np.array([p]), deg, centre)[0]) < 1.0, n
        naive, _ = profile_line_points(turned, view, size, tip)
        truth = {n: _turn(np.array([p]), deg, centre)[0] for n, p in exact.items()}
        errors.append(max(_errors({n: p for n, p in naive.items() if n in truth}, truth,
                                  size).values()))
        right_turns.append(max(_errors(points, truth, size).values()))
    assert max(right_turns) < 0.08 < max(errors), (right_turns, errors)


def test_a_profile_s_turn_is_read_off_its_tragion_and_nose_tip():
    # the right ear's tragion behind and below the nose tip as in an upright profile
    kp = np.zeros((6, 2))
    kp[2], kp[4] = (600.0, 400.0), (400.0, 400.0 - 200.0 * np.tan(np.radians(4.1)))
    assert profile_turn_deg(kp, "right") == 0.0
    for deg in (-30.0, 20.0, 30.0):
        turned = _turn(kp, deg, np.array([500.0, 500.0]))
        assert profile_turn_deg(turned, "right") == pytest.approx(deg, abs=1e-6)
        mirrored = turned * [-1.0, 1.0]
        mirrored[[4, 5]] = mirrored[[5, 4]]       # a left profile shows the left tragion
        assert profile_turn_deg(mirrored, "left") == pytest.approx(-deg, abs=1e-6)
    small = _turn(kp, MAX_TURN_DEG - 1.0, np.array([500.0, 500.0]))
    assert profile_turn_deg(small, "right") == 0.0   # within the build's own spread


def test_a_lip_without_a_bump_is_left_out_not_taken_for_another(model):
    # the upper lip flattened into a straight run from under the nose to the mouth (as on
    # the scan james): the lower lip must not be taken for it
    outline, exact, size = _profile(model, 4130, noise=0.0)
    points, _ = profile_line_points(outline, "right", size)
    assert "lip_upper_middle" in points
    a = np.argmin(np.linalg.norm(outline - exact["subnasale"], axis=1))
    b = np.argmin(np.linalg.norm(outline - exact["mouth_middle"], axis=1))
    a, b = min(a, b), max(a, b)
    flat = outline.copy()
    t = np.linspace(0.0, 1.0, b - a + 1)[:, None]
    flat[a:b + 1] = (1 - t) * outline[a] + t * outline[b]
    points, _ = profile_line_points(flat, "right", size)
    err = _errors(points, exact, size)
    assert "lip_upper_middle" not in points or err["lip_upper_middle"] < 0.04, err
    assert err["lip_lower_middle"] < 0.03, err


def test_an_outline_too_coarse_or_without_a_face_gives_nothing(model):
    outline, exact, size = _profile(model, 4140)
    coarse = outline[:: int(np.ceil(MAX_SPACING * size / 3.0)) + 1]
    assert profile_line_points(coarse, "right", size) == ({}, {})
    assert profile_line_points(outline, "right", size, nose_tip=(0.0, 0.0)) == ({}, {})
    assert profile_line_points(outline[:5], "right", size) == ({}, {})
    # a straight edge: a nose tip at most, no dips, lips or chin
    line = np.stack([np.full(400, 300.0), np.arange(400.0) * 2.0], axis=1)
    points, _ = profile_line_points(line, "right", 300.0)
    assert set(points) <= {"nose_tip"}


def test_only_the_outline_s_piece_with_the_nose_is_read(model):
    # a beard hides the outline from under the nose down; what shows through it (here the
    # outline from the lower lip over the chin) follows the face's piece after a gap:
    # nothing is read off it
    outline, exact, size = _profile(model, 4150)
    at = {n: int(np.argmin(np.linalg.norm(outline - exact[n], axis=1)))
          for n in ("subnasale", "lip_lower_middle", "chin_bottom")}
    down = 1 if at["chin_bottom"] > at["subnasale"] else -1
    face = outline[:at["subnasale"]] if down > 0 else outline[at["subnasale"] + 1:]
    a, b = sorted((at["lip_lower_middle"], at["chin_bottom"] + 10 * down))
    bit = outline[a:b + 1]
    broken = np.vstack([face, bit]) if down > 0 else np.vstack([bit, face])
    points, _ = profile_line_points(broken, "right", size, exact["nose_tip"] + 5.0)
    near_bit = [n for n, p in points.items()
                if np.min(np.linalg.norm(bit - np.asarray(p), axis=1)) < 0.05 * size]
    assert not near_bit, points
    whole, _ = profile_line_points(outline, "right", size, exact["nose_tip"] + 5.0)
    for n in ("nasion", "nose_tip"):
        assert np.linalg.norm(np.subtract(points[n], whole[n])) < 0.01 * size, n


def test_the_piece_read_holds_the_nose_tip_not_the_rough_keypoint(model):
    # on a black and white profile the points under the nose zig-zag onto the nostril's
    # shadow by more than a gap's step, and the face detector's nose keypoint lies low, by
    # the subnasale: the piece read is the one holding the most forward point near the
    # keypoint (the tip), not the one nearest it, whose first bump would be taken for the
    # nose tip and every point below shifted by a feature
    outline, exact, size = _profile(model, 4155)
    under = int(np.argmin(np.linalg.norm(outline - exact["subnasale"], axis=1)))
    tip = int(np.argmin(np.linalg.norm(outline - exact["nose_tip"], axis=1)))
    k = (under + tip) // 2
    zigzag = outline.copy()
    zigzag[k] += [0.0, -0.04 * size]           # a point 4 % of the face's size up
    hint = exact["subnasale"] + np.array([0.1, 0.05]) * size
    points, _ = profile_line_points(zigzag, "right", size, hint)
    whole, _ = profile_line_points(outline, "right", size, exact["nose_tip"] + 5.0)
    assert {"nasion", "nose_tip"} <= set(points), points
    for n, p in points.items():
        assert np.linalg.norm(np.subtract(p, whole[n])) < 0.01 * size, (n, points)


def test_a_nose_tip_guessed_up_the_nose_is_followed_to_the_tip(model):
    # the face detector's nose keypoint above the nasion, as on a bearded profile: the most
    # forward point near it lies on the dorsum; the outline is followed on to the tip
    outline, exact, size = _profile(model, 4160)
    guess = exact["nasion"] + np.array([0.03, -0.14]) * size
    points, _ = profile_line_points(outline, "right", size, guess)
    whole, _ = profile_line_points(outline, "right", size, exact["nose_tip"] + 5.0)
    assert np.linalg.norm(np.subtract(points["nose_tip"], whole["nose_tip"])) < 0.01 * size


def test_a_lower_lip_in_front_of_a_receding_chin_is_not_taken_for_the_chin(model):
    # the chin moved back (the outline below the lower lip, blended in over the sulcus)
    # until the line from the nose tip touches the lower lip first: the chin is read
    # below it, not on the lip
    outline, exact, size = _profile(model, 4179)
    back = 0.06 * size
    top, bottom = exact["lip_lower_middle"][1], exact["pogonion"][1]
    w = np.clip((outline[:, 1] - top) / (bottom - top), 0.0, 1.0)
    face = outline[:, 0] > exact["chin_bottom"][0] - 0.2 * size  # not the nape
    receding = outline - np.stack([np.where(face, w * back, 0.0), np.zeros(len(w))], 1)
    moved = dict(exact, pogonion=exact["pogonion"] - [back, 0.0])
    points, _ = profile_line_points(receding, "right", size, exact["nose_tip"] + 5.0)
    err = _errors(points, moved, size)
    assert err["pogonion"] < 0.04 and err["lip_lower_middle"] < 0.02, err


def test_lips_and_chin_are_read_where_the_forehead_is_hidden(model):
    # hair over the forehead (or a frame of glasses at the nasion) ends the outline
    # between the nasion and the nose tip: no nasion, the rest still read
    outline, exact, size = _profile(model, 4102)
    whole, _ = profile_line_points(outline, "right", size, exact["nose_tip"] + 5.0)
    cut = (exact["nasion"][1] + exact["nose_tip"][1]) / 2
    start = int(np.argmin(np.linalg.norm(outline - exact["nose_tip"], axis=1)))
    below = outline[:, 1] > cut
    piece = np.flatnonzero(below)
    runs = np.split(piece, np.flatnonzero(np.diff(piece) > 1) + 1)
    kept = outline[next(r for r in runs if start in r)]
    points, _ = profile_line_points(kept, "right", size, exact["nose_tip"] + 5.0)
    assert "nasion" not in points and "nasion" in whole
    assert set(whole) - {"nasion"} <= set(points), (sorted(whole), sorted(points))
    err, before = _errors(points, exact, size), _errors(whole, exact, size)
    assert all(e < 0.03 and e < before[n] + 0.01 for n, e in err.items()), (err, before)


def test_a_lip_is_left_out_where_taking_it_costs_more_than_missing_it(model, monkeypatch):
    # the lower lip's mean height moved away from where this head has it until the lip is
    # left out: that happens MISSING_COST standard deviations (squared) away, so a lip
    # twice as spread is taken twice as far off its mean
    import solver.detect.profile_line as profile_line

    outline, exact, size = _profile(model, 4120, noise=0.0)
    mean, _ = profile_line.HEIGHT["lip_lower_middle"]

    def dropped_at(sd):
        lo, hi = 0.0, 0.5  # the shift of its mean at which the lip is still taken, and not
        for _ in range(30):
            mid = (lo + hi) / 2
            monkeypatch.setitem(profile_line.HEIGHT, "lip_lower_middle", (mean + mid, sd))
            taken = "lip_lower_middle" in profile_line_points(outline, "right", size)[0]
            lo, hi = (mid, hi) if taken else (lo, mid)
        return lo

    near, far = dropped_at(0.02), dropped_at(0.04)
    assert far - near == pytest.approx(np.sqrt(profile_line.MISSING_COST) * 0.02, abs=1e-3)
