"""Arrays computed once per model file and kept on disk beside it (the folder
``<model's folder>-cache``, ``generated/model-cache/`` in a checkout: outside the model's
folder, which the extension zip takes whole), so that every process on a machine
after the first loads them instead of computing them again (``memo.py`` keeps them for
the process). Used for the texture bake's UV rasters: about 1 s of CPU at 1024 texels to
build, 0.05 s to load, paid once per machine instead of once per batch worker.

A stored file is named by what it holds and a digest of everything it was computed from:
the model file (path, size, modification time), the key, the source files of the code
that computes it, and the numpy and scipy versions. A change to any of them makes another
name, so a stale file is never read; saving removes the stale siblings. Files are written
to a temporary file and renamed (readers never see half a file); a folder that cannot be
written or a file that cannot be read costs only the computation.
"""

import hashlib
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import scipy

SUFFIX = "-cache"  # the stored arrays' folder: the model's folder's name and this


def folder(path):
    """The folder of the arrays stored for the model file ``path``."""
    return path.parent.with_name(path.parent.name + SUFFIX)


def stored_path(model, name, key, sources):
    """Where ``model``'s arrays ``name`` for ``key`` are kept, or None for a model without a
    file (``model.path``) or with a file that is gone.

    ``name`` is a file-name-safe label (also the prefix stale files are found by), ``key``
    anything with a stable ``repr``, ``sources`` the paths of the code computing them."""
    path = getattr(model, "path", None)
    if not path:
        return None
    path = Path(path)
    try:
        st = path.stat()
    except OSError:
        return None
    h = hashlib.sha256()
    for part in (str(path.resolve()), st.st_size, st.st_mtime_ns, repr(key), np.__version__,
                 scipy.__version__):
        h.update(f"{part}\n".encode())
    for src in sources:
        h.update(Path(src).read_bytes())
    return folder(path) / f"{path.stem}-{name}-{h.hexdigest()[:20]}.npz"


def load_arrays(path):
    """The arrays stored at ``path`` (a dict), or None when there is no readable file."""
    if path is None:
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile):  # missing, damaged
        return None


def save_arrays(path, arrays):
    """Store ``arrays`` (a dict of ndarrays) at ``path`` atomically and remove the files of
    the same name with another digest; False when the folder cannot be written."""
    if path is None:
        return False
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **arrays)
        os.chmod(tmp, 0o644)  # mkstemp's 0600 would hide it from the machine's other users
        os.replace(tmp, path)
        tmp = None
    except OSError:
        return False
    finally:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except OSError:
                pass
    prefix = path.name[:path.name.rindex("-") + 1]
    for old in path.parent.glob(f"{prefix}*.npz"):
        digest = old.name[len(prefix):-len(".npz")]
        if old.name != path.name and len(digest) == 20 and "-" not in digest:
            try:
                old.unlink()
            except OSError:
                pass
    return True


def remove_stored(model, name):
    """Remove every stored file of ``model``'s arrays whose name starts with ``name`` (e.g.
    to time a cold start)."""
    path = getattr(model, "path", None)
    if not path:
        return
    path = Path(path)
    for old in folder(path).glob(f"{path.stem}-{name}*.npz"):
        try:
            old.unlink()
        except OSError:
            pass
