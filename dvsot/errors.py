"""Deprecated import path of dvsot.core.errors: it warns, and goes in the next release."""

import warnings

from dvsot.core.errors import *  # noqa: F401,F403

warnings.warn("dvsot.errors is deprecated: import dvsot.core.errors (or dvsot.UserError, dvsot.RunError) instead",
              DeprecationWarning, stacklevel=2)
