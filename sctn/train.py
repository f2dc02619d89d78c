"""Re-exports sctn.training.snn, where this module lives now; called, it is `train` (dvsot.core.lazy says why).

The package's public `train` is this module, so its old import path stays.
"""

from dvsot.core.lazy import callable_module
from sctn.training.snn import *  # noqa: F401,F403
from sctn.training.snn import train  # noqa: F401

callable_module(__name__, "train")
