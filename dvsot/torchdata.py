"""Deprecated import path of dvsot.dataset.torchdata: it warns, and goes in the next release."""

import warnings

from dvsot.dataset.torchdata import *  # noqa: F401,F403

warnings.warn("dvsot.torchdata is deprecated: import dvsot.dataset.torchdata (or dvsot.SegmentDataset) instead",
              DeprecationWarning, stacklevel=2)
