"""What makes a batch resumable: a content hash of a head's inputs and settings, recorded in
``<base>.batch.json`` beside its outputs once every output is written (the record is the
last file a head writes, so a head killed part-way has none and is fitted again).

The hash covers the landmarks file's bytes, every photo it names (bytes, or "missing"),
the model file (size and modification time: hashing ~100 MB per head would cost more than
it saves) and the head's settings (fit options, outputs, texture size). A head whose record
holds the same hash and whose recorded outputs all exist is skipped.

A head's outputs are written into a hidden staging folder beside them
(``staging_folder``) and renamed into place; a killed batch's staging folders are removed
by the next batch (``remove_stale_partials``).
"""

import hashlib
import json
import os
import shutil
from pathlib import Path

STAMP_SUFFIX = ".batch.json"
STAMP_FORMAT = "headrecon-batch-record"
_CHUNK = 1 << 20
PARTIAL = ".partial-"  # staging folders of heads in flight: ".<name>.partial-<pid>"


def stamp_path(base):
    """The record of the head whose outputs are ``base.*``."""
    base = Path(base)
    return base.with_name(base.name + STAMP_SUFFIX)


def _file_digest(h, path):
    with open(path, "rb") as f:
        while chunk := f.read(_CHUNK):
            h.update(chunk)


def _photo_paths(landmarks):
    """Photos a landmarks file names (absolute), read from its JSON without checking it."""
    try:
        doc = json.loads(Path(landmarks).read_text(encoding="utf-8"))
        views = doc.get("views", {}) if isinstance(doc, dict) else {}
        names = [v.get("image") for v in views.values() if isinstance(v, dict)]
    except (ValueError, AttributeError):
        return []  # the fit reports the broken file with its own message
    folder = Path(landmarks).parent
    return [p if p.is_absolute() else folder / p
            for p in (Path(n) for n in names if isinstance(n, str) and n)]


def _model_path():
    from .solver_link import solver_module

    return solver_module("paths").model_path()


def content_hash(landmarks, settings):
    """SHA-256 (hex) of a head's inputs and settings.

    Parameters
    ----------
    landmarks : path-like
        The landmarks file (must exist: an ``OSError`` names it otherwise).
    settings : dict
        JSON-able settings that change the outputs.
    """
    h = hashlib.sha256()
    _file_digest(h, landmarks)
    for photo in _photo_paths(landmarks):
        h.update(b"\0photo\0" + str(photo.name).encode())
        if photo.is_file():
            _file_digest(h, photo)
        else:
            h.update(b"missing")
    model = _model_path()
    stat = model.stat() if model.is_file() else None
    h.update(f"\0model\0{model.name}:{stat and stat.st_size}:{stat and stat.st_mtime_ns}"
             .encode())
    h.update(b"\0settings\0" + json.dumps(settings, sort_keys=True).encode())
    return h.hexdigest()


def finished_record(base, digest):
    """The record of a head already done with this ``digest`` (its summary row), or None
    when it must be fitted: no record, another hash, or an output gone."""
    try:
        rec = json.loads(stamp_path(base).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(rec, dict) or rec.get("format") != STAMP_FORMAT \
            or rec.get("hash") != digest:
        return None
    row = rec.get("summary")
    if not isinstance(row, dict) or not all(
            Path(p).is_file() for p in (row.get("outputs") or {}).values()):
        return None
    return row


def write_record(base, digest, row):
    """Record that the head ``base`` is done with ``digest`` (atomically, after its
    outputs)."""
    from .solver_link import solver_module

    atomic = solver_module("io.atomic")
    text = json.dumps({"format": STAMP_FORMAT, "version": 1, "hash": digest,
                       "summary": row}, indent=1) + "\n"
    atomic.write_file_atomic(stamp_path(base), text)


def staging_folder(base):
    """The staging folder of the head ``base`` written by this process (not created)."""
    base = Path(base)
    return base.parent / f".{base.name}{PARTIAL}{os.getpid()}"


def remove_stale_partials(folder):
    """Remove the staging folders a killed batch left in ``folder`` (their process is
    gone)."""
    for tmp in Path(folder).glob(f".*{PARTIAL}*"):
        try:
            pid = int(tmp.name.rsplit(PARTIAL, 1)[1])
            os.kill(pid, 0)  # still running: another batch's head in flight
        except (ValueError, ProcessLookupError):
            shutil.rmtree(tmp, ignore_errors=True)
        except PermissionError:
            pass
