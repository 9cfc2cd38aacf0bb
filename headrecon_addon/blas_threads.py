"""One BLAS thread for every process of a batch that fits heads, unless the environment
sets the thread count itself.

The fit's and the bake's matrices are small: a second BLAS thread barely shortens a head
and, on a machine with other work (or a second worker), spins on a busy core and costs far
more CPU than it saves (docs/DECISIONS.md, "One BLAS thread per fitting process"). A worker
process gets the variables before numpy loads (:func:`environment`); the batch's own
process has numpy loaded by bpy already, so there the loaded OpenBLAS libraries are told
directly (:func:`limit_loaded`).
"""

import ctypes
import os
import sys
from pathlib import Path

VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")

# The thread-count functions of the OpenBLAS builds numpy and scipy bundle (ILP64 builds
# carry a "64_" suffix, scipy's own builds a "scipy_" prefix).
_SETTERS = ("openblas_set_num_threads", "openblas_set_num_threads64_",
            "scipy_openblas_set_num_threads", "scipy_openblas_set_num_threads64_")
_GETTERS = ("openblas_get_num_threads", "openblas_get_num_threads64_",
            "scipy_openblas_get_num_threads", "scipy_openblas_get_num_threads64_")


def environment(env):
    """``env`` (a dict, changed and returned) with one BLAS thread unless it sets one."""
    for var in VARIABLES:
        env.setdefault(var, "1")
    return env


def _loaded_openblas():
    """Paths of the OpenBLAS libraries this process has loaded (Linux: its memory map;
    elsewhere the libraries numpy's and scipy's wheels bundle, which importing them
    loads)."""
    maps = Path("/proc/self/maps")
    if maps.is_file():
        paths = {line.split(None, 5)[-1].strip() for line in maps.read_text().splitlines()
                 if "openblas" in line.lower() and len(line.split(None, 5)) == 6}
        return sorted(p for p in paths if p.startswith("/"))
    found = []
    for name in ("numpy", "scipy"):
        module = sys.modules.get(name)
        if module is None or not getattr(module, "__file__", None):
            continue
        pkg = Path(module.__file__).parent
        for folder in (pkg.parent / f"{name}.libs", pkg / ".dylibs"):
            if folder.is_dir():
                found += sorted(str(p) for p in folder.iterdir() if "openblas" in p.name.lower())
    return found


def _function(path, names):
    """The first of the functions ``names`` the library ``path`` has, or None (also when
    it cannot be opened)."""
    try:
        lib = ctypes.CDLL(path)
    except OSError:
        return None
    for name in names:
        fn = getattr(lib, name, None)
        if fn is not None:
            return fn
    return None


def limit_loaded(threads=1):
    """Set the loaded OpenBLAS libraries to ``threads`` threads unless the environment
    sets ``OPENBLAS_NUM_THREADS``; returns the libraries set."""
    if os.environ.get("OPENBLAS_NUM_THREADS"):
        return []
    done = []
    for path in _loaded_openblas():
        setter = _function(path, _SETTERS)
        if setter is not None:
            setter(ctypes.c_int(int(threads)))
            done.append(path)
    return done


def loaded_threads():
    """Library path -> its thread count, for every loaded OpenBLAS that says it."""
    out = {}
    for path in _loaded_openblas():
        getter = _function(path, _GETTERS)
        if getter is not None:
            out[path] = int(getter())
    return out
