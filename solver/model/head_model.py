"""The bundled head model: ICT-FaceKit's mesh, identity and expression shapes, our landmarks,
the midsagittal profile chain and the seven-region model of thesis §3.4.

``tools/build_model.py`` writes everything into one ``.npz`` (quantised to int16 to stay
small); :func:`load_model` reads it back into float64 arrays in metres, Blender axes
(Z up, face toward -Y, subject's left +X). The file is derived from ICT-FaceKit (MIT): its
licence travels next to it as ``LICENSE-ICT-FaceKit.txt``.
"""

import functools
import json
import threading
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from ..io.landmark_set import LandmarkSet
from ..memo import memo
from ..paths import model_path
from .linear_model import LinearModel

MODEL_FORMAT = "headrecon-head-model"
MODEL_FORMAT_VERSION = 1

_cache = {}
_cache_lock = threading.Lock()


def mesh_edges(loop_vertex, face_loop_start, face_loop_total):
    """Unique undirected edges of a polygon mesh.

    Parameters
    ----------
    loop_vertex : ndarray, shape (L,)
    face_loop_start, face_loop_total : ndarray, shape (F,)

    Returns
    -------
    ndarray, shape (E, 2), int64
        Each edge once, smaller vertex index first, sorted.
    """
    loop_vertex = np.asarray(loop_vertex, dtype=np.int64)
    start = np.asarray(face_loop_start, dtype=np.int64)
    total = np.asarray(face_loop_total, dtype=np.int64)
    nxt = np.arange(loop_vertex.size, dtype=np.int64) + 1
    last = start + total - 1
    nxt[last] = start  # close each polygon
    a, b = loop_vertex, loop_vertex[nxt]
    edges = np.stack([np.minimum(a, b), np.maximum(a, b)], axis=1)
    return np.unique(edges, axis=0)


def vertex_adjacency(edges, n_vertices):
    """Symmetric boolean adjacency matrix (CSR, shape (V, V)) from edges (E, 2)."""
    edges = np.asarray(edges, dtype=np.int64)
    ones = np.ones(2 * len(edges), dtype=bool)
    rows = np.concatenate([edges[:, 0], edges[:, 1]])
    cols = np.concatenate([edges[:, 1], edges[:, 0]])
    return sp.csr_matrix((ones, (rows, cols)), shape=(n_vertices, n_vertices))


def fan_triangles(face_loop_start, face_loop_total):
    """Fan triangulation of polygons: corner indices (T, 3) and the face of each (T,)."""
    start = np.asarray(face_loop_start, dtype=np.int64)
    total = np.asarray(face_loop_total, dtype=np.int64)
    n_tri = total - 2
    tri_face = np.repeat(np.arange(start.size), n_tri)
    # k-th triangle of its face: corners (0, k+1, k+2) of the polygon.
    k = np.arange(tri_face.size) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri)
    s = start[tri_face]
    tri_loop = np.stack([s, s + k + 1, s + k + 2], axis=1)
    return tri_loop, tri_face


class HeadModel:
    """The statistical head model in metres, Blender axes (see module docstring).

    Attributes
    ----------
    vertices : ndarray, shape (V, 3)
        Mean shape (ICT neutral), metres. V = 26719, ICT vertex order.
    source_index : ndarray, shape (V,)
        ICT vertex index of each vertex (identity: all vertices are kept in order).
    loop_vertex : ndarray, shape (L,)
        Vertex of each face corner.
    face_loop_start, face_loop_total : ndarray, shape (F,)
        First corner and corner count of each polygon (quads and triangles).
    loop_uv : ndarray, shape (L, 2)
        ICT texture coordinates of each corner.
    face_part : ndarray, shape (F,)
        Index into ``part_names`` of each polygon.
    vertex_part : ndarray, shape (V,)
        Index into ``part_names`` of each vertex.
    part_names : tuple of str, length 17
        ICT geometry parts ("Face", "Head and Neck", "Mouth socket", ...).
    identity : LinearModel
        100 identity modes over all V, standard-normal coefficients, names identity_000...
    expressions : ndarray, shape (E, V, 3)
        Expression offsets (metres) at full strength, E = 57.
    expression_names : tuple of str
        ARKit-style names (``browDown_L``, ``jawOpen``...). ``_L`` is the subject's left.
    skin : ndarray, shape (S,)
        Vertices of the parts Face and Head and Neck (S = 11248): what fits work on.
    region_names : tuple of str, length R = 7
    region_weights : ndarray, shape (R, V)
        Ring-blended region weights (§3.4): sum to 1 on the skin, 0 off it. A vertex
        belongs to grown region r where ``region_weights[r] > 0``.
    region_label : ndarray, shape (V,)
        Base (un-grown) region of each vertex, -1 off the skin.
    two_region_vertices : ndarray, shape (G / 3,)
        Vertices in exactly two grown regions, in the order of the ``gamma`` row triples
        of :meth:`regional`.
    landmarks : dict of str -> int
        Landmark name -> vertex.
    landmark_info : list of dict
        The entries of ``assets/landmarks.json`` (name, description, vertex, views, ibug,
        thesis) as they were when the model was built.
    landmark_set : LandmarkSet
        Those entries as a landmark set: resolves names and their ``ibugNN`` aliases.
    profile_chain : ndarray, shape (P,)
        Midsagittal skin vertices ordered front of neck, chin, lips, nose, forehead, over
        the skull, back of neck.
    build_hash : str
        Hash of the builder inputs the file was made from.
    """

    def __init__(self, arrays, path):
        a = arrays
        fmt = str(a["format"])
        version = int(a["format_version"])
        if fmt != MODEL_FORMAT or version != MODEL_FORMAT_VERSION:
            raise ValueError(f"{path}: not a HeadRecon head model of format version "
                             f"{MODEL_FORMAT_VERSION} (got {fmt!r} version {version}); "
                             "rebuild it with `./run model`")
        self.path = str(path)
        self.build_hash = str(a["build_hash"])
        self.vertices = a["vertices"].astype(np.float64)
        n = self.vertices.shape[0]
        self.source_index = a["source_index"].astype(np.int64)
        self.loop_vertex = a["loop_vertex"].astype(np.int64)
        self.face_loop_start = a["face_loop_start"].astype(np.int64)
        self.face_loop_total = a["face_loop_total"].astype(np.int64)
        self.loop_uv = a["loop_uv"].astype(np.float64)
        self.face_part = a["face_part"].astype(np.int64)
        self.vertex_part = a["vertex_part"].astype(np.int64)
        self.part_names = tuple(str(s) for s in a["part_names"])

        basis = np.multiply(a["identity_q"], a["identity_scale"][:, None, None])
        self.identity = LinearModel(self.vertices, basis, a["identity_stddev"].astype(np.float64),
                                    tuple(str(s) for s in a["identity_names"]))

        self.expression_names = tuple(str(s) for s in a["expression_names"])
        # Expressions are dequantised on first use (see ``expressions``): few callers need
        # them and the scatter is the slowest part of loading.
        self._expression_moved = a["expression_moved"]
        self._expression_q = a["expression_q"]
        self._expression_scale = a["expression_scale"].astype(np.float64)

        self.skin = a["skin"].astype(np.int64)
        self.region_names = tuple(str(s) for s in a["region_names"])
        self.region_weights = a["region_weights"].astype(np.float64)
        # stored as float32: renormalise so they sum to 1 on the skin to float64 precision
        self.region_weights[:, self.skin] /= self.region_weights[:, self.skin].sum(axis=0)
        self.region_label = np.full(n, -1, dtype=np.int64)
        self.region_label[self.skin] = a["region_label"]
        self._regional_vertex = a["regional_vertex"].astype(np.int64)
        self._regional_offsets = a["regional_offsets"].astype(np.int64)
        self._regional_q = a["regional_q"]
        self._regional_scale = a["regional_scale"].astype(np.float64)
        self._regional_stddev = a["regional_stddev"].astype(np.float64)
        # Vertices in exactly two grown regions: one Gamma row triple each (x, y, z).
        self.two_region_vertices = np.flatnonzero((self.region_weights > 0).sum(axis=0) == 2)
        self._regional_cache = {}
        self._regional_lock = threading.Lock()

        self.landmark_info = json.loads(str(a["landmarks_json"]))["landmarks"]
        self.landmark_set = LandmarkSet.from_entries(self.landmark_info, self.path)
        self.landmarks = dict(self.landmark_set.vertices)
        self.profile_chain = a["profile_chain"].astype(np.int64)

    @property
    def n_vertices(self):
        return self.vertices.shape[0]

    @functools.cached_property
    def expressions(self):
        """Expression offsets at full strength, shape (E, V, 3), metres."""
        n = self.n_vertices
        # Sparse storage: a bit mask of moved vertices per expression, int16 offsets.
        moved = np.unpackbits(self._expression_moved, axis=1, count=n).astype(bool)
        scale = np.repeat(self._expression_scale, moved.sum(axis=1))
        expr = np.zeros((len(self.expression_names), n, 3))
        expr[moved] = self._expression_q * scale[:, None]
        return expr

    def expression_offsets(self, weights):
        """Offsets (V, 3), metres, of the expressions ``weights`` ({name in
        ``expression_names``: weight}) together."""
        out = np.zeros((self.n_vertices, 3))
        for name, w in weights.items():
            out += w * self.expressions[self.expression_names.index(name)]
        return out

    def triangles(self):
        """Fan triangulation of the polygons.

        Returns
        -------
        tri_vertex : ndarray, shape (T, 3)
            Vertex indices of each triangle.
        tri_loop : ndarray, shape (T, 3)
            Corner (loop) indices, e.g. to look up ``loop_uv``.
        tri_face : ndarray, shape (T,)
            Polygon each triangle comes from.
        """
        tri_loop, tri_face = fan_triangles(self.face_loop_start, self.face_loop_total)
        return self.loop_vertex[tri_loop], tri_loop, tri_face

    def skin_triangles(self):
        """Vertex indices (T, 3) of the triangles whose corners are all skin (face, head
        and neck): the surface a photo sees, which hides the eyeballs. Kept with the
        model."""
        def make():
            tri_vertex = self.triangles()[0]
            skin = np.zeros(self.n_vertices, bool)
            skin[self.skin] = True
            out = tri_vertex[skin[tri_vertex].all(axis=1)]
            out.setflags(write=False)  # shared by every caller
            return out

        return memo(self, "skin_triangles", make)

    def edges(self):
        """Unique undirected mesh edges, shape (E, 2)."""
        return mesh_edges(self.loop_vertex, self.face_loop_start, self.face_loop_total)

    def landmark_vertex(self, name):
        """Vertex index of landmark ``name``; ``ibug01`` ... ``ibug68`` are accepted too
        (``landmark_set`` resolves them).

        Raises ValueError naming the landmark when it is unknown.
        """
        return self.landmark_set.vertex(name)

    def regional(self, n_per_region=10):
        """The seven-region model (thesis §3.4) as one LinearModel over all V vertices.

        Parameters
        ----------
        n_per_region : int
            Principal components kept per region (1 .. the number stored in the file).

        Returns
        -------
        LinearModel
            ``mean`` is the global mean shape; coefficient ``(r, k)`` (named
            ``<region>_NN``) moves vertex v by ``region_weights[r, v]`` times region r's
            k-th component (standard-normal units, zero off the skin). ``gamma`` has three
            rows per vertex lying in exactly two grown regions j, k: P_v^(j) - P_v^(k)
            over the coefficients, with the unweighted components (thesis eq. 40-41).
            Results are cached per ``n_per_region``; treat them as read-only.
        """
        n_stored = self._regional_q.shape[1]
        k = int(n_per_region)
        if not 1 <= k <= n_stored:
            raise ValueError(f"n_per_region: must be in 1..{n_stored}, got {n_per_region}")
        with self._regional_lock:
            if k not in self._regional_cache:
                self._regional_cache[k] = self._build_regional(k)
            return self._regional_cache[k]

    def region_basis(self, region, n_components=None):
        """One grown region's own PCA, without blend weights.

        Parameters
        ----------
        region : str or int
            Region name or index into ``region_names``.
        n_components : int, optional
            Components to return (default: all stored).

        Returns
        -------
        vertices : ndarray, shape (n_r,)
            The grown region's vertices (``region_weights[r] > 0``), sorted.
        components : ndarray, shape (k, n_r, 3)
            Principal components in standard-normal units (metres per unit coefficient).
        stddev : ndarray, shape (k,), metres
        """
        if isinstance(region, str):
            if region not in self.region_names:
                raise ValueError(f"region {region!r}: unknown, expected one of "
                                 f"{list(self.region_names)}")
            r = self.region_names.index(region)
        else:
            r = int(region)
            if not 0 <= r < len(self.region_names):
                raise ValueError(f"region: index {region} out of range")
        k = self._regional_q.shape[0] if n_components is None else int(n_components)
        if not 1 <= k <= self._regional_q.shape[0]:
            raise ValueError(f"n_components: must be in 1..{self._regional_q.shape[0]}, got {k}")
        lo, hi = self._regional_offsets[r], self._regional_offsets[r + 1]
        comp = self._regional_q[:k, lo:hi].astype(np.float64)
        comp *= self._regional_scale[r, :k, None, None]
        return self._regional_vertex[lo:hi].copy(), comp, self._regional_stddev[r, :k].copy()

    def _build_regional(self, k):
        n_reg = len(self.region_names)
        n = self.n_vertices
        basis = np.zeros((n_reg, k, n, 3))
        two = self.two_region_vertices
        owners = self.region_weights[:, two] > 0
        first = np.argmax(owners, axis=0)  # smaller region index of the pair gets sign +
        gamma = np.zeros((two.size, 3, n_reg, k))
        for r in range(n_reg):
            verts, comp, _ = self.region_basis(r, k)  # comp (k, n_r, 3)
            basis[r][:, verts] = comp * self.region_weights[r, verts][None, :, None]
            pos = np.minimum(np.searchsorted(verts, two), verts.size - 1)
            inside = verts[pos] == two
            sign = np.where(first[inside] == r, 1.0, -1.0)
            gamma[inside, :, r, :] = sign[:, None, None] * comp[:, pos[inside]].transpose(1, 2, 0)
        names = tuple(f"{name}_{i:02d}" for name in self.region_names for i in range(k))
        return LinearModel(self.vertices, basis.reshape(n_reg * k, n, 3),
                           self._regional_stddev[:, :k].reshape(-1), names,
                           gamma.reshape(two.size * 3, n_reg * k))


def load_model(path=None):
    """Load the head model (cached per path).

    Parameters
    ----------
    path : str or Path, optional
        Default: environment variable ``HEADRECON_MODEL``, else
        ``<package root>/generated/model/head_model.npz``.

    Returns
    -------
    HeadModel

    Raises
    ------
    FileNotFoundError
        When the file does not exist (the message says how to build it).
    """
    if path is None:
        path = model_path()
    path = Path(path).resolve()
    key = str(path)
    with _cache_lock:
        if key in _cache:
            return _cache[key]
        if not path.is_file():
            raise FileNotFoundError(
                f"head model not found: {path}. Build it from ICT-FaceKit with `./run model` "
                "(or `python -m tools.build_model`), or point HEADRECON_MODEL at a built "
                "head_model.npz")
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
        model = HeadModel(arrays, path)
        _cache[key] = model
        return model
