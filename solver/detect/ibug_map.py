"""The fixed map from MediaPipe's 468-point face mesh to the iBUG-68 landmarks
(``assets/mediapipe_ibug68.json``): each iBUG point is the mean of one or two mesh points."""

import functools

import numpy as np

from ..io.json_file import read_json
from ..paths import ASSETS_DIR

MAP_PATH = ASSETS_DIR / "mediapipe_ibug68.json"


@functools.cache
def ibug_map(path=MAP_PATH):
    """(68, 468) averaging matrix: row i - 1 gives iBUG point i from the mesh points."""
    data = read_json(path)
    table = data.get("ibug") if isinstance(data, dict) else None
    n = data.get("mesh_points") if isinstance(data, dict) else None
    if not isinstance(table, dict) or sorted(table, key=int) != [str(i) for i in range(1, 69)]:
        raise ValueError(f"{path}: 'ibug' must map each of 1..68 to mesh points")
    m = np.zeros((68, n))
    for key, idx in table.items():
        if not idx or not all(isinstance(i, int) and 0 <= i < n for i in idx):
            raise ValueError(f"{path}: iBUG {key}: mesh points must be integers in 0..{n - 1}")
        m[int(key) - 1, idx] = 1.0 / len(idx)
    return m


def mesh_to_ibug(points):
    """iBUG-68 points (68, D) from mesh points (468, D)."""
    return ibug_map() @ np.asarray(points, float)
