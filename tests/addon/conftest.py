"""Fixtures of the add-on tests."""

import pytest

from tests.addon.support import addon, empty_scene, synthetic_files


@pytest.fixture
def scene():
    """An empty scene (factory settings), the add-on registered."""
    return empty_scene()


@pytest.fixture(scope="module")
def files(model, tmp_path_factory, request):
    """A synthetic case written to disk with its photos, once per test module; the module's
    ``FILES_SEED`` (default 3) picks the head."""
    addon()
    seed = getattr(request.module, "FILES_SEED", 3)
    return synthetic_files(model, tmp_path_factory.mktemp(f"case{seed}"), seed=seed)
