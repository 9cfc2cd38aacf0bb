"""Apple's 52 ARKit blendshape names, and the head model's expressions under those names.

This is the one place the mapping lives: the shape keys a fit writes, the Live Link Face
import and the exports all take their names from here.

The head model keeps ICT-FaceKit's own expression names (``eyeBlink_L``, ``browInnerUp_R``,
``PupilDilate_L``, ...). ICT's ``_L`` / ``_R`` are the subject's own sides, as Apple's
``Left`` / ``Right`` are ("relative to the face": ``eyeBlinkLeft`` closes the face's left
eye; in Blender axes the subject's left is +X, which a test checks on the geometry). So
one rule names every key: ``_L`` -> ``Left``, ``_R`` -> ``Right``, first letter lower
case. Where ICT splits an ARKit shape into halves (``browInnerUp``, ``cheekPuff``) the
ARKit key is their sum (ICT's README gives AU1 and AU33 as ``_L + _R``), and the halves
stay as extra keys. Expressions ARKit has no name for (``cheekRaiser``, ``pupilDilate``)
are extra keys too, named by the same rule, so none of them is an ARKit name. The model
has no ``tongueOut`` (no tongue shape in ICT-FaceKit Light): it is not invented.
"""

import numpy as np

# Apple's ARFaceAnchor.BlendShapeLocation, in the order of Apple's documentation.
ARKIT_NAMES = (
    "eyeBlinkLeft", "eyeLookDownLeft", "eyeLookInLeft", "eyeLookOutLeft", "eyeLookUpLeft",
    "eyeSquintLeft", "eyeWideLeft",
    "eyeBlinkRight", "eyeLookDownRight", "eyeLookInRight", "eyeLookOutRight",
    "eyeLookUpRight", "eyeSquintRight", "eyeWideRight",
    "jawForward", "jawLeft", "jawRight", "jawOpen",
    "mouthClose", "mouthFunnel", "mouthPucker", "mouthLeft", "mouthRight",
    "mouthSmileLeft", "mouthSmileRight", "mouthFrownLeft", "mouthFrownRight",
    "mouthDimpleLeft", "mouthDimpleRight", "mouthStretchLeft", "mouthStretchRight",
    "mouthRollLower", "mouthRollUpper", "mouthShrugLower", "mouthShrugUpper",
    "mouthPressLeft", "mouthPressRight", "mouthLowerDownLeft", "mouthLowerDownRight",
    "mouthUpperUpLeft", "mouthUpperUpRight",
    "browDownLeft", "browDownRight", "browInnerUp", "browOuterUpLeft", "browOuterUpRight",
    "cheekPuff", "cheekSquintLeft", "cheekSquintRight",
    "noseSneerLeft", "noseSneerRight",
    "tongueOut",
)
ARKIT_SET = frozenset(ARKIT_NAMES)
SIDES = (("_L", "Left"), ("_R", "Right"))
# ARKit shapes the model has as a left and a right half: the ARKit key is their sum.
COMBINED = ("browInnerUp", "cheekPuff")


def key_name(model_name):
    """The shape key name of a model expression: ``eyeBlink_L`` -> ``eyeBlinkLeft``,
    ``PupilDilate_R`` -> ``pupilDilateRight``, ``jawOpen`` -> ``jawOpen``."""
    name = str(model_name)
    for suffix, side in SIDES:
        if name.endswith(suffix):
            name = name[:-len(suffix)] + side
            break
    return name[:1].lower() + name[1:]


def key_plan(model_names):
    """Which model expressions make each expression key of a head.

    Parameters
    ----------
    model_names : sequence of str
        The model's expression names (``HeadModel.expression_names``).

    Returns
    -------
    list of (str, tuple of str)
        (key name, the model expressions summed into it): every ARKit name the model can
        give in Apple's order, then every model expression whose key name is not an ARKit
        name (the combined halves included), in the model's order.
    """
    by_key = {key_name(n): (str(n),) for n in model_names}
    if len(by_key) != len(model_names):
        raise ValueError("two model expressions map to one shape key name: "
                         f"{sorted(model_names)}")
    for name in COMBINED:
        halves = [f"{name}{side}" for _, side in SIDES]
        if name not in by_key and all(h in by_key for h in halves):
            by_key[name] = by_key[halves[0]] + by_key[halves[1]]
    return ([(n, by_key[n]) for n in ARKIT_NAMES if n in by_key]
            + [(n, m) for n, m in by_key.items() if n not in ARKIT_SET])


def expression_keys(model_names, deltas):
    """The expression keys of a head as (key name, offset (V, 3) from the neutral head),
    in the order of ``key_plan``, one at a time (all at once they are 36 MB more at a
    batch worker's peak); ``deltas`` (E, V, 3) are the model's expression offsets
    (``HeadModel.expressions``) in the order of ``model_names``."""
    index = {str(n): i for i, n in enumerate(model_names)}
    for key, parts in key_plan(model_names):
        yield key, sum(np.asarray(deltas[index[m]]) for m in parts)


def expression_key_names(model_names):
    """The key names of ``key_plan``, in its order."""
    return [key for key, _ in key_plan(model_names)]


def missing_arkit_names(model_names):
    """ARKit names the model has no shape for (e.g. ``("tongueOut",)``)."""
    have = set(expression_key_names(model_names))
    return tuple(n for n in ARKIT_NAMES if n not in have)


def arkit_name(column):
    """The ARKit name of a column header written in any case (Live Link Face writes
    ``EyeBlinkLeft``), or None when the column is not one of Apple's 52."""
    return _BY_LOWER.get(str(column).strip().lower())


_BY_LOWER = {n.lower(): n for n in ARKIT_NAMES}
