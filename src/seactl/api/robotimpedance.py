"""A robot's impedance at its task frame and its certified passivity:
:class:`TaskImpedanceResult`, :class:`RobotPassivityResult` (the methods
:meth:`~seactl.api.robot.Robot.task_impedance` and :meth:`~seactl.api.robot.Robot.passivity`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from seactl.base.result import Result, new_axes
from seactl.base.validate import finite_array
from seactl.errors import InputError

PASSIVITY_RANGE_HZ = (0.01, 1e4)
"""The default range of :meth:`~seactl.api.robot.Robot.passivity` [Hz], the SEA's."""


@dataclass(frozen=True, eq=False)
class RobotPassivityResult(Result):
    """Whether a robot's joint impedance is passive on a frequency range (certified).

    Parameters
    ----------
    f_range_hz, passive, proven, negative_f_hz, worst_f_hz, hermitian_min, unit : object
        As the attributes.

    Attributes
    ----------
    f_range_hz : tuple of float
        The range [Hz]; nothing is claimed outside it.
    passive : bool
        ``(Z_q + Z_q^H) / 2`` is proven positive definite on the whole range
        (:mod:`seactl.certify.hermitian`); then every task impedance is passive too.
    proven : bool
        The verdict is proven: passive by the certificate, not passive by a frequency
        with a negative eigenvalue.  False where neither could be shown (the matrix
        touching singular): such a robot is not ``passive``.
    negative_f_hz : float
        A frequency [Hz] where the Hermitian part has a negative eigenvalue (NaN if none).
    worst_f_hz : float
        The frequency [Hz] of the smallest eigenvalue on the scan's grid.
    hermitian_min : float
        That eigenvalue, in ``unit``.
    unit : str
        ``N m s/rad``.

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.robot("examples/robots/planar_2link.urdf", space="task", task="tool",
    ...              q0=[0.3, 0.8], fn_hz=14, delays_ms={"stiffness": 2})  # doctest: +SKIP
    >>> p = r.passivity()                                              # doctest: +SKIP
    >>> p.passive, p.proven                                            # doctest: +SKIP
    (True, True)
    """

    f_range_hz: tuple
    passive: bool
    proven: bool
    negative_f_hz: float
    worst_f_hz: float
    hermitian_min: float
    unit: str = "N m s/rad"

    def _columns(self) -> dict[str, Any]:
        return {"f_min_hz": np.asarray(self.f_range_hz[0]),
                "f_max_hz": np.asarray(self.f_range_hz[1]),
                "passive": np.asarray(self.passive), "proven": np.asarray(self.proven),
                "negative_f_hz": np.asarray(self.negative_f_hz),
                "worst_f_hz": np.asarray(self.worst_f_hz),
                "hermitian_min": np.asarray(self.hermitian_min)}

    def plot(self, ax: Any = None) -> Any:
        """The worst frequency and eigenvalue as a marked point.

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
        ax.semilogx([self.worst_f_hz], [self.hermitian_min], "o",
                    label="passive" if self.passive else "not passive")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_xlim(*self.f_range_hz)
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel(f"smallest eigenvalue of (Z + Z^H)/2 [{self.unit}]")
        ax.legend()
        return ax


@dataclass(frozen=True, eq=False)
class TaskImpedanceResult(Result):
    """The impedance matrix felt at the task frame (or the joints), joints' references
    fixed, the links' own inertia excluded (docs/robots.md).

    Parameters
    ----------
    f_hz, space, unit, z, basis, principal_values, directions : object
        As the attributes.
    hermitian_min, passive : object
        As the attributes.

    Attributes
    ----------
    f_hz : numpy.ndarray
        Frequencies [Hz], ``(F,)``.
    space : {"task", "joint"}
        ``"task"`` (translations of the task frame, N s/m) or ``"joint"`` (N m s/rad).
    unit : str
        The unit of ``z``, ``principal_values`` and ``hermitian_min``.
    z : numpy.ndarray
        ``(F, r, r)`` complex, in the basis ``basis`` (task) or the joints.
    basis : numpy.ndarray
        Task: the orthonormal basis ``(3, r)`` of the translations the joints make (unit
        vectors in the world-aligned frame; the identity in joint space).
    principal_values : numpy.ndarray
        ``(F, r)``, the singular values of ``z``, largest first.
    directions : numpy.ndarray
        ``(F, 3, r)`` complex unit vectors (``(F, n, r)`` in joint space): column ``i``
        is the velocity direction meeting ``principal_values[:, i]``.
    hermitian_min : numpy.ndarray
        ``(F,)``, the smallest eigenvalue of ``(z + z^H) / 2``.
    passive : bool
        The robot's certified joint passivity on ``[min f_hz, max f_hz]``
        (:class:`RobotPassivityResult`); it implies the task impedance's, and is the
        same verdict when the Jacobian has rank ``n``.

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.robot("examples/robots/planar_2link.urdf", space="task", task="tool",
    ...              q0=[0.3, 0.8], fn_hz=14)                          # doctest: +SKIP
    >>> z = r.task_impedance([1.0, 10.0])                              # doctest: +SKIP
    >>> z.unit, z.principal_values.shape                               # doctest: +SKIP
    ('N s/m', (2, 2))
    """

    f_hz: np.ndarray
    space: str
    unit: str
    z: np.ndarray
    basis: np.ndarray
    principal_values: np.ndarray
    directions: np.ndarray
    hermitian_min: np.ndarray
    passive: bool

    def _columns(self) -> dict[str, Any]:
        cols: dict[str, Any] = {"f_hz": self.f_hz}
        for i in range(self.principal_values.shape[1]):
            cols[f"principal_{i + 1}"] = self.principal_values[:, i]
        cols["hermitian_min"] = self.hermitian_min
        return cols

    def plot(self, ax: Any = None) -> Any:
        """The principal values against frequency (log-log).

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
        for i in range(self.principal_values.shape[1]):
            ax.loglog(self.f_hz, self.principal_values[:, i], label=f"principal {i + 1}")
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel(f"|Z| [{self.unit}]")
        ax.legend()
        return ax


def passivity(r: Any, f_range_hz: Any = PASSIVITY_RANGE_HZ,
              points_per_decade: int = 400) -> RobotPassivityResult:
    """:meth:`seactl.api.robot.Robot.passivity` (its documentation)."""
    from seactl.systems.robot.taskimpedance import (
        certify_passive,
        hermitian_min,
        joint_impedance,
        joint_quasi,
    )

    fr = finite_array("f_range_hz", f_range_hz, minimum=0.0, strict=True).reshape(-1)
    if fr.size != 2 or not fr[0] < fr[1]:
        raise InputError("f_range_hz", f_range_hz, "(lo, hi) with 0 < lo < hi [Hz]")
    lo, hi = float(fr[0]), float(fr[1])
    N, D = joint_quasi(r.diagram, r.design, r.n)
    c = certify_passive(N, D, (lo, hi), points_per_decade=points_per_decade)
    f = np.logspace(np.log10(lo), np.log10(hi),
                    max(2, int(np.ceil(np.log10(hi / lo) * points_per_decade)) + 1))
    lam = hermitian_min(joint_impedance(N, D, f))
    i = int(np.argmin(lam))
    return RobotPassivityResult((lo, hi), bool(c.positive), bool(c.proven),
                                c.negative_w / (2 * np.pi), float(f[i]), float(lam[i]))


def task_impedance(r: Any, f_hz: Any, space: str | None = None) -> TaskImpedanceResult:
    """:meth:`seactl.api.robot.Robot.task_impedance` (its documentation)."""
    from seactl.systems.robot.taskimpedance import (
        hermitian_min,
        principal,
        task_basis,
        task_impedance_matrix,
    )

    space = ("task" if r.body.jacobian is not None else "joint") if space is None else space
    if space not in ("task", "joint"):
        raise InputError("space", space, "task or joint")
    if space == "task" and r.body.jacobian is None:
        raise InputError("space", space, "joint (the robot has no task frame: sc.robot(..., "
                         "task=FRAME))")
    zq = r.impedance_matrix(f_hz)
    f = np.asarray(f_hz, float).reshape(-1)
    if space == "joint":
        z, basis, unit = zq, np.eye(r.n), "N m s/rad"
    else:
        basis = task_basis(r.body.jacobian)
        if basis.shape[1] == 0:
            raise InputError("task", r.body.frame, "a frame the joints move (J = 0)")
        z, unit = task_impedance_matrix(zq, r.body.jacobian, basis), "N s/m"
    sv, dirs = principal(z, basis)
    lo, hi = float(f.min()), float(f.max())
    rng = (lo, hi) if hi > lo else (lo / 1.001, hi * 1.001)
    return TaskImpedanceResult(f, space, unit, z, basis, sv, dirs, hermitian_min(z),
                               bool(passivity(r, rng).passive))
