"""Small array validators shared by the design, loop and margin modules."""

from __future__ import annotations

import numpy as np

from seactl.errors import InputError


def _first_bad(arr: np.ndarray, bad: np.ndarray) -> float:
    return float(np.asarray(arr)[bad].flat[0])


def float_array(name: str, value) -> np.ndarray:
    """``value`` as a float array, or :class:`InputError` naming ``name`` when it holds
    no numbers (a string such as ``"2ms"``, None, a ragged list)."""
    if isinstance(value, (str, bytes)):
        raise InputError(name, value, "a number or an array of numbers (no units: the "
                         "name says them)")
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        shown = value if isinstance(value, (int, float)) or value is None else \
            type(value).__name__
        raise InputError(name, shown, "a number or an array of numbers") from None


def frequencies_hz(name: str, value) -> np.ndarray:
    """``value`` as a non-empty 1-D array of finite frequencies [Hz] ``> 0``, else
    :class:`InputError` naming ``name``."""
    f = np.atleast_1d(float_array(name, value))
    if f.ndim != 1 or f.size == 0:
        raise InputError(name, f"an array of shape {f.shape}", "a number or a non-empty "
                         "1-D array of frequencies [Hz]")
    bad = ~np.isfinite(f) | (f <= 0)
    if bad.any():
        raise InputError(name, _first_bad(f, bad), "finite frequencies > 0 [Hz]")
    return f


def finite_array(name: str, value, *, minimum: float | None = None,
                 strict: bool = False, allow_inf: bool = False,
                 nonempty: bool = False) -> np.ndarray:
    """Return ``value`` as a float array after range checks.

    ``minimum`` with ``strict`` means ``> minimum``, otherwise ``>= minimum``.
    ``allow_inf`` admits ``+inf`` (used for "no filter" cut-offs); ``nonempty`` refuses an
    empty array (a batch of no designs).
    """
    arr = float_array(name, value)
    if nonempty and arr.size == 0:
        raise InputError(name, f"an array of shape {arr.shape}", "at least one value")
    valid = "a finite number"
    if minimum is not None:
        valid = f"{'>' if strict else '>='} {minimum:g}" + (" (inf allowed)" if allow_inf else "")
    nan = np.isnan(arr)
    if nan.any():
        raise InputError(name, float("nan"), valid)
    inf = np.isinf(arr)
    if inf.any() and not (allow_inf and np.all(arr[inf] > 0)):
        raise InputError(name, _first_bad(arr, inf), valid)
    if minimum is not None:
        bad = (arr <= minimum) if strict else (arr < minimum)
        if bad.any():
            raise InputError(name, _first_bad(arr, bad), valid)
    return arr
