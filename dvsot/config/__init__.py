"""Deprecated import path of dvsot.scene (scene schema and loader): it warns, and goes in the next release."""

import warnings

from dvsot.scene import *  # noqa: F401,F403
from dvsot.scene.loader import *  # noqa: F401,F403
from dvsot.scene.schema import *  # noqa: F401,F403

warnings.warn("dvsot.config is deprecated: import dvsot.scene (or dvsot.load_scene) instead", DeprecationWarning,
              stacklevel=2)
