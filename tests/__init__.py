"""HeadRecon's tests, laid out as the code they test (``solver/``, ``headrecon_addon/`` as
``addon/``, ``bench/``, ``tools/``)."""

from pathlib import Path

#: The checkout's root.
ROOT = Path(__file__).resolve().parent.parent

#: The sample the tests render once per session (``tests/conftest.py``, fixture ``sample``):
#: photo size and the make_sample arguments (4 samples per pixel).
SAMPLE_SIZE = (384, 512)
SAMPLE_ARGS = ["--size", f"{SAMPLE_SIZE[0]}x{SAMPLE_SIZE[1]}", "--samples", "4"]
