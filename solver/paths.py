"""Where the package's data lives: the root that holds ``solver/``, ``assets/`` and
``generated/``, the same in a checkout and inside the extension."""

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
ASSETS_DIR = ROOT / "assets"
DEFAULT_MODEL_PATH = ROOT / "generated" / "model" / "head_model.npz"
DETECTOR_DIR = ROOT / "generated" / "detector"
