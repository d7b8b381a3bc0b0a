"""Delay-equation files: a delay equation or a quasi-polynomial in TOML (docs/delay-equations.md).

A delay equation ``x'(t) = A0 x(t) + sum_k A_k x(t - h_k)``::

    a0 = [[-2.0, 0.0], [0.0, -0.9]]     # n x n (a number: a scalar equation)
    [[term]]
    a = [[-1.0, 0.0], [-1.0, -1.0]]     # A_k, n x n
    delay_s = 6.0                       # the term's own delay [s], named by `name`
    name = "tau"                        # (default tau1, tau2, ... by term position)

A quasi-polynomial ``p0(s) + sum_k p_k(s) e^{-s h_k}`` (coefficients highest power
first)::

    p0 = [1.0, 0.0]                     # s
    [delays_s]                          # named delays [s] the terms' `delay` sums refer to
    tau1 = 1.0
    [[term]]
    p = [1.0]
    delay = "tau1"                      # or delay_s = 1.0 (own delay), or "tau1 + 2*tau2"

Every error is a :class:`~seactl.errors.LoopFileError` naming the file, the field, its
value and what is valid.
"""

from __future__ import annotations

import re
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from seactl.api.delay_system import DelaySystem, delay_equation, quasi_polynomial
from seactl.errors import InputError, LoopFileError
from seactl.userloop.schema import read_toml_file

Number = float | int
Matrix = Number | list[list[Number]]


class TermModel(BaseModel):
    """One ``[[term]]`` table."""

    model_config = ConfigDict(extra="forbid")
    a: Matrix | None = None
    p: list[Number] | None = Field(default=None, min_length=1)
    delay_s: Number | None = Field(default=None, ge=0)
    delay: str | None = None
    name: str | None = None


class DdeModel(BaseModel):
    """A whole delay-equation file."""

    model_config = ConfigDict(extra="forbid")
    title: str = ""
    a0: Matrix | None = None
    p0: list[Number] | None = Field(default=None, min_length=1)
    delays_s: dict[str, Number] = {}
    term: list[TermModel] = []


_TYPE_TAGS = ("list[", "float", "int", "union[")
_API_FIELD = re.compile(r"terms\[(\d+)\] (delay|matrix|coefficients)")


def _where(loc: tuple[Any, ...]) -> str:
    parts = [str(p) for p in loc if not str(p).startswith(_TYPE_TAGS)]
    if len(loc) >= 2 and loc[0] == "term" and isinstance(loc[1], int):
        rest = ".".join(parts[2:])
        return f"term #{loc[1] + 1}" + (f", field {rest!r}" if rest else "")
    return ".".join(parts) or "file"


def _file_field(field: str, key: str) -> str:
    """An API field (``terms[0] delay``) as the file names it (``term #1, field 'delay'``)."""
    m = _API_FIELD.fullmatch(field)
    if m is None:
        return field
    name = {"matrix": key, "coefficients": key}.get(m.group(2), m.group(2))
    return f"term #{int(m.group(1)) + 1}, field {name!r}"


def _validation_error(exc: ValidationError, file: str) -> LoopFileError:
    err = exc.errors()[0]
    where = _where(tuple(err["loc"]))
    if err["type"] == "missing":
        return LoopFileError(file, where, None, "required field missing")
    if err["type"] == "extra_forbidden":
        return LoopFileError(file, where, err.get("input"), "unknown key")
    return LoopFileError(file, where, err.get("input"), err["msg"].lower())


def _term_delay(t: TermModel, k: int, file: str) -> Any:
    if (t.delay_s is None) == (t.delay is None):
        raise LoopFileError(file, f"term #{k + 1}", None, "exactly one of delay_s (its own "
                            "delay [s]) and delay (a sum of named delays, 'tau1 + tau2')")
    if t.delay is not None and t.name is not None:
        raise LoopFileError(file, f"term #{k + 1}, field 'name'", t.name,
                            "absent with delay (name a term's own delay_s)")
    return float(t.delay_s) if t.delay_s is not None else t.delay


def _build(m: DdeModel, file: str) -> DelaySystem:
    if (m.a0 is None) == (m.p0 is None):
        raise LoopFileError(file, "file", None, "exactly one of a0 (a delay equation's "
                            "matrix) and p0 (a quasi-polynomial's undelayed coefficients)")
    key = "a" if m.a0 is not None else "p"
    delays, names, coeffs = [], [], []
    for k, t in enumerate(m.term):
        c = getattr(t, key)
        if c is None or getattr(t, "p" if key == "a" else "a") is not None:
            raise LoopFileError(file, f"term #{k + 1}", None, f"the field {key!r} (and not "
                                f"the other): the file's {'a0' if key == 'a' else 'p0'} "
                                "says which form it is")
        coeffs.append(c)
        delays.append(_term_delay(t, k, file))
        if t.delay is None:
            names.append(t.name or f"tau{k + 1}")
    terms = list(zip(coeffs, delays))
    make = delay_equation if key == "a" else quasi_polynomial
    return make(m.a0 if key == "a" else m.p0, terms, names=names, delays_s=m.delays_s)


def load_dde(path: Any, **delays_s: Any) -> DelaySystem:
    """A delay equation or quasi-polynomial from a TOML file (docs/delay-equations.md).

    Parameters
    ----------
    path : str or pathlib.Path
        The file: ``a0`` and ``[[term]]`` tables with ``a`` (a delay equation), or ``p0``
        and ``[[term]]`` tables with ``p`` (a quasi-polynomial); each term's delay is
        ``delay_s`` [s] (its own, named by ``name``, default ``tau<k>``) or ``delay``, a
        sum of the delays of the ``[delays_s]`` table.
    **delays_s
        Overrides of named delays [s] (arrays: a batch).

    Returns
    -------
    DelaySystem
        A :class:`DelayEquation` or :class:`QuasiPolynomialSystem`.

    Examples
    --------
    >>> import seactl as sc
    >>> q = sc.load_dde("examples/dde/lambert.toml")                  # doctest: +SKIP
    >>> q.kind, q.loops                                                # doctest: +SKIP
    ('quasi-polynomial', ('tau1',))
    """
    file = str(path)
    data = read_toml_file(path, "delay-equation file")
    try:
        model = DdeModel.model_validate(data)
    except ValidationError as exc:
        raise _validation_error(exc, file) from None
    try:
        system = _build(model, file)
        system.title, system.file = model.title, file
        return system.with_delays(**delays_s) if delays_s else system
    except LoopFileError:
        raise
    except InputError as exc:
        key = "a" if model.a0 is not None else "p"
        raise LoopFileError(file, _file_field(exc.field, key), exc.value, exc.valid) from None
