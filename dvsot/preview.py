"""Re-exports dvsot.dataset.preview, where this module lives now; this old import path goes in the next release."""

from dvsot.dataset.preview import *  # noqa: F401,F403
