"""A characteristic quasi-polynomial on the imaginary axis as a polynomial on the torus.

With two delays ``tau1``, ``tau2`` varied and the others fixed, ``Delta(jw; tau)`` of a
:class:`~seactl.diagram.delayterms.DelayTerms` is ``P_w(z1, z2) = sum_ab c_ab(w) z1^a z2^b``
with ``z_i = exp(-j w tau_i)`` on the unit circle: ``c_ab(w)`` gathers the terms whose
exponents of the two delays are ``(a, b)``, each with its fixed delays folded in exactly.
:func:`torus_solutions` finds every ``(z1, z2)`` on the unit torus with ``P_w = 0`` for a
vector of frequencies at once, by polynomial root finding: ``z2`` is eliminated between
``P`` and its conjugate-reciprocal ``P*`` (on the torus ``P = 0`` iff ``P* = 0``), whose
resultant ``R_w(z1)`` is sampled at roots of unity (2B x 2B Sylvester determinants) and
interpolated by an FFT; its roots on the unit circle (batched companion eigenvalues) give
``z1``, then the roots of ``P_w(z1, .)`` on the unit circle give ``z2``, and Newton on the
exact equation in the angles polishes each pair.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from seactl.diagram.delayterms import DelayTerms
from seactl.errors import InputError

TWO_PI = 2.0 * np.pi
CIRCLE_TOL = 1e-3
"""Candidates with ``| |z| - 1 |`` below this go to Newton; the residual decides."""
RESIDUAL_TOL = 1e-9
"""A polished pair is kept when ``|P| <= RESIDUAL_TOL * sum |c_ab|``."""


@dataclass(frozen=True)
class TorusPolynomial:
    """``P_w(z1, z2) = sum_j p_j(jw) e^{-j w d_j} z1^{a_j} z2^{b_j}`` of one design.

    Attributes
    ----------
    coeffs : numpy.ndarray
        ``(J, n + 1)`` ascending powers of ``s``.
    a, b : numpy.ndarray
        ``(J,)`` exponents of the two varied delays.
    fixed_s : numpy.ndarray
        ``(J,)`` the delay [s] of each term from the delays held fixed.
    """

    coeffs: np.ndarray
    a: np.ndarray
    b: np.ndarray
    fixed_s: np.ndarray

    @classmethod
    def of(cls, terms: DelayTerms, i1: int, i2: int) -> TorusPolynomial:
        """The polynomial of a one-design :class:`DelayTerms` (batch of size 1), delays
        ``i1`` and ``i2`` varied."""
        J, n1 = terms.coeffs.shape[0], terms.coeffs.shape[-1]
        coeffs = terms.coeffs.reshape(J, -1, n1)[:, 0]
        tau = terms.delays_s.reshape(len(terms.names), -1)[:, 0].copy()
        tau[[i1, i2]] = 0.0
        E = terms.exponents
        return cls(coeffs.astype(float), E[:, i1].astype(int), E[:, i2].astype(int),
                   E.astype(float) @ tau)

    @property
    def degrees(self) -> tuple[int, int]:
        """``(A, B)``: the highest powers of ``z1`` and ``z2``."""
        return int(self.a.max()), int(self.b.max())

    def terms_at(self, w: np.ndarray, derivative: bool = False) -> np.ndarray:
        """``(F, J)``: each term's ``p_j(jw) e^{-j w d_j}`` (or its ``d/dw``)."""
        s = 1j * np.asarray(w, float)[:, None]
        c = self.coeffs
        p = np.zeros(s.shape[:1] + c.shape[:1], complex) + c[:, -1]
        dp = np.zeros_like(p)
        for k in range(c.shape[1] - 2, -1, -1):
            dp = dp * s + p
            p = p * s + c[:, k]
        ex = np.exp(-s * self.fixed_s)
        if derivative:
            return 1j * (dp - self.fixed_s * p) * ex
        return p * ex

    def grid(self, w: np.ndarray, derivative: bool = False) -> np.ndarray:
        """``(F, A + 1, B + 1)``: the coefficients ``c_ab(w)`` (or ``d c_ab / dw``)."""
        A, B = self.degrees
        onehot = np.zeros((self.a.size, A + 1, B + 1))
        onehot[np.arange(self.a.size), self.a, self.b] = 1.0
        return np.einsum("fj,jab->fab", self.terms_at(w, derivative), onehot)

    def scale(self, w: np.ndarray) -> np.ndarray:
        """``(F,)``: ``sum_j |p_j(jw)|``, the size of the terms (residual tests)."""
        return np.abs(self.terms_at(w)).sum(axis=1)

    def evaluate(self, c: np.ndarray, th1: np.ndarray, th2: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``P`` and ``dP/d theta1``, ``dP/d theta2`` at ``z_i = e^{-j theta_i}``; ``c`` of
        shape ``(F, A+1, B+1)``, angles ``(F, M)``."""
        A, B = self.degrees
        e1 = np.exp(-1j * th1[..., None] * np.arange(A + 1))
        e2 = np.exp(-1j * th2[..., None] * np.arange(B + 1))
        t = c[:, None] * e1[..., :, None] * e2[..., None, :]
        P = t.sum(axis=(-1, -2))
        d1 = (t * (-1j * np.arange(A + 1))[:, None]).sum(axis=(-1, -2))
        d2 = (t * (-1j * np.arange(B + 1))).sum(axis=(-1, -2))
        return P, d1, d2


def resultant_coeffs(c: np.ndarray) -> np.ndarray:
    """``(F, 2AB + 1)`` ascending coefficients of ``R(z1) = Res_z2(P, P*)``, ``P*`` the
    conjugate-reciprocal ``z1^A z2^B conj(P(1/conj z1, 1/conj z2))``: sampled at roots of
    unity (Sylvester determinants) and interpolated by an FFT."""
    F, A1, B1 = c.shape
    A, B = A1 - 1, B1 - 1
    N = 2 * A * B + 1
    z = np.exp(2j * np.pi * np.arange(N) / N)
    zp = z[:, None] ** np.arange(A + 1)                       # (N, A+1)
    p = np.einsum("fab,na->fnb", c, zp)                       # P(z, .) coefficients in z2
    q = np.einsum("fab,na->fnb", np.conj(c[:, ::-1, ::-1]), zp)   # P*(z, .)
    S = np.zeros((F, N, 2 * B, 2 * B), complex)
    for r in range(B):                                        # Sylvester rows
        S[:, :, r, r:r + B + 1] = p[..., ::-1]
        S[:, :, B + r, r:r + B + 1] = q[..., ::-1]
    return np.fft.fft(np.linalg.det(S), axis=-1) / N


def poly_roots(coeffs: np.ndarray) -> np.ndarray:
    """Roots of a batch of polynomials ``(F, d + 1)`` (ascending), by eigenvalues of their
    companion matrices; NaN where the degree drops (a vanishing leading coefficient)."""
    F, d1 = coeffs.shape
    d = d1 - 1
    if d < 1:
        return np.zeros((F, 0), complex)
    lead = coeffs[:, -1]
    big = np.abs(coeffs).max(axis=1)
    ok = np.abs(lead) > 1e-13 * big
    comp = np.zeros((F, d, d), complex)
    comp[:, np.arange(1, d), np.arange(d - 1)] = 1.0
    comp[:, :, -1] = -coeffs[:, :-1] / np.where(ok, lead, 1.0)[:, None]
    comp[~ok] = np.eye(d)
    roots = np.linalg.eigvals(comp)
    return np.where(ok[:, None], roots, np.nan)


def newton_angles(tp: TorusPolynomial, c: np.ndarray, th1: np.ndarray, th2: np.ndarray,
                  iterations: int = 8) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Newton on ``P(e^{-j th1}, e^{-j th2}) = 0`` (two real equations, two angles);
    returns the angles in ``[0, 2 pi)`` and ``|P|``."""
    for _ in range(iterations):
        P, d1, d2 = tp.evaluate(c, th1, th2)
        det = d1.real * d2.imag - d2.real * d1.imag
        with np.errstate(divide="ignore", invalid="ignore"):
            s1 = (P.real * d2.imag - d2.real * P.imag) / det
            s2 = (d1.real * P.imag - P.real * d1.imag) / det
        good = np.isfinite(s1) & np.isfinite(s2)
        th1 = th1 - np.where(good, s1, 0.0)
        th2 = th2 - np.where(good, s2, 0.0)
    P = tp.evaluate(c, th1, th2)[0]
    return np.mod(th1, TWO_PI), np.mod(th2, TWO_PI), np.abs(P)


def torus_solutions(tp: TorusPolynomial, w: np.ndarray, gap: bool = False) -> tuple:
    """Every ``(theta1, theta2)`` in ``[0, 2 pi)^2`` with ``P_w(e^{-j theta1},
    e^{-j theta2}) = 0``, per frequency: ``(F, M)`` arrays, NaN-padded, sorted by
    ``theta1``; with ``gap``, also ``(F,)`` the distance ``min | |z1| - 1 |`` of the
    resultant's roots from the unit circle (where solutions are about to appear)."""
    A, B = tp.degrees
    if A < 1 or B < 1:
        raise InputError("delays", "a delay that no term depends on",
                         "two delays that both enter the characteristic equation")
    c = tp.grid(w)
    z1 = poly_roots(resultant_coeffs(c))                      # (F, 2AB)
    near = np.nanmin(np.abs(np.abs(z1) - 1.0), axis=1, initial=np.inf)
    on1 = np.abs(np.abs(z1) - 1.0) < CIRCLE_TOL
    z1 = np.where(on1, z1 / np.abs(np.where(on1, z1, 1.0)), np.nan)
    zp = np.where(np.isfinite(z1), z1, 0)[..., None] ** np.arange(A + 1)
    pz = np.einsum("fab,fma->fmb", c, zp)                     # P(z1, .) in z2
    F, M1 = z1.shape
    z2 = poly_roots(pz.reshape(F * M1, B + 1)).reshape(F, M1 * B)
    z1 = np.repeat(z1, B, axis=1)
    on2 = np.isfinite(z1) & (np.abs(np.abs(z2) - 1.0) < CIRCLE_TOL)
    th1 = np.where(on2, -np.angle(np.where(on2, z1, 1)), 0.0)
    th2 = np.where(on2, -np.angle(np.where(on2, z2, 1)), 0.0)
    th1, th2, res = newton_angles(tp, c, th1, th2)
    keep = on2 & (res <= RESIDUAL_TOL * tp.scale(w)[:, None])
    out = _unique(np.where(keep, th1, np.nan), np.where(keep, th2, np.nan))
    return (*out, near) if gap else out


def _unique(th1: np.ndarray, th2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop repeated solutions (a double root of the resultant found twice), sort by
    ``theta1`` and trim the NaN padding."""
    order = np.argsort(np.where(np.isnan(th1), np.inf, th1), axis=1, kind="stable")
    th1, th2 = (np.take_along_axis(x, order, axis=1) for x in (th1, th2))
    for lag in range(1, th1.shape[1]):
        d = np.maximum(_wrapped(th1[:, lag:] - th1[:, :-lag]),
                       _wrapped(th2[:, lag:] - th2[:, :-lag]))
        dup = np.zeros_like(th1, bool)
        dup[:, lag:] = d < 1e-7
        th1, th2 = np.where(dup, np.nan, th1), np.where(dup, np.nan, th2)
    order = np.argsort(np.where(np.isnan(th1), np.inf, th1), axis=1, kind="stable")
    th1, th2 = (np.take_along_axis(x, order, axis=1) for x in (th1, th2))
    m = max(int(np.isfinite(th1).sum(axis=1).max(initial=0)), 1)
    return th1[:, :m], th2[:, :m]


def _wrapped(d: np.ndarray) -> np.ndarray:
    """``|d|`` modulo ``2 pi`` (the distance of two angles)."""
    d = np.mod(d, TWO_PI)
    return np.minimum(d, TWO_PI - d)


def angle_distance(d: np.ndarray) -> np.ndarray:
    """The distance of two angles whose difference is ``d`` (in ``[0, pi]``)."""
    return _wrapped(d)
