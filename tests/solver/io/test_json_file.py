"""Reading JSON files (solver/io/json_file.py): errors name the file."""

import pytest

from solver.io.json_file import read_json


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
