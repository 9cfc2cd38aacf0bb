"""The realistic benchmark's cases and score (bench/realistic_cases.py): the out-of-model
displacement lies outside the model's span at the requested size, the surface distance is
exact, the ICP alignment finds a known similarity, people's landmarks are where they
should be, and the real scan's landmarks and photo cameras are right (skipped when the
scan is not there); the fit to 3-D landmarks finds the head they come from."""

import numpy as np
import pytest

from bench.realistic_cases import (
    FACE_PARTS,
    OUTLINE_IBUG,
    THREE_QUARTER,
    Placement,
    Surface,
    align_icp,
    calibrate,
    closest_on_triangles,
    face_parts,
    james_folder,
    landmark_fit_3d,
    load_scan,
    make_realistic_case,
    model_face_vertices,
    model_ibug,
    out_of_model_displacement,
    part_triangles,
    sample_surface,
    scan_photo_halves,
    span_basis,
)
from solver.geometry import rotation_from_vector
from solver.procrustes import Similarity, similarity_procrustes
from tests import ROOT


def test_displacement_is_outside_the_span_with_the_requested_rms(model):
    rng = np.random.default_rng(3)
    local = model.identity.instance(rng.normal(size=model.identity.n_coeffs))
    d = out_of_model_displacement(model, local, rng, 0.002)
    face = model_face_vertices(model)
    assert np.sqrt((d[face] ** 2).sum(axis=1).mean()) == pytest.approx(0.002, rel=1e-12)
    # Orthogonal over the skin to every identity mode and every similarity move.
    basis = span_basis(model, local, model.skin)
    flat = d[model.skin].reshape(-1)
    cos = basis.T @ flat / (np.linalg.norm(basis, axis=0) * np.linalg.norm(flat))
    assert np.abs(cos).max() < 1e-8
    # Smooth and not tiny anywhere it matters: the face holds most of it.
    assert np.sqrt((d[model.skin] ** 2).sum(axis=1).mean()) < 0.002


def test_the_face_parts_split_its_points_by_their_nearest_landmark(model):
    ibug = model_ibug(model, model.vertices)
    face = model.vertices[model_face_vertices(model)]
    parts = face_parts(face, ibug)
    assert list(parts) == list(FACE_PARTS)
    # every point in exactly one part, and every part holds some of the face
    assert np.array_equal(np.sum(list(parts.values()), axis=0), np.ones(len(face)))
    assert all(m.sum() > 100 for m in parts.values())
    # a landmark's own point is in its part: the nose tip (31) in the nose, 37 in the eyes
    marks = face_parts(np.array([ibug[31], ibug[37], ibug[9], ibug[20], ibug[52]]), ibug)
    assert [next(p for p, m in marks.items() if m[i]) for i in range(5)] == \
        ["nose", "eyes", "jaw", "brows", "mouth"]
    # the same rule in any frame: a similarity moves points and landmarks alike
    sim = Similarity(1.7, rotation_from_vector(np.array([0.2, -0.4, 0.1])), np.ones(3))
    moved = face_parts(sim.apply(face), {k: sim.apply(v[None])[0] for k, v in ibug.items()})
    assert all(np.array_equal(moved[p], parts[p]) for p in parts)


def test_closest_point_on_a_triangle_is_exact():
    a, b, c = np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
    cases = [
        ((0.2, 0.3, 0.5), (0.2, 0.3, 0.0)),    # above the inside
        ((0.5, -0.4, 0.3), (0.5, 0.0, 0.0)),   # beyond the edge a-b
        ((0.8, 0.8, -0.1), (0.5, 0.5, 0.0)),   # beyond the edge b-c
        ((-0.3, 0.4, 0.2), (0.0, 0.4, 0.0)),   # beyond the edge a-c
        ((-0.2, -0.1, 0.4), (0.0, 0.0, 0.0)),  # near the corner a
        ((1.5, -0.2, 0.0), (1.0, 0.0, 0.0)),   # near the corner b
        ((-0.1, 1.3, 0.2), (0.0, 1.0, 0.0)),   # near the corner c
    ]
    p = np.array([q for q, _ in cases])
    expect = np.array([e for _, e in cases])
    n = len(p)
    got = closest_on_triangles(p, np.tile(a, (n, 1)), np.tile(b, (n, 1)), np.tile(c, (n, 1)))
    np.testing.assert_allclose(got, expect, atol=1e-15)
    # The same through a Surface of that triangle and a far, large one beside it.
    verts = np.vstack([a, b, c, [5.0, 0, 0], [9.0, 0, 0], [5.0, 4, 0]])
    dist, q = Surface(verts, [[0, 1, 2], [3, 4, 5]], k=1, spacing=0.5).closest(p)
    np.testing.assert_allclose(q, expect, atol=1e-15)
    np.testing.assert_allclose(dist, np.linalg.norm(p - expect, axis=1), atol=1e-15)


def test_surface_distance_matches_brute_force_on_the_head(model):
    tris = part_triangles(model)
    rng = np.random.default_rng(0)
    p = sample_surface(model.vertices, tris, 60, rng)
    p += rng.normal(size=p.shape) * rng.choice([0.0005, 0.005, 0.03], size=(60, 1))
    dist, q = Surface(model.vertices, tris).closest(p)
    c = model.vertices[tris]
    brute = np.linalg.norm(closest_on_triangles(p[:, None], c[None, :, 0], c[None, :, 1],
                                                c[None, :, 2]) - p[:, None], axis=2).min(1)
    np.testing.assert_allclose(dist, brute, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(q - p, axis=1), dist, atol=1e-12)


def test_icp_finds_a_known_similarity(model):
    tris = part_triangles(model)
    rng = np.random.default_rng(1)
    truth = Similarity(1.04, rotation_from_vector([0.03, -0.02, 0.04]), np.array([0.003, 0.0,
                                                                                  -0.002]))
    face = model_face_vertices(model)
    face_tris = tris[face[tris].all(axis=1)]
    samples = truth.apply(sample_surface(model.vertices, face_tris, 3000, rng))
    start = Similarity(1.0, np.eye(3), np.zeros(3))
    sim, d = align_icp(Surface(model.vertices, tris), samples, start)
    assert d.shape == (3000,) and np.sqrt(np.mean(d**2)) < 2e-5
    assert sim.scale == pytest.approx(1.04, abs=1e-3)
    np.testing.assert_allclose(sim.rotation, truth.rotation, atol=1e-3)


def test_realistic_case_places_landmarks_as_people_do(model):
    case, truth = make_realistic_case(model, 5000)
    ibug = {e["name"]: e["ibug"] for e in model.landmark_info if e.get("ibug")}
    profile = set(case.views["right"].points)
    assert "chin_bottom" in profile
    assert not any(ibug.get(n) in OUTLINE_IBUG and ibug[n] != 9 for n in profile)
    assert set(case.views["front"].points) >= {n for n, i in ibug.items() if i <= 17}
    assert 1.5 <= truth.displacement_mm <= 3.0
    assert 3.0 <= truth.placement.bias_px <= 5.0 and 3.0 <= truth.placement.noise_px <= 6.0
    # Bias and noise together: about sqrt(bias^2 + noise^2), more for the sliding outline.
    assert 4.0 < truth.landmark_rms_px < 12.0
    assert case.views["right"].contour.shape == (100, 2)
    assert case.views["front"].contour is None


def test_a_realistic_case_can_be_placed_exactly_and_traced_in_front(model):
    case, truth = make_realistic_case(model, 5000)
    exact, exact_truth = make_realistic_case(model, 5000, placement=Placement(0.0, 0.0, 0.0),
                                      front_outline=True)
    # the same head and photos, only placed and traced otherwise
    np.testing.assert_array_equal(exact_truth.local_vertices, truth.local_vertices)
    assert exact.views["front"].contour.shape == (100, 2)
    assert exact.views["right"].contour.shape == (100, 2)
    assert set(exact.views["front"].points) == set(case.views["front"].points)
    # only the outline points are off their vertices' projections (anywhere on their own
    # stretch of the outline): the inner ones sit on them
    assert exact_truth.landmark_rms_px < 0.6 * truth.landmark_rms_px
    ibug = {e["name"]: e["ibug"] for e in model.landmark_info if e.get("ibug")}
    gaps = [np.linalg.norm(np.subtract(exact.views[v].points[n], case.views[v].points[n]))
            for v in ("front", "right") for n in exact.views[v].points
            if ibug.get(n) not in OUTLINE_IBUG]
    assert np.median(gaps) > 2.0


def test_a_realistic_head_photographed_from_three_quarter_angles(model):
    _, front_truth = make_realistic_case(model, 5000)
    cases = {o: make_realistic_case(model, 5000, three_quarter=o) for o in
             ("none", "cheek", "head")}
    none, truth = cases["none"]
    # the same head as the front and profile photos show, only photographed otherwise
    np.testing.assert_array_equal(truth.local_vertices, front_truth.local_vertices)
    assert set(none.views) == set(THREE_QUARTER)
    ibug = {e["name"]: e["ibug"] for e in model.landmark_info if e.get("ibug")}
    world = truth.cameras  # the true cameras: pinholes on the side of their yaw
    for name, yaw in THREE_QUARTER.items():
        view = none.views[name]
        assert view.camera is None and view.camera_hints == {"kind": "pinhole"}
        assert view.contour is None
        assert set(view.points) <= set(ibug) and len(view.points) >= 50
        assert np.sign(world[name].centre[0]) == -np.sign(yaw)  # the subject's right: -X
        cheek = cases["cheek"][0].views[name].contour
        head = cases["head"][0].views[name].contour
        for other in ("cheek", "head"):  # the landmarks the same whatever is traced
            placed = cases[other][0].views[name].points
            assert placed.keys() == view.points.keys()
            np.testing.assert_array_equal([placed[n] for n in view.points],
                                          list(view.points.values()))
        assert cheek.shape == head.shape == (100, 2)
        # the cheek: on the face's far side (beyond its nose), below the head's top
        nose = view.points["nose_tip"][0]
        beyond = np.sign(yaw) * (cheek[:, 0] - nose)
        assert np.all(beyond > -20.0) and np.median(beyond) > 30.0  # placed: a few px off
        assert cheek[:, 1].min() > head[:, 1].min() + 100.0
    with pytest.raises(ValueError, match="three_quarter"):
        make_realistic_case(model, 5000, three_quarter="ear")


def test_a_front_outline_of_the_face_alone_is_one_side_below_the_brows(model):
    head, _ = make_realistic_case(model, 5000, front_outline="head")
    face, _ = make_realistic_case(model, 5000, front_outline="face")
    full, side = head.views["front"].contour, face.views["front"].contour
    assert side.shape == full.shape == (100, 2)
    nose = face.views["front"].points["nose_tip"]
    brow = min(face.views["front"].points[n][1] for n in ("brow_outer_left", "brow_outer_right"))
    assert np.all(side[:, 0] < nose[0])  # the subject's right, left in the photo
    assert side[:, 1].min() > brow - 15.0 > full[:, 1].min()  # placed: a few px off


@pytest.fixture(scope="module")
def scan():
    folder = james_folder(ROOT)
    if not (folder / "james.obj").is_file():
        pytest.skip(f"the scan james is not in {folder}")
    return load_scan(folder)


def _subject_right(p):
    """The subject's right from iBUG points (dict number -> (3,)) without using their
    sides: up from the menton to the nose bridge, forward from the eye and mouth corners
    to the nose tip; right = forward x up (Blender: -Y x Z = -X)."""
    up = p[28] - p[9]
    forward = p[31] - np.mean([p[37], p[46], p[49], p[55]], axis=0)
    return np.cross(forward, up), up


def test_james_landmarks_are_mapped_by_side(scan, model):
    p = scan.ibug
    right, up = _subject_right(p)
    assert (p[37] - p[46]) @ right > 0  # the right eye's outer corner on the right
    assert (p[1] - p[17]) @ right > 0 and (p[49] - p[55]) @ right > 0
    assert p[28] @ up > p[31] @ up > p[34] @ up  # nose bridge top, tip, then subnasale
    mean = {int(e["ibug"]): model.vertices[e["vertex"]] for e in model.landmark_info
            if e.get("ibug")}
    m_right, _ = _subject_right(mean)
    assert (mean[37] - mean[46]) @ m_right > 0  # the rule agrees with the model's names
    # A similarity lays the mean head's points on the scan's far better than their mirror.
    keys = range(1, 69)
    src = np.array([mean[k] for k in keys])
    rms = similarity_procrustes(src, scan.landmark_array).rms
    mirrored = similarity_procrustes(src * [-1.0, 1.0, 1.0], scan.landmark_array).rms
    assert rms < 0.012 and rms < 0.3 * mirrored


def test_james_photos_are_calibrated_to_their_texture(scan):
    assert set(scan.photos) == {"photo_a", "photo_b"}
    for photo, (verts, px, size) in scan.photos.items():
        assert size == (1200, 1600)
        c = calibrate(scan, photo)
        r = np.linalg.norm(c.camera.project(scan.vertices[verts]) - px, axis=1)
        assert c.used >= 0.99 * len(verts)
        assert np.sqrt(np.mean(r**2)) < 1.0 and np.percentile(r, 99) < 3.0
        assert c.rms_px < 1.0
        assert (c.camera.depth(scan.vertices[verts]) > 1.0).all()  # about 1.5 m away


def test_a_fit_to_3d_landmarks_follows_them_under_a_similarity(model):
    """Landmarks of a model head, moved by a similarity: with little noise assumed the
    fit lies nearer the head than the mean head, and its landmarks reach theirs."""
    rng = np.random.default_rng(11)
    head = model.identity.instance(rng.normal(size=model.identity.n_coeffs))
    vertex = {int(e["ibug"]): int(e["vertex"]) for e in model.landmark_info
              if e.get("ibug") is not None}
    rot = rotation_from_vector(np.array([0.1, -0.2, 0.05]))
    ibug = {k: 1.1 * head[v] @ rot.T + [0.3, -0.1, 0.2] for k, v in vertex.items()}
    fitted = landmark_fit_3d(model, ibug, 0.1)
    idx = list(vertex.values())
    target = np.array([ibug[k] for k in vertex])
    assert similarity_procrustes(fitted[idx], target).rms < 2e-4

    def shape_error(x):
        sim = similarity_procrustes(x, head)
        return np.sqrt(((sim.scale * x @ sim.rotation.T + sim.translation - head) ** 2)
                       .sum(axis=1).mean())

    assert shape_error(fitted) < 0.5 * shape_error(model.identity.mean)
    # Strong prior: the mean head's shape.
    strong = landmark_fit_3d(model, ibug, 1e4)
    assert np.abs(strong - model.identity.mean).max() < 1e-6


def test_the_scans_photos_are_its_textures_halves_at_their_calibrated_size(scan):
    halves = scan_photo_halves(scan.texture.parent)
    assert list(halves) == list(scan.photos)
    for photo, image in halves.items():
        assert image.dtype == np.uint8 and image.shape[2] == 3
        assert (image.shape[1], image.shape[0]) == scan.photos[photo][2]
    assert not np.array_equal(halves["photo_a"], halves["photo_b"])
