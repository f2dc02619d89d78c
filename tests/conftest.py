"""Test-wide set-up: the shared helpers beside this file (synthetic.py) import as top-level modules."""

import sys
from pathlib import Path

HELPERS = str(Path(__file__).resolve().parent)
if HELPERS not in sys.path:
    sys.path.insert(0, HELPERS)
