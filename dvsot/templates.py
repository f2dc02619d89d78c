"""Re-exports dvsot.scene.templates, where this module lives now; this old import path goes in the next release."""

from dvsot.scene.templates import *  # noqa: F401,F403
