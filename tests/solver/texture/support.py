"""Small hand-built meshes with UVs and coded photos for the texture tests."""

import numpy as np

from solver.model.head_model import fan_triangles

W, H = 96, 128  # photo size of the synthetic tests


class MeshModel:
    """The parts of HeadModel the texture code reads, for a hand-built mesh."""

    def __init__(self, vertices, faces, face_uvs, face_part, part_names):
        self.vertices = np.asarray(vertices, dtype=np.float64)
        self.face_loop_total = np.array([len(f) for f in faces])
        self.face_loop_start = np.concatenate([[0], np.cumsum(self.face_loop_total)[:-1]])
        self.loop_vertex = np.concatenate([np.asarray(f) for f in faces])
        self.loop_uv = np.concatenate([np.asarray(u, dtype=np.float64) for u in face_uvs])
        self.face_part = np.asarray(face_part)
        self.part_names = tuple(part_names)
        self.skin = np.arange(len(self.vertices))

    def triangles(self):
        tri_loop, tri_face = fan_triangles(self.face_loop_start, self.face_loop_total)
        return self.loop_vertex[tri_loop], tri_loop, tri_face


def uv_sphere(radius=0.1, n_lon=48, n_lat=24):
    """Latitude-longitude sphere, outward winding, u = longitude / 2 pi, v = latitude."""
    lat = np.linspace(-np.pi / 2, np.pi / 2, n_lat + 1)[1:-1]
    lon = np.arange(n_lon) * 2 * np.pi / n_lon
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    ring = np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], -1)
    verts = np.vstack([ring.reshape(-1, 3), [[0, 0, -1], [0, 0, 1]]]) * radius
    south, north = n_lon * (n_lat - 1), n_lon * (n_lat - 1) + 1

    def vid(k, j):
        return (k - 1) * n_lon + j % n_lon

    faces, uvs = [], []
    for k in range(n_lat):
        for j in range(n_lon):
            u0, u1, v0, v1 = j / n_lon, (j + 1) / n_lon, k / n_lat, (k + 1) / n_lat
            if k == 0:
                faces.append([south, vid(1, j + 1), vid(1, j)])
                uvs.append([[(j + 0.5) / n_lon, 0], [u1, v1], [u0, v1]])
            elif k == n_lat - 1:
                faces.append([vid(k, j), vid(k, j + 1), north])
                uvs.append([[u0, v0], [u1, v0], [(j + 0.5) / n_lon, 1]])
            else:
                faces.append([vid(k, j), vid(k, j + 1), vid(k + 1, j + 1), vid(k + 1, j)])
                uvs.append([[u0, v0], [u1, v0], [u1, v1], [u0, v1]])
    return MeshModel(verts, faces, uvs, [0] * len(faces), ["Face"])


def grid_sheet(x0, x1, z0, z1, y, n, uv_box):
    """An n x n quad sheet at depth y facing -Y (the front camera), UVs filling uv_box."""
    s = np.linspace(0, 1, n + 1)
    gx, gz = np.meshgrid(s, s, indexing="ij")
    verts = np.stack([x0 + (x1 - x0) * gx, np.full_like(gx, y), z0 + (z1 - z0) * gz], -1)
    uv = np.stack([uv_box[0] + (uv_box[2] - uv_box[0]) * gx,
                   uv_box[1] + (uv_box[3] - uv_box[1]) * gz], -1)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    faces, uvs = [], []
    for i in range(n):
        for k in range(n):
            # (x, z) counter-clockwise seen from -Y: normal (x-step) x (z-step) = -Y
            q = [idx[i, k], idx[i + 1, k], idx[i + 1, k + 1], idx[i, k + 1]]
            faces.append(q)
            uvs.append(uv.reshape(-1, 2)[q])
    return verts.reshape(-1, 3), faces, uvs


def two_sheets():
    """A small sheet ("Face") 5 cm in front of a big one ("Head and Neck")."""
    v1, f1, u1 = grid_sheet(-0.03, 0.03, -0.03, 0.03, -0.05, 6, (0.02, 0.02, 0.45, 0.45))
    v2, f2, u2 = grid_sheet(-0.08, 0.08, -0.08, 0.08, 0.05, 16, (0.5, 0.02, 0.98, 0.98))
    f2 = [[i + len(v1) for i in f] for f in f2]
    return MeshModel(np.vstack([v1, v2]), f1 + f2, u1 + u2, [0] * len(f1) + [1] * len(f2),
                     ["Face", "Head and Neck"])


def coded_photo():
    """Colour = (u / W, v / H, 0.5): a photo whose colour says where it was sampled."""
    yy, xx = np.mgrid[0:H, 0:W] + 0.5
    return np.stack([xx / W, yy / H, np.full_like(xx, 0.5)], -1).astype(np.float32)
