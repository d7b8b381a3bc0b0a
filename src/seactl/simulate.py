"""Time-domain simulation of block diagrams with exact delays: continuous and sampled.

The simulator is *compiled from the block diagram* (:mod:`seactl.blockdiagram`),
the same description every frequency-domain view is derived from, so the time
and frequency domains cannot drift apart.  Any diagram works (the SEA loop of
:mod:`seactl.loops`, a rigid actuator, ...), with any design object whose
attributes are arrays broadcast to ``design.shape``; the whole batch is
simulated in one vectorized call (batch axis first, one Python loop over time
steps only).

Compilation
-----------
Each block ``num(s)/den(s) e^{-sT}`` is realized in controllable canonical
form (batched over designs).  Signals are sums of block outputs, so the
undelayed part of the diagram is one linear-algebraic system solved once per
design (``(I - P)^{-1}``, the feed-through network), which leaves a batched
state space ``x' = A x + B v``, ``S = C x + D v`` whose inputs ``v`` are the
exogenous inputs and the *delayed* block inputs.  Delayed inputs are read from
delay buffers holding the past values of their source signals.

Each mode is a compile step returning a plan (:class:`ContinuousPlan`,
:class:`SampledPlan`: batched matrices plus a :class:`Layout` naming the slices
of every packed vector) and a run loop over time steps (:func:`run_continuous`,
:func:`run_sampled`); :func:`simulate` does both.

Modes
-----
``continuous``
    Fixed step ``dt`` (default ``min(1e-4 s, smallest positive delay)``).  The
    linear part is integrated *exactly* between steps for inputs linear over a
    step (first-order hold, batched matrix exponential of an augmented matrix,
    :func:`expm_batched`); delayed inputs are linearly interpolated
    in the buffers (exact when the delays are multiples of ``dt``, second order
    otherwise).  Without delays a step response is exact to rounding.  An
    unfiltered derivative (a denominator whose leading coefficient is 0, e.g.
    ``Tf_qd = 0``) is improper and has no state-space realization; it is
    realized with leading coefficient ``derivative_tau_s`` (default 1e-7 s) times
    the next one, i.e. a roll-off at 1.6 MHz, far above any loop dynamics.  Such a
    derivative's output is a difference of nearly equal numbers, so a loop with
    unfiltered derivatives carries rounding of about 1e-5 of its response (the
    overshoot of Fig. GainScale(b) moves by 0.003 points between BLAS kernels);
    with filters the rounding is about 1e-14.
``sampled``
    What runs on the robot.  Blocks with ``role="plant"`` form a continuous
    plant integrated exactly (zero-order hold on the actuation signals,
    first-order hold on exogenous physical inputs) between ticks.  Controller
    and sensor blocks run in discrete time: each controller block belonging to
    a process runs at that process's rate (``rates_hz``, default 1 kHz for
    all) with its output held between its updates; derivatives and filters are
    discretized with the bilinear (Tustin) transform ``s = 2/T (z-1)/(z+1)``
    (which keeps unfiltered derivatives proper).  Sensors sample the plant at
    the tick, the actuation is computed at once and held (zero-order hold), so
    every feedback path sees ``T_s/2`` of effective delay; a block with delay
    ``T`` reads a buffer ``n = max(ceil((T - T_s/2)/T_s), 0)`` samples old
    (:func:`buffer_samples`), so that the effective delay ``T_s/2 + n T_s`` of the paper
    is the shortest realizable one that is not shorter than ``T`` (e.g. 1 ms at 1 kHz gives
    1.5 ms, at 500 Hz or 2 kHz exactly 1 ms); a delay is never shortened.  The effective
    delays used are returned in :attr:`SimResult.info`.  Optional: saturation of actuation signals
    (``saturation``), quantization of sampled plant signals (``quantization``)
    and Coulomb plus viscous friction (:class:`Friction`), integrated with a
    fixed sub-step ``T_s / friction_substeps`` with the friction force held
    over each sub-step.  All off unless given.

Inputs are :class:`Step`, :class:`Sine`, :class:`Impulse` (a Dirac at ``t = 0``,
applied exactly as a state jump) or any callable ``f(t) -> values``.
A design whose first recorded output leaves ``bound`` is reported unstable with the
time it left (its states are then frozen, so there is never an overflow or a
NaN); a response not decaying at the end of the window (slow divergence, or a
limit cycle bounded by saturation) is also reported unstable (``left_bounds_s``
stays ``inf`` for it).

Use for another diagram (e.g. a rigid actuator)::

    res = simulate(RIGID_DIAGRAM, design, {"x_des": Step(0.004)}, t_end_s=0.5,
                   mode="sampled", rates_hz={"embedded": 1000, "high-level": 1000},
                   outputs=("x",), saturation={"i_m": 30.0})

Examples
--------
A unity-feedback integrator ``1/s`` with gain 10 (closed loop ``10/(s+10)``):

>>> import numpy as np
>>> from types import SimpleNamespace
>>> from seactl.blockdiagram import Block, BlockDiagram
>>> d = BlockDiagram("int", [
...     Block("ref", "r", "e"), Block("fb", "y", "e", num=lambda p: (-1.0,)),
...     Block("ctrl", "e", "u", num=lambda p: (p.K,)),
...     Block("plant", "u", "y", den=lambda p: (1.0, 0.0), role="plant")])
>>> p = SimpleNamespace(K=np.array([10.0, 20.0]), shape=(2,))
>>> res = simulate(d, p, {"r": Step()}, t_end_s=0.1, outputs=("y",), dt=1e-3)
>>> y = res.outputs["y"]
>>> bool(np.allclose(y[:, -1], 1 - np.exp(-p.K * 0.1), atol=1e-12))
True
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any

import numpy as np

from ._parallel import eigvals, in_threads, stacked
from .blockdiagram import Block, BlockDiagram
from .errors import InputError, SeactlError
from .jit import njit
from .limits import check_budget, simulation_estimate
from .results import Result, flat_records, json_array, new_axes
from .verdict import RECOVERY_BAND, STEP_BAND

MODES = ("continuous", "sampled")


# ----------------------------------------------------------------------------- inputs
@dataclass(frozen=True)
class Step:
    """Step of ``amplitude`` at ``t0_s`` (default 0)."""

    amplitude: float = 1.0
    t0_s: float = 0.0

    def __call__(self, t: np.ndarray) -> np.ndarray:
        return np.where(t >= self.t0_s, self.amplitude, 0.0)

    @property
    def scale(self) -> float:
        return abs(self.amplitude)


@dataclass(frozen=True)
class Sine:
    """``amplitude sin(2 pi freq_hz t + phase_rad)`` for ``t >= 0``."""

    amplitude: float
    freq_hz: float
    phase_rad: float = 0.0

    def __call__(self, t: np.ndarray) -> np.ndarray:
        return self.amplitude * np.sin(2 * np.pi * self.freq_hz * t + self.phase_rad)

    @property
    def scale(self) -> float:
        return abs(self.amplitude)


@dataclass(frozen=True)
class Impulse:
    """Dirac impulse of ``area`` at ``t = 0`` (applied exactly, as a state jump)."""

    area: float = 1.0

    def __call__(self, t: np.ndarray) -> np.ndarray:
        return np.zeros_like(t)

    @property
    def scale(self) -> float:
        return abs(self.area)


@dataclass(frozen=True)
class Friction:
    """Coulomb plus viscous friction ``-(coulomb sign(v) + viscous v)`` added to the plant
    signal ``signal`` (a torque sum), ``v`` the time derivative of plant signal ``velocity_of``
    (a position; sampled mode only)."""

    signal: str
    velocity_of: str
    coulomb: float = 0.0
    viscous: float = 0.0


# ----------------------------------------------------------------------------- results
@dataclass(frozen=True)
class SimResult(Result):
    """Simulated responses of a batch of designs.

    Parameters
    ----------
    mode : str
        ``"continuous"`` or ``"sampled"``.
    t_s : numpy.ndarray
        Sample times [s], shape ``(T,)``.
    outputs : dict
        Signal name -> array of shape ``batch + (T,)``.
    stable : numpy.ndarray
        ``batch`` bool.
    left_bounds_s : numpy.ndarray
        Time [s] an output first left ``bound``.
    bound : float
        The divergence bound used.
    info : dict, optional
        Details.

    Attributes
    ----------
    mode : str
        ``"continuous"`` or ``"sampled"``.
    t_s : ndarray
        Sample times [s], shape ``(T,)``.
    outputs : dict
        Signal name -> array of shape ``batch + (T,)``, each in its signal's unit.
    stable : ndarray of bool
        ``batch``: stayed within ``bound`` and decaying at the end of the window.
    left_bounds_s : ndarray
        Time [s] an output first left ``bound`` (``inf`` if never).
    bound : float
        The divergence bound used (in the outputs' units).
    info : dict
        Details (step, rates, requested and effective delays per delayed block [s]:
        ``requested_delays_s``, ``effective_delays_s``; equal in continuous mode, the
        whole-sample buffers' ``T_s/2 + n T_s >= T`` in sampled mode, ...).
    """

    mode: str
    t_s: np.ndarray
    outputs: dict[str, np.ndarray]
    stable: np.ndarray
    left_bounds_s: np.ndarray
    bound: float
    info: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Time, every output, boundedness and exit times as nested lists.

        Returns
        -------
        dict
            ``mode``, ``t_s``, ``outputs`` (signal -> nested list), ``stable``,
            ``left_bounds_s``, ``bound``.
        """
        return {"mode": self.mode, "t_s": json_array(self.t_s),
                "outputs": {k: json_array(v) for k, v in self.outputs.items()},
                "stable": json_array(self.stable), "left_bounds_s": json_array(self.left_bounds_s),
                "bound": self.bound}

    def records(self) -> list[dict[str, Any]]:
        """One row per design (flattened batch): boundedness and exit time.

        Returns
        -------
        list of dict
            ``stable``, ``left_bounds_s``.
        """
        return flat_records({"stable": self.stable, "left_bounds_s": self.left_bounds_s})

    def plot(self, ax: Any = None, output: str | None = None) -> Any:
        """One output against time (default: the first), one line per design.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).
        output : str, optional
            Signal name (a key of :attr:`outputs`).

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        ax = new_axes(ax)
        name = output if output is not None else next(iter(self.outputs))
        for y in np.reshape(self.outputs[name], (-1, self.t_s.size)):
            ax.plot(self.t_s, y)
        ax.set_xlabel("time [s]")
        ax.set_ylabel(name)
        ax.grid(True, alpha=0.3)
        return ax


@dataclass(frozen=True)
class StepMetrics:
    """Step-response metrics (arrays of the batch shape; responses normalized to the step).

    ``rise_time_s``: 10 % to 90 % of the final value; ``overshoot_pct``: peak above the
    final value [% of the final value]; ``settling_time_s``: last time outside a 2 % band
    around the final value (``inf`` if still outside at the end); ``steady_state_error``:
    ``1 - final`` (final = mean of the last 2 % of the window).  Unstable designs get NaN
    metrics (their ``stable`` flag is False and ``left_bounds_s`` says when they left).
    """

    rise_time_s: np.ndarray
    overshoot_pct: np.ndarray
    settling_time_s: np.ndarray
    steady_state_error: np.ndarray
    final_value: np.ndarray
    stable: np.ndarray
    left_bounds_s: np.ndarray


@dataclass(frozen=True)
class ImpulseMetrics:
    """Impulse-disturbance metrics (arrays of the batch shape).

    ``peak_deviation``: largest ``|y - y(0)|`` (output units); ``peak_time_s``: when;
    ``recovery_time_s``: last time ``|y - y(0)|`` exceeds ``band`` times the peak (``inf``
    if it has not recovered by the end).  NaN for unstable designs.
    """

    peak_deviation: np.ndarray
    peak_time_s: np.ndarray
    recovery_time_s: np.ndarray
    band: float
    stable: np.ndarray
    left_bounds_s: np.ndarray


# ----------------------------------------------------------------------------- realization
def _coeff_matrix(coeffs: Sequence[Any], shape: tuple[int, ...], n: int) -> np.ndarray:
    return np.stack([np.broadcast_to(np.asarray(c, float), shape).reshape(n) for c in coeffs],
                    axis=1)


def _strip_leading(num: np.ndarray, den: np.ndarray, block: Block) -> tuple[np.ndarray, ...]:
    """Drop leading numerator columns that are zero for every design; check properness."""
    while num.shape[1] > den.shape[1] and np.all(num[:, 0] == 0):
        num = num[:, 1:]
    if num.shape[1] > den.shape[1] + 1:
        raise ValueError(f"block {block.name!r}: numerator degree exceeds the denominator's by "
                         "more than one; not realizable")
    return num, den


def _ccf(num: np.ndarray, den: np.ndarray) -> tuple[np.ndarray, ...]:
    """Controllable canonical form of batched ``num/den`` (same length, den[:, 0] != 0)."""
    n, q1 = den.shape
    q = q1 - 1
    a = den[:, 1:] / den[:, :1]
    b = num / den[:, :1]
    D = b[:, 0]
    A = np.zeros((n, q, q))
    if q:
        A[:, 0, :] = -a
        A[:, np.arange(1, q), np.arange(q - 1)] = 1.0
    B = np.zeros((n, q))
    if q:
        B[:, 0] = 1.0
    C = b[:, 1:] - b[:, :1] * a
    return A, B, C, D


def realize_continuous(block: Block, design: Any, shape: tuple[int, ...], n: int,
                       derivative_tau_s: float = 1e-7) -> tuple[np.ndarray, ...]:
    """Batched state space ``(A, B, C, D)`` of the block's rational part (no delay).

    A vanishing leading denominator coefficient (an unfiltered derivative) is replaced
    by ``derivative_tau_s`` times the next coefficient (a far roll-off)."""
    num_c, den_c = block.coefficients(design)
    num, den = _coeff_matrix(num_c, shape, n), _coeff_matrix(den_c, shape, n)
    num, den = _strip_leading(num, den, block)
    if den.shape[1] > 1:
        zero = den[:, 0] == 0
        if zero.any():
            den = den.copy()
            den[:, 0] = np.where(zero, derivative_tau_s * np.abs(den[:, 1]), den[:, 0])
    if np.any(den[:, 0] == 0):
        raise ValueError(f"block {block.name!r}: denominator vanishes")
    if num.shape[1] > den.shape[1]:
        raise ValueError(f"block {block.name!r} is improper for some designs")
    num = np.concatenate([np.zeros((n, den.shape[1] - num.shape[1])), num], axis=1)
    return _ccf(num, den)


def _tustin_basis(q: int) -> np.ndarray:
    """Rows j = 0..q: coefficients of ``(z-1)^j (z+1)^(q-j)`` (highest power first)."""
    rows = []
    for j in range(q + 1):
        p = np.array([1.0])
        for _ in range(j):
            p = np.polymul(p, [1.0, -1.0])
        for _ in range(q - j):
            p = np.polymul(p, [1.0, 1.0])
        rows.append(p)
    return np.array(rows)


def realize_tustin(block: Block, design: Any, shape: tuple[int, ...], n: int,
                   period_s: float) -> tuple[np.ndarray, ...]:
    """Batched discrete state space of the block's rational part, bilinear transform
    ``s = (2/T)(z-1)/(z+1)`` at period ``T`` (proper even for an unfiltered derivative)."""
    num_c, den_c = block.coefficients(design)
    num, den = _coeff_matrix(num_c, shape, n), _coeff_matrix(den_c, shape, n)
    num, den = _strip_leading(num, den, block)
    q = max(num.shape[1], den.shape[1]) - 1
    pad = lambda c: np.concatenate([np.zeros((n, q + 1 - c.shape[1])), c], axis=1)  # noqa: E731
    num, den = pad(num), pad(den)
    # c(s) = sum_k c[q-j] s^j  ->  (z+1)^q c = sum_j c[q-j] (2/T)^j (z-1)^j (z+1)^(q-j)
    w = (2.0 / period_s) ** np.arange(q + 1)
    basis = _tustin_basis(q)
    num_z = (num[:, ::-1] * w) @ basis
    den_z = (den[:, ::-1] * w) @ basis
    if np.any(den_z[:, 0] == 0):
        raise ValueError(f"block {block.name!r}: Tustin denominator vanishes")
    return _ccf(num_z, den_z)


# ----------------------------------------------------------------------------- network
@dataclass
class _Net:
    """A batched linear network ``x+ = A x + B v``, ``S = C x + D v`` over ``signals``."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    state_slices: dict[str, slice]


def _assemble(n: int, signals: Sequence[str], blocks: Sequence[Block],
              reals: Sequence[tuple[np.ndarray, ...]], inject: Sequence[str],
              inst: Mapping[str, np.ndarray], wcol: Mapping[str, int],
              held: Mapping[str, int] = {}, identity_hold: bool = True,
              nv: int | None = None) -> _Net:
    """Assemble the network.  Inputs ``v`` are: one column per ``inject`` signal (added to
    it), delayed-input columns ``wcol[block]`` (weight ``1 - inst[block]``), held-output
    columns ``held[block]`` (the block's output is the column; its state is frozen)."""
    idx = {s: i for i, s in enumerate(signals)}
    m = len(signals)
    nv = len(inject) + len(wcol) + len(held) if nv is None else nv
    slices, off = {}, 0
    for b, (A, *_rest) in zip(blocks, reals):
        slices[b.name] = slice(off, off + A.shape[1])
        off += A.shape[1]
    N = off
    P = np.zeros((n, m, m))
    Q = np.zeros((n, m, N))
    R = np.zeros((n, m, nv))
    for j, s in enumerate(inject):
        R[:, idx[s], j] += 1.0
    for b, (_A, _B, C, D) in zip(blocks, reals):
        d, sl = idx[b.dst], slices[b.name]
        if b.name in held:
            R[:, d, held[b.name]] += 1.0
            continue
        z = inst[b.name]
        Q[:, d, sl] += C
        P[:, d, idx[b.src]] += D * z
        if b.name in wcol:
            R[:, d, wcol[b.name]] += D * (1.0 - z)
    try:
        M = stacked(np.linalg.inv, np.eye(m)[None] - P)
    except np.linalg.LinAlgError:
        raise SeactlError("the loop's instantaneous (algebraic) feedback is singular in "
                          "floating point for these parameters: the gains or plant values "
                          "are too extreme to simulate") from None
    Cs, Ds = M @ Q, M @ R
    Ax = np.zeros((n, N, N))
    Bx = np.zeros((n, N, nv))
    for b, (A, B, _C, _D) in zip(blocks, reals):
        sl = slices[b.name]
        if b.name in held:
            if identity_hold:
                Ax[:, sl, sl] = np.eye(A.shape[1])
            continue
        z = inst[b.name]
        s = idx[b.src]
        Ax[:, sl, sl] += A
        Ax[:, sl, :] += B[:, :, None] * (z[:, None, None] * Cs[:, None, s, :])
        Bx[:, sl, :] += B[:, :, None] * (z[:, None, None] * Ds[:, None, s, :])
        if b.name in wcol:
            Bx[:, sl, wcol[b.name]] += B * (1.0 - z)[:, None]
    return _Net(Ax, Bx, Cs, Ds, slices)


_PADE13 = (64764752532480000.0, 32382376266240000.0, 7771770303897600.0, 1187353796428800.0,
           129060195264000.0, 10559470521600.0, 670442572800.0, 33522128640.0, 1323241920.0,
           40840800.0, 960960.0, 16380.0, 182.0, 1.0)


_MAX_SQUARINGS = 12


def balance_batched(A: np.ndarray, sweeps: int = 40) -> np.ndarray:
    """Powers of two ``d`` (shape ``(..., N)``) that balance each matrix of a stack:
    ``A * d[..., None, :] / d[..., :, None]`` (that is ``D^-1 A D``) has off-diagonal row
    and column 1-norms within a factor of about 2 of each other (Parlett and Reinsch, the
    scaling of LAPACK's ``gebal``; one index at a time, compiled, over the stack).

    Powers of two make the similarity exact in floating point.  Rows or columns that are
    zero off the diagonal, or not finite, are left alone.

    Examples
    --------
    >>> import numpy as np
    >>> A = np.array([[-1e7, 1e-5], [1e13, -10.0]])
    >>> d = balance_batched(A)
    >>> B = A * d[None, :] / d[:, None]
    >>> bool(np.all((abs(B[0, 1]) / abs(B[1, 0]) > 0.25) & (abs(B[0, 1]) / abs(B[1, 0]) < 4)))
    True
    """
    A = np.asarray(A, float)
    n = A.shape[-1]
    with np.errstate(invalid="ignore"):
        W = np.where(np.isfinite(A), np.abs(A), 0.0) * (1.0 - np.eye(n))
    d = np.ones(A.shape[:-1])
    _balance_kernel(W.reshape(-1, n, n), d.reshape(-1, n), sweeps)
    return d


@njit(cache=True, nogil=True)
def _balance_kernel(W, d, sweeps):  # pragma: no cover - compiled
    # W: |A| off the diagonal, rescaled in place to |D^-1 A D|; scaling index i by f
    # multiplies its column by f and divides its row by f
    for k in range(W.shape[0]):
        n = W.shape[1]
        for _ in range(sweeps):
            changed = False
            for i in range(n):
                c = 0.0
                r = 0.0
                for j in range(n):
                    c += W[k, j, i]
                    r += W[k, i, j]
                if not (c > 0.0 and r > 0.0):
                    continue
                f = 2.0 ** np.round(0.5 * np.log2(r / c))
                if c * f + r / f < 0.95 * (c + r):
                    for j in range(n):
                        W[k, j, i] *= f
                        W[k, i, j] /= f
                    d[k, i] *= f
                    changed = True
            if not changed:
                break


def expm_batched(A: np.ndarray) -> np.ndarray:
    """Matrix exponential of a stack ``(..., N, N)``: balancing (:func:`balance_batched`),
    then scaling and squaring with the degree-13 Pade approximant (Higham 2005), each
    matrix scaled by its own power of two.

    Balancing first matters for a loop's augmented matrices, whose entries span many
    decades (a fast roll-off next to a slow mechanism): without it the squarings lose up
    to seven digits of a Table I loop's step response, and tiny entries entirely.

    All work is stacked numpy (``matmul``/``solve``), which avoids per-matrix library
    calls (``scipy.linalg.expm`` loops over the stack: one call, and one round of
    multithreaded BLAS, per small matrix).
    Matrices needing more than 12 squarings are handed to :func:`scipy.linalg.expm`.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.linalg import expm
    >>> A = np.array([[[0.0, 1.0], [-4.0, -0.4]], [[-30.0, 2.0], [0.0, -1e3]]])
    >>> bool(np.allclose(expm_batched(A), expm(A), rtol=1e-12, atol=1e-14))
    True
    """
    A = np.asarray(A, float)
    d = balance_batched(A)
    A = A0 = A * d[..., None, :] / d[..., :, None]
    b = _PADE13
    norm = np.max(np.sum(np.abs(A), axis=-2), axis=-1)
    with np.errstate(divide="ignore"):
        s = np.maximum(0, np.ceil(np.log2(norm / 5.371920351148152))).astype(int)
    s = np.where(norm > 0, s, 0)
    A = A / (2.0 ** s)[..., None, None]
    eye = np.broadcast_to(np.eye(A.shape[-1]), A.shape)
    A2 = A @ A
    A4 = A2 @ A2
    A6 = A4 @ A2
    U = A @ (A6 @ (b[13] * A6 + b[11] * A4 + b[9] * A2)
             + b[7] * A6 + b[5] * A4 + b[3] * A2 + b[1] * eye)
    V = A6 @ (b[12] * A6 + b[10] * A4 + b[8] * A2) + b[6] * A6 + b[4] * A4 + b[2] * A2 \
        + b[0] * eye
    R = np.linalg.solve(V - U, V + U)
    hard = s > _MAX_SQUARINGS
    s = np.where(hard, 0, s)
    for k in range(int(s.max(initial=0))):
        more = k < s
        R[more] = R[more] @ R[more]
    if hard.any():
        # Badly scaled (stiff, strongly non-normal) matrices, e.g. an unfiltered derivative's
        # fast roll-off: many squarings would amplify rounding; scipy's expm (Al-Mohy and
        # Higham 2009) bounds the squarings with norm estimates of powers.
        from scipy.linalg import expm

        R[hard] = expm(np.asarray(A0)[hard])
    return R * d[..., :, None] / d[..., None, :]


def _foh(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact discretization for inputs linear over a step: ``x1 = F x0 + G0 v0 + G1 v1``."""
    n, N, _ = A.shape
    nv = B.shape[2]
    M = np.zeros((n, N + 2 * nv, N + 2 * nv))
    M[:, :N, :N] = A * h
    M[:, :N, N:N + nv] = B * h
    M[:, N:N + nv, N + nv:] = np.eye(nv)
    # (a violently unstable loop, e.g. a negative derivative gain on a micro-inertia,
    # overflows e^{A h}: its simulation leaves the bounds at the first step)
    with np.errstate(over="ignore", invalid="ignore"):
        E = expm_batched(M)
        G1, G2 = E[:, :N, N:N + nv], E[:, :N, N + nv:]
        return E[:, :N, :N], G1 - G2, G2


def _delay_attr(design: Any, block: Block, shape: tuple[int, ...], n: int) -> np.ndarray:
    return np.broadcast_to(np.asarray(getattr(design, block.delay), float), shape).reshape(n)


def _input_values(inputs: Mapping[str, Any], names: Sequence[str], t: np.ndarray,
                  shape: tuple[int, ...], n: int) -> np.ndarray:
    """Exogenous input values, shape ``(T, len(names), n)`` (or ``(T, len(names), 1)``
    when no input depends on the design)."""
    vals = []
    for name in names:
        f = inputs.get(name)
        val = np.zeros(t.shape) if f is None else np.asarray(f(t), float)
        if val.ndim <= 1:
            vals.append(np.broadcast_to(val, t.shape)[:, None])
        else:
            vals.append(np.broadcast_to(val, shape + t.shape).reshape(n, t.size).T)
    if not vals:
        return np.zeros((t.size, 0, 1))
    nb = max(v.shape[1] for v in vals)
    return np.stack([np.broadcast_to(v, (t.size, nb)) for v in vals], axis=1)


def _impulses(inputs: Mapping[str, Any], names: Sequence[str]) -> np.ndarray:
    return np.array([inputs[nm].area if isinstance(inputs.get(nm), Impulse) else 0.0
                     for nm in names])


def _default_bound(inputs: Mapping[str, Any]) -> float:
    scales = [getattr(f, "scale", 0.0) for f in inputs.values()]
    return 1e3 * max([s for s in scales if s > 0] or [1.0])


def _growing(y: np.ndarray, scale: float) -> np.ndarray:
    """Responses not decaying at the end of the window (slow divergence, or a sustained
    oscillation such as a limit cycle bounded by saturation): the deviation from the final
    mean over the last fifth of the window is above 0.9x that over the previous fifth and
    above 1e-3 x the input scale."""
    T = y.shape[-1]
    a, b = y[..., T - 2 * (T // 5):T - T // 5], y[..., T - T // 5:]
    mean = b.mean(axis=-1, keepdims=True)
    ea = np.max(np.abs(a - mean), axis=-1)
    eb = np.max(np.abs(b - mean), axis=-1)
    return (eb > 0.9 * ea) & (eb > 1e-3 * scale)


# ----------------------------------------------------------------------------- simulate
def simulate(diagram: BlockDiagram, design: Any, inputs: Mapping[str, Any], t_end_s: float, *,
             mode: str = "continuous", outputs: Sequence[str] = (), dt: float | None = None,
             record_dt: float | None = None, rates_hz: Mapping[str, float] | float = 1000.0,
             saturation: Mapping[str, float] | None = None,
             quantization: Mapping[str, float] | None = None, friction: Friction | None = None,
             friction_substeps: int = 10, bound: float | None = None,
             derivative_tau_s: float = 1e-7, timing: Any = None) -> SimResult:
    """Simulate ``diagram`` for a batch of designs (see the module docstring).

    Parameters
    ----------
    diagram : BlockDiagram
    design : object
        Attributes used by the blocks (arrays broadcast to ``design.shape``).
    inputs : mapping
        Exogenous signal name -> :class:`Step`, :class:`Sine`, :class:`Impulse` or
        ``f(t) -> values`` (broadcast to ``design.shape + t.shape``); missing inputs are 0.
    t_end_s : float
        Simulated duration [s].
    mode : ``"continuous"`` or ``"sampled"``.
    outputs : signal names to record (default: every signal fed only by plant blocks).
    dt : continuous step [s] (default ``min(1e-4, smallest positive delay)``).
    record_dt : recording interval [s] (continuous; default ``dt``, rounded to a multiple).
    rates_hz : servo rate [Hz] per process (a number: every process), sampled mode.
    saturation : actuation signal -> symmetric limit (sampled mode).
    quantization : sampled plant signal -> quantum (sampled mode).
    friction : :class:`Friction` (sampled mode), sub-step ``T_s/friction_substeps``.
    bound : divergence bound on the first recorded output (default 1e3 x the largest input
        scale); the first output is also the one checked for growth at the end.
    derivative_tau_s : roll-off of unfiltered derivatives in continuous mode [s].
    timing : object, optional
        Time-varying latency and message loss (sampled mode; see :mod:`seactl.timing`):
        ``timing.blocks`` names the delayed blocks it drives (compiled to always read
        their buffers) and ``timing.schedules(plan)`` returns, per block, the source tick
        each tick uses (see :func:`run_sampled`).

    Returns
    -------
    SimResult
    """
    t_end_s, outputs = _check_args(diagram, inputs, mode, t_end_s, outputs)
    shape = tuple(getattr(design, "shape", ()))
    bound = _default_bound(inputs) if bound is None else float(bound)
    if mode == "continuous":
        if saturation or quantization or friction or timing is not None:
            raise InputError("mode", mode, "'sampled' for saturation, quantization, friction "
                             "or timing")
        plan = compile_continuous(diagram, design, inputs, t_end_s, outputs, dt=dt,
                                  record_dt=record_dt, derivative_tau_s=derivative_tau_s)
        res = run_continuous(plan, bound)
    else:
        plan = compile_sampled(diagram, design, inputs, t_end_s, outputs, rates_hz=rates_hz,
                               saturation=saturation, quantization=quantization,
                               friction=friction, friction_substeps=friction_substeps,
                               buffered=timing.blocks if timing is not None else ())
        res = run_sampled(plan, bound, timing.schedules(plan) if timing is not None else None)
        if timing is None:  # time-varying timing has no fixed lifted map
            res.info["unstable_modes"] = sampled_unstable_modes(plan).reshape(shape)
    scale = max(bound / 1e3, 1e-300)
    grow = _growing(res.outputs[outputs[0]], scale)
    stable = np.isinf(res.left_bounds_s) & ~grow
    out = {o: res.outputs[o].reshape(shape + (res.t_s.size,)) for o in outputs}
    return SimResult(mode, res.t_s, out, stable.reshape(shape), res.left_bounds_s.reshape(shape),
                     bound, res.info)


def _check_args(diagram: BlockDiagram, inputs: Mapping[str, Any], mode: str, t_end_s: float,
                outputs: Sequence[str]) -> tuple[float, tuple[str, ...]]:
    """Validate mode, duration and input names; the outputs to record (default: plant
    signals)."""
    if mode not in MODES:
        raise InputError("mode", mode, " or ".join(MODES))
    from .limits import check_range

    t_end_s = check_range("t_end_s", t_end_s, "t_end_s")
    unknown = set(inputs) - set(diagram.inputs)
    if unknown:
        raise InputError("inputs", ", ".join(sorted(unknown)),
                         "exogenous signals of the diagram: " + ", ".join(diagram.inputs))
    plant_signals = {b.dst for b in diagram.blocks if b.role == "plant"}
    if not outputs:
        outputs = tuple(s for s in diagram.signals if s in plant_signals)
    for o in outputs:
        if o not in diagram.signals:
            raise InputError("outputs", o, "signals of the diagram: " + ", ".join(diagram.signals))
    return t_end_s, tuple(outputs)


@dataclass(frozen=True)
class Layout:
    """Named consecutive slices of a packed vector (states, inputs, ... of one batch).

    Examples
    --------
    >>> lay = Layout.of(x=3, u=2)
    >>> lay["u"], lay.size
    (slice(3, 5, None), 5)
    """

    parts: tuple[tuple[str, int], ...]

    @classmethod
    def of(cls, **sizes: int) -> Layout:
        return cls(tuple((k, int(v)) for k, v in sizes.items()))

    @cached_property
    def _slices(self) -> dict[str, slice]:
        out, off = {}, 0
        for name, size in self.parts:
            out[name] = slice(off, off + size)
            off += size
        return out

    def __getitem__(self, name: str) -> slice:
        return self._slices[name]

    def upto(self, name: str) -> slice:
        """From the start up to the end of part ``name``."""
        return slice(0, self._slices[name].stop)

    @property
    def size(self) -> int:
        return sum(s for _, s in self.parts)


@dataclass(frozen=True)
class RunOutputs:
    """What a run loop returns: flat-batch outputs ``(n, T)``, exit times, details."""

    t_s: np.ndarray
    outputs: dict[str, np.ndarray]
    left_bounds_s: np.ndarray
    info: dict[str, Any]


def _batch_last(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(np.moveaxis(a, 0, -1))


# ----------------------------------------------------------------------------- continuous
@dataclass(frozen=True)
class ContinuousPlan:
    """A diagram compiled for the continuous run loop (batch on the last axis).

    ``H = [F G0 G1]`` advances ``z = [x; v_i; v_{i+1}]`` (layout ``z``; each ``v`` has the
    layout ``v``: exogenous inputs, then delayed block inputs); ``CD`` gives the signal rows
    of layout ``rows`` (the delayed blocks' sources, then the recorded outputs) from
    ``[x; v_i]``.  Delay buffers read ``whole`` steps back, interpolated by ``frac``."""

    t_s: np.ndarray
    dt_s: float
    every: int
    outputs: tuple[str, ...]
    H: np.ndarray
    CD: np.ndarray
    inputs: np.ndarray
    x0: np.ndarray
    z: Layout
    v: Layout
    rows: Layout
    whole: np.ndarray
    frac: np.ndarray
    ring_len: int
    delays_s: dict[str, np.ndarray]
    shape: tuple[int, ...]

    @property
    def steps(self) -> int:
        return self.t_s.size - 1


def _continuous_step(delays: Mapping[str, np.ndarray], dt: float | None) -> float:
    positive = [d[d > 0] for d in delays.values()]
    min_pos = min([float(p.min()) for p in positive if p.size] or [np.inf])
    if dt is None:
        dt = min(1e-4, min_pos)
    dt = float(dt)
    if not (dt > 0 and math.isfinite(dt)):
        raise InputError("dt", dt, "a finite step > 0 [s]")
    if dt > min_pos * (1 + 1e-9):
        raise InputError("dt", dt, f"<= the smallest positive delay ({min_pos:g} s)")
    return dt


def _check_size(n: int, steps: int, recorded: int, hint: str) -> None:
    """Refuse up front a simulation larger than the machine (the command line checks its
    own options first, with their names; this guards every other caller)."""
    n_bytes, seconds = simulation_estimate(n, steps, recorded)
    check_budget(f"simulating {n:,} design(s) over {steps:,} steps", n_bytes=n_bytes,
                 seconds=seconds, hint=hint)


def compile_continuous(diagram: BlockDiagram, design: Any, inputs: Mapping[str, Any],
                       t_end_s: float, outputs: Sequence[str], *, dt: float | None = None,
                       record_dt: float | None = None,
                       derivative_tau_s: float = 1e-7) -> ContinuousPlan:
    """Compile ``diagram`` for :func:`run_continuous` (see :func:`simulate`)."""
    shape = tuple(getattr(design, "shape", ()))
    n = int(np.prod(shape, dtype=int))
    blocks = list(diagram.blocks)
    delayed = [b for b in blocks if b.delay is not None]
    delays = {b.name: _delay_attr(design, b, shape, n) for b in delayed}
    dt = _continuous_step(delays, dt)
    steps = int(math.ceil(t_end_s / dt - 1e-9))
    every = 1 if record_dt is None else max(1, int(round(record_dt / dt)))
    _check_size(n, steps, steps // every + 1, f"the continuous step is {dt:.3g} s (the "
                "smallest positive delay, at most 0.1 ms): give a coarser record_dt, a "
                "shorter t_end_s, or fewer designs")
    reals = [realize_continuous(b, design, shape, n, derivative_tau_s) for b in blocks]
    exo = list(diagram.inputs)
    inst = {b.name: np.ones(n) for b in blocks}
    wcol = {}
    for j, b in enumerate(delayed):
        inst[b.name] = (delays[b.name] == 0).astype(float)
        wcol[b.name] = len(exo) + j
    signals = list(diagram.signals)
    net = _assemble(n, signals, blocks, reals, exo, inst, wcol)
    F, G0, G1 = _foh(net.A, net.B, dt)
    idx = {s: i for i, s in enumerate(signals)}
    rows = [idx[b.src] for b in delayed] + [idx[o] for o in outputs]
    Cr, Dr = net.C[:, rows, :], net.D[:, rows, :]
    nd, ne, N = len(delayed), len(exo), F.shape[1]
    v = Layout.of(exo=ne, delayed=nd)
    # Delay buffers: position of t - T in steps, split into whole steps and a fraction.
    mpos = np.stack([delays[b.name] / dt for b in delayed], axis=1) if nd else np.zeros((n, 0))
    mint = np.floor(mpos + 1e-9)
    frac = np.clip(mpos - mint, 0.0, 1.0)
    frac[frac < 1e-9] = 0.0
    mint = mint.astype(int)
    t = np.arange(steps + 1) * dt
    x0 = np.zeros((N, n))
    imp = _impulses(inputs, exo)
    if np.any(imp):
        # A Dirac on an input: x(0+) = B_u * area, valid if it feeds no signal we read.
        cols = np.nonzero(imp)[0]
        if np.any(np.abs(Dr[:, :, cols]) > 0):
            raise InputError("inputs", ", ".join(exo[c] for c in cols),
                             "an impulse only on inputs that reach the outputs and delay "
                             "buffers through dynamics (no direct feed-through)")
        x0 = np.einsum("nij,j->in", net.B[:, :, cols], imp[cols])
    return ContinuousPlan(
        t, dt, every, tuple(outputs), _batch_last(np.concatenate([F, G0, G1], axis=2)),
        _batch_last(np.concatenate([Cr, Dr], axis=2)), _input_values(inputs, exo, t, shape, n),
        x0, Layout.of(x=N, v0=v.size, v1=v.size), v, Layout.of(src=nd, out=len(outputs)),
        mint.T.copy(), frac.T.copy(), int(mint.max(initial=0)) + 3, delays, shape)


def run_continuous(plan: ContinuousPlan, bound: float) -> RunOutputs:
    """Step a :class:`ContinuousPlan` in time (compiled: :func:`_continuous_kernel`)."""
    p, z, v = plan, plan.z, plan.v
    n = p.H.shape[-1]
    nd = v["delayed"].stop - v["delayed"].start
    rec_t = np.full((p.steps // p.every + 1, len(p.outputs), n), np.nan)  # time first
    left = np.full(n, np.inf)

    def run(k: slice) -> None:
        own = (lambda a: np.ascontiguousarray(a[..., k])) if k != slice(0, n) else \
            np.ascontiguousarray
        inputs = p.inputs if p.inputs.shape[-1] == 1 else own(p.inputs)
        _continuous_kernel(own(p.H), own(p.CD), np.ascontiguousarray(inputs), own(p.x0),
                           own(p.whole).astype(np.int64), own(p.frac).astype(float),
                           p.ring_len, z["x"].stop, v["exo"].stop, nd, p.steps, p.every,
                           p.t_s, float(bound), rec_t[:, :, k], left[k])

    in_threads(run, n, min_per_thread=64)
    # (outputs, designs, time) as a view: a copy of a large batch's record costs a
    # quarter of the run
    rec = _fill_diverged(rec_t.transpose(1, 2, 0), left)
    delays = {k: d.reshape(p.shape) for k, d in p.delays_s.items()}
    info = {"dt_s": p.dt_s, "record_dt_s": p.dt_s * p.every,
            "requested_delays_s": delays, "effective_delays_s": delays}
    return RunOutputs(p.t_s[::p.every], {o: rec[j] for j, o in enumerate(p.outputs)}, left, info)


@njit(cache=True, nogil=True)
def _continuous_kernel(H, CD, inputs, x0, whole, frac, ring_len, nx, ne, nd, steps, every,
                       t, bound, rec_t, left):  # pragma: no cover - compiled
    """Every step: ``S = CD [x; v_i]`` gives the delayed blocks' sources (into the ring
    buffer) and the outputs; ``v`` holds the exogenous inputs and the buffers read
    ``whole`` steps back, interpolated by ``frac``; ``x <- H [x; v_i; v_{i+1}]``.  The
    batch is the innermost (contiguous) axis, so the products vectorize over designs.  A
    design whose first output leaves ``bound`` is recorded no further (``left``) and
    restarted from zero (its numbers no longer matter; zeros keep them finite).
    Compiled: thousands of steps of small products, where numpy's per-call overhead and
    temporaries would outweigh the arithmetic."""
    n, nv = H.shape[2], ne + nd
    nrow = CD.shape[0]
    zb = np.zeros((nx + 2 * nv, n))
    zb[:nx] = x0
    ring = np.zeros((ring_len, max(nd, 1), n))
    S = np.zeros((nrow, n))
    xn = np.zeros((nx, n))
    alive = np.ones(n, np.bool_)
    same = True   # every design with the same buffer positions: rows read at once
    for d in range(nd):
        for k in range(1, n):
            if whole[d, k] != whole[d, 0]:
                same = False
    _fill_inputs(zb, nx, inputs, 0, ne, nd, ring, whole, frac, same)
    cd_cols = _nonzero_columns(CD, nx + nv)
    h_cols = _nonzero_columns(H, nx + 2 * nv)
    for i in range(steps + 1):
        _product(CD, zb, cd_cols, S)
        for d in range(nd):
            for k in range(n):
                ring[i % ring_len, d, k] = S[d, k]
        for k in range(n):
            if alive[k] and not abs(S[nd, k]) <= bound:
                alive[k] = False
                left[k] = t[i]
                zb[:, k] = 0.0
                ring[:, :, k] = 0.0
        if i % every == 0:
            for o in range(nrow - nd):
                for k in range(n):
                    if alive[k]:
                        rec_t[i // every, o, k] = S[nd + o, k]
        if i == steps:
            break
        _fill_inputs(zb, nx + nv, inputs, i + 1, ne, nd, ring, whole, frac, same)
        _product(H, zb, h_cols, xn)
        for r in range(nx):
            for k in range(n):
                zb[r, k] = xn[r, k]
        for r in range(nx, nx + nv):
            for k in range(n):
                zb[r, k] = zb[r + nv, k]


@njit(cache=True)
def _nonzero_columns(M, ncol):  # pragma: no cover - compiled
    """Per row of ``M`` (rows, cols, batch), the columns non-zero for some design, padded
    with -1: the products skip the structural zeros of the block diagram."""
    cols = np.full((M.shape[0], ncol), -1, np.int64)
    for r in range(M.shape[0]):
        m = 0
        for j in range(ncol):
            for k in range(M.shape[2]):
                if M[r, j, k] != 0.0:
                    cols[r, m] = j
                    m += 1
                    break
    return cols


@njit(cache=True)
def _product(M, zb, cols, out):  # pragma: no cover - compiled
    """``out[r, k] = sum_j M[r, j, k] zb[j, k]`` over the non-zero columns ``cols[r]``
    (one matrix per design, batch last).  A batch of a few designs sums in a register
    (through memory, each term would wait for the last one's store); a larger one
    vectorizes over the batch."""
    n = M.shape[2]
    for r in range(M.shape[0]):
        if n < 4:
            for k in range(n):
                acc = 0.0
                for m in range(cols.shape[1]):
                    j = cols[r, m]
                    if j < 0:
                        break
                    acc += M[r, j, k] * zb[j, k]
                out[r, k] = acc
            continue
        for k in range(M.shape[2]):
            out[r, k] = 0.0
        for m in range(cols.shape[1]):
            j = cols[r, m]
            if j < 0:
                break
            for k in range(M.shape[2]):
                out[r, k] += M[r, j, k] * zb[j, k]


@njit(cache=True)
def _fill_inputs(zb, at, inputs, i, ne, nd, ring, whole, frac, same):  # pragma: no cover
    """``v`` of step ``i`` into ``zb[at:]``: exogenous inputs, then the delayed blocks'
    inputs read from the ring buffer (linear interpolation between whole steps); ``same``:
    every design reads the same slots."""
    n, L = zb.shape[1], ring.shape[0]
    for e in range(ne):
        if inputs.shape[2] == 1:
            zb[at + e] = inputs[i, e, 0]
        else:
            zb[at + e] = inputs[i, e]
    now, before = i % L, (i - 1) % L
    for d in range(nd):
        if same:
            ia, ib = (now - whole[d, 0]) % L, (before - whole[d, 0]) % L
            for k in range(n):
                a = ring[ia, d, k]
                zb[at + ne + d, k] = a + frac[d, k] * (ring[ib, d, k] - a)
            continue
        for k in range(n):
            ia, ib = now - whole[d, k], before - whole[d, k]   # whole < L: one wrap at most
            a = ring[ia + L if ia < 0 else ia, d, k]
            b = ring[ib + L if ib < 0 else ib, d, k]
            zb[at + ne + d, k] = a + frac[d, k] * (b - a)


def _fill_diverged(rec: np.ndarray, left: np.ndarray) -> np.ndarray:
    """After a design leaves the bounds its record is held at the last in-bound value
    (plots stay finite; ``left_bounds_s`` says where the data stops meaning anything)."""
    if not np.isfinite(left).any():
        return rec
    out = rec.copy()
    for j in range(out.shape[0]):
        r = out[j]
        bad = np.isnan(r)
        if bad.any():
            last = np.where(~bad, np.arange(r.shape[1]), 0)
            np.maximum.accumulate(last, axis=1, out=last)
            r[:] = np.take_along_axis(np.nan_to_num(r), last, axis=1)
    return out


# ----------------------------------------------------------------------------- sampled
def _rates(rates_hz, processes) -> dict[str, float]:
    if isinstance(rates_hz, Mapping):
        missing = [p for p in processes if p not in rates_hz]
        if missing:
            raise InputError("rates_hz", dict(rates_hz), "a rate for every process: "
                             + ", ".join(processes))
        rates = {p: float(rates_hz[p]) for p in processes}
    else:
        rates = {p: float(rates_hz) for p in processes}
    for p, r in rates.items():
        if not (math.isfinite(r) and r > 0):
            raise InputError(f"rate ({p})", r, "a finite rate > 0 [Hz]")
    return rates


def _ticks(rates: Mapping[str, float]) -> tuple[float, dict[str, int]]:
    """Base period [s] (fastest rate) and each process's period in base ticks."""
    base = max(rates.values())
    ticks = {}
    for p, r in rates.items():
        k = base / r
        if abs(k - round(k)) > 1e-9:
            raise InputError(f"rate ({p})", r,
                             f"an integer divisor of the fastest rate {base:g} Hz")
        ticks[p] = int(round(k))
    return 1.0 / base, ticks


@dataclass(frozen=True)
class _PlantNet:
    """The continuous plant: its network, the signals it injects and exposes."""

    net: _Net
    index: dict[str, int]
    actuation: list[str]
    exo: list[str]
    sensed: list[str]


def _plant_network(diagram: BlockDiagram, design: Any, shape: tuple[int, ...], n: int,
                   saturation: Mapping[str, float], quantization: Mapping[str, float],
                   friction: Friction | None) -> _PlantNet:
    """Plant network: injections = actuation signals, exogenous physical inputs, friction."""
    plant = [b for b in diagram.blocks if b.role == "plant"]
    ctrl = [b for b in diagram.blocks if b.role != "plant"]
    if not plant:
        raise ValueError(f"diagram {diagram.name!r} has no plant blocks")
    if any(b.delay is not None for b in plant):
        raise ValueError("sampled mode: delays on plant blocks are not supported")
    plant_sig = {b.dst for b in plant}
    ctrl_sig = {b.dst for b in ctrl}
    actuation = sorted({b.src for b in plant if b.src in ctrl_sig})
    for s in saturation:
        if s not in actuation:
            raise InputError("saturation", s, "an actuation signal: " + ", ".join(actuation))
    p_exo = sorted({b.src for b in plant if b.src in diagram.inputs})
    p_inject = actuation + p_exo + ([friction.signal] if friction else [])
    p_signals = sorted(plant_sig | set(p_inject))
    p_reals = [realize_continuous(b, design, shape, n) for b in plant]
    pnet = _assemble(n, p_signals, plant, p_reals, p_inject,
                     {b.name: np.ones(n) for b in plant}, {})
    sensed = sorted({b.src for b in ctrl if b.src in plant_sig})
    for s in quantization:
        if s not in sensed:
            raise InputError("quantization", s, "a sampled plant signal: " + ", ".join(sensed))
    return _PlantNet(pnet, {s: i for i, s in enumerate(p_signals)}, actuation, p_exo, sensed)


def buffer_samples(delay_s: Any, period_s: float) -> np.ndarray:
    """Whole samples ``n >= 0`` a delayed signal waits so that its effective delay
    ``T_s/2 + n T_s`` (zero-order hold plus buffer) is the shortest realizable one that is not
    shorter than ``delay_s``: ``n = max(ceil((T - T_s/2)/T_s), 0)``.

    A request within ``1e-9`` of a sample of a realizable delay counts as that delay, so
    that ``T = 1.5 ms`` at 1 kHz is one sample, not two, despite rounding in ``T``.

    >>> buffer_samples(np.array([0.0, 0.5e-3, 1e-3, 1.5e-3, 2.2e-3]), 1e-3).tolist()
    [0, 0, 1, 1, 2]
    """
    T = np.asarray(delay_s, float)
    return np.maximum(np.ceil((T - period_s / 2) / period_s - 1e-9), 0).astype(int)


def _buffers(delayed: Sequence[Block], design: Any, shape: tuple[int, ...], n: int,
             period: Mapping[str, float], ticks: Mapping[str, int]
             ) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Whole-sample buffer lengths [base ticks] and effective delays [s] of delayed blocks."""
    nbuf, eff = {}, {}
    for b in delayed:
        T = _delay_attr(design, b, shape, n)
        Ts = period[b.name]
        nb = buffer_samples(T, Ts)
        nbuf[b.name] = nb * ticks.get(b.process, 1)  # in base ticks
        eff[b.name] = (Ts / 2 + nb * Ts).reshape(shape)
    return nbuf, eff


@dataclass(frozen=True)
class _CtrlNets:
    """Controller networks, one per phase of the slowest process's period."""

    nets: list[_Net]
    hold_rows: list[list[tuple[np.ndarray, np.ndarray]]]
    index: dict[str, int]
    exo: list[str]
    delayed: list[Block]
    slow: list[Block]
    nbuf: dict[str, np.ndarray]
    eff: dict[str, np.ndarray]
    period: dict[str, float]


def _controller_networks(diagram: BlockDiagram, design: Any, shape: tuple[int, ...], n: int,
                         sensed: Sequence[str], Tb: float, ticks: Mapping[str, int],
                         buffered: Sequence[str] = ()) -> _CtrlNets:
    """Injections = sampled plant signals, exogenous inputs, delayed inputs (buffers), held
    outputs of slower processes.  ``buffered``: delayed blocks always read their buffer (no
    instantaneous path even for a zero-sample buffer; time-varying latency)."""
    ctrl = [b for b in diagram.blocks if b.role != "plant"]
    period = {b.name: Tb * ticks.get(b.process, 1) for b in ctrl}
    c_exo = sorted({b.src for b in ctrl if b.src in diagram.inputs})
    c_inject = list(sensed) + c_exo
    c_signals = sorted({b.dst for b in ctrl} | set(c_inject))
    cidx = {s: i for i, s in enumerate(c_signals)}
    delayed = [b for b in ctrl if b.delay is not None]
    nbuf, eff = _buffers(delayed, design, shape, n, period, ticks)
    inst = {b.name: np.ones(n) for b in ctrl}
    wcol = {}
    for j, b in enumerate(delayed):
        inst[b.name] = np.zeros(n) if b.name in buffered else \
            (nbuf[b.name] == 0).astype(float)
        wcol[b.name] = len(c_inject) + j
    slow = [b for b in ctrl if ticks.get(b.process, 1) > 1]
    hcol = {b.name: len(c_inject) + len(delayed) + j for j, b in enumerate(slow)}
    c_reals = [realize_tustin(b, design, shape, n, period[b.name]) for b in ctrl]
    lcm = math.lcm(*[ticks.get(b.process, 1) for b in ctrl]) if ctrl else 1
    nets = []
    for r in range(lcm):
        held = {b.name: hcol[b.name] for b in slow if r % ticks[b.process] != 0}
        nets.append(_assemble(n, c_signals, ctrl, c_reals, c_inject, inst, wcol, held,
                              nv=len(c_inject) + len(delayed) + len(slow)))

    # Held outputs of slow blocks, evaluated when they run: y_b = C_b x_b + D_b u_b.
    def block_out_rows(net: _Net, b: Block) -> tuple[np.ndarray, np.ndarray]:
        _A, _B, C, D = c_reals[ctrl.index(b)]
        z = inst[b.name]
        s = cidx[b.src]
        Cy = z[:, None] * D[:, None] * net.C[:, s, :]
        Cy[:, net.state_slices[b.name]] += C
        Dy = (z * D)[:, None] * net.D[:, s, :]
        if b.name in wcol:
            Dy[:, wcol[b.name]] += D * (1 - z)
        return Cy, Dy

    hold_rows = [[block_out_rows(net, b) for b in slow] for net in nets]
    return _CtrlNets(nets, hold_rows, cidx, c_exo, delayed, slow, nbuf, eff, period)


@dataclass(frozen=True)
class SampledPlan:
    """A diagram compiled for the sampled run loop (batch on the last axis).

    Packed vectors, each with a :class:`Layout`:

    * plant ``zp`` (``zp``): states ``x``, then the inputs at ``t`` (``act`` actuation,
      ``exo`` physical inputs, ``fric`` friction force) and at ``t + h`` (``next``);
      ``Hp = [F G0 G1]`` advances ``x`` by a (sub-)step ``h``; ``CDp`` gives the plant rows
      of layout ``prow`` (``sensed``, then recorded plant ``out``) from ``zp[upto fric]``;
    * controller ``zc`` (``zc``): states ``x``, sampled plant signals ``ys``, exogenous
      inputs ``uc``, delayed inputs ``w`` (buffers), held outputs of slow blocks ``held``;
      per phase ``r`` of the slowest period, ``ABc[r]`` updates ``x`` and ``CDc[r]`` gives
      the rows of layout ``crow`` (``src`` delayed sources, ``act``, recorded ``out``).
    """

    t_s: np.ndarray
    base_period_s: float
    substeps: int
    outputs: tuple[str, ...]
    order: tuple[str, ...]
    zp: Layout
    zc: Layout
    prow: Layout
    crow: Layout
    Hp: np.ndarray
    CDp: np.ndarray
    ABc: list[np.ndarray]
    CDc: list[np.ndarray]
    HOLD: list[list[np.ndarray]]
    slow_ticks: tuple[int, ...]
    plant_inputs: np.ndarray
    ctrl_inputs: np.ndarray
    x0: np.ndarray
    nbuf: np.ndarray
    limit: np.ndarray
    quantum: np.ndarray
    friction: Friction | None
    VEL: np.ndarray | None
    shape: tuple[int, ...]
    info: dict[str, Any]
    actuation: tuple[str, ...]
    links: tuple[str, ...]

    @property
    def steps(self) -> int:
        return self.t_s.size - 1

    @property
    def phases(self) -> int:
        return len(self.CDc)


def _friction_rows(pn: _PlantNet, friction: Friction | None) -> np.ndarray | None:
    """Batch-last rows giving the velocity of ``friction.velocity_of`` from ``[x; v]``."""
    if not friction:
        return None
    for s in (friction.signal, friction.velocity_of):
        if s not in pn.index:
            raise InputError("friction", s, "a plant signal")
    vrow = pn.index[friction.velocity_of]
    if np.any(pn.net.D[:, vrow, :] != 0):
        raise InputError("friction.velocity_of", friction.velocity_of,
                         "a plant signal without direct feed-through (a position)")
    C = pn.net.C[:, vrow]
    return _batch_last(np.concatenate([np.einsum("nk,nkj->nj", C, pn.net.A),
                                       np.einsum("nk,nkv->nv", C, pn.net.B)], axis=1))


def _sampled_layout(pn: _PlantNet, cn: _CtrlNets, n_plant: int, friction: Friction | None,
                    outputs: Sequence[str]) -> tuple[Any, ...]:
    """Layouts of the packed plant/controller vectors and of the rows read each tick."""
    for o in outputs:
        if o not in pn.index and o not in cn.index:
            raise InputError("outputs", o, "a plant or controller signal")
    rec_p = [o for o in outputs if o in pn.index]
    rec_c = [o for o in outputs if o not in pn.index]
    na, ne, nf = len(pn.actuation), len(pn.exo), 1 if friction else 0
    zp = Layout.of(x=n_plant, act=na, exo=ne, fric=nf, next=na + ne + nf)
    nd, Nc = len(cn.delayed), cn.nets[0].A.shape[1]
    zc = Layout.of(x=Nc, ys=len(pn.sensed), uc=len(cn.exo), w=nd, held=len(cn.slow))
    prows = [pn.index[s] for s in pn.sensed] + [pn.index[o] for o in rec_p]
    crows = [cn.index[b.src] for b in cn.delayed] + [cn.index[s] for s in pn.actuation] + \
        [cn.index[o] for o in rec_c]
    return (zp, zc, Layout.of(sensed=len(pn.sensed), out=len(rec_p)),
            Layout.of(src=nd, act=na, out=len(rec_c)), prows, crows, tuple(rec_p + rec_c))


def compile_sampled(diagram: BlockDiagram, design: Any, inputs: Mapping[str, Any],
                    t_end_s: float, outputs: Sequence[str], *,
                    rates_hz: Mapping[str, float] | float = 1000.0,
                    saturation: Mapping[str, float] | None = None,
                    quantization: Mapping[str, float] | None = None,
                    friction: Friction | None = None, friction_substeps: int = 10,
                    buffered: Sequence[str] = ()) -> SampledPlan:
    """Compile ``diagram`` for :func:`run_sampled` (see :func:`simulate`); ``buffered``
    names delayed blocks whose input always comes through their buffer (timing links)."""
    saturation, quantization = dict(saturation or {}), dict(quantization or {})
    shape = tuple(getattr(design, "shape", ()))
    n = int(np.prod(shape, dtype=int))
    ctrl = [b for b in diagram.blocks if b.role != "plant"]
    processes = sorted({b.process for b in ctrl if b.process is not None}) or ["embedded"]
    rates = _rates(rates_hz, processes)
    Tb, ticks = _ticks(rates)
    pn = _plant_network(diagram, design, shape, n, saturation, quantization, friction)
    cn = _controller_networks(diagram, design, shape, n, pn.sensed, Tb, ticks, buffered)
    nsub = max(1, int(friction_substeps)) if friction else 1
    h = Tb / nsub
    F, G0, G1 = _foh(pn.net.A, pn.net.B, h)
    VEL = _friction_rows(pn, friction)
    steps = int(math.ceil(t_end_s / Tb - 1e-9))
    _check_size(n, steps * nsub, steps + 1, "lower the rates, shorten t_end_s, or simulate "
                "fewer designs")
    t = np.arange(steps + 1) * Tb
    if np.any(_impulses(inputs, cn.exo)):
        raise InputError("inputs", "impulse", "impulses only on physical (plant) inputs")
    zp, zc, prow, crow, prows, crows, order = _sampled_layout(pn, cn, F.shape[1], friction,
                                                              outputs)
    na = len(pn.actuation)
    x0 = np.zeros((zp.size, n))
    imp = _impulses(inputs, pn.exo)
    if np.any(imp):
        cols = na + np.nonzero(imp)[0]
        x0[zp["x"]] = np.einsum("nij,j->in", pn.net.B[:, :, cols], imp[cols - na])
    requested = {b.name: _delay_attr(design, b, shape, n).reshape(shape) for b in cn.delayed}
    info = {"rates_hz": rates, "base_period_s": Tb, "requested_delays_s": requested,
            "effective_delays_s": cn.eff, "controller_inputs": tuple(cn.exo),
            "buffer_samples": {b: v.reshape(shape) for b, v in cn.nbuf.items()},
            "saturation": dict(saturation), "friction_step_s": h if friction else None}
    return SampledPlan(
        t, Tb, nsub, tuple(outputs), order, zp, zc, prow, crow,
        _batch_last(np.concatenate([F, G0, G1], axis=2)),
        _batch_last(np.concatenate([pn.net.C[:, prows], pn.net.D[:, prows]], axis=2)),
        [_batch_last(np.concatenate([nt.A, nt.B], axis=2)) for nt in cn.nets],
        [_batch_last(np.concatenate([nt.C[:, crows], nt.D[:, crows]], axis=2))
         for nt in cn.nets],
        [[_batch_last(np.concatenate([cy, dy], axis=1)) for cy, dy in hr]
         for hr in cn.hold_rows],
        tuple(ticks[b.process] for b in cn.slow),
        _input_values(inputs, pn.exo, np.arange(steps * nsub + 1) * h, shape, n),
        _input_values(inputs, cn.exo, t, shape, n), x0,
        np.stack([cn.nbuf[b.name] for b in cn.delayed]) if cn.delayed else
        np.zeros((0, n), int),
        np.array([saturation.get(s, np.inf) for s in pn.actuation])[:, None],
        np.array([quantization.get(s, 0.0) for s in pn.sensed])[:, None],
        friction, VEL, shape, info, tuple(pn.actuation), tuple(b.name for b in cn.delayed))


@dataclass
class _SampledState:
    """Mutable state of a sampled run (batch on the last axis)."""

    zp: np.ndarray
    zc: np.ndarray
    ring: np.ndarray
    act: np.ndarray
    fric: np.ndarray
    rec: np.ndarray
    left: np.ndarray
    alive: np.ndarray
    peak_act: np.ndarray
    sat_ticks: np.ndarray
    held: np.ndarray | None = None

    @classmethod
    def start(cls, plan: SampledPlan, ring_len: int) -> _SampledState:
        n = plan.x0.shape[1]
        na = plan.zp["act"].stop - plan.zp["act"].start
        nf = plan.zp["fric"].stop - plan.zp["fric"].start
        nd = plan.zc["w"].stop - plan.zc["w"].start
        return cls(plan.x0.copy(), np.zeros((plan.zc.size, n)), np.zeros((ring_len, nd, n)),
                   np.zeros((na, n)), np.zeros((nf, n)),
                   np.zeros((len(plan.outputs), n, plan.steps + 1)), np.full(n, np.inf),
                   np.ones(n, bool), np.zeros((na, n)), np.zeros(n, int))


def _check_schedule(plan: SampledPlan, timing: Mapping[str, np.ndarray]) -> dict[int, np.ndarray]:
    """Validate a per-link schedule: link -> source tick used at each tick ``(T, n)``."""
    n = plan.x0.shape[1]
    out = {}
    for name, sched in timing.items():
        if name not in plan.links:
            raise InputError("timing", name, "a delayed block: " + ", ".join(plan.links))
        sched = np.asarray(sched)
        if sched.shape != (plan.steps + 1, n):
            raise InputError(f"timing[{name}] shape", sched.shape, f"{(plan.steps + 1, n)}")
        k = np.arange(plan.steps + 1)[:, None]
        if np.any(sched > k) or np.any(np.diff(sched, axis=0) < 0):
            raise InputError(f"timing[{name}]", "schedule", "non-decreasing source ticks "
                             "no later than the tick that uses them")
        j = plan.links.index(name)
        col = plan.zc["w"].start + j
        src = plan.crow["src"].start + j
        if any(np.any(cd[src, col] != 0) for cd in plan.CDc):
            raise InputError("timing", name, "a delayed block whose source does not depend "
                             "instantly on its own output")
        out[j] = sched
    return out


def _oldest_arrival(sched: Mapping[int, np.ndarray] | None) -> int:
    """Largest age [ticks] of a message when it arrives (how long buffers must be)."""
    age = 0
    for s in (sched or {}).values():
        prev = np.vstack([np.full((1, s.shape[1]), -1), s[:-1]])
        k = np.arange(s.shape[0])[:, None]
        age = max(age, int(np.max(np.where(s > prev, k - s, 0), initial=0)))
    return age


def _read_fixed(plan: SampledPlan, st: _SampledState, k: int) -> np.ndarray:
    """Delayed inputs from whole-sample buffers: the source value ``nbuf`` ticks ago."""
    L, nd, n = st.ring.shape
    flat = st.ring.reshape(-1)
    return flat[((k - plan.nbuf) % L) * (nd * n) + np.arange(nd * n).reshape(nd, n)]


def _read_timed(plan: SampledPlan, st: _SampledState, k: int,
                sched: Mapping[int, np.ndarray]) -> np.ndarray:
    """Fixed buffers, except links with a schedule: the newest message that has arrived
    (its source tick), or the last value held when nothing new arrived."""
    w = _read_fixed(plan, st, k)
    L = st.ring.shape[0]
    cols = np.arange(st.ring.shape[2])
    for j, s in sched.items():
        src = s[k]
        new = src > (s[k - 1] if k else -1)
        st.held[j] = np.where(new, st.ring[src % L, j, cols], st.held[j])
        w[j] = st.held[j]
    return w


def _control(plan: SampledPlan, st: _SampledState, k: int, ys: np.ndarray,
             sched: Mapping[int, np.ndarray] | None) -> tuple[np.ndarray, np.ndarray]:
    """One controller tick: returns the controller rows and the (clipped) actuation."""
    zc, lay, r = st.zc, plan.zc, k % plan.phases
    L = st.ring.shape[0]
    zc[lay["ys"]] = ys
    zc[lay["uc"]] = plan.ctrl_inputs[k]
    nd = st.ring.shape[1]
    if sched:
        # sources first (they do not depend on the scheduled inputs), then what arrived
        st.ring[k % L] = np.einsum("rkn,kn->rn", plan.CDc[r], zc)[plan.crow["src"]]
        zc[lay["w"]] = _read_timed(plan, st, k, sched)
    elif nd:
        zc[lay["w"]] = _read_fixed(plan, st, k)
    Sc = np.einsum("rkn,kn->rn", plan.CDc[r], zc)
    if nd and not sched:
        # whole-sample buffers hold each source's value at this tick
        st.ring[k % L] = Sc[plan.crow["src"]]
    raw = Sc[plan.crow["act"]]
    new_act = np.clip(raw, -plan.limit, plan.limit)
    st.sat_ticks += np.any(np.abs(raw) > plan.limit, axis=0)
    h0 = lay["held"].start
    for j, tk in enumerate(plan.slow_ticks):
        if k % tk == 0:
            zc[h0 + j] = np.einsum("kn,kn->n", plan.HOLD[r][j], zc)
    zc[lay["x"]] = np.einsum("ijn,jn->in", plan.ABc[r], zc)
    return Sc, new_act


def _sense(plan: SampledPlan, st: _SampledState, k: int) -> np.ndarray:
    """Plant rows at tick ``k`` (actuation held from the previous tick)."""
    zp, lay = st.zp, plan.zp
    zp[lay["act"]] = st.act
    zp[lay["exo"]] = plan.plant_inputs[k * plan.substeps]
    zp[lay["fric"]] = st.fric
    return np.einsum("rkn,kn->rn", plan.CDp, zp[lay.upto("fric")])


def _quantize(plan: SampledPlan, ys: np.ndarray) -> np.ndarray:
    q = plan.quantum
    if not np.any(q > 0):
        return ys
    return np.where(q > 0, np.round(ys / np.where(q > 0, q, 1.0)) * q, ys)


def _advance_plant(plan: SampledPlan, st: _SampledState, k: int) -> None:
    """Integrate the plant over one base period (sub-steps with friction held)."""
    zp, lay, fr = st.zp, plan.zp, plan.friction
    nxt = zp[lay["next"]]
    na = lay["act"].stop - lay["act"].start
    ne = lay["exo"].stop - lay["exo"].start
    for sub in range(plan.substeps):
        i = k * plan.substeps + sub
        zp[lay["act"]] = st.act
        zp[lay["exo"]] = plan.plant_inputs[i]
        if fr:
            zp[lay["fric"]] = st.fric
            vel = np.einsum("kn,kn->n", plan.VEL, zp[lay.upto("fric")])
            st.fric = -(fr.coulomb * np.sign(vel) + fr.viscous * vel)[None, :]
            zp[lay["fric"]] = st.fric
        nxt[:] = zp[lay["act"].start:lay["fric"].stop]
        nxt[na:na + ne] = plan.plant_inputs[i + 1]
        zp[lay["x"]] = np.einsum("ijn,jn->in", plan.Hp, zp)


def _check_bounds(plan: SampledPlan, st: _SampledState, k: int, y: np.ndarray,
                  bound: float) -> None:
    """Out of bounds, or controller states running away (e.g. wind-up of a marginal mode)."""
    i_first = plan.order.index(plan.outputs[0])
    xc = st.zc[plan.zc["x"]]
    bad = st.alive & ~((np.abs(y[i_first]) <= bound)
                       & (np.max(np.abs(xc), axis=0, initial=0.0) <= 1e100))
    if bad.any():
        st.left[bad] = plan.t_s[k]
        st.alive &= ~bad
    st.rec[:, :, k] = np.where(st.alive, y, np.nan)


def run_sampled(plan: SampledPlan, bound: float,
                timing: Mapping[str, np.ndarray] | None = None) -> RunOutputs:
    """Step a :class:`SampledPlan` tick by tick.

    ``timing`` (optional) maps delayed blocks (``plan.links``, compiled with
    ``buffered=``) to the source tick each tick uses, shape ``(T, n)`` (-1: nothing has
    arrived yet); between arrivals the receiver holds the last value."""
    sched = _check_schedule(plan, timing) if timing else None
    ring_len = max(int(plan.nbuf.max(initial=0)), _oldest_arrival(sched)) + 2
    st = _SampledState.start(plan, ring_len)
    if sched:
        st.held = np.zeros(st.ring.shape[1:])
    for k in range(plan.steps + 1):
        Sp = _sense(plan, st, k)
        Sc, new_act = _control(plan, st, k, _quantize(plan, Sp[plan.prow["sensed"]]), sched)
        y = np.concatenate([Sp[plan.prow["out"]], Sc[plan.crow["out"]]], axis=0)
        _check_bounds(plan, st, k, y, bound)
        if k == plan.steps:
            break
        st.act = np.where(st.alive, new_act, 0.0)
        st.peak_act = np.maximum(st.peak_act, np.abs(st.act))
        _advance_plant(plan, st, k)
        if not st.alive.all():
            st.zp[:, ~st.alive] = 0.0
            st.zc[:, ~st.alive] = 0.0
            st.ring[:, :, ~st.alive] = 0.0
    return _sampled_result(plan, st)


UNIT_CIRCLE_TOL = 1e-6
"""Eigenvalues of the lifted map with ``| |lambda| - 1 | <= UNIT_CIRCLE_TOL`` make the count
unknown (-1): a growth or decay slower than about 1e-3 /s at 1 kHz is not decided."""


def lifted_map(plan: SampledPlan, designs: slice = slice(None)) -> tuple[np.ndarray, float]:
    """The sampled loop's state map over ``m`` base ticks, ``(n, S, S)``, and that period
    ``m T`` [s], with ``m`` a multiple of the slowest process's period and of the delay
    buffers' length.

    The state is everything a tick carries over: plant states, the held actuation,
    controller states, held outputs of slow blocks and the delay buffers.  Each column is
    the run loop itself (:func:`_sense`, :func:`_control`, :func:`_advance_plant`) started
    from one unit state with no input, no saturation and no quantization: the linear
    loop the simulation runs while no limit is reached.  Without friction only;
    ``designs`` selects part of the batch.
    """
    if plan.friction:
        raise InputError("friction", "given", "a loop without friction (it is not linear)")
    nbuf = plan.nbuf[:, designs]
    m = _lifted_ticks(plan, nbuf)
    n = nbuf.shape[1]
    S = _lifted_size(plan, nbuf)

    def rep(a):  # per-design arrays (batch last), one copy per unit state
        return np.repeat(a[..., designs], S, axis=-1)

    probe = replace(
        plan, t_s=np.arange(m + 1) * plan.base_period_s, Hp=rep(plan.Hp), CDp=rep(plan.CDp),
        ABc=[rep(a) for a in plan.ABc], CDc=[rep(a) for a in plan.CDc],
        HOLD=[[rep(a) for a in row] for row in plan.HOLD],
        plant_inputs=np.zeros((m * plan.substeps + 1,) + plan.plant_inputs.shape[1:2] + (1,)),
        ctrl_inputs=np.zeros((m + 1,) + plan.ctrl_inputs.shape[1:2] + (1,)),
        x0=np.zeros((plan.x0.shape[0], n * S)), nbuf=np.repeat(nbuf, S, axis=-1),
        limit=np.full_like(plan.limit, np.inf))
    st = _SampledState.start(probe, m)
    slots = _read_slots(plan, nbuf)
    unit = np.tile(np.eye(S), (1, n))       # column j: design j // S, unit state j % S
    _lifted_state(probe, st, slots, unit)
    for k in range(m):
        Sp = _sense(probe, st, k)
        st.act = _control(probe, st, k, Sp[probe.prow["sensed"]], None)[1]
        _advance_plant(probe, st, k)
    M = _lifted_state(probe, st, slots).reshape(S, n, S).transpose(1, 0, 2)
    return M, m * plan.base_period_s


def _lifted_ticks(plan: SampledPlan, nbuf: np.ndarray) -> int:
    """Ticks of the lifted map: a multiple of the slowest period covering the buffers."""
    L = int(nbuf.max(initial=0)) + 2
    return -(-L // plan.phases) * plan.phases


def _read_slots(plan: SampledPlan, nbuf: np.ndarray) -> np.ndarray:
    """Buffer slots ``(m, links)`` that are read before they are overwritten in a lifted
    period: slot ``s`` holds the value of tick ``s - m`` and link ``l`` reads it at tick
    ``s - m + nbuf``.  The others never matter (their columns of the map are zero), so the
    state leaves them out; the largest buffer of the batch decides, per link."""
    m = _lifted_ticks(plan, nbuf)
    return np.arange(m)[:, None] >= m - nbuf.max(axis=1, initial=0)[None, :]


def _lifted_size(plan: SampledPlan, nbuf: np.ndarray) -> int:
    """Length of the carried-over state (:func:`_lifted_state`)."""
    sizes = [plan.zp["x"], plan.zp["act"], plan.zc["x"], plan.zc["held"]]
    return sum(sl.stop - sl.start for sl in sizes) + int(_read_slots(plan, nbuf).sum())


def _lifted_state(plan: SampledPlan, st: _SampledState, slots: np.ndarray,
                  set_to: np.ndarray | None = None) -> np.ndarray:
    """The carried-over state (the buffers' ``slots`` only) packed as rows ``(S, columns)``;
    with ``set_to``, set it."""
    parts = [(st.zp, plan.zp["x"]), (st.act, slice(None)), (st.zc, plan.zc["x"]),
             (st.zc, plan.zc["held"])]
    if set_to is not None:
        i = 0
        for arr, sl in parts:
            k = arr[sl].shape[0]
            arr[sl] = set_to[i:i + k]
            i += k
        st.ring[slots] = set_to[i:]
    return np.concatenate([arr[sl] for arr, sl in parts] + [st.ring[slots]], axis=0)


def period_map(plan: SampledPlan, designs: slice = slice(None), inputs: bool = False
               ) -> tuple[np.ndarray, ...]:
    """The sampled loop as a discrete-time state space over one period of its slowest
    process (``plan.phases`` base ticks; one tick when every process runs at one rate).

    The state ``x`` (length ``S``) is what a tick carries over: plant states, the held
    actuation, controller states, held outputs of slow blocks, then per delayed block the
    source values of the last ``J`` ticks (``J`` its longest buffer in the batch; a shift
    register, newest first).  Each column is the run loop itself (:func:`_sense`,
    :func:`_control`, :func:`_advance_plant`) started from one unit state, with no
    saturation and no quantization, as in :func:`lifted_map`.  Returns ``(A, period_s)``
    with ``A`` of shape ``(n, S, S)``; with ``inputs`` (one-rate loops only) also the
    exogenous controller inputs (``plan.info["controller_inputs"]``) and the recorded
    outputs (``plan.order``) at the period's first tick: ``(A, B, C, D, period_s)`` with
    ``x+ = A x + B u``, ``y = C x + D u``.  Without friction only.
    """
    if plan.friction:
        raise InputError("friction", "given", "a loop without friction (it is not linear)")
    P = plan.phases
    if inputs and P != 1:
        raise InputError("rates_hz", plan.info["rates_hz"], "one rate for every process "
                         "(a multi-rate loop is periodic, not time-invariant)")
    nbuf = plan.nbuf[:, designs]
    n = nbuf.shape[1]
    J = nbuf.max(axis=1, initial=0)
    parts = [plan.zp["x"], plan.zp["act"], plan.zc["x"], plan.zc["held"]]
    S0 = sum(sl.stop - sl.start for sl in parts)
    S = S0 + int(J.sum())
    nu = (plan.zc["uc"].stop - plan.zc["uc"].start) if inputs else 0
    K = S + nu
    L = int(J.max(initial=0)) + P + 1

    def rep(a):  # per-design arrays (batch last), one copy per probe column
        return np.repeat(a[..., designs], K, axis=-1)

    cin = np.zeros((P + 1, plan.ctrl_inputs.shape[1], n * K))
    if nu:
        cin[0][:, (np.arange(n)[:, None] * K + S + np.arange(nu)).ravel()] = \
            np.tile(np.eye(nu), (1, n))
    probe = replace(
        plan, t_s=np.arange(P + 1) * plan.base_period_s, Hp=rep(plan.Hp), CDp=rep(plan.CDp),
        ABc=[rep(a) for a in plan.ABc], CDc=[rep(a) for a in plan.CDc],
        HOLD=[[rep(a) for a in row] for row in plan.HOLD],
        plant_inputs=np.zeros((P * plan.substeps + 1,) + plan.plant_inputs.shape[1:2] + (1,)),
        ctrl_inputs=cin, x0=np.zeros((plan.x0.shape[0], n * K)),
        nbuf=np.repeat(nbuf, K, axis=-1), limit=np.full_like(plan.limit, np.inf))
    st = _SampledState.start(probe, L)
    unit = np.tile(np.eye(S, K), (1, n))   # column j: design j // K, unit state j % K
    _shift_state(probe, st, J, 0, unit)
    y = None
    for k in range(P):
        Sp = _sense(probe, st, k)
        Sc, st.act = _control(probe, st, k, Sp[probe.prow["sensed"]], None)
        if k == 0:
            y = np.concatenate([Sp[probe.prow["out"]], Sc[probe.crow["out"]]], axis=0)
        _advance_plant(probe, st, k)
    M = _shift_state(probe, st, J, P).reshape(S, n, K).transpose(1, 0, 2)
    period = P * plan.base_period_s
    if not inputs:
        return M, period
    Y = y.reshape(-1, n, K).transpose(1, 0, 2)
    return M[..., :S], M[..., S:], Y[..., :S], Y[..., S:], period


def _shift_state(plan: SampledPlan, st: _SampledState, J: np.ndarray, k: int,
                 set_to: np.ndarray | None = None) -> np.ndarray:
    """The state of :func:`period_map` before tick ``k``, rows ``(S, columns)``: the
    carried-over vectors, then per link the source values of ticks ``k-1 .. k-J`` (ring
    slot ``(k - j) % L``); with ``set_to``, set it."""
    parts = [(st.zp, plan.zp["x"]), (st.act, slice(None)), (st.zc, plan.zc["x"]),
             (st.zc, plan.zc["held"])]
    L = st.ring.shape[0]
    regs = [(j, int(J[j])) for j in range(len(J))]
    if set_to is not None:
        i = 0
        for arr, sl in parts:
            m = arr[sl].shape[0]
            arr[sl] = set_to[i:i + m]
            i += m
        for link, depth in regs:
            for j in range(1, depth + 1):
                st.ring[(k - j) % L, link] = set_to[i]
                i += 1
    out = [arr[sl] for arr, sl in parts]
    out += [st.ring[(k - j) % L, link][None] for link, depth in regs
            for j in range(1, depth + 1)]
    return np.concatenate(out, axis=0)


def sampled_unstable_modes(plan: SampledPlan) -> np.ndarray:
    """Per design, the number of the lifted map's eigenvalues outside the unit circle
    (:func:`lifted_map`): 0 means the linear sampled loop is stable, ``k > 0`` that ``k``
    modes grow (however slowly), -1 undecided (an eigenvalue within
    :data:`UNIT_CIRCLE_TOL` of the circle, not finite, a loop with friction, or a batch
    whose maps would take more than a few seconds: designs x S^3 > 1e9).

    Continuous-time counterpart: the right half-plane of ``s = ln(lambda) / (m T)``.

    Examples
    --------
    >>> import numpy as np
    >>> from seactl.actuators import UT_SEA
    >>> from seactl.design import critically_damped_gains
    >>> from seactl.loops import SEADesign, Timing, sea_diagram
    >>> d = SEADesign(UT_SEA, critically_damped_gains(UT_SEA, np.array([30.05, 30.2])),
    ...               Timing.from_ms(0.5, 10.5, 0.5, 50, 100))
    >>> plan = compile_sampled(sea_diagram(True), d, {"q_des": Step(1.0)}, 0.1, ("q_j",))
    >>> sampled_unstable_modes(plan).tolist()
    [0, 2]
    """
    n = plan.x0.shape[1]
    S = _lifted_size(plan, plan.nbuf)
    if plan.friction or n * float(S) ** 3 > _LIFTED_WORK:
        return np.full(n, -1)
    chunk = max(1, _LIFTED_COLUMNS // S)
    return np.concatenate([_unstable_modes(plan, slice(i, i + chunk))
                           for i in range(0, n, chunk)])


_LIFTED_COLUMNS = 20_000
"""Designs x unit states probed at once (bounds the probe's memory to tens of MB)."""
_LIFTED_WORK = 1e9
"""Designs x S^3 above which the count is not attempted (-1): a bound on one call's
eigenvalue work (S = 45 for a 30 ms buffer at 1 kHz: 11,000 designs; S = 1000, a 1 s
buffer: none)."""


def _unstable_modes(plan: SampledPlan, designs: slice) -> np.ndarray:
    with np.errstate(all="ignore"):
        M = lifted_map(plan, designs)[0]
        ok = np.all(np.isfinite(M), axis=(1, 2))
        lam = np.abs(eigvals(np.where(ok[:, None, None], M, 0.0)))
    near = np.any(np.abs(lam - 1.0) <= UNIT_CIRCLE_TOL, axis=1) | ~ok
    return np.where(near, -1, np.sum(lam > 1.0, axis=1))


def run_controller(plan: SampledPlan, sensed: np.ndarray) -> np.ndarray:
    """Drive the plan's controller alone (open loop) with given sampled plant signals.

    ``sensed`` has shape ``(T, len(sensed signals), n)`` (``plan.steps + 1`` ticks, the
    signals in the order of ``plan.prow["sensed"]``); the exogenous controller inputs are
    those the plan was compiled with.  Returns the actuation each tick computes (after
    saturation), shape ``(T, len(plan.actuation), n)``: what :func:`run_sampled` applies
    from that tick on.  This is the reference of :mod:`seactl.export`."""
    sensed = np.asarray(sensed, float)
    ring_len = int(plan.nbuf.max(initial=0)) + 2
    st = _SampledState.start(plan, ring_len)
    out = np.empty((plan.steps + 1, len(plan.actuation), plan.x0.shape[1]))
    for k in range(plan.steps + 1):
        out[k] = _control(plan, st, k, sensed[k], None)[1]
    return out


def _sampled_result(plan: SampledPlan, st: _SampledState) -> RunOutputs:
    rec = {o: st.rec[plan.order.index(o)] for o in plan.outputs}
    peak_act = st.peak_act.T
    recs = _fill_diverged(np.stack([rec[o] for o in plan.outputs]), st.left)
    info = {k: v for k, v in plan.info.items() if k != "friction_step_s"}
    info["peak_actuation"] = {s: peak_act[:, j].reshape(plan.shape)
                              for j, s in enumerate(plan.actuation)}
    info["saturated_fraction"] = (st.sat_ticks / (plan.steps + 1)).reshape(plan.shape)
    info["friction_step_s"] = plan.info["friction_step_s"]
    return RunOutputs(plan.t_s, {o: recs[j] for j, o in enumerate(plan.outputs)}, st.left, info)


# ----------------------------------------------------------------------------- metrics
def step_metrics(t: np.ndarray, y: np.ndarray, stable: np.ndarray | None = None,
                 left_bounds_s: np.ndarray | None = None, reference: float = 1.0,
                 band: float = STEP_BAND) -> StepMetrics:
    """Metrics of step responses ``y`` (time on the last axis) to a step of ``reference``:
    final value (mean of the last 2 %), 10-90 % rise time (interpolated), overshoot [%],
    settling time (the sample after the last one outside ``band`` of the final value;
    inf if that is the last sample) and steady-state error.  One compiled pass per
    response (:func:`_step_kernel`): the record is time-major, so numpy's passes along
    the time axis of a batch would be strided.

    Examples
    --------
    >>> t = np.linspace(0, 5, 5001)
    >>> m = step_metrics(t, 1 - np.exp(-t * 10))
    >>> round(float(m.rise_time_s), 3), round(float(m.settling_time_s), 2)  # ln 9/10, ln 50/10
    (0.22, 0.39)
    """
    y = np.asarray(y, float)
    batch = y.shape[:-1]
    stable = np.ones(batch, bool) if stable is None else np.asarray(stable)
    left = np.full(batch, np.inf) if left_bounds_s is None else np.asarray(left_bounds_s)
    out = np.empty((5,) + batch)
    _step_kernel(np.asarray(t, float), y.reshape(-1, y.shape[-1]), float(reference),
                 float(band), max(1, y.shape[-1] // 50), out.reshape(5, -1))
    out = np.where(~stable, np.nan, out)
    return StepMetrics(*(out[k, ...] for k in range(5)), stable, left)


@njit(cache=True, error_model="numpy")
def _step_kernel(t, y, reference, band, tail, out):  # pragma: no cover - compiled
    """Rows of ``out``: rise, overshoot, settling time, steady-state error and final value
    of each row of ``y / reference`` (see :func:`step_metrics`; a NaN sample makes the
    overshoot NaN and is never outside the band, as numpy's max and comparisons do).
    Time in the outer loop: simulation records are time-major."""
    m, n = y.shape
    fin, peak, prev = np.zeros(m), np.full(m, -np.inf), np.zeros(m)
    nan, last = np.zeros(m, np.bool_), np.full(m, -1)
    cross = np.full((2, m), np.inf)
    for k in range(n - tail, n):
        for d in range(m):
            fin[d] += y[d, k] / reference / tail
    for k in range(n):
        for d in range(m):
            v = y[d, k] / reference
            r = v / fin[d]
            if r != r:
                nan[d] = True
            elif r > peak[d]:
                peak[d] = r
            if abs(v - fin[d]) > band * abs(fin[d]):
                last[d] = k
            for c, level in ((0, 0.1), (1, 0.9)):  # first reach, interpolated
                if cross[c, d] == np.inf and r >= level:
                    cross[c, d] = t[0] if k == 0 else \
                        t[k - 1] + (level - prev[d]) / (r - prev[d]) * (t[k] - t[k - 1])
            prev[d] = r
    for d in range(m):
        out[0, d] = cross[1, d] - cross[0, d]
        out[1, d] = np.nan if nan[d] else max(peak[d] - 1.0, 0.0) * 100.0
        out[2, d] = t[0] if last[d] < 0 else (np.inf if last[d] >= n - 1 else t[last[d] + 1])
        out[3, d], out[4, d] = 1.0 - fin[d], fin[d]


def impulse_metrics(t: np.ndarray, y: np.ndarray, stable: np.ndarray | None = None,
                    left_bounds_s: np.ndarray | None = None, band: float = RECOVERY_BAND
                    ) -> ImpulseMetrics:
    """Peak deviation from the initial value and recovery time (last exit from
    ``band`` x peak) of impulse responses ``y`` (time on the last axis).

    Examples
    --------
    >>> t = np.linspace(0, 2, 2001)
    >>> m = impulse_metrics(t, t * np.exp(-10 * t))
    >>> round(float(m.peak_time_s), 3), round(float(m.peak_deviation), 5)
    (0.1, 0.03679)
    """
    y = np.asarray(y, float)
    batch = y.shape[:-1]
    stable = np.ones(batch, bool) if stable is None else np.asarray(stable)
    left = np.full(batch, np.inf) if left_bounds_s is None else np.asarray(left_bounds_s)
    dev = np.abs(y - y[..., :1])
    ipk = np.argmax(dev, axis=-1)
    peak = np.take_along_axis(dev, ipk[..., None], -1)[..., 0]
    outside = dev > band * peak[..., None]
    last = y.shape[-1] - 1 - np.argmax(outside[..., ::-1], axis=-1)
    rec = np.where(last >= y.shape[-1] - 1, np.inf, t[np.minimum(last + 1, t.size - 1)])
    nan = ~stable
    f = lambda a: np.where(nan, np.nan, a)  # noqa: E731
    return ImpulseMetrics(f(peak), f(t[ipk]), f(rec), band, stable, left)


# ----------------------------------------------------------------------------- SEA helpers
@dataclass(frozen=True)
class SEAResponse:
    """A simulated SEA response with its metrics (``metrics`` is a :class:`StepMetrics`
    or :class:`ImpulseMetrics`); ``position`` is ``q_j`` (normalized to the step for steps,
    in rad for impulses) of shape ``batch + (T,)``; ``current`` is ``i_m`` [A]."""

    kind: str
    result: SimResult
    metrics: StepMetrics | ImpulseMetrics

    @property
    def t_s(self) -> np.ndarray:
        return self.result.t_s

    @property
    def position(self) -> np.ndarray:
        return self.result.outputs["q_j"]

    @property
    def current(self) -> np.ndarray:
        return self.result.outputs["i_m"]


