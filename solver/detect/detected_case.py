"""Detected faces as a landmarks case: one view per photo, named and its camera guessed
from the detection (``view_guess``: front, right or left profile, three-quarter), its
iBUG-68 points under the project's landmark names with each point's uncertainty in
pixels and (but in a profile) its depth toward the camera, a profile's landmarks read
off its outline, and the outline as the view's contour, so ``python -m solver detect``
(and ``headless --detect``) write a file the fit reads."""

import os
from pathlib import Path

import numpy as np

from ..cameras import PinholeCamera
from ..io.case import LandmarkCase, View
from ..io.exif import photo_lens_mm
from ..io.landmark_counts import landmarks_needed
from ..io.landmark_set import load_landmark_set
from ..io.photo_lens import plausible_lens
from .detector import face_notes
from .face_detection import KEYPOINTS
from .ibug_map import mesh_to_ibug
from .photo_turn import camera_to_photo, turned_size
from .profile_line import profile_line_points, profile_turn_deg
from .view_guess import ViewGuess, guess_view, placed, point_uncertainty

#: The view names the detection gives (and ``--view NAME=PHOTO`` may use to say one).
VIEW_NAMES = ("front", "right", "left", "three_quarter_right", "three_quarter_left")
#: Said when several photos include no profile: without the face's side outline the depth
#: comes from turned photos' landmarks alone (measured: README, "Three-quarter photos").
NO_PROFILE_NOTE = ("none of the photos is a profile: the head's depth comes from the "
                   "landmarks alone, which fits it several times less accurately than a "
                   "front and a profile photo do (README: three-quarter photos)")
#: Said of a profile photo beside a photo that was turned to show its face upright: the
#: photos may all have lost the turn their EXIF gave them, and a profile's turn is not told
#: (``Detector.detect``: only where the photo turned shows a face that is not a profile).
TURNED_PROFILE_NOTE = ("a profile, whose turn the detection does not tell, beside a photo "
                       "stored turned: check that this one is upright")
#: A three-quarter photo without a lens gets a pinhole camera whose focal length the fit
#: estimates; two photos' points tell it poorly (docs/DECISIONS.md: `bench_lens --yaw -22
#: --lens 50 85`, 1.98 mm mean with the EXIF lens, 2.94 without).
UNKNOWN_LENS_NOTE = ("a three-quarter view whose lens is not known (no EXIF, no --lens): "
                     "the fit estimates its focal length, which the photos' points tell "
                     "poorly (rendered heads fitted 1.5 times as far from the truth without "
                     "their lens); give --lens MM if you know it")
#: Which photos get their outline detected (``wants_outline``).
OUTLINES = ("all", "profile", "none")
_YAW = {"front": 0.0, "right": 90.0, "left": -90.0, "three_quarter_right": 45.0,
        "three_quarter_left": -45.0}


def detected_points(face, size):
    """The points of a detected face to keep, under the project's landmark names: those
    ``point_uncertainty`` keeps (a profile's few) that lie on the photo of ``size`` (w, h)
    and are not covered (``DetectedFace.covered``: a beard over the jaw).

    Returns
    -------
    points : dict of str -> (float, float)
        Landmark name -> (u, v) px on the photo as given (``DetectedFace.in_photo``).
    uncertainty : dict of str -> float
        Landmark name -> standard deviation px (rounded to 1/1000 px, as files store it).
    """
    names = load_landmark_set().ibug
    w, h = size
    points, sigma = {}, {}
    kept = point_uncertainty(face)
    for number, (u, v) in enumerate(face.in_photo(face.ibug), start=1):
        if number in names and number in kept and number not in face.covered \
                and 0 <= u <= w and 0 <= v <= h:
            points[names[number]] = (float(u), float(v))
            if kept[number] is not None:
                sigma[names[number]] = round(float(kept[number]), 3)
    return points, sigma


#: The face mesh's depth over the head's true depth toward the camera, both in pixels: the
#: slope of the one against the other at the 68 points of the rendered sample's front
#: photo (correlation 0.993; docs/DECISIONS.md).
MESH_DEPTH_SCALE = 1.13


def detected_depth(face, names):
    """How far each of the landmarks ``names`` (detected points of ``face``, as
    :func:`detected_points` keeps them) lies toward the camera, px relative to the mesh's
    centre, rounded to 1/1000 px: the mesh's own depth (its z grows away from the camera)
    over ``MESH_DEPTH_SCALE``. Empty for a profile, where the mesh is unreliable, and for a
    face partly covered (``DetectedFace.covered``), whose depths bend to what covers it."""
    if face.is_profile or face.covered:
        return {}
    numbers = {n: i for i, n in load_landmark_set().ibug.items()}
    z = mesh_to_ibug(face.mesh[:, 2:3])[:, 0]
    return {n: round(float(-z[numbers[n] - 1] / MESH_DEPTH_SCALE), 3) for n in names
            if n in numbers}


def face_landmarks(face, size, side=None, contour=None):
    """A detected face's landmarks to keep on its photo of ``size`` (w, h): (points,
    uncertainty, depth, off_outline) with points, uncertainty and depth as
    :func:`detected_points` and :func:`detected_depth` give them; but in a profile
    (``side`` "right" or "left") with its outline (``contour`` (n, 2) px), the profile
    line's points read off the outline (``profile_line_points``: 1-2 % of the face's size,
    on the photo turned as the face was detected) in place of the mesh's few (22-46 px),
    when it shows any, and then ``off_outline`` is True. Points are on the photo as
    given."""
    if face.is_profile and side in ("right", "left") and contour is not None \
            and face.face_size is not None:
        hint = None if face.keypoints is None else face.keypoints[KEYPOINTS.index("nose_tip")]
        turn = 0.0 if face.keypoints is None else profile_turn_deg(face.keypoints, side)
        line, line_sigma = profile_line_points(face.in_frame(contour), side, face.face_size,
                                               hint, turn)
        w, h = size
        at = face.in_photo(np.array(list(line.values()), float).reshape(-1, 2))
        line = {n: (float(u), float(v)) for n, (u, v) in zip(line, at, strict=True)
                if 0 <= u <= w and 0 <= v <= h}
        if line:
            return line, {n: line_sigma[n] for n in line}, {}, True
    points, sigma = detected_points(face, size)
    return points, sigma, detected_depth(face, sigma), False


def detected_case(photos, faces, base_dir=None, guesses=None, outlines=None, lenses=None):
    """A :class:`LandmarkCase` from detected faces.

    Parameters
    ----------
    photos : list of (view name, photo path, (width, height))
    faces : list of DetectedFace
        One per photo.
    base_dir : Path, optional
        Photo paths are written relative to it (the landmarks file's folder).
    guesses : list of ViewGuess, optional
        Each photo's view (its camera). Default: ``guess_view`` of each face (a front photo
        where it says nothing). The points kept are the face's (``point_uncertainty``: a
        profile keeps only those trustworthy there), whatever the view says.
    outlines : list of (Outline or None), optional
        Each photo's outline (``Detector.outline``'s): its ``contour`` is written as the
        view's contour, and a profile's landmarks are read off its ``points``.
    lenses : list of (float or None), optional
        Each photo's lens (mm, 36 mm equivalent; its EXIF's, ``photo_lens_mm``): the view's
        camera is then a pinhole camera of that lens (``ViewGuess.camera``) wherever the
        view keeps the points to calibrate one (``landmarks_needed`` of a pinhole); a
        profile with fewer keeps the camera it has without a lens (orthographic).
    """
    views = {}
    if guesses is None:
        guesses = [guess_view(f) or ViewGuess("front", 0.0) for f in faces]
    if outlines is None:
        outlines = [None] * len(faces)
    if lenses is None:
        lenses = [None] * len(faces)
    guesses = placed(guesses, [not lens for lens in lenses])
    for (name, path, size), face, guess, outline, lens in zip(photos, faces, guesses,
                                                               outlines, lenses, strict=True):
        w, h = size
        points, sigma, depth, _ = face_landmarks(
            face, size, guess.side, None if outline is None else outline.points)
        contour = None if outline is None else outline.contour
        image = Path(path).absolute()
        if base_dir is not None:
            image = Path(os.path.relpath(image, Path(base_dir).absolute()))
        if len(points) < landmarks_needed(PinholeCamera.min_refit_points):
            lens = None
        camera, hints = guess.camera(turned_size((w, h), face.turn), lens)
        camera = camera_to_photo(camera, face.turn, (w, h))
        views[name] = View(name, image.as_posix(), (w, h), camera, points,
                           camera_hints=hints, uncertainty=sigma, depth=depth,
                           contour=contour)
    return LandmarkCase(views)


def _side(name):
    if name.endswith("right"):
        return "right"
    if name.endswith("left"):
        return "left"
    return None


def wants_outline(face, outlines):
    """Whether a photo of ``face`` gets its outline detected: ``outlines`` "all" (the
    default: on the rendered sample the front's outline took the fit from 2.5 to 1.6 mm,
    docs/DECISIONS.md), "profile" (profiles only) or "none"."""
    if outlines not in OUTLINES:
        raise ValueError(f"outlines must be one of {', '.join(OUTLINES)}, got {outlines!r}")
    return outlines == "all" or (outlines == "profile" and face.is_profile)


def photo_outline(detector, image, face, path, echo):
    """The :class:`~.outline.Outline` of ``image`` (``Detector.outline``), or None with one
    line naming the photo given to ``echo`` when none is found; its ends are said too, and
    its warnings, each a line."""
    try:
        found = detector.outline(image, face)
    except ValueError as err:
        echo(f"warning: {path}: {err}; the view gets no outline")
        return None
    echo(f"{path}: outline of {len(found.contour)} points, {'; '.join(found.notes)}")
    for warning in found.warnings:
        echo(f"warning: {path}: {warning}")
    return found


def detect_photos(entries, detector, load, base_dir=None, echo=None, outlines="all",
                  exif_lens=True, lens_mm=None):
    """Detect the face in each photo and make the case.

    Parameters
    ----------
    entries : list of (str or None, path)
        Each photo with the view name the user gave it (None: the detection names it).
        A given name among ``VIEW_NAMES`` also says the view's camera; any other name only
        names it.
    detector : Detector
    load : callable
        path -> uint8 RGB image (H, W, 3), or RGBA (H, W, 4) for a cut-out
        (``Detector.detect``); its errors name the photo.
    base_dir : Path, optional
        As for :func:`detected_case`.
    echo : callable, optional
        Gets each message line: per photo what was found, "warning: ..." for a given view
        the detection contradicts, an outline not found or a profile beside a photo found
        turned (``TURNED_PROFILE_NOTE``), "note: ..." for a profile's few points and a
        photo detected turned upright (``face_notes``).
    outlines : {"all", "profile", "none"}
        Which photos get the head's outline as their contour (``wants_outline``).
    exif_lens : bool
        A photo whose EXIF gives its lens gets a pinhole camera of that lens
        (``detected_case``'s ``lenses``); False: front and profile photos are orthographic
        whatever their EXIF says.
    lens_mm : float, optional
        The lens (mm, 36 mm equivalent) of the photos whose EXIF gives none (or is not
        read): they get a pinhole camera of it as if their EXIF said so (a phone photo
        whose EXIF a messaging app removed). None: such photos are orthographic.

    Returns
    -------
    LandmarkCase

    Raises
    ------
    ValueError
        One line naming the photo: no face in it, or a face whose direction is not told.
    """
    echo = echo or (lambda line: None)
    photos, faces, guesses, traced, lenses, used = [], [], [], [], [], set()
    for given, path in entries:
        image = load(path)
        face = detector.detect(image)
        if face is None:
            raise ValueError(f"{path}: no face found")
        guess = guess_view(face)
        if guess is None:
            raise ValueError(f"{path}: a face was found (score {face.score:.2f}) but not which "
                             "way it looks (the face mesh sees none and the nose is not beside "
                             "the eyes); give its view with --view NAME=PHOTO")
        name = guess.name
        if given is not None:
            name = given
            if given in VIEW_NAMES and _side(given) and guess.side \
                    and _side(given) != guess.side:
                # a profile (or three-quarter) labelled with the other side
                name = given.replace(_side(given), guess.side)
                echo(f"warning: {path}: given as view {given!r}, but the face looks the other "
                     f"way: {guess.describe()}; written as view {name!r}")
            elif given in VIEW_NAMES and given != guess.name:
                echo(f"warning: {path}: given as view {given!r}, detected as "
                     f"{guess.describe()}; written as given")
                guess = ViewGuess(given, _YAW[given])
        base, n = name, 2
        while name in used:
            name, n = f"{base}_{n}", n + 1
        used.add(name)
        if face.is_profile:
            echo(f"note: {path}: a profile, where the face mesh is unreliable (22-46 px median "
                 "on the sample's profile photos): its landmarks are read off its outline "
                 "(nasion, nose tip, subnasale, lips, chin, as it shows them), or without one "
                 "only the mesh's nose tip, subnasale and upper lip are kept, with their "
                 "larger uncertainty")
        h, w = image.shape[:2]
        photos.append((name, path, (w, h)))
        faces.append(face)
        guesses.append(guess)
        lens, problem = plausible_lens(photo_lens_mm(path, (w, h)) if exif_lens else None,
                                       path)
        if problem:
            echo(f"warning: {problem}")
        source = "EXIF" if lens else "as given"
        lenses.append(lens or lens_mm)
        lens = f", its {lenses[-1]:.0f} mm lens ({source})" if lenses[-1] else ""
        echo(f"{path}: face (score {face.score:.2f}), {guess.describe()}{lens} -> view "
             f"{name!r}")
        for note in face_notes(face):
            echo(f"note: {path}: {note}")
        traced.append(photo_outline(detector, image, face, path, echo)
                      if wants_outline(face, outlines) else None)
    if len(guesses) > 1 and not any(g.profile for g in guesses):
        echo(f"note: {NO_PROFILE_NOTE}")
    turned_ones = [path for (_, path, _), face in zip(photos, faces, strict=True) if face.turn]
    for (_, path, _), face in zip(photos, faces, strict=True):
        if turned_ones and face.is_profile and not face.turn:
            echo(f"warning: {path}: {TURNED_PROFILE_NOTE} ({', '.join(map(str, turned_ones))})")
    case = detected_case(photos, faces, base_dir=base_dir, guesses=guesses,
                         outlines=traced, lenses=lenses)
    for (name, path, _), lens in zip(photos, lenses, strict=True):
        if lens and case.views[name].camera is not None:
            echo(f"note: {path}: taken as a parallel projection despite its {lens:.0f} mm "
                 "lens: too few landmarks to calibrate its camera on")
        elif not lens and case.views[name].camera is None:
            echo(f"note: {path}: {UNKNOWN_LENS_NOTE}")
    return case
