"""What the fit tests measure a fitted head by."""

import numpy as np

from solver.procrustes import similarity_procrustes


def skin_error_mm(model, local, truth):
    """RMS distance (mm) over the skin between ``local`` (V, 3) and ``truth.local_vertices``
    after similarity alignment (photos cannot tell size)."""
    a, b = local[model.skin], truth.local_vertices[model.skin]
    sim = similarity_procrustes(a, b)
    return 1000.0 * float(np.sqrt(((sim.apply(a) - b) ** 2).sum(axis=1).mean()))
