"""Give the C heap's free memory back to the system between the big steps of a head.

A batch worker's texture bake frees a few hundred MB of numpy temporaries that glibc keeps
for itself; Blender then takes fresh memory for the head's shape keys, so both counted in
the worker's peak (docs/DECISIONS.md, "What a batch worker spends"). ``malloc_trim``
returns the free pages first. Only glibc has it: elsewhere this does nothing.
"""

import ctypes
import sys

_trim = None
if sys.platform.startswith("linux"):
    try:  # the process's own symbols, libc's among them
        _trim = ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError):  # not glibc (musl has no malloc_trim)
        _trim = None


def release_free_memory():
    """Return the C heap's free pages to the system; True when it could (glibc)."""
    if _trim is None:
        return False
    _trim(0)
    return True
