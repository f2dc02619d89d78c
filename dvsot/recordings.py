"""Re-exports dvsot.interop.recordings, where this module lives now; this old import path goes in the next release."""

from dvsot.interop.recordings import *  # noqa: F401,F403
