"""Texture coordinates of the head: per-vertex UVs into one photo, and the model's own UV
layout rasterised tile by tile for the bake (``bake.py``) to fill.

* :func:`orthographic_uvs` is the thesis' own texturing (§5, eq. 48-49): every vertex gets
  the texture coordinate of its projection into one photo, so the photo itself is the
  texture. Cheap and exact on the photo's side, but the far side of the head smears.
* :func:`uv_raster` says which surface point every texel of one UDIM tile of
  ``model.loop_uv`` shows. The layout never changes, so a raster is built once per model,
  size, parts and tile and kept with the model (``solver.memo``): repeated bakes, e.g. in
  the live add-on, skip the rasterisation. It is also stored beside the model's file
  (``solver.stored_arrays``), so the next process on the machine loads it instead.

Texture convention: ``texture[row, column]`` with row 0 at the top (v = 1), as written to a
PNG; texel (r, c) is centred on UV ((c + 0.5) / size, 1 - (r + 0.5) / size) inside its UDIM
tile. Blender's ``Image.pixels`` run bottom-up, so the add-on flips rows when it fills an
image from memory (not when it saves a PNG and loads that).

UV tiles: the ICT layout puts the parts "Face" in UDIM tile 1001 (u in [0, 1]) and
"Head and Neck" in 1002 (u in [1, 2]); the bake returns one texture per tile. Blender maps
either as a tiled (UDIM) image or, since an Image Texture node repeats by default, as one
image per material (u in [1, 2] samples the second image at u - 1).
"""

from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np
import scipy.ndimage as ndi
import scipy.sparse as sp

from .. import stored_arrays
from ..errors import as_points
from ..memo import memo
from .raster import first_per_pixel, rasterize

SKIN_PARTS = ("Face", "Head and Neck")
BLEED = 4  # default texels of bleed around the UV islands (BakeOptions.bleed)
#: The code a stored raster was computed by (``_stored_raster``): editing it stores anew.
_SOURCES = (Path(__file__), Path(__file__).with_name("raster.py"),
            Path(__file__).parent.parent / "model" / "head_model.py")


def orthographic_uvs(vertices, camera, image_size=None):
    """Texture coordinates of each vertex in one photo (thesis §5, eq. 48-49).

    The thesis maps the front photo orthographically: with the model in image-height
    units centred on the nose tip, u = (U_n + Y h) / b and v = 1 - V_n / h + X, i.e. the
    pixel the point projects to, divided by the image size, with v flipped because UVs
    start at the bottom-left. With a fitted camera that is exactly
    ``u = U / W, v = 1 - V / H`` for ``(U, V) = camera.project(vertex)``, which is what
    this computes (so it also works for a fitted, rotated or DLT camera).

    Parameters
    ----------
    vertices : ndarray, shape (V, 3), metres
        World positions (the fitted head).
    camera : Camera
        The photo's camera; its ``size`` (W, H) gives the image size unless
        ``image_size`` is given.
    image_size : (int, int), optional
        (width, height) in pixels of the photo the UVs index.

    Returns
    -------
    ndarray, shape (V, 2)
        UVs with (0, 0) at the photo's bottom-left and (1, 1) at its top-right (Blender's
        convention); points outside the photo get UVs outside [0, 1]. Per face corner:
        ``uv[model.loop_vertex]``.
    """
    x = as_points(vertices, "vertices")
    w, h = _image_size(camera, image_size, "camera")
    px = np.asarray(camera.project(x), dtype=np.float64)
    return np.column_stack([px[:, 0] / w, 1.0 - px[:, 1] / h])


def _image_size(camera, image_size, name):
    size = image_size if image_size is not None else getattr(camera, "size", None)
    if size is None:
        raise ValueError(f"{name}: has no size; pass image_size=(width, height)")
    w, h = (float(s) for s in size)
    if not (w > 0 and h > 0):
        raise ValueError(f"{name}: image size must be positive, got {tuple(size)}")
    return w, h


@dataclass(frozen=True, eq=False)
class UVRaster:
    """Which surface point every texel of one UV tile shows: built once per (model, size,
    parts, tile) because the UV layout never changes; reuse it for every bake.

    Attributes
    ----------
    size : int
        Texture width and height in texels.
    tile : int
        UDIM tile number (1001 + floor(u) + 10 floor(v)).
    parts : tuple of str
        Geometry parts rasterised.
    n_vertices : int
        Vertex count of the model.
    triangles : ndarray, shape (T, 3)
        Vertex indices of the tile's triangles.
    texel : ndarray, shape (N,), int32
        Flat index ``row * size + column`` of each covered texel (one triangle each).
    interp : scipy.sparse.csr_matrix, shape (N, V)
        Barycentric weights: ``interp @ vertex_values`` is the value at each texel.
    vertices : ndarray, shape (M,)
        Vertices of the tile's triangles (the hole fill's unknowns live among them).
    cover : ndarray, shape (M,), float32
        Each of ``vertices``' interpolation weights summed over the tile's texels (how much
        of the texture a vertex's value reaches).
    laplacian : scipy.sparse.csr_matrix, shape (M, M)
        Cotangent Laplacian over ``vertices`` (the tile's triangles, mean shape).
    bleed_to, bleed_from : ndarray, shape (B,)
        Flat texel indices: uncovered texels within ``bleed`` of an island and the nearest
        covered texel each copies.
    """

    size: int
    tile: int
    parts: tuple
    n_vertices: int
    triangles: np.ndarray
    texel: np.ndarray
    interp: sp.csr_matrix
    vertices: np.ndarray
    cover: np.ndarray
    laplacian: sp.csr_matrix
    bleed_to: np.ndarray
    bleed_from: np.ndarray

    @property
    def mask(self):
        """Covered texels, shape (size, size), bool (row 0 = top)."""
        m = np.zeros(self.size * self.size, dtype=bool)
        m[self.texel] = True
        return m.reshape(self.size, self.size)

    @property
    def gather(self):
        """``interp`` transposed, shape (V, N): ``gather @ texel_values`` sums them onto the
        vertices (0 off the tile). A view of ``interp`` (CSC), not a copy: a stored CSR
        transpose was 39 MB of a worker's 1024-texel rasters, and sums the same terms in
        the same order."""
        return self.interp.T


def resolve_parts(model, parts=None):
    """Part indices and names to rasterise and bake.

    Parameters
    ----------
    model : HeadModel
    parts : sequence of str or int, optional
        Part names (as in ``model.part_names``, case-insensitive) or indices. Default: the
        skin parts ("Face", "Head and Neck").

    Returns
    -------
    tuple of int, tuple of str
    """
    names = tuple(model.part_names)
    lower = {n.lower(): i for i, n in enumerate(names)}
    if parts is None:
        parts = [p for p in SKIN_PARTS if p.lower() in lower]
        if not parts:
            raise ValueError(f"parts: the model has none of the skin parts {SKIN_PARTS}; "
                             f"pass parts= from {names}")
    if isinstance(parts, str | int | np.integer):
        parts = [parts]
    idx = []
    for p in parts:
        if isinstance(p, str):
            if p.lower() not in lower:
                raise ValueError(f"parts: unknown part {p!r}; known: {', '.join(names)}")
            idx.append(lower[p.lower()])
        elif isinstance(p, int | np.integer) and 0 <= int(p) < len(names):
            idx.append(int(p))
        else:
            raise ValueError(f"parts: {p!r} is neither a part name nor an index "
                             f"0..{len(names) - 1}")
    idx = tuple(sorted(set(idx)))
    return idx, tuple(names[i] for i in idx)


def _texture_cache(model):
    """The model's triangle table and UV rasters, a dict kept with the model."""
    return memo(model, "texture cache", dict)


def _model_cached(model, key, build):
    """``build()`` once per model and key (topology and UVs never change); thread-safe."""
    cache = _texture_cache(model)
    try:
        return cache[key]
    except KeyError:
        pass
    return cache.setdefault(key, build())


def _triangle_table(model):
    """Every triangle's vertices (T, 3), corner UVs (T, 3, 2), part (T,) and UDIM tile."""
    tri_vertex, tri_loop, tri_face = model.triangles()
    uv = np.asarray(model.loop_uv, dtype=np.float64)[np.asarray(tri_loop)]
    corner = np.floor(uv.mean(axis=1)).astype(np.int64)
    tile = 1001 + corner[:, 0] + 10 * corner[:, 1]
    part = np.asarray(model.face_part)[np.asarray(tri_face)]
    return np.asarray(tri_vertex), uv, part, tile


def selected_triangles(model, part_idx):
    """Triangles (vertex indices, corner UVs) of the chosen parts and the UDIM tile of each."""
    tri_vertex, uv, part, tile = _model_cached(model, ("triangles",),
                                               lambda: _triangle_table(model))
    keep = np.isin(part, part_idx)
    return tri_vertex[keep], uv[keep], tile[keep]


def uv_tiles(model, parts=None):
    """UDIM tiles the chosen parts' UVs occupy, sorted (e.g. (1001, 1002) for the skin)."""
    idx, _ = resolve_parts(model, parts)
    _, _, tile = selected_triangles(model, idx)
    return tuple(int(t) for t in np.unique(tile))


def uv_raster(model, size=1024, *, parts=None, tile=None, bleed=BLEED):
    """The (cached) UV raster of one tile of the chosen parts.

    Parameters
    ----------
    model : HeadModel
    size : int
        Texture size in texels (square).
    parts : sequence of str or int, optional
        See :func:`resolve_parts`; default the skin.
    tile : int, optional
        UDIM tile; default the only tile the parts use (ValueError if they use several).
    bleed : int
        Texels of bleed around the islands.

    Returns
    -------
    UVRaster
    """
    size = _check_size(size)
    idx, names = resolve_parts(model, parts)
    tile = _pick_tile(model, idx, names, tile)
    bleed = int(bleed)
    if bleed < 0:
        raise ValueError(f"bleed: must be >= 0, got {bleed}")
    return _model_cached(model, ("raster", size, idx, tile, bleed),
                         lambda: _stored_raster(model, size, idx, names, tile, bleed))


def clear_raster_cache(model, stored=False):
    """Forget the UV rasters (and triangle table) cached for ``model``, e.g. to time a cold
    bake; with ``stored``, remove the ones stored beside its file too."""
    _texture_cache(model).clear()
    if stored:
        stored_arrays.remove_stored(model, "uv-raster")


def _stored_raster(model, size, idx, names, tile, bleed):
    """The raster from beside the model's file, else built (and stored there)."""
    parts = "_".join(map(str, idx))
    path = stored_arrays.stored_path(model, f"uv-raster-{size}-{tile}-{bleed}-p{parts}",
                                     (idx, names), _SOURCES)
    arrays = stored_arrays.load_arrays(path)
    if arrays is not None:
        try:
            return _raster_from_arrays(arrays)
        except (KeyError, ValueError):
            pass  # not a raster this code wrote: build it again
    raster = _build_raster(model, size, idx, names, tile, bleed)
    stored_arrays.save_arrays(path, _raster_arrays(raster))
    return raster


_SPARSE = ("interp", "laplacian")


def _raster_arrays(r):
    """A raster as a dict of arrays (the sparse matrices as their CSR arrays)."""
    out = {}
    for f in fields(r):
        v = getattr(r, f.name)
        if f.name in _SPARSE:
            for part in ("data", "indices", "indptr"):
                out[f"{f.name}.{part}"] = getattr(v, part)
            out[f"{f.name}.shape"] = np.asarray(v.shape)
        else:
            out[f.name] = np.asarray(v)
    return out


def _raster_from_arrays(a):
    """The raster :func:`_raster_arrays` stored."""
    kw = {}
    for f in fields(UVRaster):
        if f.name in _SPARSE:
            kw[f.name] = sp.csr_matrix((a[f"{f.name}.data"], a[f"{f.name}.indices"],
                                        a[f"{f.name}.indptr"]),
                                       shape=tuple(int(n) for n in a[f"{f.name}.shape"]))
        else:
            kw[f.name] = a[f.name]
    for name in ("size", "tile", "n_vertices"):
        kw[name] = int(kw[name])
    kw["parts"] = tuple(str(p) for p in kw["parts"])
    return UVRaster(**kw)


def _check_size(size):
    try:
        s = int(size)
    except (TypeError, ValueError):
        raise ValueError(f"size: expected a positive integer, got {size!r}") from None
    if s != size or not 8 <= s <= 16384:
        raise ValueError(f"size: expected an integer in 8..16384, got {size!r}")
    return s


def _pick_tile(model, idx, names, tile):
    _, _, tiles = selected_triangles(model, idx)
    present = sorted(int(t) for t in np.unique(tiles))
    if not present:
        raise ValueError(f"parts: {', '.join(names)} have no polygons")
    if tile is None:
        if len(present) > 1:
            raise ValueError(f"parts: {', '.join(names)} use UV tiles "
                             f"{', '.join(map(str, present))}; pass tile= or use bake_tiles()")
        return present[0]
    if int(tile) not in present:
        raise ValueError(f"tile: {tile!r} is not used by parts {', '.join(names)} "
                         f"(they use {', '.join(map(str, present))})")
    return int(tile)


def _build_raster(model, size, idx, names, tile, bleed):
    n_vertices = int(np.asarray(model.vertices).shape[0])
    tri_vertex, uv, tiles = selected_triangles(model, idx)
    sel = tiles == tile
    tri_vertex, uv = tri_vertex[sel], uv[sel]
    tu, tv = (tile - 1001) % 10, (tile - 1001) // 10
    # UV -> texel grid with row 0 at the top (v = 1)
    xy = np.stack([(uv[..., 0] - tu) * size, (1.0 - (uv[..., 1] - tv)) * size], axis=-1)
    pixel, tri, bary = rasterize(xy, size, size)
    texel, tri, bary = first_per_pixel(pixel, tri, bary)  # overlapping UVs: one wins
    texel = texel.astype(np.int32)  # at most 16384² texels

    n = len(texel)
    rows = np.repeat(np.arange(n), 3)
    interp = sp.csr_matrix((bary.ravel().astype(np.float32), (rows, tri_vertex[tri].ravel())),
                           shape=(n, n_vertices))
    interp.sum_duplicates()

    verts = np.unique(tri_vertex)
    lap = cotan_laplacian(np.asarray(model.vertices, dtype=np.float64)[verts],
                           np.searchsorted(verts, tri_vertex))

    covered = np.zeros((size, size), dtype=bool)
    covered.flat[texel] = True
    if bleed > 0 and n:
        dist, (ri, ci) = ndi.distance_transform_edt(~covered, return_indices=True)
        ring = (~covered) & (dist <= bleed)
        bleed_to = np.flatnonzero(ring)
        bleed_from = (ri * size + ci).ravel()[bleed_to]
    else:
        bleed_to = bleed_from = np.zeros(0, np.int64)
    # summed as the rows of a CSR transpose (numpy's pairwise sums), as bakes always have
    cover = np.asarray(interp.T.tocsr()[verts].sum(axis=1)).ravel()
    return UVRaster(size, tile, names, n_vertices, tri_vertex, texel, interp, verts, cover,
                    lap, bleed_to, bleed_from)


def mesh_laplacian(model, rasters):
    """The vertices (M,) of the rasters' triangles and the cotangent Laplacian (M, M) over
    them (mean shape): one tile's own (``UVRaster.laplacian``, kept with the raster), the
    union's for several tiles, whose shared vertices join them (kept with the model)."""
    if len(rasters) == 1:
        return rasters[0].vertices, rasters[0].laplacian

    def build():
        tris = np.concatenate([r.triangles for r in rasters])
        verts = np.unique(tris)
        return verts, cotan_laplacian(np.asarray(model.vertices, dtype=np.float64)[verts],
                                      np.searchsorted(verts, tris))

    key = ("mesh laplacian", tuple(sorted((r.tile, r.parts) for r in rasters)))
    return _model_cached(model, key, build)


def cotan_laplacian(points, triangles):
    """Cotangent Laplacian (M, M) of a triangle mesh, weights clamped positive.

    Geometric weights make the hole fill follow surface distance rather than mesh
    density (ICT is dense on the face, coarse on the skull); clamping obtuse corners'
    negative weights keeps the discrete maximum principle, so a fill never overshoots.
    """
    m = len(points)
    p = points[triangles]
    rows, cols, vals = [], [], []
    for k in range(3):  # the corner opposite each of a triangle's three edges
        i, j = (k + 1) % 3, (k + 2) % 3
        a, b = p[:, i] - p[:, k], p[:, j] - p[:, k]
        cross = np.linalg.norm(np.cross(a, b), axis=1)
        cot = np.einsum("ij,ij->i", a, b) / np.maximum(cross, 1e-30)
        rows.append(triangles[:, i])
        cols.append(triangles[:, j])
        vals.append(0.5 * np.clip(cot, -1e3, 1e3))
    r, c, v = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
    w = sp.coo_matrix((np.r_[v, v], (np.r_[r, c], np.r_[c, r])), shape=(m, m)).tocsr()
    w.sum_duplicates()
    floor = 1e-2 * np.abs(w.data).mean() if w.nnz else 0.0
    w.data = np.maximum(w.data, floor)
    return (sp.diags(np.asarray(w.sum(axis=1)).ravel()) - w).tocsr()
