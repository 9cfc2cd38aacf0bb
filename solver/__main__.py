"""``python -m solver``: the headless command line (see ``solver/cli.py``)."""

import sys

from .cli import main

if __name__ == "__main__":
    sys.exit(main())
