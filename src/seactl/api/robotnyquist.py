"""A robot's MIMO loop at the central process: :class:`MimoMarginsResult`
(:meth:`seactl.api.robot.Robot.mimo_margins`).

Every stiffness channel is broken at once (the signals ``qs.jN``), the damping and
torque loops closed: the ``n x n`` loop matrix of the central process, its characteristic
loci and generalized Nyquist margins (:mod:`seactl.analysis.characteristic_loci`).  Every
path of that loop runs through the central process's delay, so its delay margin is the
extra central latency that puts a root on the imaginary axis.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.base.result import Result, new_axes

DECADES = (-3.0, 2.0)
"""The grid's span around the robot's reference frequency, in decades."""
PER_DECADE = 160
"""Grid points per decade."""


@dataclass(frozen=True, eq=False)
class MimoMarginsResult(Result):
    """Generalized Nyquist margins of the loop broken at every stiffness channel.

    Parameters
    ----------
    joints, frequency_hz, characteristic_loci : tuple or ndarray
        As the attributes.
    phase_margin_deg, crossover_hz, crossovers_hz, crossover_margins_deg : float or ndarray
        As the attributes.
    gain_margin, phase_crossover_hz, delay_margin_s, delay_crossing_hz : float
        As the attributes.
    min_return_difference, min_return_difference_hz, stable : float or bool
        As the attributes.

    Attributes
    ----------
    joints : tuple of str
        The joint names (the channels, in order).
    frequency_hz : numpy.ndarray
        The grid [Hz], ``(F,)``.
    characteristic_loci : numpy.ndarray
        The eigenvalues of ``L(j 2 pi f)`` on the grid, ``(F, n)`` complex
        (dimensionless), each column continued across frequency.
    phase_margin_deg : float
        The smallest common phase rotation of every channel that puts a locus on -1 [deg]
        (wrapped to (-180, 180]; ``inf`` without crossover).
    crossover_hz : float
        The gain crossover of that margin [Hz] (NaN without one).
    crossovers_hz : numpy.ndarray
        Every gain crossover (a locus on the unit circle) [Hz].
    crossover_margins_deg : numpy.ndarray
        The phase margin at each of them [deg].
    gain_margin : float
        The common gain of every channel that puts a locus on -1, the one closest to 1
        (``inf`` without a phase crossover).
    gain_margin_db : float
        The same in dB.
    phase_crossover_hz : float
        Where [Hz] (NaN without one).
    delay_margin_s : float
        The extra central latency that puts a root on the imaginary axis [s]: 0 when the
        loop is unstable, ``inf`` without crossover (JSON: ``delay_margin_ms``).
    delay_crossing_hz : float
        The crossover where it does [Hz].
    min_return_difference : float
        The smallest singular value of ``I + L`` over frequency (dimensionless): every
        perturbation of ``L`` smaller in norm at every frequency keeps the verdict.
    min_return_difference_hz : float
        Where [Hz].
    stable : bool
        The certified verdict (:meth:`seactl.System.margins`).

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.robot("examples/robots/planar_2link.urdf", space="task", task="tool",
    ...              q0=[0.0, 1.5], fn_hz=14,
    ...              delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
    ...              filters_hz=(50, 100))                       # doctest: +SKIP
    >>> m = r.mimo_margins()                                      # doctest: +SKIP
    >>> round(m.phase_margin_deg, 2), round(m.crossover_hz, 2), m.stable   # doctest: +SKIP
    (50.13, 4.43, True)
    """

    joints: tuple
    frequency_hz: np.ndarray
    characteristic_loci: np.ndarray
    phase_margin_deg: float
    crossover_hz: float
    crossovers_hz: np.ndarray
    crossover_margins_deg: np.ndarray
    gain_margin: float
    phase_crossover_hz: float
    delay_margin_s: float
    delay_crossing_hz: float
    min_return_difference: float
    min_return_difference_hz: float
    stable: bool

    @property
    def gain_margin_db(self) -> float:
        return float(20 * np.log10(self.gain_margin))

    def _columns(self) -> dict[str, Any]:
        return {"phase_margin_deg": np.asarray(self.phase_margin_deg),
                "crossover_hz": np.asarray(self.crossover_hz),
                "gain_margin": np.asarray(self.gain_margin),
                "gain_margin_db": np.asarray(self.gain_margin_db),
                "phase_crossover_hz": np.asarray(self.phase_crossover_hz),
                "delay_margin_ms": np.asarray(1e3 * self.delay_margin_s),
                "delay_crossing_hz": np.asarray(self.delay_crossing_hz),
                "min_return_difference": np.asarray(self.min_return_difference),
                "min_return_difference_hz": np.asarray(self.min_return_difference_hz),
                "stable": np.asarray(self.stable)}

    def plot(self, ax: Any = None) -> Any:
        """The characteristic loci around -1, with the unit circle.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        ax = new_axes(ax)
        t = np.linspace(0, 2 * np.pi, 361)
        ax.plot(np.cos(t), np.sin(t), color="0.7", lw=0.8)
        for i in range(len(self.joints)):
            z = self.characteristic_loci[:, i]
            keep = np.abs(z) < 4
            ax.plot(np.where(keep, z.real, np.nan), np.where(keep, z.imag, np.nan),
                    label=f"locus {i + 1}")
        ax.plot([-1], [0], "r+", ms=10)
        ax.set_xlim(-2.5, 1.5)
        ax.set_ylim(-2.0, 2.0)
        ax.set_aspect("equal")
        ax.set_xlabel("Re lambda(L)")
        ax.set_ylabel("Im lambda(L)")
        ax.set_title(f"PM {self.phase_margin_deg:.3g} deg, delay margin "
                     f"{1e3 * self.delay_margin_s:.3g} ms")
        ax.legend(fontsize=8)
        return ax


def mimo_margins(r: Any) -> MimoMarginsResult:
    """The generalized Nyquist margins of robot ``r`` at its central process (the body of
    :meth:`seactl.api.robot.Robot.mimo_margins`)."""
    from seactl.analysis.characteristic_loci import loci_margins, loop_matrix
    from seactl.systems.robot.loops import BREAKS

    breaks = [f"{BREAKS['stiffness']}.j{j + 1}" for j in range(r.n)]
    returns = [f"{BREAKS['outer']}.j{j + 1}" for j in range(r.n)]
    w_ref = float(r.reference_frequency())
    count = int(round((DECADES[1] - DECADES[0]) * PER_DECADE)) + 1
    omega = w_ref * np.logspace(DECADES[0], DECADES[1], count)
    m = loci_margins(loop_matrix(r.diagram, r.design, returns, breaks), omega)
    stable = bool(r.margins().stable)
    hz = 1 / (2 * np.pi)
    return MimoMarginsResult(
        tuple(r.body.joints), omega * hz, m.loci, m.phase_margin_deg, m.crossover * hz,
        m.crossover_w * hz, m.crossover_pm_deg, m.gain_margin, m.phase_crossover * hz,
        m.delay_margin_s if stable else 0.0, m.delay_crossing * hz, m.min_return,
        m.min_return_w * hz, stable)
