"""The public API's arguments checked: delays by loop name, filters, batches, actuators."""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from seactl.base.axes import MAX_DELAY_MS
from seactl.base.validate import finite_array
from seactl.errors import InputError

SUSPICIOUS_DELAY_MS = 1e-3
"""Non-zero delays below this [ms] (1 us) trigger a :class:`UnitWarning`."""


class UnitWarning(UserWarning):
    """A value is legal but looks like it was given in another unit.

    Examples
    --------
    >>> import warnings, seactl as sc
    >>> with warnings.catch_warnings(record=True) as caught:
    ...     warnings.simplefilter("always")
    ...     _ = sc.design(14, delays_ms={"stiffness": 0.0005})   # seconds, not ms
    >>> caught[0].category.__name__
    'UnitWarning'
    """


def delays_from_ms(delays_ms: Sequence[Any], names: Sequence[str], stacklevel: int = 3
                   ) -> list[np.ndarray]:
    """Check a tuple of delays in milliseconds and return them in seconds.

    Parameters
    ----------
    delays_ms : sequence of array_like
        One delay [ms] per name (arrays broadcast as a batch).
    names : sequence of str
        Names of the delays, for error messages.
    stacklevel : int
        Of the :class:`UnitWarning` (3: the caller of the function that calls this one).

    Returns
    -------
    list of numpy.ndarray
        The delays in seconds.

    Raises
    ------
    InputError
        Wrong length, negative, non-finite or above :data:`MAX_DELAY_MS`.

    Examples
    --------
    >>> [float(x) for x in delays_from_ms((0.5, 2), ("T_s", "T_d"))]
    [0.0005, 0.002]
    """
    # not np.ndim(delays_ms): the delays may have different shapes (a batch grid)
    if isinstance(delays_ms, (str, bytes)) or not isinstance(delays_ms, (Sequence, np.ndarray)) \
            or len(delays_ms) != len(names):
        raise InputError("delays_ms", delays_ms,
                         f"a sequence of {len(names)} delays ({', '.join(names)}) [ms]")
    out = []
    for name, value in zip(names, delays_ms):
        v = finite_array(f"{name} [ms]", value, minimum=0.0, nonempty=True)
        if np.any(v > MAX_DELAY_MS):
            raise InputError(f"{name} [ms]", float(v[v > MAX_DELAY_MS].flat[0]),
                             f"<= {MAX_DELAY_MS:g} ms (delays_ms takes milliseconds)")
        if np.any((v > 0) & (v < SUSPICIOUS_DELAY_MS)):
            warnings.warn(f"{name} = {float(v[(v > 0) & (v < SUSPICIOUS_DELAY_MS)].flat[0])!r}"
                          " ms is below 1 us; delays_ms takes milliseconds (0.5 means 0.5 ms)",
                          UnitWarning, stacklevel=stacklevel)
        out.append(v / 1e3)
    return out


def delays_by_loop(delays_ms: Any, loops: Sequence[str], symbols: Sequence[str]
                   ) -> list[np.ndarray]:
    """Delays given by loop name, checked and in seconds, in the order of ``loops``.

    Parameters
    ----------
    delays_ms : mapping or None
        Loop name -> delay [ms] (array_like; arrays broadcast as a batch); a loop not
        named has no delay.  A sequence in the order of ``loops`` is the deprecated
        positional form (a :class:`DeprecationWarning`).
    loops : sequence of str
        The system's loop names.
    symbols : sequence of str
        The delays' symbols (``T_tau``, ...), one per loop, for error messages.

    Returns
    -------
    list of numpy.ndarray
        One delay [s] per loop.

    Raises
    ------
    InputError
        A name that is not a loop (the message lists them), or a delay out of range
        (:func:`delays_from_ms`).

    Examples
    --------
    >>> [float(x) for x in delays_by_loop({"damping": 2}, ("stiffness", "damping"),
    ...                                   ("T_s", "T_d"))]
    [0.0, 0.002]
    """
    if delays_ms is None:
        delays_ms = {}
    if isinstance(delays_ms, Mapping):
        unknown = [k for k in delays_ms if k not in loops]
        if unknown:
            raise InputError("delays_ms", unknown[0], "loop names: " + ", ".join(loops))
        values = [delays_ms.get(k, 0.0) for k in loops]
    else:
        names = ", ".join(f"{k!r}: ..." for k in loops)
        if isinstance(delays_ms, (str, bytes)) or not isinstance(delays_ms,
                                                                 (Sequence, np.ndarray)):
            raise InputError("delays_ms", delays_ms, f"a mapping {{{names}}} of delays [ms]")
        warnings.warn(f"delays_ms as a sequence ({', '.join(symbols)}) is deprecated; name "
                      f"the loops: delays_ms={{{names}}}", DeprecationWarning, stacklevel=3)
        values = delays_ms
    return delays_from_ms(values, symbols, stacklevel=4)


def filter_cutoffs(filters_hz: Sequence[Any], names: Sequence[str]) -> list[Any]:
    if isinstance(filters_hz, (str, bytes)) or not isinstance(filters_hz, (Sequence, np.ndarray)) \
            or len(filters_hz) != len(names):
        raise InputError("filters_hz", filters_hz,
                         f"a sequence of {len(names)} cut-offs ({', '.join(names)}) [Hz], "
                         "None for no filter")
    return [None if f is None else finite_array(f"{n} [Hz]", f, minimum=0.0, strict=True,
                                                allow_inf=True, nonempty=True)
            for n, f in zip(names, filters_hz)]


def check_batch(**arguments: Any) -> tuple[int, ...]:
    """The broadcast shape of the arguments' arrays (an argument holding several, such as
    ``delays_ms``, gives each), or :class:`InputError` naming the first argument that does
    not broadcast with those before it, or that has no value (a batch without designs)."""
    shape: tuple[int, ...] = ()
    for name, value in arguments.items():
        parts = value if isinstance(value, tuple) else (value,)
        for part in (v for v in parts if v is not None):
            try:
                part = np.asarray(part, dtype=float)
            except (TypeError, ValueError):
                raise InputError(name, plain_value(value), "a number or an array of numbers "
                                 "(not ragged)") from None
            if np.size(part) == 0:
                raise InputError(name, plain_value(value), "at least one value (a batch of "
                                 "designs is never empty)")
            try:
                shape = np.broadcast_shapes(shape, np.shape(part))
            except ValueError:
                raise InputError(name, plain_value(value), f"an array that broadcasts with the "
                                 f"shape {shape} of the arguments before it") from None
    return shape


def plain_value(value: Any) -> Any:
    if isinstance(value, tuple):
        return tuple(plain_value(v) for v in value)
    return value.tolist() if isinstance(value, (np.ndarray, np.generic)) else value


def resolve_actuator(actuator: Any, loader: Any, cls: type) -> Any:
    """An actuator object as is, or a preset name / TOML path loaded by ``loader``."""
    return actuator if isinstance(actuator, cls) else loader(actuator)
