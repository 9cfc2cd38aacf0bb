"""Shared pytest fixtures."""

import pytest

from solver.model import load_model


@pytest.fixture(scope="session")
def model():
    """The built head model (``generated/model/head_model.npz``). A missing model is an
    error, not a skip: the loader's message says to run ``./run model``."""
    return load_model()
