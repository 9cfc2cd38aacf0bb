"""Atomic file writing: readers see the old file or the new one, never half of either."""

import os
import tempfile
from pathlib import Path


def write_file_atomic(path, data):
    """Write ``data`` (str as UTF-8, or bytes) to ``path`` through a temporary file in the
    same folder and ``os.replace``: readers see the old file or the new one, never half.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if isinstance(data, str):
        data = data.encode("utf-8")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        # mkstemp makes the file private (0600); give it the mode a plain open() would.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
