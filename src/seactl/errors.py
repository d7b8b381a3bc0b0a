"""Exceptions raised by seactl.

Every error that results from user input names the field, the offending
value and the valid range, so the CLI can print it verbatim (exit status 2).
"""

from __future__ import annotations

from typing import Any


class SeactlError(Exception):
    """Base class of all seactl errors.

    Examples
    --------
    >>> import seactl as sc
    >>> try:
    ...     sc.design(5.0)
    ... except sc.SeactlError as exc:
    ...     print(type(exc).__name__)
    InfeasibleDesignError
    """


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

    Examples
    --------
    >>> import seactl as sc
    >>> try:
    ...     sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2000, "damping": 0.5})
    ... except sc.InputError as exc:
    ...     print(exc)
    invalid T_qs [ms] = 2000.0: must be <= 1000 ms (delays_ms takes milliseconds)
    """

    def __init__(self, field: str, value: Any, valid: str):
        self.field = field
        self.value = value
        self.valid = valid
        super().__init__(f"invalid {field} = {value!r}: must be {valid}")


class LoopFileError(InputError):
    """A loop file (or a :class:`~seactl.LoopBuilder` call) describes no valid loop.

    The message names the file, where in it (block and field), the offending value and
    what is valid, on one line.

    Parameters
    ----------
    file : str
        The loop file (or ``"<builder>"``).
    where : str
        The block and field, variable, break or port, e.g. ``"block 'Kq_fb', field 'gain'"``.
    value : Any
        The rejected value (``None``: the error is about structure, not one value).
    valid : str
        What is valid, or why the structure is rejected.

    Examples
    --------
    >>> import seactl as sc
    >>> b = sc.LoopBuilder("demo").variables(m=1.0)
    >>> try:
    ...     b.block("k", "gain", input="e", output="u", gain="m * oops")
    ... except sc.LoopFileError as exc:
    ...     print(exc)
    <builder>: block 'k', field 'gain' = 'm * oops': unknown name 'oops'; known: m, pi, e
    """

    def __init__(self, file: Any, where: str, value: Any, valid: str):
        self.file, self.where = str(file), where
        self.field, self.value, self.valid = where, value, valid
        shown = "" if value is None else f" = {value!r}"
        SeactlError.__init__(self, f"{self.file}: {where}{shown}: {valid}")


class InfeasibleDesignError(SeactlError, ValueError):
    """No critically-damped gain set with four positive gains exists.

    Parameters
    ----------
    message : str
        What failed and the feasible range.
    fn_hz : array_like, optional
        The natural frequencies [Hz] without a solution.
    feasible_hz : list of tuple of float, optional
        The feasible ``f_n`` intervals [Hz].

    Examples
    --------
    >>> import seactl as sc
    >>> try:
    ...     sc.design([8, 12])
    ... except sc.InfeasibleDesignError as exc:
    ...     print(exc.fn_hz, round(exc.feasible_hz[0][0], 3))
    [8.] 9.456
    """

    def __init__(self, message: str, fn_hz: Any = None, feasible_hz: Any = None):
        self.fn_hz = fn_hz
        self.feasible_hz = feasible_hz
        super().__init__(message)


class OutputError(SeactlError, OSError):
    """An output path cannot be written, or writing it would destroy what seactl did not
    create.

    Parameters
    ----------
    path : str
        The output path.
    reason : str
        Why it cannot be written.

    Examples
    --------
    >>> from seactl.errors import OutputError
    >>> print(OutputError("/proc/x.png", "permission denied"))
    cannot write /proc/x.png: permission denied
    """

    def __init__(self, path: Any, reason: str):
        self.path = str(path)
        self.reason = reason
        SeactlError.__init__(self, f"cannot write {path}: {reason}")


class ResourceError(SeactlError, ValueError):
    """The work asked for needs more memory or time than the machine can give.

    Parameters
    ----------
    message : str
        The estimate, the limit, and how to ask for less.

    Examples
    --------
    >>> from seactl.errors import ResourceError
    >>> print(ResourceError("a 1e12-point grid needs about 14.6 TiB of memory"))
    a 1e12-point grid needs about 14.6 TiB of memory
    """


class Terminated(KeyboardInterrupt):
    """SIGTERM arrived (the command line's handler raises it): handled like Ctrl-C, so every
    clean-up that Ctrl-C runs (child processes stopped, temporary files removed) runs too;
    the command line then exits with status 143 instead of 130."""
