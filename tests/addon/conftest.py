"""Fixtures of the add-on tests."""

import pytest

from tests.addon.support import empty_scene


@pytest.fixture
def scene():
    """An empty scene (factory settings), the add-on registered."""
    return empty_scene()
