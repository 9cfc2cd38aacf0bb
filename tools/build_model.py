"""Build HeadRecon's head model from ICT-FaceKit into ``generated/model/head_model.npz``.

    python -m tools.build_model [--if-missing] [--ict DIR] [--out FILE]

ICT-FaceKit (github.com/ICT-VGL/ICT-FaceKit, MIT) is read in either layout:

(a) the repository itself: ``DIR/FaceXModel/`` with ``generic_neutral_mesh.obj``,
    ``identity000.obj`` ... ``identity099.obj`` and one OBJ per expression (identity and
    expression shapes are those OBJs minus the neutral mesh);
(b) ``DIR/ict_shapes.npz`` (the same shapes as float32 arrays, see its SOURCE.txt) plus
    ``DIR/FaceXModel/generic_neutral_mesh.obj`` for faces and UVs.

``DIR`` may be the repository root or its ``FaceXModel`` folder. Default: ``--ict``, else
the environment variable ``HEADRECON_ICT_DIR``, else ``../shared/third_party/ict-facekit``
next to the repository.

ICT is in centimetres, Y up, face toward +Z; the model is stored in metres, Blender axes
(Z up, face toward -Y; the subject's left stays at +X): ``(x, y, z) -> 0.01 (x, -z, y)``.
Identity modes and expressions are stored as int16 with one scale per mode (expressions
sparsely, only the vertices they move) to keep the file small and quick to load. The
regional model of thesis §3.4 is computed here from ``assets/regions.json``.
"""

import argparse
import hashlib
import json
import os
import re
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from solver.io.obj import read_obj, read_obj_positions
from solver.model.head_model import MODEL_FORMAT, MODEL_FORMAT_VERSION, mesh_edges, vertex_adjacency
from solver.model.pca import fit_pca

# Bump when the builder's output changes for the same inputs (forces a rebuild).
BUILD_VERSION = 1

REPO_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_OUT = REPO_ROOT / "generated" / "model" / "head_model.npz"
LICENSE_NAME = "LICENSE-ICT-FaceKit.txt"
LANDMARKS_PATH = REPO_ROOT / "assets" / "landmarks.json"
REGIONS_PATH = REPO_ROOT / "assets" / "regions.json"
NEUTRAL_OBJ = "generic_neutral_mesh.obj"
SHAPES_NPZ = "ict_shapes.npz"
ICT_URL = "https://github.com/ICT-VGL/ICT-FaceKit"

# ICT README, "Face Model Topology": (name, first vertex, last vertex, first face, last face).
ICT_PARTS = (
    ("Face", 0, 9408, 0, 9229),
    ("Head and Neck", 9409, 11247, 9230, 11143),
    ("Mouth socket", 11248, 13293, 11144, 13225),
    ("Eye socket left", 13294, 13677, 13226, 13629),
    ("Eye socket right", 13678, 14061, 13630, 14033),
    ("Gums and tongue", 14062, 17038, 14034, 17005),
    ("Teeth", 17039, 21450, 17006, 21495),
    ("Eyeball left", 21451, 23020, 21496, 23093),
    ("Eyeball right", 23021, 24590, 23094, 24691),
    ("Lacrimal fluid left", 24591, 24794, 24692, 24854),
    ("Lacrimal fluid right", 24795, 24998, 24855, 25017),
    ("Eye blend left", 24999, 25022, 25018, 25032),
    ("Eye blend right", 25023, 25046, 25033, 25047),
    ("Eye occlusion left", 25047, 25198, 25048, 25175),
    ("Eye occlusion right", 25199, 25350, 25176, 25303),
    ("Eyelashes left", 25351, 26034, 25304, 25843),
    ("Eyelashes right", 26035, 26718, 25844, 26383),
)
SKIN_PARTS = ("Face", "Head and Neck")
N_VERTICES = ICT_PARTS[-1][2] + 1
N_FACES = ICT_PARTS[-1][4] + 1


class IctNotFoundError(FileNotFoundError):
    """ICT-FaceKit is not where we looked; the message says where to get it."""


@dataclass(frozen=True)
class IctLocation:
    """Where the ICT files are: ``model_dir`` holds the OBJs, ``root`` the licence."""

    root: Path
    model_dir: Path
    layout: str  # "npz" or "obj"
    shapes_npz: Path | None


@dataclass(frozen=True)
class IctSource:
    """ICT-FaceKit data as read (centimetres, ICT axes: Y up, face toward +Z).

    neutral (V, 3); identity (K, V, 3) at one standard deviation; expression (E, V, 3);
    mesh: the neutral OBJ (faces, UVs); license_text: LICENSE (+ CREDITS) to ship along.
    """

    location: IctLocation
    neutral: np.ndarray
    identity: np.ndarray
    identity_names: tuple
    expression: np.ndarray
    expression_names: tuple
    mesh: object
    license_text: str


def default_ict_dir():
    """``--ict`` default: env ``HEADRECON_ICT_DIR``, else ../shared/third_party/ict-facekit."""
    env = os.environ.get("HEADRECON_ICT_DIR")
    if env:
        return Path(env)
    return REPO_ROOT.parent / "shared" / "third_party" / "ict-facekit"


def not_found_message(directory, detail):
    return (f"ICT-FaceKit not found in {directory}: {detail}. HeadRecon's head model is built "
            f"from ICT-FaceKit (MIT licence): clone {ICT_URL} (git clone --depth 1 "
            f"{ICT_URL}.git) and pass its folder with --ict DIR or set HEADRECON_ICT_DIR "
            "(the repository root or its FaceXModel folder).")


def locate_ict(directory):
    """Find the ICT files under ``directory`` (repository root or its FaceXModel folder).

    Returns
    -------
    IctLocation

    Raises
    ------
    IctNotFoundError
        With a message saying where to get ICT-FaceKit.
    """
    directory = Path(directory).expanduser()
    if not directory.is_dir():
        raise IctNotFoundError(not_found_message(directory, "no such folder"))
    if (directory / "FaceXModel" / NEUTRAL_OBJ).is_file():
        root, model_dir = directory, directory / "FaceXModel"
    elif (directory / NEUTRAL_OBJ).is_file():
        root, model_dir = directory.parent, directory
    else:
        raise IctNotFoundError(not_found_message(
            directory, f"neither FaceXModel/{NEUTRAL_OBJ} nor {NEUTRAL_OBJ}"))
    for candidate in (model_dir / SHAPES_NPZ, root / SHAPES_NPZ):
        if candidate.is_file():
            return IctLocation(root, model_dir, "npz", candidate)
    if (model_dir / "identity000.obj").is_file():
        return IctLocation(root, model_dir, "obj", None)
    raise IctNotFoundError(not_found_message(
        directory, f"found {NEUTRAL_OBJ} but neither {SHAPES_NPZ} nor identity000.obj ... "
        "(the identity and expression OBJ files)"))


def _license_text(location):
    for folder in (location.root, location.model_dir):
        lic = folder / "LICENSE"
        if lic.is_file():
            text = lic.read_text(encoding="utf-8")
            credits = folder / "CREDITS.md"
            if credits.is_file():
                text += "\n\n" + credits.read_text(encoding="utf-8")
            return text
    raise IctNotFoundError(not_found_message(
        location.root, "its LICENSE file is missing (the MIT notice must ship with the model)"))


def read_shape_objs(model_dir, neutral):
    """Read layout (a): identityNNN.obj and expression OBJs minus the neutral mesh.

    Parameters
    ----------
    model_dir : Path
        The FaceXModel folder.
    neutral : ndarray, shape (V, 3)

    Returns
    -------
    identity (K, V, 3) float32, identity_names, expression (E, V, 3) float32,
    expression_names (names sorted, ICT file stems).
    """
    model_dir = Path(model_dir)
    objs = sorted(p for p in model_dir.glob("*.obj") if p.name != NEUTRAL_OBJ)
    ident = sorted((p for p in objs if re.fullmatch(r"identity\d+", p.stem)),
                   key=lambda p: int(p.stem[len("identity"):]))
    expr = sorted((p for p in objs if not re.fullmatch(r"identity\d+", p.stem)),
                  key=lambda p: p.stem)
    if not ident:
        raise IctNotFoundError(not_found_message(model_dir, "no identityNNN.obj files"))

    def deltas(paths):
        out = np.empty((len(paths),) + neutral.shape, dtype=np.float32)
        for i, p in enumerate(paths):
            pos = read_obj_positions(p)
            if pos.shape != neutral.shape:
                raise ValueError(f"{p}: {pos.shape[0]} vertices, but {NEUTRAL_OBJ} has "
                                 f"{neutral.shape[0]}")
            out[i] = pos - neutral
        return out

    return (deltas(ident), tuple(p.stem for p in ident), deltas(expr),
            tuple(p.stem for p in expr))


def read_ict(directory):
    """Read ICT-FaceKit in either layout (see module docstring).

    Returns
    -------
    IctSource
    """
    loc = locate_ict(directory)
    license_text = _license_text(loc)
    mesh = read_obj(loc.model_dir / NEUTRAL_OBJ)
    neutral = mesh.positions
    if loc.layout == "npz":
        with np.load(loc.shapes_npz, allow_pickle=False) as d:
            missing = {"neutral", "identity", "identity_names", "expression",
                       "expression_names"} - set(d.files)
            if missing:
                raise ValueError(f"{loc.shapes_npz}: missing arrays {sorted(missing)}")
            npz_neutral = d["neutral"].astype(np.float64)
            identity = d["identity"].astype(np.float32)
            identity_names = tuple(str(s) for s in d["identity_names"])
            expression = d["expression"].astype(np.float32)
            expression_names = tuple(str(s) for s in d["expression_names"])
        if npz_neutral.shape != neutral.shape or np.abs(npz_neutral - neutral).max() > 1e-3:
            raise ValueError(f"{loc.shapes_npz}: 'neutral' does not match "
                             f"{loc.model_dir / NEUTRAL_OBJ}")
        for name, arr in (("identity", identity), ("expression", expression)):
            if arr.ndim != 3 or arr.shape[1:] != neutral.shape:
                raise ValueError(f"{loc.shapes_npz}: '{name}' has shape {arr.shape}, expected "
                                 f"(n, {neutral.shape[0]}, 3)")
    else:
        identity, identity_names, expression, expression_names = read_shape_objs(
            loc.model_dir, neutral)
    return IctSource(loc, neutral, identity, identity_names, expression, expression_names,
                     mesh, license_text)


def to_blender(points_cm):
    """ICT centimetres (Y up, face +Z) -> metres, Blender axes (Z up, face -Y).

    ``(x, y, z) -> 0.01 (x, -z, y)``: a proper rotation (no mirroring), so the subject's
    left stays at +X.
    """
    p = np.asarray(points_cm, dtype=np.float64)
    return 0.01 * np.stack([p[..., 0], -p[..., 2], p[..., 1]], axis=-1)


def quantize(values, axis_keep=0):
    """int16 quantisation with one scale per slice along ``axis_keep``.

    Returns ``(q, scale)`` with ``values ~= q * scale`` (broadcast along the other axes);
    the error is at most ``scale / 2 = max|slice| / 65534``.
    """
    v = np.asarray(values, dtype=np.float64)
    other = tuple(i for i in range(v.ndim) if i != axis_keep)
    peak = np.abs(v).max(axis=other) if other else np.abs(v)
    scale = np.where(peak > 0, peak / 32767.0, 1.0)
    shape = [1] * v.ndim
    shape[axis_keep] = -1
    q = np.rint(v / scale.reshape(shape)).astype(np.int16)
    return q, scale


def part_indices(n_vertices, n_faces):
    """``vertex_part (V,)`` and ``face_part (F,)`` from the ICT README's index ranges."""
    if n_vertices != N_VERTICES or n_faces != N_FACES:
        raise ValueError(f"ICT neutral mesh has {n_vertices} vertices and {n_faces} faces; "
                         f"this builder knows the layout with {N_VERTICES} and {N_FACES} "
                         "(ICT Face Model Light)")
    vertex_part = np.empty(n_vertices, dtype=np.int8)
    face_part = np.empty(n_faces, dtype=np.int8)
    for i, (_, v0, v1, f0, f1) in enumerate(ICT_PARTS):
        vertex_part[v0:v1 + 1] = i
        face_part[f0:f1 + 1] = i
    return vertex_part, face_part


def builder_hash():
    """Hash of everything (ours) the model depends on besides ICT itself."""
    h = hashlib.sha256(f"headrecon-build-model {BUILD_VERSION}\n".encode())
    for path in (LANDMARKS_PATH, REGIONS_PATH):
        h.update(path.name.encode() + b"\n")
        h.update(path.read_bytes())
    return h.hexdigest()


def is_up_to_date(out_path):
    """True when ``out_path`` and its licence exist and were built from the current inputs."""
    out_path = Path(out_path)
    if not out_path.is_file() or not (out_path.parent / LICENSE_NAME).is_file():
        return False
    try:
        with np.load(out_path, allow_pickle=False) as d:
            return str(d["build_hash"]) == builder_hash()
    except (OSError, ValueError, KeyError):
        return False


# --------------------------------------------------------------------------- landmarks

VIEWS = ("front", "right", "left")


def load_landmark_set(path=LANDMARKS_PATH, n_vertices=N_VERTICES):
    """Read and check ``assets/landmarks.json``; returns its list of entries.

    Raises ValueError naming the file and the entry at fault.
    """
    path = Path(path)
    data = json.loads(path.read_text(encoding="utf-8"))
    if data.get("format") != "headrecon-landmark-set" or data.get("version") != 1:
        raise ValueError(f"{path}: expected format 'headrecon-landmark-set' version 1")
    entries = data.get("landmarks")
    if not isinstance(entries, list) or not entries:
        raise ValueError(f"{path}: 'landmarks' must be a non-empty list")
    seen, ibug, thesis = set(), {}, {}
    for i, e in enumerate(entries):
        where = f"{path}: landmarks[{i}]"
        name = e.get("name")
        if not isinstance(name, str) or not re.fullmatch(r"[a-z][a-z0-9_]*", name):
            raise ValueError(f"{where}: 'name' must be snake_case, got {name!r}")
        where = f"{path}: landmark {name!r}"
        if name in seen:
            raise ValueError(f"{where}: duplicate name")
        seen.add(name)
        v = e.get("vertex")
        if not isinstance(v, int) or not 0 <= v < n_vertices:
            raise ValueError(f"{where}: 'vertex' must be an int in 0..{n_vertices - 1}")
        views = e.get("views")
        if not isinstance(views, list) or not views or not set(views) <= set(VIEWS) \
                or len(set(views)) != len(views):
            raise ValueError(f"{where}: 'views' must be a non-empty subset of {list(VIEWS)}")
        outline = e.get("outline", [])
        if not isinstance(outline, list) or not set(outline) <= set(views) \
                or len(set(outline)) != len(outline):
            raise ValueError(f"{where}: 'outline' must be a subset of its 'views' {views}")
        if not isinstance(e.get("description"), str) or not e["description"].strip():
            raise ValueError(f"{where}: 'description' must be a non-empty string")
        for key, table, top in (("ibug", ibug, 68), ("thesis", thesis, 40)):
            num = e.get(key)
            if num is None:
                continue
            if not isinstance(num, int) or not 1 <= num <= top:
                raise ValueError(f"{where}: '{key}' must be null or an int in 1..{top}")
            if num in table:
                raise ValueError(f"{where}: '{key}' {num} already used by {table[num]!r}")
            table[num] = name
    return entries


# --------------------------------------------------------------------------- profile chain

def _walk(adj, start, stop_at):
    """Follow a path through a graph whose nodes have degree <= 2, from ``start``."""
    path, prev, cur = [start], -1, start
    while cur not in stop_at:
        nxt = [int(j) for j in adj.indices[adj.indptr[cur]:adj.indptr[cur + 1]] if j != prev]
        if not nxt:
            break
        prev, cur = cur, nxt[0]
        path.append(cur)
    return path


def profile_chain(vertices, edges, skin, lower_stomion, upper_stomion, tol=1e-6):
    """Midsagittal chain of skin vertices, front of neck -> lips -> nose -> skull -> nape.

    ICT's mesh is symmetric with a column of vertices at exactly x = 0. Restricted to
    those, the skin's edges form two paths that end inside the mouth: neck front -> chin
    -> lower lip -> (inner lower lip) and nape -> skull -> nose -> upper lip -> (inner
    upper lip). Each path is cut at its stomion (where the lips meet: iBUG 67 and 63) and
    the two are joined there, so the chain never goes into the mouth and back.

    Parameters
    ----------
    vertices : ndarray, shape (V, 3), metres, Blender axes
    edges : ndarray, shape (E, 2)
    skin : ndarray, shape (S,)
    lower_stomion, upper_stomion : int
        Vertices of the lower and upper lip's inner midline where the lips meet.
    tol : float
        |x| below which a vertex is on the midline, metres.

    Returns
    -------
    ndarray, shape (P,)
    """
    n = len(vertices)
    on_mid = np.zeros(n, dtype=bool)
    on_mid[skin] = np.abs(vertices[skin, 0]) < tol
    keep = on_mid[edges[:, 0]] & on_mid[edges[:, 1]]
    adj = vertex_adjacency(edges[keep], n).tocsr()
    deg = np.asarray(adj.sum(axis=1)).ravel()
    if deg.max() > 2:
        raise ValueError("profile chain: the midline vertices do not form simple paths")
    ends = np.flatnonzero(on_mid & (deg == 1))
    if not on_mid[lower_stomion] or not on_mid[upper_stomion]:
        raise ValueError("profile chain: a stomion vertex is not a midline skin vertex")
    # The two path ends lowest on the body are the bottom of the neck (front and nape);
    # the others lie inside the mouth.
    if ends.size < 2:
        raise ValueError("profile chain: the midline is not open at the neck")
    neck_ends = ends[np.argsort(vertices[ends, 2])[:2]]
    stops = {int(lower_stomion), int(upper_stomion)}
    paths = {}
    for end in neck_ends:
        path = _walk(adj, int(end), stops)
        paths[path[-1]] = path
    if set(paths) != stops:
        raise ValueError("profile chain: could not reach both stomion vertices from the neck")
    lower, upper = paths[int(lower_stomion)], paths[int(upper_stomion)]
    return np.array(lower + upper[::-1], dtype=np.int64)


# --------------------------------------------------------------------------- regions

def load_region_rules(path=REGIONS_PATH):
    """Read ``assets/regions.json`` (see the file's own ``rule`` text)."""
    path = Path(path)
    data = json.loads(path.read_text(encoding="utf-8"))
    if data.get("format") != "headrecon-region-rules" or data.get("version") != 1:
        raise ValueError(f"{path}: expected format 'headrecon-region-rules' version 1")
    regions = data.get("regions")
    if not isinstance(regions, list) or len(regions) < 2:
        raise ValueError(f"{path}: 'regions' must list at least two regions")
    names = [r.get("name") for r in regions]
    if len(set(names)) != len(names) or not all(isinstance(n, str) for n in names):
        raise ValueError(f"{path}: region names must be unique strings")
    if data.get("default_region") not in names:
        raise ValueError(f"{path}: 'default_region' must be one of {names}")
    for key in ("blend_rings", "components_per_region", "training_heads", "seed",
                "min_island_vertices"):
        if not isinstance(data.get(key), int) or data[key] < 0:
            raise ValueError(f"{path}: '{key}' must be a non-negative int")
    if data["training_heads"] % 2 or data["training_heads"] <= data["components_per_region"]:
        raise ValueError(f"{path}: 'training_heads' must be even and larger than "
                         "'components_per_region'")
    for region in regions:
        for j, shape in enumerate(region.get("ellipsoids", [])):
            if not isinstance(shape.get("center_landmarks"), list) or \
                    not shape["center_landmarks"] or len(shape.get("radii", [])) != 3:
                raise ValueError(f"{path}: region {region['name']!r} ellipsoid {j} needs "
                                 "'center_landmarks' (non-empty list) and 'radii' (3 numbers)")
    return data


def assign_regions(vertices, skin, rules, landmarks, adjacency=None):
    """Base region of every skin vertex from the ellipsoid rules of ``regions.json``.

    A region is a union of ellipsoids (centre: mean of landmark vertices plus an offset,
    radii in metres along X, Y, Z). Regions are tried in the order listed; the first whose
    ellipsoid holds a vertex takes it, and vertices no ellipsoid holds go to
    ``default_region``. With ``adjacency``, connected pieces of a region smaller than
    ``min_island_vertices`` (ellipsoids clipping a fold of the surface) are handed to the
    regions around them.

    Returns
    -------
    ndarray, shape (S,), int: region index of each skin vertex (order of ``skin``).
    """
    names = [r["name"] for r in rules["regions"]]
    p = vertices[skin]
    label = np.full(len(skin), -1, dtype=np.int64)
    for ri, region in enumerate(rules["regions"]):
        inside = np.zeros(len(skin), dtype=bool)
        for j, shape in enumerate(region.get("ellipsoids", [])):
            where = f"regions.json: region {region['name']!r} ellipsoid {j}"
            try:
                idx = [landmarks[n] for n in shape["center_landmarks"]]
            except KeyError as exc:
                raise ValueError(f"{where}: unknown landmark {exc}") from None
            centre = vertices[idx].mean(axis=0) + np.asarray(shape.get("offset", [0, 0, 0]))
            radii = np.asarray(shape["radii"], dtype=np.float64)
            if radii.shape != (3,) or (radii <= 0).any():
                raise ValueError(f"{where}: 'radii' must be three positive numbers (metres)")
            inside |= (((p - centre) / radii) ** 2).sum(axis=1) <= 1.0
        label[(label < 0) & inside] = ri
    label[label < 0] = names.index(rules["default_region"])
    if adjacency is not None and rules.get("min_island_vertices", 0) > 0:
        adj = adjacency[skin][:, skin].tocsr()
        label = _absorb_islands(adj, label, len(names), rules["min_island_vertices"])
    return label


def _absorb_islands(adj, label, n_regions, min_size):
    """Relabel connected pieces of a region with fewer than ``min_size`` vertices by the
    majority label of their neighbours (repeated until every vertex has a label)."""
    label = label.copy()
    for r in range(n_regions):
        members = np.flatnonzero(label == r)
        if members.size == 0:
            continue
        _, comp = connected_components(adj[members][:, members], directed=False)
        sizes = np.bincount(comp)
        label[members[sizes[comp] < min_size]] = -1
    adj = adj.astype(np.float64)
    while (label < 0).any():
        known = label >= 0
        onehot = sp.csr_matrix((np.ones(known.sum()), (np.flatnonzero(known), label[known])),
                               shape=(label.size, n_regions))
        votes = (adj @ onehot).toarray()
        todo = (~known) & (votes.sum(axis=1) > 0)
        if not todo.any():
            raise ValueError("regions: a piece of skin is not connected to any region")
        label[todo] = np.argmax(votes[todo], axis=1)
    return label


def ring_weights(adjacency, skin, label, n_regions, n_rings):
    """Ring-blended region weights (thesis §3.4, Fig. 6).

    Each region is grown by ``n_rings`` rings of skin neighbours; ring i adds weight
    1 / (i + 1) to the region's original 0/1 weight; weights are then normalised to sum
    to 1 per vertex.

    Returns
    -------
    ndarray, shape (R, V), float64: zero off the skin.
    """
    n = adjacency.shape[0]
    on_skin = np.zeros(n, dtype=bool)
    on_skin[skin] = True
    # adjacency restricted to skin vertices
    mask = sp.diags(on_skin.astype(np.float64))
    adj = (mask @ adjacency.astype(np.float64) @ mask).tocsr()
    weights = np.zeros((n_regions, n))
    for r in range(n_regions):
        member = np.zeros(n, dtype=bool)
        member[skin[label == r]] = True
        weights[r, member] = 1.0
        for ring in range(1, n_rings + 1):
            grown = (adj @ member.astype(np.float64)) > 0
            new = grown & ~member & on_skin
            weights[r, new] = 1.0 / (ring + 1)
            member |= new
    total = weights.sum(axis=0)
    weights[:, on_skin] /= total[on_skin]
    return weights


def regional_pca(identity_basis, weights, rules):
    """Per-region PCA (small-matrix trick, §2.1) of heads sampled from the identity model.

    Heads are drawn as ``+c`` / ``-c`` pairs (c ~ N(0, I)), so their mean is exactly the
    global mean and each region's PCA is centred where the regional model puts it.

    Parameters
    ----------
    identity_basis : ndarray, shape (K, V, 3), metres per standard deviation
    weights : ndarray, shape (R, V)
    rules : dict from regions.json

    Returns
    -------
    vertex : ndarray (N,), offsets (R + 1,), q : int16 (C, N, 3), scale (R, C),
    stddev (R, C): components (standard-normal units: unit direction times stddev) of each
    grown region ``r`` over ``vertex[offsets[r]:offsets[r+1]]``.
    """
    n_comp = rules["components_per_region"]
    n_heads = rules["training_heads"]
    rng = np.random.default_rng(rules["seed"])
    half = rng.standard_normal((n_heads // 2, identity_basis.shape[0]))
    coeffs = np.concatenate([half, -half])
    verts, comps, scales, sds = [], [], [], []
    for r in range(weights.shape[0]):
        v = np.flatnonzero(weights[r] > 0)
        b = identity_basis[:, v].reshape(identity_basis.shape[0], -1)
        samples = coeffs @ b  # offsets from the mean, (M, 3 n_r)
        pca = fit_pca(samples, n_components=n_comp)
        k = pca.components.shape[0]
        if k < n_comp:
            raise ValueError(f"region {r}: only {k} principal components, need {n_comp}")
        comp = (pca.components * pca.stddevs[:, None]).reshape(n_comp, v.size, 3)
        q, s = quantize(comp, axis_keep=0)
        verts.append(v)
        comps.append(q)
        scales.append(s)
        sds.append(pca.stddevs)
    offsets = np.concatenate([[0], np.cumsum([len(v) for v in verts])])
    return (np.concatenate(verts), offsets, np.concatenate(comps, axis=1), np.array(scales),
            np.array(sds))


# --------------------------------------------------------------------------- build

def _publish(tmp, path):
    """Give the temp file ordinary permissions (mkstemp makes it private), then rename."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    os.replace(tmp, path)


def _atomic_write(path, write):
    """Call ``write(f)`` on a binary temp file next to ``path``, then rename it to ``path``:
    a reader never sees a half-written file, and a failure leaves no temp file behind."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name + ".", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
        _publish(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def build_arrays(src, log=print):
    """Everything the model file holds, from an :class:`IctSource`. Returns a dict."""
    mesh = src.mesh
    n = src.neutral.shape[0]
    vertex_part, face_part = part_indices(n, mesh.face_loop_start.size)
    if (mesh.loop_uv < 0).any():
        raise ValueError(f"{src.location.model_dir / NEUTRAL_OBJ}: some face corners lack UVs")
    vertices = to_blender(src.neutral)
    skin = np.flatnonzero(np.isin(vertex_part, [i for i, p in enumerate(ICT_PARTS)
                                                if p[0] in SKIN_PARTS]))

    # Identity: 1-sigma modes (metres per standard deviation).
    identity = to_blender(src.identity)
    id_q, id_scale = quantize(identity, axis_keep=0)
    id_stddev = np.linalg.norm(identity.reshape(len(identity), -1), axis=1)

    # Expressions: sparse, only vertices whose quantised offset is non-zero.
    expr = to_blender(src.expression)
    ex_peak = np.abs(expr).max(axis=(1, 2))
    ex_scale = np.where(ex_peak > 0, ex_peak / 32767.0, 1.0)
    ex_q_full = np.rint(expr / ex_scale[:, None, None]).astype(np.int16)
    moved = (ex_q_full != 0).any(axis=2)
    ex_q = ex_q_full[moved]  # (N, 3), expression-major order, as np.nonzero(moved)
    log(f"  expressions: {len(expr)} shapes, {len(ex_q)} moved vertices stored")

    entries = load_landmark_set(LANDMARKS_PATH, n)
    landmarks = {e["name"]: e["vertex"] for e in entries}
    ibug = {e["ibug"]: e["vertex"] for e in entries if e.get("ibug")}
    edges = mesh_edges(mesh.loop_vertex, mesh.face_loop_start, mesh.face_loop_total)
    chain = profile_chain(vertices, edges, skin, lower_stomion=ibug[67], upper_stomion=ibug[63])

    rules = load_region_rules(REGIONS_PATH)
    region_names = [r["name"] for r in rules["regions"]]
    adjacency = vertex_adjacency(edges, n)
    label = assign_regions(vertices, skin, rules, landmarks, adjacency)
    weights = ring_weights(adjacency, skin, label, len(region_names), rules["blend_rings"])
    reg_vertex, reg_offsets, reg_q, reg_scale, reg_sd = regional_pca(
        identity, weights, rules)
    log("  regions: " + ", ".join(f"{nm} {int((label == i).sum())}"
                                   for i, nm in enumerate(region_names)))

    return {
        "format": np.array(MODEL_FORMAT),
        "format_version": np.array(MODEL_FORMAT_VERSION),
        "build_hash": np.array(builder_hash()),
        "build_version": np.array(BUILD_VERSION),
        "vertices": vertices,
        "source_index": np.arange(n, dtype=np.int32),
        "loop_vertex": mesh.loop_vertex.astype(np.int32),
        "face_loop_start": mesh.face_loop_start.astype(np.int32),
        "face_loop_total": mesh.face_loop_total.astype(np.int32),
        "loop_uv": mesh.uvs[mesh.loop_uv].astype(np.float32),
        "face_part": face_part,
        "vertex_part": vertex_part,
        "part_names": np.array([p[0] for p in ICT_PARTS]),
        "identity_q": id_q,
        "identity_scale": id_scale,
        "identity_stddev": id_stddev,
        "identity_names": np.array([f"identity_{i:03d}" for i in range(len(identity))]),
        "expression_names": np.array(src.expression_names),
        "expression_moved": np.packbits(moved, axis=1),  # (E, ceil(V / 8)) bit masks
        "expression_q": ex_q,
        "expression_scale": ex_scale,
        "skin": skin.astype(np.int32),
        "region_names": np.array(region_names),
        "region_label": label.astype(np.int8),
        "region_weights": weights.astype(np.float32),
        "regional_vertex": reg_vertex.astype(np.int32),
        "regional_offsets": reg_offsets.astype(np.int64),
        "regional_q": reg_q,
        "regional_scale": reg_scale,
        "regional_stddev": reg_sd,
        "landmarks_json": np.array(json.dumps({"format": "headrecon-landmark-set",
                                               "version": 1, "landmarks": entries})),
        "profile_chain": chain.astype(np.int32),
    }


def build(ict_dir=None, out_path=DEFAULT_OUT, log=print):
    """Build the model file (and its licence next to it). Returns the output path."""
    ict_dir = Path(ict_dir) if ict_dir else default_ict_dir()
    out_path = Path(out_path)
    t0 = time.perf_counter()
    src = read_ict(ict_dir)
    log(f"read ICT-FaceKit ({src.location.layout} layout) from {src.location.root} "
        f"in {time.perf_counter() - t0:.1f} s")
    arrays = build_arrays(src, log)
    source_note = ""
    source_txt = src.location.root / "SOURCE.txt"
    if source_txt.is_file():
        source_note = source_txt.read_text(encoding="utf-8").strip() + "\n\n"
    notice = ("head_model.npz in this folder is derived from ICT-FaceKit "
              f"({ICT_URL}), USC Institute for Creative Technologies, and used under the MIT "
              "licence below. It is generated by HeadRecon's tools/build_model.py and is not "
              "part of HeadRecon's source repository.\n\n"
              + source_note + src.license_text.strip() + "\n")
    _atomic_write(out_path.parent / LICENSE_NAME, lambda f: f.write(notice.encode("utf-8")))
    # last: a complete npz means a complete build
    _atomic_write(out_path, lambda f: np.savez(f, **arrays))
    return out_path


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m tools.build_model",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--ict", metavar="DIR",
                        help="ICT-FaceKit folder (repository root or FaceXModel); default: "
                             "$HEADRECON_ICT_DIR or ../shared/third_party/ict-facekit")
    parser.add_argument("--out", metavar="FILE", default=str(DEFAULT_OUT),
                        help="output .npz (default: generated/model/head_model.npz)")
    parser.add_argument("--if-missing", action="store_true",
                        help="do nothing when the model exists and is up to date")
    args = parser.parse_args(argv)
    out = Path(args.out)
    if args.if_missing and is_up_to_date(out):
        print(f"head model up to date: {out}")
        return 0
    t0 = time.perf_counter()
    try:
        build(args.ict, out)
    except IctNotFoundError as exc:
        if args.if_missing and out.is_file():
            # Keep working with the model we have rather than stop the user's command.
            print(f"warning: {out} is out of date (built by another builder version or from "
                  f"other landmarks/regions) and cannot be rebuilt: {exc}", file=sys.stderr)
            return 0
        print(f"error: {exc}", file=sys.stderr)
        return 2
    elapsed = time.perf_counter() - t0
    with np.load(out, allow_pickle=False) as d:
        n_v = d["vertices"].shape[0]
        n_id = d["identity_q"].shape[0]
        n_ex = d["expression_names"].shape[0]
        n_skin = d["skin"].shape[0]
        n_lm = len(json.loads(str(d["landmarks_json"]))["landmarks"])
        n_chain = d["profile_chain"].shape[0]
        regions = [str(s) for s in d["region_names"]]
        n_comp = d["regional_q"].shape[0]
    size = out.stat().st_size
    print(f"wrote {out} ({size / 1e6:.1f} MB) in {elapsed:.1f} s")
    print(f"  {n_v} vertices ({n_skin} skin), {n_id} identity modes, {n_ex} expressions, "
          f"{n_lm} landmarks, profile chain of {n_chain} vertices")
    print(f"  {len(regions)} regions ({', '.join(regions)}), {n_comp} components each")
    return 0


if __name__ == "__main__":
    sys.exit(main())
