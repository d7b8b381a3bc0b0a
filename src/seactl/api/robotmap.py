"""A robot's stability over its workspace: :class:`WorkspaceMap` (:func:`seactl.workspace_map`)
and the largest task stiffness its certified verdict allows (:func:`max_task_stiffness`)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from seactl.base.result import Result, new_axes


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
        Phase margin at ``outer.j1`` [deg], ``(m,)``.
    delay_margin_ms : numpy.ndarray
        Delay margin at ``outer.j1`` [ms], ``(m,)``.
    max_task_stiffness_n_per_m : numpy.ndarray
        Task space: per configuration the largest translational task stiffness ``k_x``
        [N/m] the certified verdict calls stable, ``k_r = k_x r^2`` scaled with it
        (:func:`max_task_stiffness`); ``inf`` if stable up to ``1e6`` times the default
        ``k_x``, 0 if unstable down to ``1e-6`` times it.  NaN in joint space, ``(m,)``.
    passive : numpy.ndarray or None
        Per configuration the certified passivity of the joint impedance on 0.01 Hz to
        10 kHz (:meth:`seactl.api.robot.Robot.passivity`), ``(m,)``.
    worst : int
        The index of the configuration with the smallest phase margin (an unstable one
        first).

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
    passive: Any = None

    @property
    def worst(self) -> int:
        """The index of the configuration with the smallest phase margin (an unstable
        one first)."""
        key = np.where(self.stable, self.phase_margin_deg, -np.inf)
        return int(np.argmin(key))

    def _columns(self) -> dict[str, Any]:
        cols = {f"{j}_rad": self.q0_rad[:, i] for i, j in enumerate(self.joints)}
        cols.update(stable=self.stable, phase_margin_deg=self.phase_margin_deg,
                    delay_margin_ms=self.delay_margin_ms,
                    max_task_stiffness_n_per_m=self.max_task_stiffness_n_per_m)
        if self.passive is not None:
            cols["passive"] = self.passive
        return cols

    def plot(self, ax: Any = None) -> Any:
        """Phase margin per configuration, unstable ones marked.

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
        idx = np.arange(len(self.stable))
        ax.plot(idx, self.phase_margin_deg, "o-", label="phase margin at outer.j1")
        bad = ~self.stable
        ax.plot(idx[bad], np.zeros(bad.sum()), "rx", label="unstable")
        ax.set_xlabel("configuration")
        ax.set_ylabel("phase margin [deg]")
        ax.legend()
        return ax


STIFFNESS_RTOL = 1e-3
"""The relative width of the last bracket of :func:`max_task_stiffness`."""


def _scaled(r: Any, factor: float) -> Any:
    """The robot with its task stiffness ``K_x`` times ``factor`` (``J^T K_x J`` is linear
    in ``K_x``)."""
    kx, kr = r.task_stiffness
    return replace(r, stiffness=r.stiffness * factor, task_stiffness=(kx * factor, kr * factor))


def max_task_stiffness(r: Any, rtol: float = STIFFNESS_RTOL, span: float = 1e6) -> float:
    """The largest translational task stiffness ``k_x`` [N/m] at which the robot's certified
    verdict (``margins().stable``) is stable, ``k_r / k_x`` kept as in ``r``.

    From ``r``'s own ``k_x`` the bracket grows (or shrinks) by factors of 4 until the
    verdict changes, then geometric bisection narrows it to ``hi / lo <= 1 + rtol``; the
    stable end ``lo`` is returned.  The verdict is assumed to change once in the bracket
    (it does on the planar arms: stable below, unstable above).

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
        ``k_x`` [N/m]; ``inf`` if stable up to ``k_x span``, 0 if unstable down to
        ``k_x / span``.
    """
    def stable(f: float) -> bool:
        return bool(_scaled(r, f).margins().stable)

    lo = hi = 1.0
    if stable(1.0):
        while stable(hi * 4.0):
            hi *= 4.0
            if hi > span:
                return float("inf")
        lo, hi = hi, hi * 4.0
    else:
        while not stable(lo / 4.0):
            lo /= 4.0
            if lo < 1.0 / span:
                return 0.0
        lo, hi = lo / 4.0, lo
    while hi / lo > 1.0 + rtol:
        mid = float(np.sqrt(lo * hi))
        lo, hi = (mid, hi) if stable(mid) else (lo, mid)
    return lo * float(r.task_stiffness[0])
