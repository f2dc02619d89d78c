"""Re-exports dvsot.dataset.torchdata, where this module lives now; this old import path goes in the next release."""

from dvsot.dataset.torchdata import *  # noqa: F401,F403
