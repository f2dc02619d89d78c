"""Re-exports dvsot.render.sample_times, where this module lives now; this old import path goes in the next release."""

from dvsot.render.sample_times import *  # noqa: F401,F403
