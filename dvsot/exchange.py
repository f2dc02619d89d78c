"""Re-exports dvsot.interop.event_files, where this module lives now; this old import path goes in the next release."""

from dvsot.interop.event_files import *  # noqa: F401,F403
