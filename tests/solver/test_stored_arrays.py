"""Arrays kept on disk beside a model's file (solver/stored_arrays.py)."""

import os

import numpy as np

from solver.stored_arrays import load_arrays, remove_stored, save_arrays, stored_path


class _Model:
    def __init__(self, path):
        self.path = str(path)


def _model(tmp_path):
    (tmp_path / "model").mkdir(exist_ok=True)
    f = tmp_path / "model" / "head.npz"
    f.write_bytes(b"a model")
    return _Model(f)


def test_arrays_round_trip_beside_the_model_file(tmp_path):
    m = _model(tmp_path)
    path = stored_path(m, "thing-8", ("key", 1), [__file__])
    # beside the model's folder, not in it (the extension zip takes that folder whole)
    assert path.parent == tmp_path / "model-cache" and path.name.startswith("head-thing-8-")
    assert load_arrays(path) is None
    arrays = {"a": np.arange(5, dtype=np.int32), "b": np.linspace(0, 1, 7)}
    assert save_arrays(path, arrays)
    got = load_arrays(path)
    assert got.keys() == arrays.keys()
    for k, v in arrays.items():
        assert got[k].dtype == v.dtype
        np.testing.assert_array_equal(got[k], v)
    assert not list(path.parent.glob(".*.tmp"))  # no temporary left behind


def test_another_model_file_key_or_code_is_another_file(tmp_path):
    m = _model(tmp_path)
    path = stored_path(m, "thing", 1, [__file__])
    assert stored_path(m, "thing", 2, [__file__]) != path
    other_code = tmp_path / "code.py"
    other_code.write_text("x = 1\n")
    assert stored_path(m, "thing", 1, [other_code]) != path
    st = os.stat(m.path)
    os.utime(m.path, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))  # the model rebuilt
    assert stored_path(m, "thing", 1, [__file__]) != path


def test_saving_removes_stale_siblings_only(tmp_path):
    m = _model(tmp_path)
    old = stored_path(m, "thing", 1, [__file__])
    save_arrays(old, {"a": np.zeros(2)})
    longer = stored_path(m, "thing-2", 1, [__file__])  # another name with the same start
    save_arrays(longer, {"a": np.zeros(2)})
    new = stored_path(m, "thing", 2, [__file__])
    save_arrays(new, {"a": np.ones(2)})
    assert not old.exists() and new.exists() and longer.exists()
    remove_stored(m, "thing")
    assert not new.exists() and not longer.exists()


def test_no_file_no_folder_or_damage_only_costs_the_computation(tmp_path):
    assert stored_path(object(), "thing", 1, [__file__]) is None
    assert stored_path(_Model(tmp_path / "gone.npz"), "thing", 1, [__file__]) is None
    assert load_arrays(None) is None and not save_arrays(None, {})
    m = _model(tmp_path)
    path = stored_path(m, "thing", 1, [__file__])
    (tmp_path / "model-cache").write_text("a file where the folder would be")
    assert not save_arrays(path, {"a": np.zeros(2)})
    (tmp_path / "model-cache").unlink()
    save_arrays(path, {"a": np.zeros(1000)})
    path.write_bytes(path.read_bytes()[:100])  # damaged
    assert load_arrays(path) is None
