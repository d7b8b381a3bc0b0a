"""A robot's stability over its workspace: :class:`WorkspaceMap` (:func:`seactl.workspace_map`)."""

from __future__ import annotations

from dataclasses import dataclass
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

    @property
    def worst(self) -> int:
        """The index of the configuration with the smallest phase margin (an unstable
        one first)."""
        key = np.where(self.stable, self.phase_margin_deg, -np.inf)
        return int(np.argmin(key))

    def _columns(self) -> dict[str, Any]:
        cols = {f"{j}_rad": self.q0_rad[:, i] for i, j in enumerate(self.joints)}
        cols.update(stable=self.stable, phase_margin_deg=self.phase_margin_deg,
                    delay_margin_ms=self.delay_margin_ms)
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
