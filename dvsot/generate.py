"""Re-exports dvsot.pipeline.generate, where this module lives now; called, it is `generate` (dvsot.lazy says why).

The package's public `generate` is this module, so its old import path stays.
"""

from dvsot.lazy import callable_module
from dvsot.pipeline.generate import *  # noqa: F401,F403
from dvsot.pipeline.generate import generate  # noqa: F401

callable_module(__name__, "generate")
