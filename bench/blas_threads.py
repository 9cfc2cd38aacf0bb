"""Limit BLAS threads before numpy is imported.

The fit's matrices are small: on 2 cores one BLAS thread is fastest and steadiest, and a
busy multi-threaded BLAS makes tiny solves many times slower. This module imports nothing
heavy, so a benchmark can call it before numpy loads.
"""

import os

VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def limit(threads):
    """Set the BLAS thread variables to ``threads`` (a string) unless the environment
    already sets them; ``"default"`` leaves the library's choice."""
    if threads != "default":
        for var in VARIABLES:
            os.environ.setdefault(var, threads)
