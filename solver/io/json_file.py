"""Reading a JSON file with errors that name it: not UTF-8, not JSON, a key given twice,
too large or nested too deeply (Python's parser would otherwise end in a RecursionError
or use memory without bound)."""

import json
import re

import numpy as np

#: Largest JSON file read, bytes. A landmarks file with a 20,000-point contour is 0.6 MB.
MAX_JSON_BYTES = 32 * 1024 * 1024
#: Deepest nesting of arrays and objects read. A landmarks file needs 5 levels; tools' own
#: "x-" keys get the rest, well inside what every recursive reader of the data handles.
MAX_JSON_DEPTH = 64

_STRING = re.compile(rb'"(?:[^"\\]|\\.)*"', re.DOTALL)


def _reject_duplicate_keys(pairs):
    keys = [k for k, _ in pairs]
    if len(set(keys)) != len(keys):
        dup = next(k for i, k in enumerate(keys) if k in keys[:i])
        raise ValueError(f"key {dup!r} appears twice in one object")
    return dict(pairs)


def json_depth(raw):
    """Deepest nesting of arrays and objects in JSON text (bytes), strings left out; counted
    with numpy before parsing so no recursion sees a deep document."""
    bare = np.frombuffer(_STRING.sub(b'""', raw), dtype=np.uint8)
    step = np.isin(bare, np.frombuffer(b"[{", np.uint8)).astype(np.int64)
    step -= np.isin(bare, np.frombuffer(b"]}", np.uint8))
    return int(np.cumsum(step).max(initial=0))


def read_json(path):
    """Parse a UTF-8 JSON file; errors name the file (ValueError, FileNotFoundError).

    Files over ``MAX_JSON_BYTES`` or nested deeper than ``MAX_JSON_DEPTH`` are refused
    before parsing.
    """
    path = str(path)
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_JSON_BYTES + 1)
    except FileNotFoundError:
        raise FileNotFoundError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise IsADirectoryError(f"{path}: is a folder, not a file") from None
    if len(raw) > MAX_JSON_BYTES:
        raise ValueError(f"{path}: larger than {MAX_JSON_BYTES / 2**20:g} MB; not a landmarks "
                         "file HeadRecon reads")
    depth = json_depth(raw)
    if depth > MAX_JSON_DEPTH:
        raise ValueError(f"{path}: arrays and objects nested {depth} deep; at most "
                         f"{MAX_JSON_DEPTH} are read")
    try:
        text = raw.decode("utf-8-sig")  # tolerate the BOM some Windows editors write
    except UnicodeDecodeError as e:
        raise ValueError(f"{path}: not UTF-8 text (byte 0x{raw[e.start]:02x} at offset "
                         f"{e.start})") from None
    try:
        return json.loads(text, object_pairs_hook=_reject_duplicate_keys)
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}: not valid JSON: {e.msg} (line {e.lineno}, "
                         f"column {e.colno})") from None
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from None
