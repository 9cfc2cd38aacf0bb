"""A small JSON Schema (draft 2020-12) validator for HeadRecon's own schemas.

Blender does not ship the ``jsonschema`` package and an extension should not need it just
to check a landmarks file, so this module implements the subset of keywords our schemas use
(listed in ``KEYWORDS``) with the same semantics as the reference implementation; the tests
cross-check both on valid and invalid documents. A keyword outside the subset raises
``SchemaKeywordError`` instead of being ignored, so nobody extends a schema with a keyword
that would silently not be checked here.

Errors carry a readable JSON path (``views.front.points.nose_tip[1]``) so a message can name
the view and key at fault.
"""

import difflib
import json
import math
import re
from dataclasses import dataclass

# Keywords that constrain an instance (implemented below).
KEYWORDS = frozenset({
    "type", "required", "properties", "additionalProperties", "patternProperties",
    "items", "prefixItems", "minItems", "maxItems", "enum", "const", "minimum", "maximum",
    "exclusiveMinimum", "exclusiveMaximum", "minProperties", "minLength", "pattern",
    "anyOf", "allOf", "if", "then", "else", "$ref",
})
# Keywords that only annotate; accepted and ignored (as the reference implementation does).
ANNOTATIONS = frozenset({
    "$schema", "$id", "$comment", "$defs", "title", "description", "default", "examples",
    "deprecated", "readOnly", "writeOnly",
})


class SchemaKeywordError(Exception):
    """The schema uses a keyword this validator does not implement (a bug in the schema,
    not in the document being checked)."""


@dataclass(frozen=True)
class ValidationError:
    """One violation: where (``path``, a tuple of keys and indices) and what (``message``).
    ``keyword`` is the schema keyword that failed, for callers that rank errors."""

    path: tuple
    message: str
    keyword: str

    @property
    def where(self):
        """The path as text, e.g. ``views.front.points.nose_tip[1]`` ("" for the root)."""
        return format_path(self.path)

    def __str__(self):
        return f"{self.where}: {self.message}" if self.path else self.message


_PLAIN_KEY = re.compile(r"^[A-Za-z0-9_\-]+$")


def format_path(path):
    """``('views', 'front', 'points', 'nose_tip', 1)`` -> ``views.front.points.nose_tip[1]``.

    Keys that are not plain words (spaces, dots, quotes...) are written ``["my key"]`` so the
    path stays unambiguous, with characters that do not print (line breaks such as U+0085)
    escaped, so a message stays one line.
    """
    out = ""
    for part in path:
        if isinstance(part, int):
            out += f"[{part}]"
        elif _PLAIN_KEY.match(part):
            out += f".{part}" if out else part
        else:
            quoted = json.dumps(part, ensure_ascii=False)
            out += "[" + "".join(c if c.isprintable() else f"\\u{ord(c):04x}"
                                 for c in quoted) + "]"
    return out


def _type_ok(instance, name):
    # bool is a subclass of int in Python but never a JSON number; an integer-valued float
    # (1.0) is a JSON integer, as in the reference implementation.
    if name == "object":
        return isinstance(instance, dict)
    if name == "array":
        return isinstance(instance, list)
    if name == "string":
        return isinstance(instance, str)
    if name == "boolean":
        return isinstance(instance, bool)
    if name == "null":
        return instance is None
    if isinstance(instance, bool):
        return False
    if name == "number":
        return isinstance(instance, int | float)
    if name == "integer":
        return isinstance(instance, int) or (isinstance(instance, float)
                                             and instance.is_integer())
    raise SchemaKeywordError(f"unknown JSON type {name!r} in schema")


def _json_type(instance):
    for name in ("null", "boolean", "object", "array", "string", "integer", "number"):
        if _type_ok(instance, name):
            return name
    return type(instance).__name__


def _equal(a, b):
    """JSON equality: True is not 1, 1 equals 1.0, containers compare element-wise."""
    if isinstance(a, bool) or isinstance(b, bool):
        return isinstance(a, bool) and isinstance(b, bool) and a == b
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, int | float) and isinstance(b, int | float):
        return a == b
    return type(a) is type(b) and a == b


def _show(value):
    """Short JSON-ish rendering of a value for messages."""
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)
    try:
        text = json.dumps(value, ensure_ascii=False, allow_nan=True)
    except (TypeError, ValueError):
        text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _suggest(word, choices):
    """'; did you mean 'x'?' for a close string match, else ''."""
    if not isinstance(word, str):
        return ""
    close = difflib.get_close_matches(word, [c for c in choices if isinstance(c, str)], n=1)
    return f"; did you mean {close[0]!r}?" if close else ""


class Validator:
    """Validates instances against one schema (whose ``$ref`` point into its own ``$defs``).

    Parameters
    ----------
    schema : dict
        A JSON Schema using only ``KEYWORDS`` and ``ANNOTATIONS``.
    """

    def __init__(self, schema):
        if not isinstance(schema, dict | bool):
            raise SchemaKeywordError("a schema must be an object or a boolean")
        self.schema = schema
        self._patterns = {}
        self._check_keywords(schema, "#")

    def _check_keywords(self, schema, where):
        # Walk the whole schema once up front: an unsupported keyword anywhere is an error
        # even if no document ever reaches that branch.
        if isinstance(schema, bool):
            return
        if not isinstance(schema, dict):
            raise SchemaKeywordError(f"{where}: a schema must be an object or a boolean")
        unknown = set(schema) - KEYWORDS - ANNOTATIONS
        if unknown:
            raise SchemaKeywordError(f"{where}: keyword(s) {sorted(unknown)} not supported by "
                                     "jsonschema_lite; implement them or change the schema")
        for key in ("properties", "patternProperties", "$defs"):
            for name, sub in schema.get(key, {}).items():
                self._check_keywords(sub, f"{where}/{key}/{name}")
        for key in ("additionalProperties", "items", "if", "then", "else"):
            if key in schema:
                self._check_keywords(schema[key], f"{where}/{key}")
        for key in ("prefixItems", "anyOf", "allOf"):
            for i, sub in enumerate(schema.get(key, [])):
                self._check_keywords(sub, f"{where}/{key}/{i}")
        if "$ref" in schema:
            self._resolve(schema["$ref"])

    def _resolve(self, ref):
        if not ref.startswith("#/"):
            raise SchemaKeywordError(f"$ref {ref!r}: only local references ('#/...') supported")
        node = self.schema
        for part in ref[2:].split("/"):
            part = part.replace("~1", "/").replace("~0", "~")
            if not isinstance(node, dict) or part not in node:
                raise SchemaKeywordError(f"$ref {ref!r} does not resolve")
            node = node[part]
        return node

    def _regex(self, pattern):
        if pattern not in self._patterns:
            self._patterns[pattern] = re.compile(pattern)
        return self._patterns[pattern]

    def errors(self, instance):
        """Every violation of ``instance``, in document order (list of ValidationError)."""
        out = []
        self._validate(instance, self.schema, (), out)
        return out

    def is_valid(self, instance):
        return not self.errors(instance)

    def _validate(self, inst, schema, path, out):
        if schema is True:
            return
        if schema is False:
            out.append(ValidationError(path, "not allowed here", "false"))
            return
        if "$ref" in schema:
            self._validate(inst, self._resolve(schema["$ref"]), path, out)

        def err(keyword, message):
            out.append(ValidationError(path, message, keyword))

        if "type" in schema:
            types = schema["type"] if isinstance(schema["type"], list) else [schema["type"]]
            if not any(_type_ok(inst, t) for t in types):
                want = " or ".join("an " + t if t[0] in "aeiou" else "a " + t for t in types)
                err("type", f"expected {want}, got {_json_type(inst)} {_show(inst)}")
                return  # the other keywords would only repeat the same problem
        if "enum" in schema and not any(_equal(inst, v) for v in schema["enum"]):
            choices = ", ".join(_show(v) for v in schema["enum"])
            err("enum", f"{_show(inst)} is not one of {choices}{_suggest(inst, schema['enum'])}")
        if "const" in schema and not _equal(inst, schema["const"]):
            err("const", f"expected {_show(schema['const'])}, got {_show(inst)}")
        if "anyOf" in schema:
            self._any_of(inst, schema["anyOf"], path, out)
        for sub in schema.get("allOf", []):
            self._validate(inst, sub, path, out)
        if "if" in schema:
            # A discriminated union ("if kind is dlt then the DLT fields"): the condition's
            # own errors are never reported, only those of the branch it selects.
            branch = "then" if self._passes(inst, schema["if"], path) else "else"
            if branch in schema:
                self._validate(inst, schema[branch], path, out)

        if isinstance(inst, int | float) and not isinstance(inst, bool):
            if "minimum" in schema and inst < schema["minimum"]:
                err("minimum", f"{_show(inst)} is less than the minimum {schema['minimum']}")
            if "maximum" in schema and inst > schema["maximum"]:
                err("maximum", f"{_show(inst)} is more than the maximum {schema['maximum']}")
            if "exclusiveMinimum" in schema and inst <= schema["exclusiveMinimum"]:
                err("exclusiveMinimum",
                    f"{_show(inst)} must be greater than {schema['exclusiveMinimum']}")
            if "exclusiveMaximum" in schema and inst >= schema["exclusiveMaximum"]:
                err("exclusiveMaximum",
                    f"{_show(inst)} must be less than {schema['exclusiveMaximum']}")
        elif isinstance(inst, str):
            if "minLength" in schema and len(inst) < schema["minLength"]:
                err("minLength", "empty string" if not inst else
                    f"{_show(inst)} is shorter than {schema['minLength']} characters")
            if "pattern" in schema and not self._regex(schema["pattern"]).search(inst):
                err("pattern", f"{_show(inst)} does not match {schema['pattern']!r}")
        elif isinstance(inst, list):
            self._array(inst, schema, path, out, err)
        elif isinstance(inst, dict):
            self._object(inst, schema, path, out, err)

    def _passes(self, inst, schema, path):
        errs = []
        self._validate(inst, schema, path, errs)
        return not errs

    def _array(self, inst, schema, path, out, err):
        if "minItems" in schema and len(inst) < schema["minItems"]:
            err("minItems", f"expected at least {schema['minItems']} items, got {len(inst)}")
        if "maxItems" in schema and len(inst) > schema["maxItems"]:
            err("maxItems", f"expected at most {schema['maxItems']} items, got {len(inst)}")
        prefix = schema.get("prefixItems", [])
        for i, (item, sub) in enumerate(zip(inst, prefix, strict=False)):
            self._validate(item, sub, path + (i,), out)
        if "items" in schema:
            for i in range(len(prefix), len(inst)):
                self._validate(inst[i], schema["items"], path + (i,), out)

    def _object(self, inst, schema, path, out, err):
        missing = [k for k in schema.get("required", []) if k not in inst]
        for key in missing:
            err("required", f"missing required key {key!r}")
        if "minProperties" in schema and len(inst) < schema["minProperties"]:
            n = schema["minProperties"]
            err("minProperties", f"expected at least {n} entr{'y' if n == 1 else 'ies'}, "
                                 f"got {len(inst)}")
        props = schema.get("properties", {})
        patterns = schema.get("patternProperties", {})
        additional = schema.get("additionalProperties", True)
        for key, value in inst.items():
            matched = key in props
            if matched:
                self._validate(value, props[key], path + (key,), out)
            for pattern, sub in patterns.items():
                if self._regex(pattern).search(key):
                    matched = True
                    self._validate(value, sub, path + (key,), out)
            if not matched:
                if additional is False:
                    out.append(ValidationError(path + (key,), "unexpected key"
                                               + _suggest(key, list(props)),
                                               "additionalProperties"))
                else:
                    self._validate(value, additional, path + (key,), out)

    def _any_of(self, inst, branches, path, out):
        per_branch = []
        for sub in branches:
            errs = []
            self._validate(inst, sub, path, errs)
            if not errs:
                return
            per_branch.append(errs)
        # Report the branch meant for this kind of value (the ones whose type fits), so a
        # misspelt camera string reads "not one of ..." rather than "not valid under anyOf".
        fitting = [e for e in per_branch
                   if not any(x.keyword == "type" and x.path == path for x in e)]
        if len(fitting) == 1:
            out.extend(fitting[0])
            return
        types, titles = [], []
        for sub in branches:
            sub = self._resolve(sub["$ref"]) if isinstance(sub, dict) and "$ref" in sub else sub
            t = sub.get("type", []) if isinstance(sub, dict) else []
            types += [x for x in (t if isinstance(t, list) else [t]) if x not in types]
            titles.append(sub.get("title") if isinstance(sub, dict) else None)
        detail = ""
        if all(titles):  # the schema names its forms: list them ("11 numbers; 16 numbers")
            detail = ": " + "; ".join(titles)
        elif not fitting and types:
            detail = " (expected " + " or ".join(
                "an " + t if t[0] in "aeiou" else "a " + t for t in types) + ")"
        what = (f"an array of {len(inst)} item{'s' * (len(inst) != 1)}"
                if isinstance(inst, list) else _show(inst))
        out.append(ValidationError(path, f"{what} matches none of the allowed forms"
                                   + detail, "anyOf"))


def validate(instance, schema):
    """All violations of ``instance`` against ``schema`` (a list; empty when valid)."""
    return Validator(schema).errors(instance)
