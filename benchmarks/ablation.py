"""Re-exports benchmarks.experiments.ablation, where this module lives now (`python -m benchmarks.experiments.ablation`); this old path goes in the
next release."""

import sys

from benchmarks.experiments.ablation import *  # noqa: F401,F403
from benchmarks.experiments.ablation import main

if __name__ == "__main__":
    sys.exit(main())
