"""The model head's skin in regions (the face, the ears, the back of the head, the rest) and
a fitted head's error in each: where a photos-only fit loses, which one RMS over the whole
skin does not say (docs/DECISIONS.md, "Where the photos-only fit's spread lies").
"""

import numpy as np

from bench.realistic_cases import model_face_vertices
from solver.synthetic import skin_squared_distances

#: Skin within this distance of an ear landmark's vertex, on the mean head, is the ears'.
EAR_RADIUS_M = 0.025

#: The regions, in the order the benchmarks print them.
REGIONS = ("face", "ears", "back", "rest")


def skin_regions(model):
    """Region name -> which of the skin vertices (``model.skin``) lie in it, (n,) bool;
    each skin vertex in exactly one: the face (the realistic benchmark's face region,
    ``model_face_vertices``), the ears (within ``EAR_RADIUS_M`` of an ear landmark's
    vertex, outside the face), the back (behind the ears' landmarks: the back of the head
    and of the neck), the rest (the crown, the temples, the neck's front and sides)."""
    skin = np.asarray(model.skin, dtype=np.intp)
    points = model.vertices[skin]
    ears = model.vertices[[model.landmark_vertex(n) for n in model.landmarks
                           if n.startswith("ear")]]
    face = model_face_vertices(model)[skin]
    gap = np.min(np.linalg.norm(points[:, None] - ears[None], axis=2), axis=1)
    ear = ~face & (gap < EAR_RADIUS_M)
    # the face looks toward -Y: behind the ears is a larger Y than theirs
    back = ~face & ~ear & (points[:, 1] > ears[:, 1].mean())
    return {"face": face, "ears": ear, "back": back, "rest": ~(face | ear | back)}


def region_errors(model, local, truth_local, regions=None):
    """Region name -> RMS vertex distance (mm) between ``local`` and ``truth_local`` (V, 3)
    metres over its skin vertices, the heads laid on each other by the similarity over the
    whole skin (``solver.synthetic.skin_squared_distances``, as ``skin_error_mm``), so the
    regions' mean squares, weighted by their vertex counts, make up the skin's.
    ``regions``: ``skin_regions``'s answer (made when not given)."""
    regions = skin_regions(model) if regions is None else regions
    d2 = skin_squared_distances(model, np.asarray(local), np.asarray(truth_local))
    return {name: 1000.0 * float(np.sqrt(d2[mask].mean())) if mask.any() else float("nan")
            for name, mask in regions.items()}
