"""HeadRecon's tests, laid out as the code they test (``solver/``, ``headrecon_addon/`` as
``addon/``, ``bench/``, ``tools/``)."""

from pathlib import Path

#: The checkout's root.
ROOT = Path(__file__).resolve().parent.parent
