"""Mesh and rotation math (solver/geometry.py) on meshes and rotations with known answers."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from solver.geometry import (
    check_orthonormal,
    check_rotation,
    distance_to_segments,
    orthonormalize,
    rotation_between,
    rotation_from_vector,
    skew,
    vertex_normals,
)


def _rot_err_deg(a, b):
    return np.degrees(np.arccos(np.clip((np.trace(a.T @ b) - 1) / 2, -1, 1)))


def _octahedron():
    """Vertices +-x, +-y, +-z and 8 triangles wound counter-clockwise seen from outside."""
    v = np.vstack([np.eye(3), -np.eye(3)])
    tri = []
    for sx in (1, -1):
        for sy in (1, -1):
            for sz in (1, -1):
                t = [0 if sx > 0 else 3, 1 if sy > 0 else 4, 2 if sz > 0 else 5]
                tri.append(t if sx * sy * sz > 0 else t[::-1])
    return v, np.array(tri)


def test_octahedron_vertex_normals_point_outward_along_the_axes():
    v, tri = _octahedron()
    # the winding is outward: every face normal points away from the centre
    p = v[tri]
    face = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert (np.einsum("ij,ij->i", face, p.mean(axis=1)) > 0).all()
    n = vertex_normals(v, tri)
    np.testing.assert_allclose(n, v, atol=1e-15)
    # reversed winding turns them inward; scaling the mesh changes nothing
    np.testing.assert_allclose(vertex_normals(v, tri[:, ::-1]), -v, atol=1e-15)
    np.testing.assert_allclose(vertex_normals(0.01 * v, tri), v, atol=1e-15)


def test_normals_are_area_weighted_and_zero_where_no_triangle():
    # Vertex 0 is shared by a triangle of area 2 in the xy-plane (normal +z) and one of
    # area 1/2 in the xz-plane (normal -y); vertex 5 belongs to no triangle.
    v = np.array([[0.0, 0, 0], [2, 0, 0], [0, 2, 0], [1, 0, 0], [0, 0, 1], [7, 7, 7]])
    tri = np.array([[0, 1, 2], [0, 3, 4]])
    n = vertex_normals(v, tri)
    np.testing.assert_allclose(n[0], np.array([0.0, -0.5, 2.0]) / np.sqrt(4.25), atol=1e-15)
    np.testing.assert_allclose(n[1], [0.0, 0.0, 1.0])
    np.testing.assert_allclose(n[3], [0.0, -1.0, 0.0])
    np.testing.assert_array_equal(n[5], 0.0)


def test_normals_sum_the_faces_corner_by_corner():
    # The one-pass sum gives the same bits as adding the faces at each corner in turn.
    rng = np.random.default_rng(1)
    v = rng.standard_normal((200, 3))
    tri = rng.integers(0, 200, (500, 3))
    face = np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])
    ref = np.zeros_like(v)
    for k in range(3):
        np.add.at(ref, tri[:, k], face)
    ref /= np.maximum(np.linalg.norm(ref, axis=1, keepdims=True), 1e-12)
    np.testing.assert_array_equal(vertex_normals(v, tri), ref)


def test_skew_rotation_and_orthonormalize():
    a, b = np.random.default_rng(0).standard_normal((2, 5, 3))
    np.testing.assert_allclose(skew(a) @ b[..., None], np.cross(a, b)[..., None], atol=1e-15)
    r = rotation_from_vector([0.3, 0.2, -0.1])
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
    assert _rot_err_deg(r, np.eye(3)) == pytest.approx(np.degrees(np.sqrt(0.14)))
    np.testing.assert_allclose(orthonormalize(r + 1e-4), r, atol=2e-4)
    assert np.linalg.det(orthonormalize(-r)) == pytest.approx(1.0)


def test_rotation_from_vector_turns_a_known_vector():
    quarter = rotation_from_vector([0.0, 0.0, np.pi / 2])  # a quarter turn about z
    np.testing.assert_allclose(quarter @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(quarter @ [0.0, 0.0, 2.0], [0.0, 0.0, 2.0], atol=1e-15)
    rng = np.random.default_rng(2)
    for theta in [*rng.standard_normal((20, 3)), [1e-9, -2e-9, 3e-10], [0.0, 0.0, 0.0]]:
        r = rotation_from_vector(theta)
        np.testing.assert_allclose(r, Rotation.from_rotvec(theta).as_matrix(), atol=1e-14)
        np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
        assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-14)
    # either side of the switch to the small-angle series: exact to rounding
    axis = np.array([2.0, -1.0, 2.0]) / 3.0
    for angle in (0.999999e-8, 1.000001e-8):
        np.testing.assert_allclose(rotation_from_vector(angle * axis),
                                   Rotation.from_rotvec(angle * axis).as_matrix(), atol=1e-16)


def test_rotation_between_two_directions():
    rng = np.random.default_rng(3)
    a, b = rng.standard_normal((2, 3))
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    r = rotation_between(a, b)
    np.testing.assert_allclose(r @ a, b, atol=1e-15)
    np.testing.assert_allclose(r @ np.cross(a, b), np.cross(a, b), atol=1e-15)  # the axis
    np.testing.assert_array_equal(rotation_between(a, a), np.eye(3))
    half = rotation_between(a, -a)
    np.testing.assert_allclose(half @ a, -a, atol=1e-15)
    np.testing.assert_allclose(half @ half, np.eye(3), atol=1e-15)


def test_check_rotation():
    r = rotation_from_vector([0.3, -0.4, 0.5])
    np.testing.assert_allclose(check_rotation(r + 1e-8), r, atol=1e-7)
    got = check_rotation(r + 1e-8)
    np.testing.assert_allclose(got @ got.T, np.eye(3), atol=1e-15)
    with pytest.raises(ValueError, match="start: not a proper rotation"):
        check_rotation(np.diag([1.0, 1.0, -1.0]), "start")
    with pytest.raises(ValueError, match="not a proper rotation"):
        check_rotation(r * 1.01)
    with pytest.raises(ValueError, match=r"rotation: expected a finite \(3, 3\) matrix"):
        check_rotation(np.eye(2))


def test_check_orthonormal_keeps_exact_matrices_and_reflections():
    r = rotation_from_vector([0.1, 0.2, 0.3])
    kept = check_orthonormal(r, "R")
    np.testing.assert_array_equal(kept, r)
    assert kept is not r
    snapped = check_orthonormal(r + 1e-8, "R")
    np.testing.assert_allclose(snapped @ snapped.T, np.eye(3), atol=1e-15)
    flip = np.diag([1.0, 1.0, -1.0])
    np.testing.assert_array_equal(check_orthonormal(flip, "R"), flip)  # its determinant kept
    with pytest.raises(ValueError, match="R: not orthonormal"):
        check_orthonormal(r + 1e-3, "R")
    with pytest.raises(ValueError, match="R: must be a finite 3x3 matrix"):
        check_orthonormal(np.full((3, 3), np.nan), "R")


def test_a_point_s_distance_to_segments_is_to_the_nearest_and_within_its_ends():
    a = np.array([[0.0, 0.0], [10.0, 0.0]])
    b = np.array([[10.0, 0.0], [10.0, 10.0]])
    points = np.array([[5.0, 3.0], [13.0, 5.0], [-3.0, -4.0], [10.0, 0.0]])
    np.testing.assert_allclose(distance_to_segments(points, a, b), [3.0, 3.0, 5.0, 0.0])
    assert np.isinf(distance_to_segments(points, a[:0], b[:0])).all()
