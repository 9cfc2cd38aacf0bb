"""Our JSON Schema validator (solver/io/jsonschema_lite.py): every keyword it implements
cross-checked against the reference ``jsonschema`` package, refused keywords, error paths."""


import pytest

from solver.io.jsonschema_lite import KEYWORDS, SchemaKeywordError, Validator, format_path, validate
from tests.solver.io.support import agree

GENERIC_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "type": "object",
    "required": ["n"],
    "minProperties": 2,
    "properties": {
        "n": {"type": "number", "exclusiveMinimum": 0, "exclusiveMaximum": 10},
        "i": {"type": ["integer", "null"], "minimum": -2, "maximum": 2},
        "e": {"enum": [1, "one", None, [1, 2], {"a": 1}]},
        "c": {"const": False},
        "s": {"type": "string", "minLength": 2, "pattern": "^[a-z]+$"},
        "t": {"type": "array", "prefixItems": [{"type": "string"}, {"type": "boolean"}],
              "items": False},
        "r": {"$ref": "#/$defs/pair"},
        "a": {"anyOf": [{"type": "string"}, {"$ref": "#/$defs/pair"}]},
        "k": {"type": "object", "allOf": [{"required": ["kind"]}, {"minProperties": 1}],
              "if": {"required": ["kind"], "properties": {"kind": {"const": "a"}}},
              "then": {"required": ["x"]},
              "else": {"properties": {"x": {"type": "string"}}}},
    },
    "patternProperties": {"^p_": {"type": "integer"}},
    "additionalProperties": {"type": "boolean"},
    "$defs": {"pair": {"type": "array", "items": {"type": "number"}, "minItems": 2,
                       "maxItems": 2}},
}


GENERIC_CASES = [
    ({"n": 1, "i": 2}, True), ({"n": 1}, False), ({"n": 0, "i": 1}, False),
    ({"n": 10, "i": 1}, False), ({"n": 9.9, "i": None}, True), ({"n": 1, "i": 3}, False),
    ({"n": 1, "i": 1.0}, True), ({"n": 1, "i": 1.5}, False), ({"n": 1, "i": True}, False),
    ({"n": 1, "e": 1.0}, True), ({"n": 1, "e": True}, False), ({"n": 1, "e": [1, 2]}, True),
    ({"n": 1, "e": [2, 1]}, False), ({"n": 1, "e": {"a": 1.0}}, True),
    ({"n": 1, "e": {"a": True}}, False), ({"n": 1, "c": False}, True), ({"n": 1, "c": 0}, False),
    ({"n": 1, "s": "ab"}, True), ({"n": 1, "s": "a"}, False), ({"n": 1, "s": "aB"}, False),
    ({"n": 1, "t": ["a", True]}, True), ({"n": 1, "t": ["a"]}, True),
    ({"n": 1, "t": ["a", 1]}, False), ({"n": 1, "t": ["a", True, 3]}, False),
    ({"n": 1, "r": [1, 2]}, True), ({"n": 1, "r": [1]}, False), ({"n": 1, "r": [1, "2"]}, False),
    ({"n": 1, "a": "x"}, True), ({"n": 1, "a": [1, 2.5]}, True), ({"n": 1, "a": [1]}, False),
    ({"n": 1, "a": 3}, False), ({"n": 1, "p_x": 3}, True), ({"n": 1, "p_x": "3"}, False),
    ({"n": 1, "other": True}, True), ({"n": 1, "other": 1}, False), ({"n": "1", "i": 1}, False),
    ({"n": float("nan"), "i": 1}, True), ([1], False), ("n", False),
    ({"n": 1, "k": {"kind": "a", "x": 1}}, True), ({"n": 1, "k": {"kind": "a"}}, False),
    ({"n": 1, "k": {"kind": "b", "x": "s"}}, True), ({"n": 1, "k": {"kind": "b", "x": 1}}, False),
    ({"n": 1, "k": {"kind": "b"}}, True), ({"n": 1, "k": {"x": "s"}}, False),
    ({"n": 1, "k": {}}, False),
]


@pytest.mark.parametrize("instance,valid", GENERIC_CASES)
def test_every_keyword_agrees_with_jsonschema(instance, valid):
    assert agree(GENERIC_SCHEMA, instance) is valid


def test_generic_schema_uses_every_implemented_keyword():
    used = set()

    def walk(s):
        if isinstance(s, dict):
            used.update(k for k in s if k in KEYWORDS)
            for v in s.values():
                walk(v)
        elif isinstance(s, list):
            for v in s:
                walk(v)

    walk(GENERIC_SCHEMA)
    assert used == set(KEYWORDS)


def test_unsupported_keywords_and_refs_are_refused():
    with pytest.raises(SchemaKeywordError, match="oneOf"):
        Validator({"properties": {"a": {"oneOf": [{"type": "string"}]}}})
    with pytest.raises(SchemaKeywordError, match="does not resolve"):
        Validator({"$ref": "#/$defs/missing"})
    with pytest.raises(SchemaKeywordError, match="only local"):
        Validator({"$ref": "https://example.com/s.json"})


def test_error_paths_and_messages():
    errs = validate({"views": {"front": {"points": {"nose_tip": [1, "x"]}}}},
                    {"properties": {"views": {"additionalProperties": {"properties": {
                        "points": {"additionalProperties": {"items": {"type": "number"}}}}}}}})
    assert [str(e) for e in errs] == [
        'views.front.points.nose_tip[1]: expected a number, got string "x"']
    assert format_path(()) == ""
    assert format_path(("a", 0, "b c", 'q"')) == 'a[0]["b c"]["q\\""]'


def test_a_key_that_breaks_lines_is_escaped():
    path = format_path(("views", "\x85", "a\u2028b", "é"))
    assert path == 'views["\\u0085"]["a\\u2028b"]["é"]' and len(path.splitlines()) == 1
