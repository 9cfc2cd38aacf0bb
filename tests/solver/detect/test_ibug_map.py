"""The mesh -> iBUG-68 map."""

import json

import numpy as np
import pytest

from solver.detect import mesh_to_ibug
from solver.detect.ibug_map import MAP_PATH, ibug_map


def test_ibug_map_averages_mesh_points():
    m = ibug_map()
    assert m.shape == (68, 468)
    np.testing.assert_allclose(m.sum(1), 1.0)
    mesh = np.random.default_rng(0).normal(size=(468, 2))
    np.testing.assert_allclose(mesh_to_ibug(mesh)[8], mesh[152])   # iBUG 9: the menton


def test_map_is_mirror_symmetric_in_size_and_a_bad_map_names_its_file(tmp_path):
    table = json.loads(MAP_PATH.read_text())["ibug"]
    # iBUG mirror pairs: jaw 1<->17 ..., brows 18<->27 ..., eyes 37<->46 ..., mouth 49<->55
    pairs = [(i, 18 - i) for i in range(1, 9)] + [(i, 45 - i) for i in range(18, 23)]
    assert all(len(table[str(a)]) == len(table[str(b)]) for a, b in pairs)
    assert len({tuple(v) for v in table.values()}) == 68        # no two points the same
    bad = tmp_path / "map.json"
    bad.write_text(json.dumps({"mesh_points": 468, "ibug": {"1": [500]}}))
    with pytest.raises(ValueError, match="map.json"):
        ibug_map(bad)
