"""Strict number and flag types and the strict base model, shared by every pydantic schema of the project.

Numbers must be numbers: no "1.6" strings or true/false where a number goes (an int is a fine float), and
no "False" string that would mean true. `Strict` models refuse unknown keys and NaN or infinite numbers.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict
from pydantic import Strict as _StrictType

Int = Annotated[int, _StrictType()]
Float = Annotated[float, _StrictType()]
Bool = Annotated[bool, _StrictType()]


class Strict(BaseModel):
    """Base model: unknown keys are errors, and so are NaN and infinite numbers."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)
