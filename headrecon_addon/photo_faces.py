"""The solver's face detector on the scene's photos (their pixels from
``photos.detector_pixels``): one detector for the session, and what a face tells: its
landmarks under the project's names with each one's uncertainty, the view it looks like,
whether that is the view the photo was loaded as, and the direction Load Photos sorts a
photo by. No bpy: the photos come as arrays.
"""

import dataclasses
import functools

from .solver_link import Detector, face_landmarks, guess_view


@functools.cache
def detector():
    """MediaPipe's networks, read once a session.

    Raises
    ------
    ValueError
        A model file is missing (the message names it and says ``./run detector``).
    """
    return Detector()


@dataclasses.dataclass
class Face:
    """The face found on a photo: its landmarks and which way it looks.

    Attributes
    ----------
    points : dict of str -> (float, float)
        Landmark name -> (u, v) px: those the detector is trusted with (a profile's three)
        that lie on the photo.
    uncertainty : dict of str -> float
        Landmark name -> standard deviation px.
    depth : dict of str -> float
        Landmark name -> depth toward the camera, px (none in a profile).
    guess : solver ViewGuess or None
        The view the face looks like (None: the detector cannot tell).
    profile : bool
        Seen from the side: its landmarks are read off its outline, or without one only
        the mesh's nose tip, subnasale and upper lip are kept.
    score : float
        The face detector's confidence.
    off_outline : bool
        The landmarks were read off the photo's outline (a profile's).
    outline : solver Outline or None
        The photo's outline: a profile's, its landmarks read off it, or any face's traced
        with it (``find_face(outline=True)``), so a job that wants the outline too need
        not look again.
    found : solver DetectedFace or None
        The detector's own answer, which the outline starts from (``find_outline``).
    outline_problem : str or None
        Why the outline looked for was not found (``find_outline``'s error), one line.
    """

    points: dict
    uncertainty: dict
    depth: dict
    guess: object
    profile: bool
    score: float
    off_outline: bool = False
    outline: object = None
    found: object = None
    outline_problem: str = None


def find_face(pixels, outline=False):
    """The largest face (the subject's) in ``pixels`` ((H, W, 3) float in [0, 1], row 0
    at the top, sRGB, or (H, W, 4) with alpha for a cut-out: ``photos.detector_pixels``),
    or None when there is none. A profile's outline is traced for its landmarks;
    ``outline``: any face's is (Auto Fit's, while the other photos are detected)."""
    found = detector().detect(pixels)
    if found is None:
        return None
    h, w = pixels.shape[:2]
    guess = guess_view(found)
    side = guess.side if guess is not None else None
    read_off = found.is_profile and side is not None  # a profile's landmarks: its outline
    traced, problem = None, None
    if outline or read_off:
        try:
            traced = find_outline(pixels, found)
        except ValueError as e:
            problem = str(e)
    points, sigma, depth, off_outline = face_landmarks(
        found, (w, h), side, traced.points if read_off and traced is not None else None)
    return Face(points, sigma, depth, guess, found.is_profile, float(found.score),
                off_outline, traced, found, problem)


def find_outline(pixels, found=None):
    """The head's outline in ``pixels`` (as ``find_face``): the solver's ``Outline``
    (points (n, 2) px, notes). ``found``: the detector's face on these pixels
    (``Face.found``), when known, instead of detecting it again.

    Raises
    ------
    ValueError
        No face on the photo, or no outline around it (one line, the photo not named).
    """
    d = detector()
    if found is None:
        found = d.detect(pixels)
    if found is None:
        raise ValueError("no face found, so no outline")
    return d.outline(pixels, found)


def loaded_as_problem(kind, perspective, guess):
    """Why a face that looks like ``guess`` contradicts the view its photo was loaded as
    (``kind``: "front", "right", "left"; ``perspective``: any camera, its direction rough),
    a sentence, or None. A perspective photo only contradicts by its side."""
    if guess is None:
        return None
    if perspective:
        if kind in ("right", "left") and guess.side not in (None, kind):
            return (f"loaded as seen from the subject's {kind}, but the face looks like "
                    f"{guess.describe()}: set its Direction")
        return None
    if guess.name == kind:
        return None
    names = {"front": "a front photo", "right": "a right profile", "left": "a left profile"}
    fix = ("set its Direction" if guess.name in names
           else "load it with Add Photo (Any Camera)")
    return f"loaded as {names[kind]}, but the face looks like {guess.describe()}: {fix}"


def face_direction(pixels):
    """The direction (``photo_sorting``: "orthographic-front", "-right", "-left") the face
    in a photo's pixels shows, or None: no face, a three-quarter view, a face whose
    direction the detector cannot tell, or no detector models (the photos' shapes decide
    then)."""
    try:
        face = find_face(pixels)
    except ValueError:
        return None
    if face is None or face.guess is None or face.guess.name not in ("front", "right", "left"):
        return None
    return f"orthographic-{face.guess.name}"
