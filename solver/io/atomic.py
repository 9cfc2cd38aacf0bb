"""Writing the user's files safely: one file or a set of them (an OBJ, its .mtl and
texture, a report) all written to temporary files first and moved in only when every one
is complete, never over one of the inputs or over each other."""

import os
import tempfile
from pathlib import Path


def same_file(a, b, fold_case=False):
    """Whether paths ``a`` and ``b`` name one file: the same resolved path (symbolic links
    followed; case folded where the platform's paths are case-insensitive, or everywhere
    with ``fold_case``), or, when both exist, one file by ``os.path.samefile`` (hard links,
    case-insensitive file systems)."""
    ra = os.path.normcase(os.path.realpath(a))
    rb = os.path.normcase(os.path.realpath(b))
    if ra == rb or fold_case and ra.casefold() == rb.casefold():
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist (yet)
        return False


def check_outputs(outputs, inputs=None):
    """Refuse an output set that would overwrite an input or write one file twice.

    Parameters
    ----------
    outputs : dict of str -> path-like
        What each output is called in a message (e.g. "--report") -> its path.
    inputs : dict of str -> path-like, optional
        What each input is called (e.g. "the landmarks file") -> its path.

    Raises
    ------
    ValueError
        Naming both files, before anything is written.
    """
    outs = [(label, Path(p)) for label, p in outputs.items() if p is not None]
    ins = [(label, Path(p)) for label, p in (inputs or {}).items() if p is not None]
    for i, (label, path) in enumerate(outs):
        for other, known in ins:
            if same_file(path, known):
                raise ValueError(f"{label} {path}: is {other} ({known}); refusing to "
                                 "overwrite an input, give another file name")
        for other, known in outs[:i]:
            # Outputs not written yet cannot be compared by samefile: names that differ in
            # case only are one file on a case-insensitive file system (macOS, Windows).
            if same_file(path, known, fold_case=True):
                raise ValueError(f"{label} {path}: is also {other} ({known}); give the "
                                 "outputs different file names")
        if path.is_dir():
            raise ValueError(f"{label} {path}: is a folder; give a file name")


def _encoded(data):
    return data.encode("utf-8") if isinstance(data, str) else data


def _plain_mode(path):
    # mkstemp makes the file private (0600); give it the mode a plain open() would.
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(path, 0o666 & ~umask)


def write_files_atomic(files):
    """Write a set of files so that readers (and a failure or kill part-way) see either
    all the old files or all the new ones.

    Each file goes to a temporary file in its own folder (written, flushed and synced);
    only when all are complete are they moved over their targets with ``os.replace``, one
    after the other in a few microseconds. A failure removes the temporary files and
    leaves every target as it was; its ``OSError`` names the target, not the temporary.

    Parameters
    ----------
    files : dict of path-like -> str or bytes
        Target -> contents (str is written as UTF-8).

    Raises
    ------
    ValueError
        Two targets are one file (``check_outputs``).
    OSError
        Naming the target that could not be written.
    """
    targets = {Path(p): _encoded(data) for p, data in files.items()}
    check_outputs({str(p): p for p in targets})
    temps = []
    try:
        for path, data in targets.items():
            folder = path.parent if str(path.parent) else Path(".")
            try:
                fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp",
                                           dir=folder)
                temps.append(tmp)
                with os.fdopen(fd, "wb") as f:
                    f.write(data)
                    f.flush()
                    os.fsync(f.fileno())
                _plain_mode(tmp)
            except OSError as e:
                raise OSError(e.errno, e.strerror or str(e), str(path)) from None
        for path, tmp in zip(targets, list(temps), strict=True):
            try:
                os.replace(tmp, path)
            except OSError as e:
                raise OSError(e.errno, e.strerror or str(e), str(path)) from None
            temps.remove(tmp)
    finally:
        for tmp in temps:
            try:
                os.unlink(tmp)
            except OSError:
                pass


def write_file_atomic(path, data):
    """Write ``data`` (str as UTF-8, or bytes) to ``path`` through a temporary file in the
    same folder and ``os.replace``: readers see the old file or the new one, never half
    (``write_files_atomic`` with one file)."""
    write_files_atomic({path: data})
