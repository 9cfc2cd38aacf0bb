"""Detected points whose part of the face is covered: a dark beard over the jaw. The face
mesh still draws a jaw there, on the beard's edge, up to a centimetre outside the true one,
and its depths bend to the beard's chin; fitted to them the whole face went wrong
(docs/DECISIONS.md, "A beard"). A jaw point counts as covered when the face just inside
it is not the colour of the face's skin; skin-coloured stubble, or a blond or grey beard,
is not told apart."""

import numpy as np

from ..photo_colour import has_colour, sample_photo, skin_colour, skin_like
from .outline import between_keypoints
from .view_guess import FRONT_MAX_DEG, mesh_yaw_deg

#: The jaw's iBUG points looked at (the two at each temple lie above any beard).
JAW = tuple(range(3, 16))
#: The mesh's whole jaw line (iBUG 1-17), left out when any of ``JAW`` is covered: the mesh
#: draws it as one curve, widened as a whole by a beard (its points at the temples kept,
#: the ten bearded heads' faces fitted to 2.01 mm, all left out 1.80).
JAW_LINE = tuple(range(1, 18))
#: Where inside a jaw point the face is sampled: these fractions of the way from it to
#: under the nose (iBUG 34), 0.5-1.5 cm inside the jaw's line on a face.
INSIDE = (0.08, 0.14, 0.20)
#: iBUG point the samples run toward (under the nose).
TOWARD = 34
#: The skin the samples are told against: on the lines from each eye to the nose tip and
#: to its ear (the detector's keypoints), above where a beard grows.
SKIN_PAIRS = ((0, 2), (1, 2), (0, 4), (1, 5))
#: The jaw's points on the subject's right (iBUG 1-8) and left (10-17) side; 9 is the chin.
RIGHT_SIDE, LEFT_SIDE = frozenset(range(1, 9)), frozenset(range(10, 18))


def covered_points(image, face):
    """iBUG numbers of the covered points of ``face`` (a front or three-quarter
    ``DetectedFace`` of ``image`` (H, W, 3) float in [0, 1]): the whole jaw line
    (``JAW_LINE``) when the face just inside some point of ``JAW`` is not the face's skin
    (most of its ``INSIDE`` samples fail ``photo_colour.skin_like``), else none. Empty for
    a photo without colour (nothing to tell a beard by) or a face without keypoints.

    Returns
    -------
    frozenset of int
    """
    if face.keypoints is None:
        return frozenset()
    skin = skin_colour(sample_photo(image, between_keypoints(face, SKIN_PAIRS)))
    if not has_colour(skin):
        return frozenset()
    ibug = np.asarray(face.ibug, float)
    jaw = ibug[np.array(looked_at(mesh_yaw_deg(face.mesh))) - 1]   # (j, 2)
    f = np.asarray(INSIDE)[None, :, None]
    inside = jaw[:, None] + f * (ibug[TOWARD - 1] - jaw)[:, None]  # (j, s, 2)
    ok = skin_like(sample_photo(image, inside.reshape(-1, 2)), skin).reshape(len(jaw), -1)
    covered = 2 * ok.sum(axis=1) < ok.shape[1]
    return frozenset(JAW_LINE) if covered.any() else frozenset()


def looked_at(yaw_deg):
    """The ``JAW`` points whose insides tell a beard in a face seen from ``yaw_deg``
    (degrees, toward the subject's right positive): all of them in a front photo (within
    ``view_guess.FRONT_MAX_DEG``); in a three-quarter view the side facing the camera (the
    subject's right for a positive yaw) and the chin, since the far side's points lie on or
    past the face's outline, where the photo shows the background or the neck (a bald,
    shaven head at 45 degrees read as bearded)."""
    if abs(yaw_deg) <= FRONT_MAX_DEG:
        return JAW
    far = LEFT_SIDE if yaw_deg > 0 else RIGHT_SIDE
    return tuple(i for i in JAW if i not in far)


def covered_note(face):
    """What the report says of a face's covered points (``DetectedFace.covered``), a
    phrase, or None when none are."""
    if not face.covered:
        return None
    return (f"the jaw looks covered (a dark beard?): its {len(face.covered)} points and the "
            "face mesh's depths are left out, the jaw left to the model")
