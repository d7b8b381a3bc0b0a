"""Characteristic quasi-polynomials as functions of named delays.

A :class:`DelayTerms` is ``Q(s; tau) = sum_j p_j(s) exp(-s (E_j . tau))``: polynomial
coefficients ``p_j``, a matrix ``E`` of non-negative integer exponents and a vector of named
delays ``tau`` [s].  Fixing ``tau`` gives a :class:`~seactl.diagram.blockdiagram.QuasiPolynomial`
(:meth:`DelayTerms.at`); keeping ``E`` lets delay margins along a direction and stability
charts vary some delays while the others stay fixed.  A block diagram's characteristic
gives one (:func:`diagram_delay_terms`), and so does a delay equation typed in directly.

Examples
--------
``s + e^{-s}`` with the delay named ``tau``, then the same at ``tau = 2``:

>>> import numpy as np
>>> t = DelayTerms(np.array([[0.0, 1.0], [1.0, 0.0]]), np.array([[0], [1]]), ("tau",),
...                np.array([1.0]))
>>> q = t.at(np.array([2.0]))
>>> q.delays.tolist(), complex(q(np.array([0j]))[0])
([0.0, 2.0], (1+0j))
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.diagram.blockdiagram import QuasiForm, QuasiPolynomial
from seactl.errors import InputError


@dataclass(frozen=True)
class DelayTerms:
    """``Q(s; tau) = sum_j p_j(s) exp(-s (E_j . tau))`` for a batch of designs.

    Attributes
    ----------
    coeffs : numpy.ndarray
        ``(J,) + batch + (n + 1,)``, ascending powers of ``s``; term 0 is undelayed.
    exponents : numpy.ndarray
        ``(J, D)`` non-negative integers: term ``j``'s delay is ``exponents[j] @ tau``;
        row 0 is zero, no two rows are equal.
    names : tuple of str
        The ``D`` delays' names (a system's loop names, or an equation's).
    delays_s : numpy.ndarray
        ``(D,) + batch``: the delays [s] of the design(s).
    """

    coeffs: np.ndarray
    exponents: np.ndarray
    names: tuple[str, ...]
    delays_s: np.ndarray

    @property
    def shape(self) -> tuple[int, ...]:
        """The batch shape."""
        return self.coeffs.shape[1:-1]

    def index(self, name: str) -> int:
        """The position of delay ``name`` in :attr:`names`.

        Parameters
        ----------
        name : str
            A delay's name.

        Returns
        -------
        int
            Its index; :class:`~seactl.errors.InputError` naming the valid names if none.
        """
        if name not in self.names:
            raise InputError("delay", name, "one of " + ", ".join(self.names))
        return self.names.index(name)

    def at(self, delays_s: Any = None) -> QuasiPolynomial:
        """The quasi-polynomial with delays ``delays_s`` (default: :attr:`delays_s`).

        Parameters
        ----------
        delays_s : array_like, optional
            ``(D,) + S`` [s], ``S`` broadcasting with the batch shape.

        Returns
        -------
        QuasiPolynomial
            Of batch shape ``broadcast(S, shape)``; term ``j`` delayed by
            ``exponents[j] @ delays_s``.
        """
        tau = self.delays_s if delays_s is None else np.asarray(delays_s, float)
        if tau.shape[:1] != (len(self.names),):
            raise InputError("delays_s", tau.shape, f"a leading axis of {len(self.names)}")
        shape = np.broadcast_shapes(tau.shape[1:], self.shape)
        with np.errstate(over="ignore"):  # (an overflowing delay is inf: refused downstream)
            term = np.tensordot(self.exponents.astype(float), tau, axes=(1, 0))
        n1 = self.coeffs.shape[-1]
        coeffs = np.broadcast_to(self.coeffs, (len(self.exponents),) + shape + (n1,))
        return QuasiPolynomial(np.ascontiguousarray(coeffs),
                               np.ascontiguousarray(np.broadcast_to(term, (len(term),) + shape)))


def diagram_delay_terms(form: QuasiForm, design: Any, names: dict[str, str]) -> DelayTerms:
    """The :class:`DelayTerms` of a diagram's characteristic form for ``design``.

    Parameters
    ----------
    form : QuasiForm
        E.g. ``diagram.characteristic()``.
    design : object
        Design batch of that diagram.
    names : dict
        Delay attribute of the design (a block's ``delay``) -> the delay's name (the
        system's loop name); every delay attribute of ``form`` must appear.

    Returns
    -------
    DelayTerms
        The delays in the order of ``names``.
    """
    keys, coeffs = form.grouped(design)
    attrs = list(names)
    exponents = np.zeros((len(keys), len(attrs)), int)
    for j, key in enumerate(keys):
        for a in key:
            if a not in names:
                raise InputError("names", a, "a name for every delay of the diagram")
            exponents[j, attrs.index(a)] += 1
    shape = coeffs.shape[1:-1]
    tau = np.stack([np.broadcast_to(np.asarray(getattr(design, a), float), shape)
                    for a in attrs]) if attrs else np.zeros((0,) + shape)
    return DelayTerms(coeffs, exponents, tuple(names[a] for a in attrs), tau)
