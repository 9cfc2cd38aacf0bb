"""The eyes of the bundled head (ICT's vertex order): which vertices are each eyeball's
sclera and iris, how large the iris and pupil are, and where on the sclera a point lies
against the eye's axis; and which landmarks draw the eye openings in a photo. The add-on's
eye material paints by it and the texture reads the irises' colour off the photos by it,
so both agree on where the iris is."""

import numpy as np

# ICT README, "Eyeball details" (vertex ranges, inclusive; the model keeps ICT's vertex
# order). The sclera is the outer shell with the cornea bulge; the iris part is an inner
# sphere the opaque sclera hides, so the iris is painted onto the sclera's front.
SCLERA_RANGES = ((21451, 22220), (23021, 23790))
IRIS_RANGES = ((22221, 23020), (23791, 24590))
IRIS_RADIUS = 0.0058  # metres from the eye's axis
PUPIL_RADIUS = 0.0021
#: The eye openings' landmarks, in order round each eye (iBUG 37-42 and 43-48): where a
#: photo's landmarks draw the eyes.
EYE_OPENINGS = (range(37, 43), range(43, 49))


def sclera_axis_distance(vertices):
    """Each eye's sclera vertices and their distance from the eye's axis.

    Parameters
    ----------
    vertices : ndarray, shape (V, 3), metres
        A head in the ICT vertex order, in the model's own frame (looking toward -Y).

    Returns
    -------
    list of (indices (k,) int, distance (k,) metres, front (k,) bool), one per eye
        ``distance`` from the line through the iris sphere's centre along -Y; ``front``:
        the vertex lies on the half of the sclera that faces forward.
    """
    v = np.asarray(vertices, dtype=np.float64)
    need = IRIS_RANGES[-1][1] + 1
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < need:
        raise ValueError(f"vertices: expected the ICT head's (V, 3) vertices with V >= {need}"
                         f", got shape {v.shape}")
    out = []
    for (s0, s1), (i0, i1) in zip(SCLERA_RANGES, IRIS_RANGES, strict=True):
        d = v[s0:s1 + 1] - v[i0:i1 + 1].mean(axis=0)
        out.append((np.arange(s0, s1 + 1), np.hypot(d[:, 0], d[:, 2]), d[:, 1] < 0))
    return out
