"""Fixtures of the landmarks-file tests (documents of both versions, the landmark set, the
schema)."""

import json

import pytest

from solver import load_landmark_set
from solver.io.landmarks_file import SCHEMA_PATH
from tests.solver.io.support import make_doc, make_doc2


@pytest.fixture(scope="module")
def lms():
    return load_landmark_set()


@pytest.fixture(scope="module")
def names(lms):
    """Canonical names to place: landmarks with an ibug number first (for alias tests)."""
    with_ibug = [lms.ibug[k] for k in sorted(lms.ibug)]
    rest = [n for n in lms.names if n not in with_ibug]
    return with_ibug + rest


@pytest.fixture(scope="module")
def schema():
    with open(SCHEMA_PATH, encoding="utf-8") as f:
        return json.load(f)


@pytest.fixture
def doc(names):
    return make_doc(names)


@pytest.fixture
def doc2(names):
    return make_doc2(names)
