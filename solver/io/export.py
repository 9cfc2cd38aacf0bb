"""The fitted head as the files an artist takes away: the OBJ, the baked texture as one PNG
and the ``.mtl`` that puts it on the head. ``solver fit --texture`` and the demo both write
them through :func:`write_head_obj`."""

import io
from pathlib import Path

import numpy as np

from ..texture.uvs import resolve_parts
from .atomic import check_outputs, write_files_atomic
from .obj import obj_files

#: Rows of a texture converted to 8 bits at a time (``png_bytes``).
PNG_ROWS = 128


def png_bytes(image):
    """float (H, W, 3|4) in [0, 1] -> PNG file contents."""
    from PIL import Image  # on use: the rest of the solver (and the add-on) runs without it

    a = np.asarray(image)
    if a.ndim != 3 or a.shape[2] not in (3, 4):
        raise ValueError(f"texture: expected (H, W, 3|4), got {a.shape}")
    u8 = np.empty(a.shape, np.uint8)
    # a band of rows at a time: the whole atlas in float64 with its temporaries was 150 MB
    # at a batch worker's peak
    for r in range(0, a.shape[0], PNG_ROWS):
        band = np.nan_to_num(a[r:r + PNG_ROWS].astype(np.float64))
        u8[r:r + PNG_ROWS] = np.round(np.clip(band, 0.0, 1.0) * 255.0)
    buf = io.BytesIO()
    Image.fromarray(u8).save(buf, format="PNG")  # mode from the shape: RGB or RGBA
    return buf.getvalue()


def texture_atlas(model, tiles):
    """Put baked UDIM tiles side by side in one image and remap the UVs to match, so an
    OBJ needs a single texture (the ICT skin spans tiles 1001 and 1002).

    Parameters
    ----------
    model : HeadModel
    tiles : dict of int -> ndarray (size, size, C)
        UDIM tile -> texture (``texture.bake_tiles``); row 0 at the top.

    Returns
    -------
    atlas : ndarray, shape (size, n * size, C)
        The tiles in increasing tile order, left to right.
    loop_uv : ndarray, shape (L, 2)
        UVs into the atlas for the faces of baked tiles, the model's UVs elsewhere.
    textured : ndarray, shape (F,), bool
        Faces the atlas covers: parts the bake covers (the skin) whose UVs lie in a tile.
    """
    order = sorted(tiles)
    n = len(order)
    atlas = np.concatenate([np.asarray(tiles[t]) for t in order], axis=1)
    start = np.asarray(model.face_loop_start)
    total = np.asarray(model.face_loop_total)
    uv = np.asarray(model.loop_uv, dtype=np.float64)
    first = np.repeat(np.cumsum(total) - total, total)
    loops = np.repeat(start, total) + np.arange(first.size) - first  # faces in order
    face_mean = np.add.reduceat(uv[loops], np.cumsum(total) - total, axis=0) / total[:, None]
    corner = np.floor(face_mean).astype(np.int64)
    face_tile = 1001 + corner[:, 0] + 10 * corner[:, 1]  # same rule as the bake
    part_idx, _ = resolve_parts(model)
    textured = np.isin(np.asarray(model.face_part), part_idx) & np.isin(face_tile, order)
    column = np.searchsorted(order, face_tile)  # tile's place in the atlas
    face_of_loop = np.repeat(np.arange(total.size), total)
    sel = textured[face_of_loop]
    lp = loops[sel]
    f = face_of_loop[sel]
    out = uv.copy()
    out[lp, 0] = (column[f] + uv[lp, 0] - corner[f, 0]) / n
    out[lp, 1] = uv[lp, 1] - corner[f, 1]
    return atlas, out, textured


def head_obj_files(path, model, vertices, tiles=None, texture_path=None, faces=None):
    """The files of the head as OBJ: ``write_head_obj``'s parameters, its files not written.

    Returns
    -------
    names : dict of str -> Path
        "obj", and with ``tiles`` "mtl" and "texture".
    files : dict of Path -> str or bytes
        Each file's contents, for ``write_files_atomic`` (with other outputs, as one set).
    """
    if tiles is not None and texture_path is None:
        raise ValueError("texture_path: needed to write the texture of the tiles")
    keep = slice(None) if faces is None else np.asarray(faces, dtype=bool)
    loop_uv, textured = model.loop_uv, None
    if tiles is not None:
        atlas, loop_uv, textured = texture_atlas(model, tiles)
        texture_path = Path(texture_path)
        textured = textured[keep]
    # A polygon subset keeps the model's corner arrays: faces point into them.
    files = obj_files(path, vertices, model.loop_vertex, model.face_loop_start[keep],
                      model.face_loop_total[keep], loop_uv,
                      mtl_texture=texture_path if tiles is not None else None,
                      textured_faces=textured)
    names = dict(zip(("obj", "mtl"), files, strict=False))
    if tiles is not None:
        names["texture"] = texture_path
        check_outputs({f"the {key}": p for key, p in names.items()})
        files[texture_path] = png_bytes(atlas)
    return names, files


def write_head_obj(path, model, vertices, tiles=None, texture_path=None, faces=None):
    """Write the head as OBJ and, with ``tiles``, its texture and ``.mtl``, as one atomic set
    (all old or all new, never over each other).

    Parameters
    ----------
    path : path-like
        The ``.obj`` file (Y up, see ``obj.write_obj``).
    model : HeadModel
        Its polygons and UVs.
    vertices : array_like, shape (V, 3), metres
        The head's vertices, Blender axes (e.g. ``FitResult.local_vertices``).
    tiles : dict of int -> ndarray (size, size, C), optional
        The baked UDIM tiles (``texture.bake_fit_texture``): put side by side into one PNG
        at ``texture_path`` (``texture_atlas``); the ``.mtl`` next to the OBJ shows it on
        the faces it covers, the others get the grey material "untextured".
    texture_path : path-like
        The PNG to write; required with ``tiles``.
    faces : array_like, shape (F,), bool, optional
        Polygons to write (default: all). Every vertex is written either way.

    Returns
    -------
    dict of str -> Path
        "obj", and with ``tiles`` "texture" and "mtl": the files written.
    """
    names, files = head_obj_files(path, model, vertices, tiles, texture_path, faces)
    write_files_atomic(files)
    return names
