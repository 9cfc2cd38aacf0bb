"""Which side of the head each of several photos shows, so *Load Photos* can put them into
views at once: the file's name first (``front``, ``side``/``profile``/``right``,
``left``), then the face in the photo when a detector is given (``face_direction``: the
hook for automatic detection), then the photos' shapes: a head seen from the side is
deeper than it is wide, so among the photos left the narrowest is the front and the
widest the profile. Plain Python (no bpy), so it is tested on its own.
"""

import re

FRONT = "orthographic-front"
RIGHT = "orthographic-right"
LEFT = "orthographic-left"
SIDES = (RIGHT, LEFT)

# words of a file name and the direction they say (the first that matches wins)
_WORDS = ((LEFT, ("left",)),
          (RIGHT, ("right", "side", "profile", "lateral")),
          (FRONT, ("front", "frontal", "face")))


def direction_from_name(name):
    """The direction a file name says (``IMG_0042_profile_left.jpg``: left), or None."""
    words = set(re.findall(r"[a-z]+", str(name).lower()))
    for direction, names in _WORDS:
        if words & set(names):
            return direction
    return None


def sort_photos(photos, taken=(), face_direction=None):
    """A direction ("orthographic-front" | "-right" | "-left") for each photo.

    Parameters
    ----------
    photos : sequence of (str, (int, int))
        Each photo's file name and upright size (w, h) in pixels, in the order to decide
        ties by (the first of two alike is the front).
    taken : iterable of str
        Directions the scene's photos already have: the shapes then fill only what is
        missing (a front, a profile); the rest are fronts.
    face_direction : callable, optional
        ``face_direction(index) -> direction or None``: where the face in photo ``index``
        looks, asked for photos whose names say nothing (the detector's hook).

    Returns
    -------
    list of str
    """
    out = [direction_from_name(name) for name, _ in photos]
    if face_direction is not None:
        for i, d in enumerate(out):
            if d is None:
                d = face_direction(i)
                if d is not None and d not in (FRONT, *SIDES):
                    raise ValueError(f"face_direction({i}): {d!r} is not a direction")
                out[i] = d
    have = set(taken) | {d for d in out if d is not None}

    def aspect(i):
        w, h = photos[i][1]
        return float(w) / float(h) if h else 0.0

    left = [i for i, d in enumerate(out) if d is None]
    if FRONT not in have and left:
        front = min(left, key=aspect)  # min keeps the first of equals
        out[front] = FRONT
        left.remove(front)
    if not have & set(SIDES) and left:
        side = max(left, key=aspect)  # max keeps the first of equals
        out[side] = RIGHT
        left.remove(side)
    for i in left:
        out[i] = FRONT
    return out
