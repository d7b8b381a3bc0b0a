"""Exceptions raised by seactl.

Every error that results from user input names the field, the offending
value and the valid range, so the CLI can print it verbatim (exit status 2).
"""

from __future__ import annotations

from typing import Any


class SeactlError(Exception):
    """Base class of all seactl errors."""


class InputError(SeactlError, ValueError):
    """A parameter is outside its valid range.

    Parameters
    ----------
    field : str
        Name of the offending field, as the user spelled it.
    value : Any
        The rejected value.
    valid : str
        Human-readable description of the valid range.
    """

    def __init__(self, field: str, value: Any, valid: str):
        self.field = field
        self.value = value
        self.valid = valid
        super().__init__(f"invalid {field} = {value!r}: must be {valid}")


class InfeasibleDesignError(SeactlError, ValueError):
    """No critically-damped gain set with four positive gains exists."""

    def __init__(self, message: str, fn_hz: Any = None, feasible_hz: Any = None):
        self.fn_hz = fn_hz
        self.feasible_hz = feasible_hz
        super().__init__(message)
