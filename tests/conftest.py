"""Shared pytest fixtures, and a clean exit on old Blender modules."""

import os
import sys

import pytest

from solver import load_model


@pytest.fixture(scope="session")
def model():
    """The built head model (``generated/model/head_model.npz``). A missing model is an
    error, not a skip: the loader's message says to run ``./run model``."""
    return load_model()


_exit_status = 0


def pytest_sessionfinish(session, exitstatus):
    global _exit_status
    _exit_status = int(exitstatus)


def pytest_unconfigure(config):
    """The bpy module before Blender 4.4 crashes while Python shuts down (Blender issue
    #125376), which would turn a green run red: once pytest has reported, end the process
    with pytest's own exit status."""
    bpy = sys.modules.get("bpy")
    if bpy is not None and bpy.app.version < (4, 4, 0):
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(_exit_status)
