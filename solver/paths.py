"""Where the package's data lives: the root that holds ``solver/``, ``assets/`` and
``generated/``, the same in a checkout and inside the extension."""

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ASSETS_DIR = ROOT / "assets"
DEFAULT_MODEL_PATH = ROOT / "generated" / "model" / "head_model.npz"
DETECTOR_DIR = ROOT / "generated" / "detector"


def model_path():
    """The head model file a process loads by default: ``HEADRECON_MODEL`` when set, else
    ``DEFAULT_MODEL_PATH``."""
    return Path(os.environ.get("HEADRECON_MODEL") or DEFAULT_MODEL_PATH)
