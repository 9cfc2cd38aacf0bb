"""What the fit tests measure a fitted head by."""

from bench.common import skin_error_mm as _skin_error_mm


def skin_error_mm(model, local, truth):
    """RMS distance (mm) over the skin between ``local`` (V, 3) and ``truth.local_vertices``
    after similarity alignment: the benchmarks' measure (``bench.common``)."""
    return _skin_error_mm(model, local, truth.local_vertices)
