"""Re-exports dvsot.scene, where this package lives now (its schema and loader included); this old import path
goes in the next release."""

from dvsot.scene import *  # noqa: F401,F403
from dvsot.scene.loader import *  # noqa: F401,F403
from dvsot.scene.schema import *  # noqa: F401,F403
