"""Re-exports dvsot.scene, where this module lives now; this old import path goes in the next release."""

from dvsot.scene import *  # noqa: F401,F403
