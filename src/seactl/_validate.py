"""Small array validators shared by the design, loop and margin modules."""

from __future__ import annotations

import numpy as np

from .errors import InputError


def _first_bad(arr: np.ndarray, bad: np.ndarray) -> float:
    return float(np.asarray(arr)[bad].flat[0])


def finite_array(name: str, value, *, minimum: float | None = None,
                 strict: bool = False, allow_inf: bool = False,
                 nonempty: bool = False) -> np.ndarray:
    """Return ``value`` as a float array after range checks.

    ``minimum`` with ``strict`` means ``> minimum``, otherwise ``>= minimum``.
    ``allow_inf`` admits ``+inf`` (used for "no filter" cut-offs); ``nonempty`` refuses an
    array without values.
    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(name, value, "a number or an array of numbers") from None
    if nonempty and arr.size == 0:
        raise InputError(name, value, "at least one value")
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
