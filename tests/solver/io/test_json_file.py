"""Reading JSON files (solver/io/json_file.py): errors name the file."""

import pytest

from solver.io.json_file import json_depth, read_json


def test_read_json(tmp_path):
    p = tmp_path / "a.json"
    p.write_bytes(b'\xef\xbb\xbf{"a": [1, 2.5]}')  # a BOM is tolerated
    assert read_json(p) == {"a": [1, 2.5]}
    p.write_text('{"a": 1, "a": 2}', encoding="utf-8")
    with pytest.raises(ValueError, match=r"a\.json: key 'a' appears twice in one object"):
        read_json(p)
    p.write_text("{", encoding="utf-8")
    with pytest.raises(ValueError, match=r"a\.json: not valid JSON: .*line 1, column 2"):
        read_json(p)
    p.write_bytes(b'"\xff"')
    with pytest.raises(ValueError, match=r"a\.json: not UTF-8 text \(byte 0xff at offset 1\)"):
        read_json(p)
    with pytest.raises(FileNotFoundError, match=r"b\.json: no such file"):
        read_json(tmp_path / "b.json")
    with pytest.raises(IsADirectoryError, match="is a folder"):
        read_json(tmp_path)


def test_deep_nesting_is_refused_before_parsing(tmp_path):
    p = tmp_path / "deep.json"
    p.write_text('{"x-tool": ' + "[" * 5000 + "]" * 5000 + "}", encoding="utf-8")
    with pytest.raises(ValueError, match=r"deep\.json: arrays and objects nested 5001 deep; "
                                         r"at most 64"):
        read_json(p)
    # brackets inside strings are text, not nesting
    p.write_text('{"x-tool": "' + "[" * 5000 + '", "a": [[1]]}', encoding="utf-8")
    assert read_json(p)["a"] == [[1]]
    p.write_text("[" * 64 + "]" * 64, encoding="utf-8")
    got, levels = read_json(p), 1
    while got:
        got, levels = got[0], levels + 1
    assert levels == 64  # the limit itself is read
    assert json_depth(b'{"a": "\\"[[", "b": [{}]}') == 3


def test_a_huge_file_is_refused(tmp_path, monkeypatch):
    import solver.io.json_file as jf

    monkeypatch.setattr(jf, "MAX_JSON_BYTES", 100)
    p = tmp_path / "big.json"
    p.write_text("[" + ",".join(["1"] * 100) + "]", encoding="utf-8")
    with pytest.raises(ValueError, match=r"big\.json: larger than"):
        read_json(p)
