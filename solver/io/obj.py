"""Wavefront OBJ files: writing a fitted head (the model's polygons with its UVs, in
metres, and optionally a ``.mtl`` that puts the baked texture on it), and reading the
positions, UVs and polygons the head-model build needs.

OBJ has no axis convention of its own, but nearly every tool (and Blender's own OBJ
importer, by default) reads it as Y up with the front toward +Z. So by default the head is
written that way: OBJ (x, y, z) = Blender (x, z, -y), which is exactly what Blender's OBJ
exporter writes; importing the file into Blender with default settings gives back the
Blender coordinates. ``axes="blender"`` writes Blender's coordinates unchanged. Reading
keeps the file's own units and axes.

Both directions are vectorised with numpy: the text is built with ``np.savetxt`` into a
buffer and one ``%`` over a joined format string for the faces; parsing is one regular
expression pass per record type and one numpy conversion of the joined tokens.
"""

import io
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .atomic import check_outputs, write_files_atomic

AXES = ("y_up", "blender")
MATERIALS = ("head", "untextured")


def _int_array(a, name):
    arr = np.asarray(a)
    if arr.ndim != 1 or (arr.size and not np.issubdtype(arr.dtype, np.integer)):
        raise ValueError(f"{name}: expected a 1-D integer array, got shape {arr.shape} "
                         f"dtype {arr.dtype}")
    return arr.astype(np.int64)


def _loops_in_face_order(face_loop_start, face_loop_total):
    """Loop indices of every face corner, faces one after the other: (sum(total),)."""
    first = np.repeat(np.cumsum(face_loop_total) - face_loop_total, face_loop_total)
    return np.repeat(face_loop_start, face_loop_total) + np.arange(first.size) - first


def _unique_uvs(uv):
    """Distinct UVs at the written precision (1e-6) and each row's index among them."""
    q = np.round(uv * 1e6)
    if np.abs(q).max(initial=0) < 2.0 ** 30:
        # one int64 key per row: a 1-D unique is much faster than np.unique(axis=0)
        qi = q.astype(np.int64)
        keys, inverse = np.unique(qi[:, 0] * (1 << 32) + qi[:, 1], return_inverse=True)
        v = (keys + (1 << 31)) % (1 << 32) - (1 << 31)
        u = (keys - v) >> 32
        return np.column_stack([u, v]) / 1e6, inverse.reshape(-1)
    uniq, inverse = np.unique(q, axis=0, return_inverse=True)
    return uniq / 1e6, inverse.reshape(-1)


def _savetxt(arr, fmt):
    buf = io.StringIO()
    np.savetxt(buf, arr, fmt=fmt)
    return buf.getvalue()


def obj_text(vertices, loop_vertex, face_loop_start, face_loop_total, loop_uv=None,
             mtl_name=None, axes="y_up", object_name="head", textured_faces=None):
    """The OBJ file's text (see ``write_obj`` for the parameters; ``mtl_name`` is the
    ``mtllib`` file name, None for no materials)."""
    v = np.asarray(vertices, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] != 3 or v.shape[0] == 0:
        raise ValueError(f"vertices: expected shape (V, 3), got {v.shape}")
    if not np.isfinite(v).all():
        raise ValueError(f"vertices: row {int(np.flatnonzero(~np.isfinite(v).all(1))[0])} "
                         "is not finite")
    if axes not in AXES:
        raise ValueError(f"axes: expected one of {AXES}, got {axes!r}")
    lv = _int_array(loop_vertex, "loop_vertex")
    start = _int_array(face_loop_start, "face_loop_start")
    total = _int_array(face_loop_total, "face_loop_total")
    if start.shape != total.shape or start.size == 0:
        raise ValueError(f"face_loop_start, face_loop_total: expected equal non-empty shapes, "
                         f"got {start.shape} and {total.shape}")
    if (total < 3).any():
        raise ValueError(f"face_loop_total: face {int(np.flatnonzero(total < 3)[0])} has "
                         "fewer than 3 corners")
    if start.min() < 0 or (start + total).max() > lv.size:
        raise ValueError(f"face_loop_start: faces reach past the {lv.size} loops")
    if lv.size and (lv.min() < 0 or lv.max() >= v.shape[0]):
        raise ValueError(f"loop_vertex: indices must be in 0..{v.shape[0] - 1}")

    if axes == "y_up":
        v = np.column_stack([v[:, 0], v[:, 2], -v[:, 1]])
    loops = _loops_in_face_order(start, total)
    parts = ["# HeadRecon head, metres, " +
             ("Y up, face toward +Z\n" if axes == "y_up" else "Blender axes (Z up)\n")]
    if mtl_name is not None:
        parts.append(f"mtllib {mtl_name}\n")
    parts.append(f"o {object_name}\n")
    parts.append(_savetxt(v, "v %.6f %.6f %.6f"))

    corner_v = lv[loops] + 1  # OBJ indices are 1-based
    if loop_uv is not None:
        uv = np.asarray(loop_uv, dtype=np.float64)
        if uv.shape != (lv.size, 2):
            raise ValueError(f"loop_uv: expected shape ({lv.size}, 2), got {uv.shape}")
        if not np.isfinite(uv).all():
            raise ValueError("loop_uv: not finite")
        # One vt per distinct UV: corners of a vertex inside a UV island share it. Round to
        # the written precision first so values equal in the file are one vt.
        uniq, inverse = _unique_uvs(uv[loops])
        parts.append(_savetxt(uniq, "vt %.6f %.6f"))
        values = np.column_stack([corner_v, inverse.reshape(-1) + 1]).reshape(-1)
        corner = " %d/%d"
    else:
        values = corner_v
        corner = " %d"
    parts.append("s 1\n")
    # One format template per polygon size, joined in face order: the faces keep their
    # order (face i of the model is face i of the file) without a Python loop per corner.
    sizes, size_index = np.unique(total, return_inverse=True)
    templates = np.array(["f" + corner * int(n) + "\n" for n in sizes], dtype=object)
    face_lines = templates[size_index.reshape(-1)]
    if mtl_name is not None:
        if textured_faces is None:
            material = np.zeros(start.size, dtype=np.int64)
        else:
            textured = np.asarray(textured_faces)
            if textured.shape != start.shape or textured.dtype != bool:
                raise ValueError(f"textured_faces: expected a bool array of shape "
                                 f"{start.shape}, got {textured.dtype} {textured.shape}")
            material = (~textured).astype(np.int64)
        # "usemtl" wherever the material changes; faces stay in model order.
        change = np.flatnonzero(np.diff(material, prepend=-1))
        face_lines = face_lines.copy()
        for i in change:  # once per run of faces, not per face
            face_lines[i] = f"usemtl {MATERIALS[material[i]]}\n" + face_lines[i]
    parts.append("".join(face_lines) % tuple(values.tolist()))
    return "".join(parts)


def mtl_text(texture_relpath):
    """The ``.mtl``: material "head" shows the texture image; "untextured" (light grey) is
    for the faces the texture does not cover (eyes, teeth, mouth interior...)."""
    return (f"# HeadRecon materials\nnewmtl {MATERIALS[0]}\nKa 1.000 1.000 1.000\n"
            "Kd 1.000 1.000 1.000\nKs 0.000 0.000 0.000\nNs 10.0\nd 1.0\nillum 1\n"
            f"map_Kd {texture_relpath}\n\n"
            f"newmtl {MATERIALS[1]}\nKa 1.000 1.000 1.000\nKd 0.800 0.800 0.800\n"
            "Ks 0.000 0.000 0.000\nNs 10.0\nd 1.0\nillum 1\n")


def mtl_path(obj_path):
    """The ``.mtl`` written beside an OBJ with a texture: the OBJ's path with ``.mtl``."""
    return Path(obj_path).with_suffix(".mtl")


def obj_files(path, vertices, loop_vertex, face_loop_start, face_loop_total, loop_uv=None,
              mtl_texture=None, axes="y_up", textured_faces=None):
    """The files ``write_obj`` writes, as ``{path: text}`` (the OBJ first, then the MTL if
    any), for a caller that writes them with others as one set (``write_files_atomic``).
    """
    path = Path(path)
    mtl = mtl_path(path) if mtl_texture is not None else None
    text = obj_text(vertices, loop_vertex, face_loop_start, face_loop_total, loop_uv,
                    mtl_name=None if mtl is None else mtl.name, axes=axes,
                    object_name=path.stem or "head", textured_faces=textured_faces)
    files = {path: text}
    if mtl is not None:
        check_outputs({"the OBJ": path, "its .mtl": mtl})
        tex = Path(mtl_texture)
        try:
            rel = Path(os.path.relpath(tex.resolve(), path.resolve().parent)).as_posix()
        except ValueError:  # another drive on Windows
            rel = tex.resolve().as_posix()
        files[mtl] = mtl_text(rel)
    return files


def write_obj(path, vertices, loop_vertex, face_loop_start, face_loop_total, loop_uv=None,
              mtl_texture=None, axes="y_up", textured_faces=None):
    """Write a polygon mesh as OBJ (metres), the OBJ and its MTL as one atomic set.

    Parameters
    ----------
    path : path-like
        The ``.obj`` file.
    vertices : array_like, shape (V, 3), metres
        Positions in Blender axes (Z up, face toward -Y).
    loop_vertex : array_like, shape (L,), int
        Vertex of each face corner.
    face_loop_start, face_loop_total : array_like, shape (F,), int
        First corner and corner count of each polygon.
    loop_uv : array_like, shape (L, 2), optional
        Texture coordinate of each corner ((0, 0) bottom-left, as in Blender and OBJ);
        identical UVs are written once.
    mtl_texture : path-like, optional
        Texture image: also writes ``<path stem>.mtl`` next to the OBJ referring to it
        (by a path relative to the OBJ's folder) and assigns that material.
    axes : {"y_up", "blender"}
        "y_up" (default) writes OBJ (x, y, z) = Blender (x, z, -y), the usual OBJ
        convention; "blender" writes the coordinates unchanged.
    textured_faces : array_like, shape (F,), bool, optional
        With ``mtl_texture``: the faces the texture covers get material "head", the others
        "untextured" (default: all textured).

    Returns
    -------
    list of Path
        The files written (the OBJ, and the MTL if any).
    """
    files = obj_files(path, vertices, loop_vertex, face_loop_start, face_loop_total,
                      loop_uv, mtl_texture, axes, textured_faces)
    write_files_atomic(files)
    return list(files)


# --------------------------------------------------------------------------------------
# Reading

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
