"""A robot's stability over its workspace: :class:`WorkspaceMap` (:func:`seactl.workspace_map`)
and the largest task stiffness its certified verdict allows (:func:`max_task_stiffness`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.base.result import Result


@dataclass(frozen=True, eq=False)
class WorkspaceMap(Result):
    """One robot design linearized at each of a list of configurations.

    Attributes
    ----------
    joints : tuple of str
        The joint names.
    q0_rad : numpy.ndarray
        The configurations [rad], ``(m, n)``.
    stable : numpy.ndarray
        The certified verdict per configuration, ``(m,)``.
    phase_margin_deg : numpy.ndarray
        Phase margin at ``outer.j1`` [deg], ``(m,)``: one loop broken, the others
        closed; on a coupled robot it can look ample where the robot is unstable.
    delay_margin_ms : numpy.ndarray
        Delay margin at ``outer.j1`` [ms], ``(m,)``.
    mimo_phase_margin_deg : numpy.ndarray or None
        The generalized Nyquist phase margin of every stiffness channel broken at once
        (:meth:`seactl.api.robot.Robot.mimo_margins`, its ``phase_margin_deg``) [deg],
        ``(m,)``.
    mimo_delay_margin_ms : numpy.ndarray or None
        The extra latency of the central process that puts a root on the imaginary axis
        (:meth:`~seactl.api.robot.Robot.mimo_margins`, its ``delay_margin_s``) [ms]: 0
        where unstable, ``inf`` without crossover, ``(m,)``.
    max_task_stiffness_n_per_m : numpy.ndarray
        Task space: per configuration the largest translational task stiffness ``k_x``
        [N/m] the certified verdict calls stable, ``k_r = k_x r^2`` scaled with it
        (:func:`max_task_stiffness`: the top of the highest stable stretch); ``inf`` if
        stable at ``1e6`` times the default ``k_x``, 0 if unstable everywhere from
        ``1e-6`` to ``1e6`` times it.  NaN in joint space, ``(m,)``.
    passive : numpy.ndarray or None
        Per configuration the certified passivity of the joint impedance on 0.01 Hz to
        10 kHz (:meth:`seactl.api.robot.Robot.passivity`), ``(m,)``; None entries (an
        object array) where not computed: more than three joints.
    worst : int
        The index of the configuration with the smallest ``mimo_delay_margin_ms`` (an
        unstable one first): the least extra central latency the robot tolerates
        (without the MIMO margins: the smallest ``phase_margin_deg``).
    single_flip : numpy.ndarray
        Per configuration, whether the stiffness search saw the verdict flip once (stable
        below ``max_task_stiffness_n_per_m``, unstable above); False flags a map whose
        largest stiffness is not the whole story (:mod:`seactl.api.robotstiffness`).
        True in joint space, ``(m,)``.
    stiffness_intervals_n_per_m : tuple
        Per configuration, the stable stretches ``(low, high)`` of ``k_x`` [N/m] the
        search found (empty in joint space).
    t_s : numpy.ndarray or None
        The trajectory's times [s] (its ``t_s`` column), ``(m,)``.

    Examples
    --------
    >>> import seactl as sc
    >>> m = sc.workspace_map("examples/robots/planar_2link.urdf",
    ...                      [[0.3, 0.8], [0.0, 1.5]], fn_hz=14)   # doctest: +SKIP
    >>> m.stable.tolist(), m.worst                                  # doctest: +SKIP
    ([True, True], 0)
    """

    joints: tuple
    q0_rad: np.ndarray
    stable: np.ndarray
    phase_margin_deg: np.ndarray
    delay_margin_ms: np.ndarray
    max_task_stiffness_n_per_m: np.ndarray
    single_flip: np.ndarray | None = None
    stiffness_intervals_n_per_m: tuple = ()
    t_s: np.ndarray | None = None
    passive: Any = None
    mimo_phase_margin_deg: Any = None
    mimo_delay_margin_ms: Any = None

    @property
    def worst(self) -> int:
        """The index of the configuration with the smallest central delay margin
        (``mimo_delay_margin_ms``; an unstable one first)."""
        value = self.phase_margin_deg if self.mimo_delay_margin_ms is None else \
            self.mimo_delay_margin_ms
        return int(np.argmin(np.where(self.stable, value, -np.inf)))

    def _columns(self) -> dict[str, Any]:
        cols = {} if self.t_s is None else {"t_s": self.t_s}
        cols.update({f"{j}_rad": self.q0_rad[:, i] for i, j in enumerate(self.joints)})
        cols.update(stable=self.stable, phase_margin_deg=self.phase_margin_deg,
                    delay_margin_ms=self.delay_margin_ms,
                    max_task_stiffness_n_per_m=self.max_task_stiffness_n_per_m)
        if self.single_flip is not None:
            cols["single_flip"] = self.single_flip
        if self.passive is not None:
            cols["passive"] = self.passive
        if self.mimo_delay_margin_ms is not None:
            cols.update(mimo_phase_margin_deg=self.mimo_phase_margin_deg,
                        mimo_delay_margin_ms=self.mimo_delay_margin_ms)
        return cols

    def plot(self, ax: Any = None, quantity: str | None = None) -> Any:
        """The map's figure: a heat map over the two joints of a 2-joint grid, else the
        values along the trajectory (time, or sample index); unstable configurations and
        the worst one marked (:func:`seactl.api.robotmapplot.plot_workspace_map`).

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).
        quantity : str, optional
            The value drawn, a key of :data:`seactl.api.robotmapplot.QUANTITIES`
            (default: the largest task stiffness in task space, else the central delay
            margin ``mimo_delay_margin_ms``).

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        from seactl.api.robotmapplot import plot_workspace_map

        return plot_workspace_map(self, ax, quantity)


def max_task_stiffness(r: Any, rtol: float = 1e-3, span: float = 1e6) -> float:
    """The largest translational task stiffness ``k_x`` [N/m] at which the robot's certified
    verdict (``margins().stable``) is stable, ``k_r / k_x`` kept as in ``r``: the top of
    the highest stable stretch of a scan and bisection
    (:func:`seactl.api.robotstiffness.search_task_stiffness`, which also says whether the
    verdict flips once).

    Parameters
    ----------
    r : seactl.api.robot.Robot
        A task-space robot.
    rtol : float
        Relative tolerance of the result.
    span : float
        The search stays within ``[k_x / span, k_x span]``.

    Returns
    -------
    float
        ``k_x`` [N/m]; ``inf`` if stable at ``k_x span``, 0 if unstable everywhere
        scanned.
    """
    from seactl.api.robotstiffness import search_task_stiffness

    return search_task_stiffness(r, rtol, span).kx_max_n_per_m
