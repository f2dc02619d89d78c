"""Re-exports dvsot.interop.text_events, where this module lives now; this old import path goes in the next release."""

from dvsot.interop.text_events import *  # noqa: F401,F403
