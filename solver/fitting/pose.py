"""Where the head starts: placed in the world of the calibrated cameras (triangulated
landmarks, or a resection through one perspective camera), else at the origin for the
free cameras to come to."""

import numpy as np

from ..cameras import PinholeCamera
from ..cameras.triangulate import triangulate
from ..procrustes import similarity_procrustes


def init_pose(eng, state):
    """Place the head in the world of the calibrated (kept) cameras. With two or more, the
    landmarks seen in two of them are triangulated and the mean head's landmark vertices
    fitted to those points by a similarity (Procrustes). With one perspective camera, the
    mean head is posed so its landmarks project onto the placed ones (a pose-only pinhole
    refit, scale 1: one photo cannot tell size from distance). Otherwise the head starts
    at the origin, upright, at scale 1 (the free cameras come to it)."""
    fixed = [v for v in eng.views if not v.refit and v.mirror_of is None]
    if len(fixed) >= 2 and pose_by_triangulation(eng, state, fixed):
        return
    persp = [v for v in fixed if v.camera.perspective]
    if len(persp) >= 1:
        pose_by_resection(eng, state, max(persp, key=lambda v: len(v.vertices)))


def pose_by_triangulation(eng, state, fixed):
    verts = np.unique(np.concatenate([v.vertices for v in fixed]))
    pix = np.full((len(fixed), len(verts), 2), np.nan)
    for j, v in enumerate(fixed):
        pix[j, np.searchsorted(verts, v.vertices)] = v.pixels
    try:
        tri = triangulate([v.camera for v in fixed], pix)
    except (ValueError, TypeError):  # a kind triangulation does not know
        return False
    ok = np.isfinite(tri.points).all(axis=1)
    if ok.sum() < 4:
        return False
    try:
        sim = similarity_procrustes(eng.local(state, verts[ok]), tri.points[ok])
    except ValueError:
        return False
    state.scale, state.rotation, state.translation = sim.scale, sim.rotation, sim.translation
    return True


def pose_by_resection(eng, state, view):
    """Pose the head (scale kept) from one calibrated perspective camera: the camera's pose
    relative to the mean head (a pinhole refit with its intrinsics kept) composed with
    its pose in the world."""
    try:
        probe = PinholeCamera.with_pose_of(view.camera, free_focal=False, focal_range_mm=None)
        local = eng.local(state, view.vertices)
        rel = probe.refit(local, view.pixels, view.weights)
    except ValueError:
        return
    rot = probe.rotation.T @ rel.rotation
    state.rotation = rot
    state.translation = probe.centre - rot @ rel.centre
    state.scale = 1.0

