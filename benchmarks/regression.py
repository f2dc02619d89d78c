"""Re-exports benchmarks.experiments.regression, where this module lives now (`python -m benchmarks.experiments.regression`); this old path goes in the
next release."""

import sys

from benchmarks.experiments.regression import *  # noqa: F401,F403
from benchmarks.experiments.regression import main

if __name__ == "__main__":
    sys.exit(main())
