"""Delay equations and quasi-polynomials typed in directly, as :class:`~seactl.System`\\ s.

:func:`delay_equation` takes the matrices of a retarded delay differential equation
``x'(t) = A_0 x(t) + sum_k A_k x(t - h_k)``; :func:`quasi_polynomial` the polynomials of a
characteristic ``sum_k p_k(s) e^{-s h_k}``.  Each term's delay ``h_k`` is either a number
[s] (the term's own delay, named ``tau1``, ``tau2``, ... in term order unless ``names``
says otherwise) or a string naming a sum of the delays given in ``delays_s``, such as
``"tau1 + 2*tau2"``.  Delays may be arrays: they broadcast into a batch of systems.

Both systems know their characteristic as a function of the named delays
(:meth:`DelaySystem.delay_terms`, exact: :mod:`seactl.diagram.delay_equation`); their
``loops`` are the delay names, so every view written on the characteristic (roots, the
certified count of right-half-plane roots, delay margins, stability charts) applies.
Views of a block diagram (loop-break margins, impedance, responses, exports) do not, and
raise :class:`~seactl.errors.InputError` saying so.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from seactl.api.results import RootsResult
from seactl.api.system import System
from seactl.base.validate import finite_array, float_array
from seactl.diagram.delayterms import DelayTerms
from seactl.errors import InputError, ResourceError

MAX_DELAY_RATIO = 1e8
"""Longest delay in units of the equation's time scale (1 / its root scale
:meth:`DelaySystem.reference_frequency`) that :meth:`DelaySystem.roots` accepts: beyond it
the roots crowd the imaginary axis every ``2 pi / tau`` rad/s, and the certified count's
scan needs more than about 1e8 frequency points."""

ROOT_SCALE_RANGE = (1e-12, 1e100)
"""The root scale [rad/s] of a characteristic whose roots are computed in double precision."""

POWER_RANGE = (1e-150, 1e150)
"""The range of the root scale's power ``n`` (the order): the certified count's bounds
multiply such powers, which must neither overflow nor vanish."""

COLLOCATION_SECONDS = 6e-9
"""Estimated time [s] of the root finder's largest collocation per cubed matrix size
(its eigenvalues), for refusing an equation of too high an order up front."""

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_PART = re.compile(r"\s*(?:(\d+)\s*\*\s*)?([A-Za-z_][A-Za-z0-9_]*)\s*(?:\*\s*(\d+)\s*)?\Z")


def parse_delay(text: str, names: Sequence[str], field: str) -> np.ndarray:
    """A sum of named delays such as ``"tau1 + 2*tau2"`` -> its exponent row over ``names``.

    Parameters
    ----------
    text : str
        Terms ``name``, ``k*name`` or ``name*k`` (``k`` a positive integer) joined by ``+``.
    names : sequence of str
        The named delays.
    field : str
        The term, for the error message.

    Returns
    -------
    numpy.ndarray
        Integer counts per name.
    """
    row = np.zeros(len(names), int)
    for part in text.split("+"):
        m = _PART.match(part)
        if m is None or (m.group(1) and m.group(3)):
            raise InputError(field, text, "a sum of named delays such as 'tau1 + 2*tau2'")
        if m.group(2) not in names:
            raise InputError(field, text, "names among the delays given in delays_s: "
                             + (", ".join(names) or "none given"))
        k = int(m.group(1) or m.group(3) or 1)
        if k < 1:
            raise InputError(field, text, "positive integer multiples of named delays")
        row[list(names).index(m.group(2))] += k
    return row


def term_delays(delays: Sequence[Any], names: Sequence[str] | None,
                delays_s: Mapping[str, Any] | None
                ) -> tuple[np.ndarray, tuple[str, ...], dict[str, np.ndarray]]:
    """The terms' delays -> exponent rows ``(K, D)``, the delay names and their values [s].

    A number (or array) is the term's own delay, named ``names[k]`` or ``tau<k+1>``; a
    string is a sum of the delays in ``delays_s``.
    """
    given = {str(k): v for k, v in (delays_s or {}).items()}
    numeric = [k for k, h in enumerate(delays) if not isinstance(h, str)]
    if names is not None and len(names) != len(numeric):
        raise InputError("names", list(names), f"{len(numeric)} name(s), one per term "
                         "whose delay is a number")
    own = list(names) if names is not None else [f"tau{k + 1}" for k in numeric]
    order = own + [k for k in given if k not in own]
    for name in order:
        if not isinstance(name, str) or not _NAME.match(name):
            raise InputError("delay name", name, "an identifier (letters, digits, _)")
    if len(set(own)) != len(own) or set(own) & set(given):
        raise InputError("names", own, "distinct names, none of them a key of delays_s")
    values = dict(zip(own, (delays[k] for k in numeric))) | given
    tau = {n: finite_array(f"delay {n} [s]", values[n], minimum=0.0) for n in order}
    rows = np.zeros((len(delays), len(order)), int)
    for k, h in enumerate(delays):
        if isinstance(h, str):
            rows[k] = parse_delay(h, order, f"terms[{k}] delay")
        else:
            rows[k, order.index(own[numeric.index(k)])] = 1
    return rows, tuple(order), tau


def _batch_shape(tau: Mapping[str, np.ndarray]) -> tuple[int, ...]:
    try:
        return np.broadcast_shapes(*(v.shape for v in tau.values()))
    except ValueError:
        raise InputError("delays [s]", {k: v.shape for k, v in tau.items()},
                         "arrays whose shapes broadcast together (one batch)") from None


def _not_here(view: str, reason: str) -> Any:
    def method(self: DelaySystem, *args: Any, **kwargs: Any) -> Any:
        raise self.unsupported(view, reason)

    method.__name__ = view
    method.__doc__ = (f"""Not available for a delay equation or quasi-polynomial: {reason}.

        Parameters
        ----------
        *args
            Ignored.
        **kwargs
            Ignored.

        Raises
        ------
        InputError
            Always, naming the view and the reason.
        """)
    return method


_NO_DIAGRAM = ("a delay equation is not a block diagram with a loop to break, signals or "
               "ports; use roots(), delay_margin() or stability_chart()")
_NO_SIGNAL = ("a characteristic alone has no input or output signal; use roots() or "
              "delay_margin()")


class DelaySystem(System):
    """A batch of retarded delay equations given by their characteristic (the common part
    of :class:`DelayEquation` and :class:`QuasiPolynomialSystem`).

    Parameters
    ----------
    coeffs : numpy.ndarray
        ``(J, n + 1)`` ascending coefficients of the characteristic's terms.
    exponents : numpy.ndarray
        ``(J, D)`` exponent rows over the named delays (row 0 undelayed).
    delays_s : dict
        Delay name -> delay [s] (arrays broadcast into the batch).

    Attributes
    ----------
    title : str
        A title (a file's ``title``; empty when typed in).
    file : str
        The file it was read from (``"<python>"`` when typed in).

    Examples
    --------
    >>> import seactl as sc
    >>> d = sc.delay_equation(-1.0, terms=[(0.5, [1.0, 2.0])])
    >>> d.shape, d.loops, d.size, type(d[0]).__name__
    ((2,), ('tau1',), 2, 'DelayEquation')
    """

    title: str = ""
    file: str = "<python>"

    def __init__(self, coeffs: np.ndarray, exponents: np.ndarray,
                 delays_s: Mapping[str, Any]):
        self._coeffs, self._exponents = coeffs, exponents
        self._tau = {k: np.asarray(v, float) for k, v in delays_s.items()}
        self._shape = _batch_shape(self._tau)
        self.characteristic.at().require_retarded(f"{self.kind} characteristic")
        self._check_magnitudes()

    def _check_magnitudes(self) -> None:
        """Refuse coefficients whose roots double precision cannot hold: the Fujiwara root
        scale ``max_j (sum_k |c_kj| / |c_0n|)^{1/(n-j)}`` (0 when every root is 0) must lie
        in :data:`ROOT_SCALE_RANGE` and its power ``n`` in :data:`POWER_RANGE`."""
        c, n = np.abs(self._coeffs), self.order
        lo, hi = ROOT_SCALE_RANGE
        with np.errstate(all="ignore"):
            total = c.sum(axis=0)[:n] / c[0, n]
            scale = float(np.max(total ** (1.0 / (n - np.arange(n))), initial=0.0))
            ok = np.all(np.isfinite(self._coeffs)) and (scale == 0 or (
                lo <= scale <= hi and POWER_RANGE[0] <= scale ** n <= POWER_RANGE[1]))
        if not ok:
            raise InputError(f"{self.kind} coefficients", f"a root scale of {scale:.3g} rad/s",
                             f"a root scale in [{lo:g}, {hi:g}] rad/s whose power {n} (the "
                             f"order) is in [{POWER_RANGE[0]:g}, {POWER_RANGE[1]:g}]: rescale "
                             "time (or the values)")

    @property
    def loops(self) -> tuple[str, ...]:  # type: ignore[override]
        """The delay names."""
        return tuple(self._tau)

    @property
    def shape(self) -> tuple[int, ...]:
        """The batch shape (the broadcast shape of the delays)."""
        return self._shape

    @property
    def delays_s(self) -> dict[str, np.ndarray]:
        """Delay name -> delay [s] (batch shape)."""
        return {k: np.broadcast_to(v, self.shape) for k, v in self._tau.items()}

    @property
    def links(self) -> dict[str, str]:
        """Delay name -> itself (a delay equation's loops are its delays)."""
        return {k: k for k in self._tau}

    @property
    def order(self) -> int:
        """The degree ``n`` of the characteristic in ``s`` (the state dimension)."""
        return self._coeffs.shape[-1] - 1

    def _with_tau(self, tau: Mapping[str, np.ndarray]) -> DelaySystem:
        new = object.__new__(type(self))
        new.__dict__.update(self.__dict__)
        new._tau = {k: np.asarray(v, float) for k, v in tau.items()}
        new._shape = _batch_shape(new._tau)
        return new

    def __getitem__(self, idx: Any) -> DelaySystem:
        return self._with_tau({k: np.asarray(v[idx]) for k, v in self.delays_s.items()})

    def with_delays(self, **delays_s: Any) -> DelaySystem:
        """The same equation with some named delays replaced.

        Parameters
        ----------
        **delays_s
            Delay name -> delay [s] (a number or an array: a batch).

        Returns
        -------
        DelaySystem
            Of the same type.
        """
        tau = dict(self._tau)
        for k, v in delays_s.items():
            if k not in tau:
                raise InputError("delay", k, "one of " + ", ".join(tau))
            tau[k] = finite_array(f"delay {k} [s]", v, minimum=0.0)
        return self._with_tau(tau)

    @property
    def characteristic(self) -> DelayTerms:
        """The characteristic quasi-polynomial as a function of the named delays."""
        return self.delay_terms()

    def delay_terms(self) -> DelayTerms:
        """The characteristic as a :class:`~seactl.diagram.delayterms.DelayTerms` (delays
        named by :attr:`loops`), exact.

        Returns
        -------
        seactl.diagram.delayterms.DelayTerms
            Of the batch shape.
        """
        shape = self.shape
        j, n1 = self._coeffs.shape
        coeffs = np.broadcast_to(self._coeffs.reshape((j,) + (1,) * len(shape) + (n1,)),
                                 (j,) + shape + (n1,))
        tau = (np.stack(list(self.delays_s.values())) if self._tau
               else np.zeros((0,) + shape))
        return DelayTerms(coeffs, self._exponents, self.loops, tau)

    def labels(self) -> list[str]:
        """One label per design (flattened batch): its delays [s].

        Returns
        -------
        list of str
            ``"tau1=0.5 s, ..."`` per design.
        """
        cols = {k: np.ravel(v) for k, v in self.delays_s.items()}
        return [", ".join(f"{k}={v[i]:g} s" for k, v in cols.items()) or self.kind
                for i in range(self.size)]

    def label_columns(self, gains: bool = True) -> dict[str, np.ndarray]:
        """Per-design columns of the results' records: ``<delay name>_s`` [s].

        Parameters
        ----------
        gains : bool
            Unused (an equation has no gains).

        Returns
        -------
        dict
            Column -> array of the batch shape.
        """
        return {f"{k}_s": v for k, v in self.delays_s.items()}

    def reference_frequency(self) -> np.ndarray:
        """The characteristic's root scale [rad/s] per design
        (:func:`seactl.analysis.roots.frequency_scale`).

        Returns
        -------
        numpy.ndarray
            Of the batch shape.
        """
        from seactl.analysis.roots import frequency_scale

        return frequency_scale(self.characteristic.at().flat()).reshape(self.shape)

    def roots(self, count: int = 6) -> RootsResult:
        """Rightmost roots of the characteristic, per design
        (:func:`seactl.analysis.roots.quasi_roots`: Chebyshev collocation, Newton on the
        exact characteristic, inclusion discs and the argument principle's certified count
        of right-half-plane roots).

        Parameters
        ----------
        count : int
            Roots per design (a conjugate pair counts once).

        Returns
        -------
        RootsResult
            ``roots`` [rad/s] of shape ``shape + (count,)`` by decreasing real part,
            ``spectral_abscissa`` [1/s], ``stable``, ``uncertain``,
            ``right_half_plane_roots`` (certified), ``records()``.

        Examples
        --------
        >>> import seactl as sc
        >>> r = sc.quasi_polynomial([1, 0], terms=[([1], 1.0)]).roots(count=1)
        >>> z = complex(r.roots[0]); round(z.real, 6), round(z.imag, 6)
        (-0.318132, 1.337236)
        """
        from seactl.analysis.roots import MAX_NODES, quasi_roots
        from seactl.base.limits import check_budget, check_roots

        check_roots(self.size, count, bool(self._tau) and any(
            np.any(v > 0) for v in self._tau.values()))
        ratio = max((float(np.max(v)) for v in self._tau.values()), default=0.0) * \
            float(np.max(self.reference_frequency()))
        if ratio > MAX_DELAY_RATIO:
            raise ResourceError(f"a delay {ratio:.3g} times the time scale of the equation "
                                f"(1 / its root scale) is beyond the {MAX_DELAY_RATIO:.0e} the "
                                "root finder and its certified count accept (its roots crowd "
                                "the imaginary axis every 2 pi / tau rad/s); rescale time or "
                                "shorten the delay")
        m = self.order * (MAX_NODES + 1)
        check_budget(f"the rightmost roots of one equation of order {self.order} (a "
                     f"collocation matrix of size up to {m:,})",
                     seconds=COLLOCATION_SECONDS * float(m) ** 3,
                     hint="give an equation of lower order")
        # (candidates far left overflow e^{-s tau}: the residual test rejects them)
        with np.errstate(over="ignore", invalid="ignore"):
            roots = quasi_roots(self.characteristic.at(), count=count,
                                what=f"{self.kind} characteristic")
        return RootsResult(roots, self.label_columns())

    margins = _not_here("margins", "a characteristic has no loop to break; use "
                        "roots().stable, delay_margin() or stability_chart()")
    impedance = _not_here("impedance", _NO_DIAGRAM)
    jitter_margins = _not_here("jitter_margins", _NO_DIAGRAM)
    to_control = _not_here("to_control", _NO_SIGNAL)
    step = _not_here("step", _NO_SIGNAL)
    impulse = _not_here("impulse", _NO_SIGNAL)
    monte_carlo = _not_here("monte_carlo", _NO_DIAGRAM)
    export = _not_here("export", "there is no controller to export")
    run = _not_here("run", "there is no controller to run")
    sweep = _not_here("sweep", "use arrays of delays (a batch) or with_delays()")

    @property
    def design(self) -> Any:
        """Not available: a delay equation is not a block diagram."""
        raise self.unsupported("design", _NO_DIAGRAM)

    @property
    def diagram(self) -> Any:
        """Not available: a delay equation is not a block diagram."""
        raise self.unsupported("diagram", _NO_DIAGRAM)

    def _delays_text(self) -> str:
        return ", ".join(f"{k}={np.asarray(v).tolist()}" for k, v in self._tau.items())


class DelayEquation(DelaySystem):
    """``x'(t) = A_0 x(t) + sum_k A_k x(t - h_k)`` (retarded), a batch over its delays.

    Made by :func:`delay_equation` (or :func:`load_dde`); a :class:`~seactl.System` of
    kind ``"dde"`` whose ``loops`` are the delay names.

    Parameters
    ----------
    a0 : numpy.ndarray
        ``(n, n)``.
    mats : sequence of numpy.ndarray
        The delayed terms' matrices ``A_k``.
    exponents : numpy.ndarray
        ``(K, D)``: term ``k``'s delay is ``exponents[k] @ tau``.
    delays_s : dict
        Delay name -> delay [s].

    Attributes
    ----------
    a0 : numpy.ndarray
        ``(n, n)``.
    terms : list of tuple
        ``(A_k, delay)``: the matrix and its delay (a name's sum, as an expression).

    Examples
    --------
    >>> import seactl as sc
    >>> d = sc.delay_equation([[0.0, 1.0], [-1.0, 0.0]], terms=[([[0, 0], [0, -1]], 0.5)])
    >>> d.order, d.terms[0][1], d.characteristic.coeffs.shape
    (2, 'tau1', (2, 3))
    """

    kind = "dde"

    def __init__(self, a0: np.ndarray, mats: Sequence[np.ndarray], exponents: np.ndarray,
                 delays_s: Mapping[str, Any]):
        from seactl.diagram.delay_equation import equation_characteristic

        self.a0, self._mats, self._term_rows = a0, list(mats), exponents
        coeffs, rows = equation_characteristic(a0, self._mats, exponents)
        super().__init__(coeffs, rows, delays_s)

    @property
    def terms(self) -> list[tuple[np.ndarray, str]]:
        """``(A_k, delay)`` per delayed term, the delay as a sum of the named delays."""
        return [(a, _expression(r, self.loops)) for a, r in zip(self._mats, self._term_rows)]

    def __repr__(self) -> str:
        n = self.order
        return (f"DelayEquation({n}x{n}, terms=[{', '.join(h for _, h in self.terms)}], "
                f"shape={self.shape}, delays_s={{{self._delays_text()}}})")


class QuasiPolynomialSystem(DelaySystem):
    """``sum_k p_k(s) e^{-s h_k}`` (retarded), a batch over its delays.

    Made by :func:`quasi_polynomial` (or :func:`load_dde`); a :class:`~seactl.System` of
    kind ``"quasi-polynomial"`` whose ``loops`` are the delay names.

    Parameters
    ----------
    coeffs : numpy.ndarray
        ``(J, n + 1)`` ascending coefficients of the terms.
    exponents : numpy.ndarray
        ``(J, D)`` exponent rows over the named delays (row 0 undelayed).
    delays_s : dict
        Delay name -> delay [s].

    Examples
    --------
    >>> import seactl as sc
    >>> q = sc.quasi_polynomial([1, 0], terms=[([1], 1.0)])
    >>> q.kind, q.order, q.characteristic.coeffs.tolist()
    ('quasi-polynomial', 1, [[0.0, 1.0], [1.0, 0.0]])
    """

    kind = "quasi-polynomial"

    def __repr__(self) -> str:
        return (f"QuasiPolynomialSystem(degree={self.order}, terms={len(self._coeffs)}, "
                f"shape={self.shape}, delays_s={{{self._delays_text()}}})")


def _expression(row: np.ndarray, names: Sequence[str]) -> str:
    return " + ".join((f"{int(e)}*{n}" if e > 1 else n) for e, n in zip(row, names) if e)


def _matrix(name: str, value: Any, n: int | None) -> np.ndarray:
    a = float_array(name, value)
    a = a.reshape(1, 1) if a.ndim == 0 else a
    if a.ndim != 2 or a.shape[0] != a.shape[1] or a.shape[0] == 0 or (
            n is not None and a.shape[0] != n):
        raise InputError(name, f"an array of shape {a.shape}",
                         f"a square matrix{'' if n is None else f' {n} x {n}'} (a number "
                         "for a scalar equation)")
    return finite_array(name, a)


def _terms(terms: Any) -> list[tuple[Any, Any]]:
    out = []
    for k, t in enumerate(terms or ()):
        if not isinstance(t, (tuple, list)) or len(t) != 2:
            raise InputError(f"terms[{k}]", t, "a pair (coefficients, delay)")
        out.append((t[0], t[1]))
    return out


def delay_equation(a0: Any, terms: Sequence[tuple[Any, Any]] = (), *,
                   names: Sequence[str] | None = None,
                   delays_s: Mapping[str, Any] | None = None) -> DelayEquation:
    """The retarded delay equation ``x'(t) = A_0 x(t) + sum_k A_k x(t - h_k)``.

    Parameters
    ----------
    a0 : array_like
        ``(n, n)`` (a number: a scalar equation).
    terms : sequence of (array_like, delay)
        Each ``(A_k, h_k)``: ``A_k`` ``(n, n)``; ``h_k`` a delay [s] >= 0 (a number or
        an array: a batch), the term's own, or a string naming a sum of the delays in
        ``delays_s`` (``"tau1 + tau2"``, ``"2*tau1"``).  No upper limit on delays: the
        work they cost is estimated and refused up front when too large.
    names : sequence of str, optional
        The names of the terms' own delays, in term order (default ``tau1``, ``tau2``,
        ... by term position).
    delays_s : dict, optional
        Named delays [s] the string delays refer to.

    Returns
    -------
    DelayEquation
        A :class:`~seactl.System` of kind ``"dde"``; its characteristic
        ``det(s I - A_0 - sum_k A_k e^{-s h_k})`` is expanded exactly.

    Notes
    -----
    This form is always retarded (the delayed terms have degree below ``n`` in ``s``); a
    neutral equation (a delayed derivative) cannot be written in it, and
    :func:`quasi_polynomial` refuses its characteristic.

    Examples
    --------
    ``x' = -x(t - 1)``, whose rightmost roots are the Lambert W values ``W_k(-1)``:

    >>> import seactl as sc
    >>> d = sc.delay_equation(0.0, terms=[(-1.0, 1.0)])
    >>> d.loops, d.kind, bool(d.roots(count=2).stable)
    (('tau1',), 'dde', True)
    """
    a0 = _matrix("a0", a0, None)
    pairs = _terms(terms)
    mats = [_matrix(f"terms[{k}] matrix", a, a0.shape[0]) for k, (a, _) in enumerate(pairs)]
    rows, order, tau = term_delays([h for _, h in pairs], names, delays_s)
    return DelayEquation(a0, mats, rows, tau)


def _poly(name: str, value: Any) -> np.ndarray:
    p = np.atleast_1d(finite_array(name, value))
    if p.ndim != 1 or p.size == 0:
        raise InputError(name, f"an array of shape {p.shape}", "a non-empty list of "
                         "coefficients, highest power of s first")
    return p[::-1].copy()


def quasi_polynomial(p0: Any, terms: Sequence[tuple[Any, Any]] = (), *,
                     names: Sequence[str] | None = None,
                     delays_s: Mapping[str, Any] | None = None) -> QuasiPolynomialSystem:
    """The characteristic ``p_0(s) + sum_k p_k(s) e^{-s h_k}`` of a retarded equation.

    Coefficients are given highest power of ``s`` first, as :func:`numpy.polyval` and
    python-control take them: ``[1, 0]`` is ``s``.

    Parameters
    ----------
    p0 : array_like
        The undelayed polynomial, of degree ``n >= 1``.
    terms : sequence of (array_like, delay)
        Each ``(p_k, h_k)``: ``p_k`` of degree below ``n`` (a delayed term of degree ``n``
        makes the equation neutral, which is refused); ``h_k`` as in
        :func:`delay_equation` (a number [s], the term's own delay, or a string naming a
        sum of the delays in ``delays_s``).
    names : sequence of str, optional
        The names of the terms' own delays (default ``tau1``, ``tau2``, ... by term
        position).
    delays_s : dict, optional
        Named delays [s] the string delays refer to.

    Returns
    -------
    QuasiPolynomialSystem
        A :class:`~seactl.System` of kind ``"quasi-polynomial"``.

    Examples
    --------
    ``s + e^{-s tau1} + 0.5 e^{-s (tau1 + tau2)}``:

    >>> import seactl as sc
    >>> q = sc.quasi_polynomial([1, 0], terms=[([1], "tau1"), ([0.5], "tau1 + tau2")],
    ...                         delays_s={"tau1": 1.0, "tau2": 0.5})
    >>> q.loops, q.characteristic.exponents.tolist()
    (('tau1', 'tau2'), [[0, 0], [1, 0], [1, 1]])
    """
    from seactl.diagram.delay_equation import merge_terms

    p = _poly("p0", p0)
    pairs = _terms(terms)
    polys = [p] + [_poly(f"terms[{k}] coefficients", c) for k, (c, _) in enumerate(pairs)]
    n1 = max(len(q) for q in polys)
    polys = [np.pad(q, (0, n1 - len(q))) for q in polys]
    rows, order, tau = term_delays([h for _, h in pairs], names, delays_s)
    rows = np.vstack([np.zeros((1, len(order)), int), rows])
    coeffs, rows = merge_terms(polys, rows)
    deg = np.nonzero(coeffs[0])[0]
    if deg.size == 0 or deg[-1] == 0:
        raise InputError("p0", np.asarray(p0).tolist(), "a polynomial of degree >= 1")
    coeffs = coeffs[:, : deg[-1] + 1] if not coeffs[:, deg[-1] + 1:].any() else coeffs
    return QuasiPolynomialSystem(coeffs, rows, tau)
