"""A small, fast Wavefront OBJ reader: positions, texture coordinates and polygon faces.

Only what the head-model build needs. Parsing is done with one regular-expression pass
per record type and numpy conversion of the joined tokens, so the 158 ICT OBJ files
(26719 vertices each) parse in seconds rather than minutes with a line-by-line loop.
"""

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

_V_RE = re.compile(r"^v[ \t]+(\S+)[ \t]+(\S+)[ \t]+(\S+)", re.MULTILINE)
_VT_RE = re.compile(r"^vt[ \t]+(\S+)[ \t]+(\S+)", re.MULTILINE)
_F_RE = re.compile(r"^f[ \t]+(.*?)[ \t]*$", re.MULTILINE)


@dataclass(frozen=True)
class ObjMesh:
    """Polygon mesh as read from an OBJ file (indices 0-based).

    Attributes
    ----------
    positions : ndarray, shape (n, 3), float64
        Vertex positions in the file's units and axes.
    uvs : ndarray, shape (m, 2), float64
        Texture coordinates (``vt``); empty when the file has none.
    loop_vertex : ndarray, shape (L,), int64
        Vertex index of each face corner ("loop"), faces one after the other.
    loop_uv : ndarray, shape (L,), int64
        Index into ``uvs`` of each corner, -1 where the corner has no ``vt``.
    face_loop_start : ndarray, shape (F,), int64
        First corner of each face in ``loop_vertex``.
    face_loop_total : ndarray, shape (F,), int64
        Number of corners of each face (3 for triangles, 4 for quads...).
    """

    positions: np.ndarray
    uvs: np.ndarray
    loop_vertex: np.ndarray
    loop_uv: np.ndarray
    face_loop_start: np.ndarray
    face_loop_total: np.ndarray


def _floats(rows, width, source, what):
    """Tuples of numeric strings -> (n, width) float64, naming the file on failure."""
    if not rows:
        return np.zeros((0, width))
    try:
        return np.array(rows, dtype=np.float64).reshape(-1, width)
    except ValueError as exc:
        raise ValueError(f"{source}: malformed '{what}' record ({exc})") from None


def parse_obj_positions(text, source="<text>"):
    """Vertex positions (``v`` records) of OBJ text.

    Parameters
    ----------
    text : str
        Contents of an OBJ file.
    source : str
        Name used in error messages.

    Returns
    -------
    ndarray, shape (n, 3), float64
    """
    return _floats(_V_RE.findall(text), 3, source, "v")


def parse_obj(text, source="<text>"):
    """Parse OBJ text into an :class:`ObjMesh` (positions, UVs, polygon faces).

    Face corners may be ``v``, ``v/vt``, ``v/vt/vn`` or ``v//vn``. Relative (negative)
    indices are not supported and raise ValueError, as does any index out of range.
    """
    positions = parse_obj_positions(text, source)
    uvs = _floats(_VT_RE.findall(text), 2, source, "vt")
    face_lines = _F_RE.findall(text)
    if not face_lines:
        raise ValueError(f"{source}: no faces ('f' records)")
    total = np.array([line.count(" ") + line.count("\t") + 1 for line in face_lines],
                     dtype=np.int64)
    corners = " ".join(face_lines).split()
    if len(corners) != int(total.sum()):
        # Repeated blanks inside a face line: count tokens properly (rare, slower path).
        total = np.array([len(line.split()) for line in face_lines], dtype=np.int64)
    if (total < 3).any():
        bad = int(np.flatnonzero(total < 3)[0])
        raise ValueError(f"{source}: face {bad} has fewer than 3 corners")
    parts = [c.split("/") for c in corners]
    try:
        loop_vertex = np.array([p[0] for p in parts], dtype=np.int64) - 1
        loop_uv = np.array([p[1] if len(p) > 1 and p[1] else "0" for p in parts],
                           dtype=np.int64) - 1
    except ValueError as exc:
        raise ValueError(f"{source}: malformed 'f' record ({exc})") from None
    if (loop_vertex < 0).any() or (loop_uv < -1).any():
        raise ValueError(f"{source}: relative (negative) or zero indices in 'f' records "
                         "are not supported")
    if loop_vertex.size and loop_vertex.max() >= len(positions):
        raise ValueError(f"{source}: face corner refers to vertex {int(loop_vertex.max()) + 1} "
                         f"but the file has {len(positions)} vertices")
    if loop_uv.size and loop_uv.max() >= len(uvs):
        raise ValueError(f"{source}: face corner refers to texture coordinate "
                         f"{int(loop_uv.max()) + 1} but the file has {len(uvs)}")
    start = np.concatenate([[0], np.cumsum(total)[:-1]])
    return ObjMesh(positions, uvs, loop_vertex, loop_uv, start, total)


def read_obj(path):
    """:func:`parse_obj` on the file at ``path``."""
    path = Path(path)
    return parse_obj(path.read_text(encoding="utf-8", errors="replace"), str(path))


def read_obj_positions(path):
    """:func:`parse_obj_positions` on the file at ``path``, shape (n, 3)."""
    path = Path(path)
    return parse_obj_positions(path.read_text(encoding="utf-8", errors="replace"), str(path))
