"""The result family: :class:`Result`, the base of every result seactl returns.

A result holds computed arrays as explicit attributes, each documented in its class's
``Attributes`` section with its unit in its name (``delay_margin_s``, ``crossover_hz``,
``phase_margin_deg``); the JSON of :meth:`Result.to_dict` and :meth:`Result.records`
uses the same names, with one conversion: a value in seconds ``<stem>_s`` is written in
milliseconds as ``<stem>_ms`` where the command line prints milliseconds.  Every result
can draw itself (:meth:`Result.plot`); matplotlib is imported only then.

An attribute that was renamed keeps its old name as a :class:`Renamed` property, which
reads the new one and warns (:class:`DeprecationWarning`).
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np


def json_value(x: Any, digits: int = 10) -> Any:
    """A JSON-safe scalar: NaN and infinities become ``None``, numpy scalars Python ones.

    Parameters
    ----------
    x : scalar
        A bool, integer or real number (Python or numpy); None stays None.
    digits : int
        Decimal digits kept of a real number.

    Returns
    -------
    bool, int, float or None
        The value as a Python scalar.
    """
    if x is None:
        return None
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (str, np.str_)):
        return str(x)
    x = float(x)
    return round(x, digits) if math.isfinite(x) else None


def json_array(a: Any) -> Any:
    """A nested list of JSON-safe values (a scalar for a 0-d array).

    Parameters
    ----------
    a : array_like
        Numbers, booleans or strings.

    Returns
    -------
    list or scalar
        As :func:`json_value`, element by element.
    """
    arr = np.asarray(a)
    if arr.ndim == 0:
        return json_value(arr[()])
    return [json_array(x) for x in arr]


def new_axes(ax: Any = None) -> Any:
    """``ax``, or the axes of a new figure (matplotlib imported here, on first use).

    Parameters
    ----------
    ax : matplotlib.axes.Axes, optional
        Axes to draw on.

    Returns
    -------
    matplotlib.axes.Axes
        ``ax`` itself, or a new figure's axes.
    """
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(6.0, 3.6), layout="constrained")
    return ax


def flat_records(columns: dict[str, Any]) -> list[dict[str, Any]]:
    """One JSON-ready dict per element of equally shaped columns, in C order.

    Parameters
    ----------
    columns : dict
        Name -> array; arrays broadcast together.

    Returns
    -------
    list of dict
        ``{name: json_value(column[i])}`` per flat index ``i``.
    """
    if not columns:
        return []
    arrays = np.broadcast_arrays(*(np.asarray(v) for v in columns.values()))
    flat = {k: np.ravel(a) for k, a in zip(columns, arrays)}
    n = next(iter(flat.values())).size
    return [{k: json_value(v[i]) for k, v in flat.items()} for i in range(n)]


class Renamed(property):
    """A renamed attribute's old name: reads the new attribute and warns.

    Parameters
    ----------
    new : str
        The attribute's name now.
    scale : float
        Factor from the new attribute's unit to the old one's (e.g. 1e3: the old name
        was in milliseconds, the new one is in seconds).
    """

    def __init__(self, new: str, scale: float = 1.0):
        self.new = new
        self.scale = scale
        self.old = ""
        super().__init__(self._read)
        self.__doc__ = f"Deprecated name of ``{new}``" + (
            f" (times {scale:g})." if scale != 1.0 else ".")

    def __set_name__(self, owner: type, name: str) -> None:
        self.old = name

    def _read(self, obj: Any) -> Any:
        warnings.warn(f"{type(obj).__name__}.{self.old} is deprecated; use "
                      f".{self.new}" + (f" (x {self.scale:g})" if self.scale != 1.0 else ""),
                      DeprecationWarning, stacklevel=2)
        value = getattr(obj, self.new)
        return value if self.scale == 1.0 else np.asarray(value) * self.scale


class Result:
    """Base of every result: explicit attributes, ``to_dict``, ``records`` and ``plot``.

    A subclass documents every public attribute in its ``Attributes`` section, with the
    unit in the name (``_s``, ``_ms``, ``_hz``, ``_deg``, ``_db``, ``_rad``, ``_a``, ...)
    unless the value has none (a verdict, a count, a label).  It implements
    :meth:`_columns` (name -> array of the batch shape) or overrides :meth:`to_dict` and
    :meth:`records`, and it overrides :meth:`plot`.

    Examples
    --------
    >>> import seactl as sc
    >>> m = sc.design([12, 14], delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
    ...               filters_hz=(50, 100)).margins()
    >>> isinstance(m, sc.Result), m.records()[0]["fn_hz"]
    (True, 12.0)
    """

    def _columns(self) -> dict[str, Any]:
        """Name -> array of the batch shape (labels first), the rows of :meth:`records`."""
        raise NotImplementedError(f"{type(self).__name__} has no columns")

    def to_dict(self) -> dict[str, Any]:
        """Every value as JSON-ready nested lists (NaN and infinities become ``None``).

        Returns
        -------
        dict
            Column name -> nested list of the batch shape.
        """
        return {k: json_array(v) for k, v in self._columns().items()}

    def records(self) -> list[dict[str, Any]]:
        """One flat JSON-ready dict per design or row, in C order of the batch.

        Returns
        -------
        list of dict
            The keys of :meth:`to_dict`, one value each.
        """
        return flat_records(self._columns())

    def plot(self, ax: Any = None) -> Any:
        """Draw the result (matplotlib is imported on the first call).

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        raise NotImplementedError(f"{type(self).__name__}.plot")
