"""The exact peak of a delay-free linear system's step response.

For ``x' = A x + B u``, ``y = C x + D u`` at rest and a unit step ``u``, the response at
any time ``t`` is ``y(t) = C Phi(t) + D`` with ``Phi(t) = int_0^t e^{A s} ds B``, the
upper-right block of ``expm([[A, B], [0, 0]] t)``: exact at every ``t``, with no time
step.  The realization is first balanced by an exact power-of-two diagonal similarity
(:func:`balanced`): a companion-form realization of a high-order loop has entries of
1e21 and loses most digits in the matrix exponential otherwise.  :func:`step_peak`
samples it on a grid (each sample exact, by powers of one matrix exponential), then
refines the largest sample between its neighbours with a bounded Brent search, so the
peak between samples is found too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class StepPeak:
    """The largest value of a step response on ``[0, t_end_s]``.

    Attributes
    ----------
    t_s : time of the peak [s].
    value : the response there.
    final : the steady-state value ``D - C A^{-1} B`` (NaN when ``A`` is singular).
    """

    t_s: float
    value: float
    final: float

    @property
    def overshoot_pct(self) -> float:
        """``100 (peak / final - 1)`` [%]."""
        return 100.0 * (self.value / self.final - 1.0)


def balanced(A, B, C) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(T^-1 A T, T^-1 B, C T)`` with ``T`` the power-of-two diagonal scaling that
    balances ``[[A, B], [C, 0]]`` (scipy ``matrix_balance``, no permutation): the same
    input-output map, exactly."""
    from scipy.linalg import matrix_balance

    A, B, C = (np.atleast_2d(np.asarray(x, float)) for x in (A, B, C))
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n], M[n, :n] = A, B[:, 0], C[0]
    Mb, T = matrix_balance(M, permute=False)
    s = np.diag(T)
    return Mb[:n, :n], (Mb[:n, n] / s[n])[:, None], (Mb[n, :n] * s[n])[None, :]


def _augmented(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n] = A, B[:, 0]
    return M


def step_value(A, B, C, D, t_s: float) -> float:
    """``y(t_s)`` of the unit step response, exact (one matrix exponential)."""
    from scipy.linalg import expm

    A, B, C = balanced(A, B, C)
    n = A.shape[0]
    E = expm(_augmented(A, B) * t_s)
    return float(C[0] @ E[:n, n] + np.ravel(D)[0])


def step_peak(A, B, C, D, t_end_s: float, n: int = 20_001) -> StepPeak:
    """Peak of the unit step response of a single-input, single-output system on
    ``[0, t_end_s]``: ``n`` exact samples, then a bounded Brent search (``xatol`` 1e-12 s)
    between the largest sample's neighbours."""
    from scipy.linalg import expm
    from scipy.optimize import minimize_scalar

    A, B, C = balanced(A, B, C)
    d = float(np.ravel(D)[0])
    m = A.shape[0]
    h = t_end_s / (n - 1)
    step = expm(_augmented(A, B) * h)
    z = np.zeros(m + 1)
    z[m] = 1.0
    y = np.empty(n)
    for k in range(n):           # z_k = [x(kh); 1]: exact samples of the step response
        y[k] = C[0] @ z[:m] + d
        z = step @ z
    j = int(np.argmax(y))
    lo, hi = h * max(j - 1, 0), h * min(j + 1, n - 1)
    res = minimize_scalar(lambda t: -step_value(A, B, C, d, t), bounds=(lo, hi),
                          method="bounded", options={"xatol": 1e-12})
    t_pk, v_pk = (float(res.x), -float(res.fun)) if -res.fun >= y[j] else (j * h, float(y[j]))
    try:
        final = float(d - C[0] @ np.linalg.solve(A, B[:, 0]))
    except np.linalg.LinAlgError:
        final = float("nan")
    return StepPeak(t_pk, v_pk, final)
