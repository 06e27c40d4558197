"""Checks of the public functions' scalar arguments, shared so that one mistake gets one
error everywhere: a wrong type is a ``TypeError``, a value out of range a ``ValueError``."""

from __future__ import annotations

from typing import Any

import numpy as np


def whole(name: str, value: Any, least: int = 0) -> int:
    """`value` as a whole number of at least `least`: a ``TypeError`` for another type (a
    bool, a float or a string included: none is taken for a count), a ``ValueError`` below
    `least`."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name}: expected a whole number, got {value!r}")
    if value < least:
        raise ValueError(f"{name}: expected at least {least}, got {value}")
    return int(value)
