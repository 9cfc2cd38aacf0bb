"""Shared pytest fixtures, and a clean exit on old Blender modules."""

import os
import subprocess
import sys

import numpy as np
import pytest

from solver import load_model
from tests import ROOT, SAMPLE_ARGS


@pytest.fixture(scope="session")
def model():
    """The built head model (``generated/model/head_model.npz``). A missing model is an
    error, not a skip: the loader's message says to run ``./run model``."""
    return load_model()


def _rendered(tmp_path_factory, name, *args):
    """``tools.make_sample`` with ``args`` at the sample's reduced size (``SAMPLE_ARGS``),
    in a subprocess so Blender's global state never mixes with other tests: (folder, the
    arrays of its truth.npz)."""
    folder = tmp_path_factory.mktemp(name) / "sample"
    proc = subprocess.run([sys.executable, "-m", "tools.make_sample", "--out", str(folder),
                           *args, *SAMPLE_ARGS], cwd=ROOT, capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, f"make_sample failed:\n{proc.stdout[-3000:]}\n" \
                                 f"{proc.stderr[-3000:]}"
    with np.load(folder / "truth.npz", allow_pickle=False) as t:
        truth = {k: t[k] for k in t.files}
    return folder, truth


@pytest.fixture(scope="session")
def sample(tmp_path_factory):
    """The sample case rendered once per session: (folder, the arrays of its truth.npz)."""
    return _rendered(tmp_path_factory, "sample")


@pytest.fixture(scope="session")
def open_mouth_sample(tmp_path_factory):
    """The sample with its mouth a little open in both photos (``make_sample --expression
    jaw_open``)."""
    return _rendered(tmp_path_factory, "open_mouth_sample", "--expression", "jaw_open")


@pytest.fixture(scope="session")
def turned_sample(tmp_path_factory):
    """A head turned 45 degrees toward the side camera (``make_sample --seed 201 --yaw
    -45``): two three-quarter photos."""
    return _rendered(tmp_path_factory, "turned_sample", "--seed", "201", "--yaw", "-45")


@pytest.fixture(scope="session")
def turned_side_sample(tmp_path_factory):
    """A head turned 15 degrees toward the side camera (``make_sample --seed 201 --yaw
    -15``): a front photo about 16 degrees off, a side photo about 74 degrees from the
    front, short of a profile."""
    return _rendered(tmp_path_factory, "turned_side_sample", "--seed", "201", "--yaw", "-15")


@pytest.fixture(scope="session")
def three_quarter_sample(tmp_path_factory):
    """A head turned 25 degrees (``make_sample --seed 201 --yaw -25``): a three-quarter
    front photo about 26 degrees off, a side photo about 65 degrees from the front."""
    return _rendered(tmp_path_factory, "three_quarter_sample", "--seed", "201", "--yaw",
                     "-25")


@pytest.fixture(scope="session")
def window_sample(tmp_path_factory):
    """A head lit by a window at the subject's left alone (``make_sample --seed 205 --light
    window``): the front photo's far side and the whole profile in shade, a band of light
    along the profile's forehead and nose."""
    return _rendered(tmp_path_factory, "window_sample", "--seed", "205", "--light", "window")


@pytest.fixture(scope="session")
def lens_sample(tmp_path_factory):
    """The sample photographed with a 50 mm lens (``make_sample --lens 50``: pinhole cameras
    about half a metre away, JPEGs with the lens in their EXIF)."""
    return _rendered(tmp_path_factory, "lens_sample", "--lens", "50")


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
