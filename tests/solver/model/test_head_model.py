"""The head model: the builder (tools/build_model.py), the loader
(solver/model/head_model.py) and our landmark and region assets."""

import json
import shutil
import subprocess

import numpy as np
import pytest

from solver.model.head_model import fan_triangles, load_model, mesh_edges
from solver.paths import DEFAULT_MODEL_PATH
from tests import ROOT as REPO
from tools import build_model as bm

ICT_DIR = bm.default_ict_dir()
HAVE_ICT = (ICT_DIR / bm.SHAPES_NPZ).is_file() or (ICT_DIR / "FaceXModel" / "identity000.obj"
                                                   ).is_file()
needs_ict = pytest.mark.skipif(not HAVE_ICT, reason=f"ICT-FaceKit not present in {ICT_DIR}")
# --------------------------------------------------------------------------- loading, shapes

def test_model_loads_with_expected_shapes(model):
    v = model.n_vertices
    assert v == 26719
    assert model.vertices.shape == (v, 3) and model.vertices.dtype == np.float64
    np.testing.assert_array_equal(model.source_index, np.arange(v))
    assert model.identity.basis.shape == (100, v, 3)
    assert model.identity.mean.shape == (v, 3)
    assert model.identity.names[0] == "identity_000" and model.identity.names[-1] == "identity_099"
    assert model.expressions.shape == (57, v, 3)
    assert len(model.expression_names) == 57 and "jawOpen" in model.expression_names
    assert len(model.part_names) == 17 and model.part_names[:2] == ("Face", "Head and Neck")
    assert model.skin.shape == (11248,)
    np.testing.assert_array_equal(model.skin, np.arange(11248))  # Face + Head and Neck
    n_faces = model.face_loop_start.shape[0]
    assert n_faces == 26384 and model.face_part.shape == (n_faces,)
    assert model.loop_vertex.shape == (int(model.face_loop_total.sum()),)
    assert model.loop_uv.shape == (model.loop_vertex.shape[0], 2)
    np.testing.assert_array_equal(model.face_loop_start[1:],
                                  np.cumsum(model.face_loop_total)[:-1])
    # ICT README table: faces per part; a part's faces use its own vertices (and, where
    # parts are sewn to the face, Face vertices)
    counts = np.bincount(model.face_part, minlength=17)
    assert counts[0] == 9230 and counts[1] == 1914 and counts[6] == 4490 and counts[16] == 540
    loop_face = np.repeat(np.arange(n_faces), model.face_loop_total)
    vpart = model.vertex_part[model.loop_vertex]
    fpart = model.face_part[loop_face]
    assert ((vpart == fpart) | (vpart == 0)).all()
    assert np.bincount(model.vertex_part, minlength=17)[[0, 1, 15]].tolist() == [9409, 1839, 684]
    assert len(model.region_names) == 7
    assert model.region_weights.shape == (7, v)


def test_load_model_is_cached_and_missing_file_says_how_to_build(tmp_path):
    assert load_model() is load_model(DEFAULT_MODEL_PATH)
    with pytest.raises(FileNotFoundError, match="run model"):
        load_model(tmp_path / "nope.npz")


def test_triangles_cover_every_polygon(model):
    tri_vertex, tri_loop, tri_face = model.triangles()
    assert tri_vertex.shape == (int((model.face_loop_total - 2).sum()), 3)
    np.testing.assert_array_equal(model.loop_vertex[tri_loop], tri_vertex)
    np.testing.assert_array_equal(np.bincount(tri_face), model.face_loop_total - 2)
    # no degenerate triangles
    assert (tri_vertex[:, 0] != tri_vertex[:, 1]).all()
    assert (tri_vertex[:, 1] != tri_vertex[:, 2]).all()


def test_fan_triangles_and_edges_of_a_quad_and_a_triangle():
    start, total = np.array([0, 4]), np.array([4, 3])
    tri_loop, tri_face = fan_triangles(start, total)
    np.testing.assert_array_equal(tri_loop, [[0, 1, 2], [0, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(tri_face, [0, 0, 1])
    loops = np.array([0, 1, 2, 3, 2, 1, 4])
    edges = mesh_edges(loops, start, total)
    np.testing.assert_array_equal(edges, [[0, 1], [0, 3], [1, 2], [1, 4], [2, 3], [2, 4]])


# --------------------------------------------------------------------------- units and axes

def test_metres_z_up_face_toward_minus_y_subject_left_plus_x(model):
    p = model.vertices
    face_lm = [e["vertex"] for e in model.landmark_info if e["vertex"] < 9409]
    tip = model.landmark_vertex("nose_tip")
    assert p[tip, 1] == pytest.approx(p[face_lm, 1].min())  # most forward face landmark
    assert p[tip, 1] < -0.1  # nose ~13 cm in front of the ICT origin: metres, not cm
    skin = p[model.skin]
    assert p[model.landmark_vertex("head_top"), 2] == pytest.approx(skin[:, 2].max())
    height = np.ptp(skin[:, 2])
    assert 0.25 < height < 0.45  # head and neck, metres
    # ICT's Multi-PIE landmark 36 (0-based) = iBUG 37 is the subject's RIGHT eye's outer
    # corner: it must come out at -X, the subject's left eye at +X.
    assert model.landmark_vertex("ibug37") == 1507
    assert p[1507, 0] < -0.03
    assert p[model.landmark_vertex("eye_outer_left"), 0] > 0.03
    # eyes above the mouth, mouth above the chin
    assert p[model.landmark_vertex("eye_outer_left"), 2] > p[model.landmark_vertex(
        "mouth_middle"), 2] > p[model.landmark_vertex("chin_bottom"), 2]


def test_to_blender_is_a_proper_rotation_in_metres():
    m = bm.to_blender(np.eye(3))  # rows: images of the ICT unit axes
    np.testing.assert_allclose(m, 0.01 * np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]]))
    assert np.linalg.det(m / 0.01) == pytest.approx(1.0)  # no mirroring


# --------------------------------------------------------------------------- identity, expressions

def test_identity_stddev_is_the_norm_of_each_one_sigma_mode(model):
    norms = np.linalg.norm(model.identity.basis.reshape(100, -1), axis=1)
    np.testing.assert_allclose(model.identity.stddev, norms, rtol=1e-4)
    assert (np.diff(model.identity.stddev) <= 1e-12).all()  # PCA order: decreasing
    assert 0.05 < model.identity.stddev[0] < 2.0  # metres over 80k coordinates


@needs_ict
def test_identity_and_expressions_match_ict_within_quantisation(model):
    with np.load(ICT_DIR / bm.SHAPES_NPZ) as d:
        ident = bm.to_blender(d["identity"][[0, 1, 50, 99]].astype(np.float64))
        expr = bm.to_blender(d["expression"].astype(np.float64))
        neutral = bm.to_blender(d["neutral"].astype(np.float64))
        names = [str(s) for s in d["expression_names"]]
    np.testing.assert_allclose(model.vertices, neutral, atol=1e-7)
    bound = np.abs(ident).max(axis=(1, 2)) / 32767  # one quantisation step per mode
    err = np.abs(model.identity.basis[[0, 1, 50, 99]] - ident).max(axis=(1, 2))
    assert (err <= bound * 0.5 + 1e-12).all()
    assert tuple(names) == model.expression_names
    bound = np.abs(expr).max(axis=(1, 2)) / 32767
    err = np.abs(model.expressions - expr).max(axis=(1, 2))
    assert (err <= bound * 0.5 + 1e-12).all()
    # a 1-sigma identity head differs from the mean by millimetres to centimetres
    assert 0.001 < np.abs(ident[0]).max() < 0.05


def test_quantize_error_bound():
    rng = np.random.default_rng(0)
    a = rng.standard_normal((3, 50, 3)) * np.array([1.0, 1e-3, 0.0])[:, None, None]
    q, scale = bm.quantize(a, axis_keep=0)
    assert q.dtype == np.int16
    err = np.abs(q * scale[:, None, None] - a).max(axis=(1, 2))
    assert (err <= np.abs(a).max(axis=(1, 2)) / 65534 + 1e-15).all()
    assert err[2] == 0.0


# --------------------------------------------------------------------------- regions

def test_region_weights_blend_to_one_on_the_skin(model):
    w = model.region_weights
    assert (w >= 0).all() and (w <= 1 + 1e-6).all()
    np.testing.assert_allclose(w[:, model.skin].sum(axis=0), 1.0, atol=1e-6)
    off = np.setdiff1d(np.arange(model.n_vertices), model.skin)
    assert (w[:, off] == 0).all()
    assert model.region_names == ("ears", "eyes", "nose", "mouth", "chin", "cheeks", "rest")
    base = model.region_label[model.skin]
    assert (base >= 0).all() and (model.region_label[off] == -1).all()
    for r, name in enumerate(model.region_names):
        assert (base == r).sum() > 100, name
        # a vertex keeps weight 1 for its own region before normalising: the largest share
        inside = model.skin[base == r]
        assert (w[r, inside] >= w[:, inside].max(axis=0) - 1e-6).all(), name
    # ring blending reaches beyond the base region (two rings by default)
    grown = (w > 0).sum(axis=0)
    assert grown[model.skin].max() >= 2


def test_regions_are_where_their_names_say(model):
    lab = model.region_label
    name = dict(enumerate(model.region_names))
    assert name[lab[model.landmark_vertex("nose_tip")]] == "nose"
    assert name[lab[model.landmark_vertex("eye_outer_left")]] == "eyes"
    assert name[lab[model.landmark_vertex("mouth_corner_right")]] == "mouth"
    assert name[lab[model.landmark_vertex("ear_middle_right")]] == "ears"
    assert name[lab[model.landmark_vertex("pogonion")]] == "chin"
    assert name[lab[model.landmark_vertex("head_top")]] == "rest"
    assert name[lab[model.landmark_vertex("head_back")]] == "rest"


def test_ring_weights_on_a_strip():
    # a chain 0-1-2-...-7: region 0 = {0..3}, region 1 = {4..7}; two rings of blending
    import scipy.sparse as sp
    n = 8
    edges = np.array([[i, i + 1] for i in range(n - 1)])
    adj = sp.csr_matrix((np.ones(2 * len(edges)), (np.r_[edges[:, 0], edges[:, 1]],
                                                   np.r_[edges[:, 1], edges[:, 0]])), (n, n))
    label = np.array([0, 0, 0, 0, 1, 1, 1, 1])
    w = bm.ring_weights(adj, np.arange(n), label, 2, 2)
    # vertex 3: own 1 + region 1's first ring 1/2 -> 2/3, 1/3
    np.testing.assert_allclose(w[:, 3], [2 / 3, 1 / 3])
    # vertex 2: own 1 + region 1's second ring 1/3 -> 3/4, 1/4
    np.testing.assert_allclose(w[:, 2], [3 / 4, 1 / 4])
    np.testing.assert_allclose(w[:, 0], [1, 0])
    np.testing.assert_allclose(w.sum(axis=0), 1)


def test_regional_model_layout_and_gamma_rows(model):
    k = 5
    reg = model.regional(k)
    assert reg is model.regional(k)  # cached
    n_reg = len(model.region_names)
    assert reg.basis.shape == (n_reg * k, model.n_vertices, 3)
    assert reg.names[0] == "ears_00" and reg.names[-1] == f"rest_{k - 1:02d}"
    np.testing.assert_array_equal(reg.mean, model.vertices)
    off = np.setdiff1d(np.arange(model.n_vertices), model.skin)
    assert not reg.basis[:, off].any()
    two = model.two_region_vertices
    assert ((model.region_weights[:, two] > 0).sum(axis=0) == 2).all()
    assert reg.gamma.shape == (3 * two.size, n_reg * k)
    # rows for vertex two[i]: P^(j) - P^(k) with the unweighted components
    i = two.size // 2
    v = two[i]
    j, kk = np.flatnonzero(model.region_weights[:, v] > 0)
    vj, cj, _ = model.region_basis(int(j), k)
    vk, ck, _ = model.region_basis(int(kk), k)
    row = reg.gamma[3 * i:3 * i + 3]
    np.testing.assert_allclose(row[:, j * k:(j + 1) * k], cj[:, np.searchsorted(vj, v)].T)
    np.testing.assert_allclose(row[:, kk * k:(kk + 1) * k], -ck[:, np.searchsorted(vk, v)].T)
    others = np.ones(n_reg * k, dtype=bool)
    others[j * k:(j + 1) * k] = others[kk * k:(kk + 1) * k] = False
    assert not row[:, others].any()
    # blended basis = weight times the region's own component
    np.testing.assert_allclose(reg.basis[j * k:(j + 1) * k, v],
                               model.region_weights[j, v] * cj[:, np.searchsorted(vj, v)])
    with pytest.raises(ValueError, match="n_per_region"):
        model.regional(0)


def _identity_sample(model, seed):
    c = np.random.default_rng(seed).standard_normal(model.identity.n_coeffs)
    return model.identity.instance(c) - model.vertices  # offsets, (V, 3)


def test_regional_model_reconstructs_identity_heads(model):
    reg = model.regional(40)
    skin = model.skin
    b = reg.basis[:, skin].reshape(reg.n_coeffs, -1).T
    for seed in (1, 2):
        x = _identity_sample(model, seed)[skin].ravel()
        c, *_ = np.linalg.lstsq(b, x, rcond=None)
        r = np.linalg.norm((b @ c - x).reshape(-1, 3), axis=1)
        assert np.sqrt((r ** 2).mean()) < 0.001  # < 1 mm RMS
        assert r.max() < 0.006
        assert np.sqrt((r ** 2).mean()) < 0.2 * np.sqrt((x.reshape(-1, 3) ** 2).sum(1).mean())


def test_gamma_is_small_when_each_region_reproduces_a_global_head(model):
    k = 40
    reg = model.regional(k)
    x = _identity_sample(model, 3)
    coeffs = []
    for r in range(len(model.region_names)):
        verts, comp, _ = model.region_basis(r, k)
        a = comp.reshape(k, -1).T
        c, *_ = np.linalg.lstsq(a, x[verts].ravel(), rcond=None)
        coeffs.append(c)
    c = np.concatenate(coeffs)
    gap = np.linalg.norm((reg.gamma @ c).reshape(-1, 3), axis=1)
    random_c = np.random.default_rng(4).standard_normal(c.size)
    random_gap = np.linalg.norm((reg.gamma @ random_c).reshape(-1, 3), axis=1)
    assert np.sqrt((gap ** 2).mean()) < 0.001
    assert np.sqrt((gap ** 2).mean()) < 0.2 * np.sqrt((random_gap ** 2).mean())


def test_region_rules_file_is_valid():
    rules = bm.load_region_rules()
    assert [r["name"] for r in rules["regions"]] == ["ears", "eyes", "nose", "mouth", "chin",
                                                     "cheeks", "rest"]
    assert rules["blend_rings"] == 2 and rules["default_region"] == "rest"


# --------------------------------------------------------------------------- landmarks

def test_landmark_file_is_consistent_with_the_mesh(model):
    entries = bm.load_landmark_set()  # raises on bad names, vertices, views, numbers
    names = [e["name"] for e in entries]
    assert len(names) == len(set(names))
    assert sorted(e["ibug"] for e in entries if e["ibug"]) == list(range(1, 69))
    assert sorted(e["thesis"] for e in entries if e["thesis"]) == list(range(1, 41))
    skin = set(model.skin.tolist())
    p = model.vertices
    for e in entries:
        v = e["vertex"]
        assert v in skin, e["name"]
        assert e["description"].strip() and set(e["views"]) <= {"front", "right", "left"}
        x = p[v, 0]
        if e["name"].endswith("_right"):
            assert x < -1e-4 and "left" not in e["views"], e["name"]
        elif e["name"].endswith("_left"):
            assert x > 1e-4 and "right" not in e["views"], e["name"]
        else:  # midline points: seen in both profiles or in neither
            assert abs(x) < 1e-6, e["name"]
            assert ("right" in e["views"]) == ("left" in e["views"]), e["name"]
    # the model carries the same set
    assert [e["name"] for e in model.landmark_info] == names
    # iBUG indices from the ICT README (0-based Multi-PIE list)
    assert model.landmark_vertex("ibug31") == 4857 == model.landmark_vertex("nose_tip")
    assert model.landmark_vertex("ibug09") == 966
    assert model.landmark_vertex("ibug52") == 0


def test_left_and_right_landmarks_mirror_each_other(model):
    p = model.vertices
    for name, v in model.landmarks.items():
        if name.endswith("_right"):
            twin = model.landmarks[name[:-len("_right")] + "_left"]
            np.testing.assert_allclose(p[twin], p[v] * [-1, 1, 1], atol=2e-5, err_msg=name)


def test_landmark_geometry_makes_sense(model):
    p = model.vertices

    def at(name):
        return p[model.landmark_vertex(name)]

    # ears stick out sideways; top above lobe; middle is the most lateral
    assert at("ear_middle_right")[0] < at("head_outline_right")[0] - 0.005
    assert at("ear_top_right")[2] > at("ear_middle_right")[2] > at("ear_lobe_right")[2]
    assert at("ear_attachment_top_right")[2] > at("ear_lobe_attachment_right")[2]
    # nose wings are wider than the nostrils' outer ends
    assert abs(at("nose_wing_left")[0]) > abs(at("nostril_outer_left")[0])
    # profile points
    assert at("nasion")[1] > at("glabella")[1]  # the dip lies behind the forehead
    assert at("pogonion")[1] < at("chin_bottom")[1]
    assert at("head_back")[1] == pytest.approx(p[model.profile_chain][p[model.profile_chain, 2]
                                                                      > 0, 1].max())
    # neck base is wider than the neck outline (it widens into the shoulder)
    assert at("neck_base_right")[0] < at("neck_outline_right")[0] < 0


@pytest.mark.parametrize("change, message", [
    (lambda e: e[1].update(name=e[0]["name"]), "duplicate name"),
    (lambda e: e[0].update(name="Nose Tip"), "snake_case"),
    (lambda e: e[0].update(vertex=10 ** 6), "'vertex'"),
    (lambda e: e[0].update(views=["top"]), "'views'"),
    (lambda e: e[0].update(description=" "), "'description'"),
    (lambda e: e[0].update(outline=["right"]), "'outline'"),
    (lambda e: e[1].update(ibug=e[0]["ibug"]), "'ibug' 1 already used"),
    (lambda e: e[0].update(thesis=41), "'thesis'"),
])
def test_bad_landmark_files_are_rejected_naming_the_entry(tmp_path, change, message):
    data = json.loads(bm.LANDMARKS_PATH.read_text())
    change(data["landmarks"])
    path = tmp_path / "landmarks.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match=message) as err:
        bm.load_landmark_set(path)
    assert str(path) in str(err.value)


def test_bad_region_rules_are_rejected(tmp_path, model):
    data = json.loads(bm.REGIONS_PATH.read_text())
    data["regions"][0]["ellipsoids"][0]["center_landmarks"] = ["no_such_point"]
    with pytest.raises(ValueError, match="no_such_point"):
        bm.assign_regions(model.vertices, model.skin, data, model.landmarks)
    data["default_region"] = "neck"
    path = tmp_path / "regions.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError, match="default_region"):
        bm.load_region_rules(path)


def test_landmark_vertex_accepts_names_and_ibug_numbers(model):
    assert model.landmark_vertex("eye_outer_right") == model.landmark_vertex("ibug37")
    assert model.landmark_vertex("mouth_corner_left") == model.landmark_vertex("ibug55")
    for n in range(1, 69):
        assert 0 <= model.landmark_vertex(f"ibug{n:02d}") < model.n_vertices
    for bad in ("ibug69", "ibug00", "nose", "ibugxx"):
        with pytest.raises(ValueError, match=bad):
            model.landmark_vertex(bad)


# --------------------------------------------------------------------------- profile chain

def test_profile_chain_is_a_clean_midline_path(model):
    chain = model.profile_chain
    p = model.vertices[chain]
    assert len(np.unique(chain)) == len(chain) > 100
    assert np.isin(chain, model.skin).all()
    assert np.abs(p[:, 0]).max() < 1e-6
    step = np.linalg.norm(np.diff(p, axis=0), axis=1)
    assert step.max() < 0.015 and step.min() > 0
    # consecutive vertices are mesh neighbours
    edges = {tuple(e) for e in model.edges().tolist()}
    pairs = np.sort(np.stack([chain[:-1], chain[1:]], axis=1), axis=1)
    neighbours = [tuple(e) in edges for e in pairs.tolist()]
    assert sum(neighbours) >= len(pairs) - 1  # all but the stomion jump between the lips
    # starts at the front of the neck, ends at the nape, both at the bottom
    assert p[0, 1] < 0 < p[-1, 1] and p[0, 2] < -0.15 and p[-1, 2] < -0.1
    # landmarks in profile order
    order = ["chin_bottom", "pogonion", "lip_lower_middle", "mouth_middle", "lip_upper_middle",
             "subnasale", "nose_tip", "nasion", "glabella", "head_top", "head_back"]
    where = {v: i for i, v in enumerate(chain.tolist())}
    idx = [where[model.landmark_vertex(n)] for n in order]
    assert idx == sorted(idx)
    # no back-tracking: the polyline does not cross itself in the YZ plane
    yz = p[:, 1:]
    a0, a1 = yz[:-1, None], yz[1:, None]
    b0, b1 = yz[None, :-1], yz[None, 1:]

    def cross(o, a, b):
        return (a[..., 0] - o[..., 0]) * (b[..., 1] - o[..., 1]) - \
            (a[..., 1] - o[..., 1]) * (b[..., 0] - o[..., 0])

    hit = (cross(a0, a1, b0) * cross(a0, a1, b1) < 0) & (cross(b0, b1, a0) * cross(b0, b1, a1) < 0)
    assert not hit.any()


# --------------------------------------------------------------------------- ICT readers

def _write_obj(path, positions, with_faces=True):
    lines = [f"v {x} {y} {z}" for x, y, z in positions]
    if with_faces:
        lines += ["vt 0 0", "vt 1 0", "vt 1 1", "vt 0 1", "f 1/1 2/2 3/3 4/4", "f 2/2 5/3 3/3"]
    path.write_text("\n".join(lines) + "\n")


NEUTRAL = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0.5, 0]], dtype=float)


def _fake_ict_repo(root):
    """Layout (a): the ICT-FaceKit repository with OBJ shapes."""
    fx = root / "FaceXModel"
    fx.mkdir(parents=True)
    _write_obj(fx / bm.NEUTRAL_OBJ, NEUTRAL)
    for i in range(3):
        _write_obj(fx / f"identity{i:03d}.obj", NEUTRAL + (i + 1) * 0.1, with_faces=False)
    _write_obj(fx / "jawOpen.obj", NEUTRAL + [0, -1, 0], with_faces=False)
    _write_obj(fx / "browDown_L.obj", NEUTRAL + [0, 0, 2], with_faces=False)
    (root / "LICENSE").write_text("MIT License\nCopyright (c) 2020 USC ICT\n")
    (root / "CREDITS.md").write_text("# Credits\n")
    return root


@pytest.mark.parametrize("point_at", ["root", "FaceXModel"])
def test_read_ict_repository_layout(tmp_path, point_at):
    root = _fake_ict_repo(tmp_path / "ICT-FaceKit")
    src = bm.read_ict(root if point_at == "root" else root / "FaceXModel")
    assert src.location.layout == "obj" and src.location.root == root
    assert src.identity.shape == (3, 5, 3)
    np.testing.assert_allclose(src.identity[2], 0.3, atol=1e-6)
    assert src.identity_names == ("identity000", "identity001", "identity002")
    assert src.expression_names == ("browDown_L", "jawOpen")  # sorted
    np.testing.assert_allclose(src.expression[1], np.tile([0, -1, 0], (5, 1)))
    np.testing.assert_allclose(src.neutral, NEUTRAL)
    assert src.mesh.face_loop_total.tolist() == [4, 3]
    assert "MIT License" in src.license_text and "Credits" in src.license_text


def test_read_ict_npz_layout(tmp_path):
    root = tmp_path / "ict"
    (root / "FaceXModel").mkdir(parents=True)
    _write_obj(root / "FaceXModel" / bm.NEUTRAL_OBJ, NEUTRAL)
    (root / "LICENSE").write_text("MIT License\n")
    ident = np.random.default_rng(0).standard_normal((4, 5, 3)).astype(np.float32)
    expr = np.ones((2, 5, 3), np.float32)
    np.savez(root / bm.SHAPES_NPZ, neutral=NEUTRAL.astype(np.float32), identity=ident,
             identity_names=np.array([f"identity{i:03d}" for i in range(4)]), expression=expr,
             expression_names=np.array(["a_L", "b"]))
    src = bm.read_ict(root)
    assert src.location.layout == "npz"
    np.testing.assert_array_equal(src.identity, ident)
    assert src.expression_names == ("a_L", "b")
    # the npz wins over OBJ shapes when both are present; mismatched neutral is an error
    np.savez(root / bm.SHAPES_NPZ, neutral=np.zeros((5, 3), np.float32), identity=ident,
             identity_names=np.array(["x"] * 4), expression=expr,
             expression_names=np.array(["a_L", "b"]))
    with pytest.raises(ValueError, match="neutral"):
        bm.read_ict(root)


def test_read_ict_rejects_a_shape_with_other_vertex_count(tmp_path):
    root = _fake_ict_repo(tmp_path / "ict")
    _write_obj(root / "FaceXModel" / "jawOpen.obj", NEUTRAL[:4], with_faces=False)
    with pytest.raises(ValueError, match="jawOpen.obj"):
        bm.read_ict(root)


def test_ict_not_found_message_says_where_to_get_it(tmp_path, capsys):
    with pytest.raises(bm.IctNotFoundError) as err:
        bm.locate_ict(tmp_path)
    msg = str(err.value)
    assert str(tmp_path) in msg and "github.com/ICT-VGL/ICT-FaceKit" in msg
    assert "--ict" in msg and "HEADRECON_ICT_DIR" in msg
    with pytest.raises(bm.IctNotFoundError, match="no such folder"):
        bm.locate_ict(tmp_path / "missing")
    # neutral mesh only, no shapes
    (tmp_path / "FaceXModel").mkdir()
    _write_obj(tmp_path / "FaceXModel" / bm.NEUTRAL_OBJ, NEUTRAL)
    with pytest.raises(bm.IctNotFoundError, match="identity000.obj"):
        bm.locate_ict(tmp_path)
    out = tmp_path / "out" / "m.npz"
    assert bm.main(["--ict", str(tmp_path / "missing"), "--out", str(out)]) == 2
    assert "ICT-VGL/ICT-FaceKit" in capsys.readouterr().err
    assert not out.exists()


# --------------------------------------------------------------------------- build, freshness

@needs_ict
def test_build_writes_model_and_licence_atomically(tmp_path, monkeypatch):
    out = tmp_path / "model" / "head_model.npz"
    bm.build(ICT_DIR, out, log=lambda *a: None)
    assert out.stat().st_size <= 30e6
    assert sorted(p.name for p in out.parent.iterdir()) == [bm.LICENSE_NAME, out.name]
    lic = (out.parent / bm.LICENSE_NAME).read_text()
    assert "MIT License" in lic and "Permission is hereby granted" in lic
    assert bm.is_up_to_date(out)
    built = load_model(out)
    np.testing.assert_array_equal(built.profile_chain, load_model().profile_chain)
    np.testing.assert_allclose(built.region_weights, load_model().region_weights)
    # a new builder version (or edited landmarks/regions) makes the file stale
    monkeypatch.setattr(bm, "BUILD_VERSION", bm.BUILD_VERSION + 1000)
    assert not bm.is_up_to_date(out)


def test_installed_model_is_up_to_date():
    assert bm.is_up_to_date(DEFAULT_MODEL_PATH), "run ./run model: the model is stale"


def test_if_missing_does_nothing_when_up_to_date(tmp_path, capsys):
    out = tmp_path / "head_model.npz"
    shutil.copy(DEFAULT_MODEL_PATH, out)
    shutil.copy(DEFAULT_MODEL_PATH.parent / bm.LICENSE_NAME, tmp_path / bm.LICENSE_NAME)
    mtime = out.stat().st_mtime_ns
    assert bm.main(["--if-missing", "--out", str(out), "--ict", str(tmp_path / "none")]) == 0
    assert "up to date" in capsys.readouterr().out
    assert out.stat().st_mtime_ns == mtime


def test_if_missing_keeps_a_stale_model_when_ict_is_gone(tmp_path, capsys, monkeypatch):
    out = tmp_path / "head_model.npz"
    shutil.copy(DEFAULT_MODEL_PATH, out)
    shutil.copy(DEFAULT_MODEL_PATH.parent / bm.LICENSE_NAME, tmp_path / bm.LICENSE_NAME)
    monkeypatch.setattr(bm, "BUILD_VERSION", bm.BUILD_VERSION + 1000)  # now stale
    assert bm.main(["--if-missing", "--out", str(out), "--ict", str(tmp_path / "none")]) == 0
    assert "out of date" in capsys.readouterr().err
    # without --if-missing a missing ICT is an error
    assert bm.main(["--out", str(out), "--ict", str(tmp_path / "none")]) == 2


def test_git_tracks_nothing_under_generated():
    res = subprocess.run(["git", "ls-files", "generated"], cwd=REPO, capture_output=True,
                         text=True, check=True)
    assert res.stdout.strip() == ""
    assert json.loads((REPO / "assets" / "landmarks.json").read_text())["format"] == \
        "headrecon-landmark-set"


def test_the_skin_triangles_are_the_skin_s_and_kept_with_the_model(model):
    tris = model.skin_triangles()
    skin = np.zeros(model.n_vertices, bool)
    skin[model.skin] = True
    assert skin[tris].all() and len(tris) > 10_000
    # every triangle with only skin corners is there, none other
    all_tris = model.triangles()[0]
    assert len(tris) == int(skin[all_tris].all(axis=1).sum())
    assert model.skin_triangles() is tris and not tris.flags.writeable


def test_expression_offsets_add_the_named_expressions_at_their_weights(model):
    names = model.expression_names
    jaw, blink = names.index("jawOpen"), names.index("eyeBlink_L")
    np.testing.assert_allclose(
        model.expression_offsets({"jawOpen": 0.5, "eyeBlink_L": 1.0}),
        0.5 * model.expressions[jaw] + model.expressions[blink])
    assert not model.expression_offsets({}).any()
    assert model.expression_offsets({}).shape == (model.n_vertices, 3)
