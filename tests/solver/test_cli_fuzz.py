"""Fuzz tests of the command line (hypothesis): mutated landmarks files and random option
values never end in a traceback; the exit code is 0 or 1 (2: argparse's usage error), an
error is exactly one line naming the file or option (validate: one line per problem, each
naming the file), and no input file is ever changed. Derandomized and bounded: the whole
set runs in well under a minute."""

import contextlib
import copy
import hashlib
import io
import json
from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from solver import cli
from solver.fitting.options import RANGES
from tests.solver.test_cli import landmarks_doc

W, H = 300, 400


def bounded(max_examples):
    """Reproducible (derandomized, no example database) and bounded settings."""
    return settings(derandomize=True, deadline=None, database=None,
                    max_examples=max_examples,
                    suppress_health_check=[HealthCheck.too_slow,
                                           HealthCheck.function_scoped_fixture])

JSON_LEAF = (st.none() | st.booleans() | st.integers(-10**20, 10**20)
             | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=6))
JSON_VALUE = st.recursive(JSON_LEAF, lambda kids: st.lists(kids, max_size=4)
                          | st.dictionaries(st.text(max_size=6), kids, max_size=4),
                          max_leaves=12)


def _doc():
    doc = landmarks_doc(W, H, margin=20, seed=2, front=(0, 12), side=(40, 48))
    doc["views"]["side"]["contour"] = [[100.0, 50.0], [90.0, 120.0], [110.0, 200.0]]
    return doc


DOC = _doc()


def _paths(node, prefix=()):
    """Every path (tuple of keys) inside a JSON document."""
    out = [prefix]
    if isinstance(node, dict):
        for k, v in node.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += _paths(v, prefix + (i,))
    return out


@st.composite
def mutated_docs(draw):
    """The valid document with 1-3 nodes replaced, removed or renamed, or a pixel moved."""
    doc = copy.deepcopy(DOC)
    for _ in range(draw(st.integers(1, 3))):
        paths = [p for p in _paths(doc) if p]
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        parent = doc
        for key in path[:-1]:
            parent = parent[key]
        key = path[-1]
        action = draw(st.sampled_from(["replace", "replace", "number", "delete", "rename",
                                       "nudge"]))
        if action == "nudge" and isinstance(parent[key], int | float):
            # a landmark moved within the photo: still a valid file, fitted
            parent[key] = draw(st.floats(0.0, float(W)))
        elif action == "replace":
            parent[key] = draw(JSON_VALUE)
        elif action == "number":
            parent[key] = draw(st.floats(allow_nan=True, allow_infinity=True)
                               | st.integers(-10**30, 10**30))
        elif action == "delete" and isinstance(parent, dict):
            del parent[key]
        elif action == "rename" and isinstance(parent, dict):
            parent[draw(st.text(min_size=1, max_size=8))] = parent.pop(key)
    return doc


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    from PIL import Image

    root = tmp_path_factory.mktemp("fuzz")
    for name in ("front", "side"):
        Image.new("RGB", (W, H), (120, 90, 60)).save(root / f"{name}.png")
    return root


def _snapshot(folder):
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest()
            for p in Path(folder).iterdir() if p.is_file()}


def _run(argv):
    err, out = io.StringIO(), io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            code = cli.main([str(a) for a in argv])
        except SystemExit as e:  # argparse: usage error
            code = e.code
    return code, err.getvalue()


def _assert_clean(code, stderr, one_line=True):
    assert "Traceback" not in stderr and "internal error" not in stderr, stderr
    assert code in (0, 1, 2), (code, stderr)
    lines = stderr.strip().splitlines()
    if code == 1 and one_line:
        assert len(lines) == 1, stderr
    if code == 2:
        assert lines[-1].startswith(f"{cli.PROG} fit: error: "), stderr


def _write(folder, doc):
    """The document (or JSON text as it is) as ``case.json`` in ``folder``."""
    text = doc if isinstance(doc, str) else json.dumps(doc, allow_nan=True)
    path = Path(folder) / "case.json"
    path.write_text(text, encoding="utf-8")
    return path


@bounded(150)
@given(doc=mutated_docs())
@example(doc=json.dumps(DOC)[:-1] + ', "x-tool": ' + "[" * 2000 + "]" * 2000 + "}")  # text
@example(doc={**DOC, "views": {"\x85": None}})  # a view name that breaks the line
def test_validate_a_mutated_file(folder, doc):
    path = _write(folder, doc)
    before = _snapshot(folder)
    code, stderr = _run(["validate", path])
    _assert_clean(code, stderr, one_line=False)
    if code == 1:
        assert all(line.startswith(str(path)) for line in stderr.strip().splitlines()), stderr
    assert _snapshot(folder) == before


@bounded(20)
@given(doc=mutated_docs())
def test_fit_a_mutated_file(folder, doc, model):
    path = _write(folder, doc)
    before = _snapshot(folder)
    code, stderr = _run(["fit", path, "--out", Path(folder) / "out" / "head.obj",
                         "--components", 5, "--max-iterations", 2, "--noise", "fixed",
                         "-q"])
    _assert_clean(code, stderr)
    assert _snapshot(folder) == before


NUMBER_TEXT = (st.floats(allow_nan=True, allow_infinity=True).map(repr)
               | st.integers(-10**12, 10**12).map(str)
               | st.sampled_from(["1e300", "-0", "nan", "inf", "1e-300", "", "x", "0x10"]))
OUTPUTS = st.sampled_from(["case.json", "front.png", "side.png", "out/head.obj",
                           "out/head.mtl", "out/head.png", "out/report.json", "out"])


class _ReachedTheFit(BaseException):
    """Raised instead of fitting: every option was accepted."""


@bounded(80)
@given(options=st.dictionaries(st.sampled_from(["--lambda1", "--lambda2", "--noise-px",
                                                "--components", "--regional",
                                                "--max-iterations", "--texture-size"]),
                               NUMBER_TEXT, max_size=3),
       out=OUTPUTS, texture=st.none() | OUTPUTS, report=st.none() | OUTPUTS)
@example(options={"--lambda2": "1e300"}, out="out/head.obj", texture=None, report=None)
@example(options={}, out="out/head.obj", texture=None, report="case.json")
def test_fit_options_and_output_paths(folder, model, monkeypatch, options, out, texture,
                                      report):
    import solver.fitting.fit as fit_module

    def reached(model, case, options):
        for name, (lo, hi) in RANGES.items():
            value = getattr(options, name)
            assert value is None or lo <= value <= hi, (name, value)
        raise _ReachedTheFit

    monkeypatch.setattr(fit_module, "fit_head", reached)
    path = _write(folder, DOC)
    before = _snapshot(folder)
    argv = ["fit", path, "--out", Path(folder) / out, "-q"]
    if texture is not None:
        argv += ["--texture", Path(folder) / texture]
    if report is not None:
        argv += ["--report", Path(folder) / report]
    for flag, value in options.items():
        argv.append(f"{flag}={value}")
    try:
        code, stderr = _run(argv)
    except _ReachedTheFit:
        outs = [Path(folder) / p for p in (out, texture, report) if p is not None]
        outs += [Path(folder) / Path(out).with_suffix(".mtl")] if texture else []
        assert len({p.resolve() for p in outs}) == len(outs)  # all distinct, and
        assert not {"case.json", "front.png", "side.png"} & {p.name for p in outs}  # new
        return
    _assert_clean(code, stderr)
    assert _snapshot(folder) == before
