"""The tuning criterion and procedure of the base's architectures."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from seactl.base import progress
from seactl.base.result import Result, json_value, new_axes
from seactl.errors import InputError
from seactl.systems.mobile_base.kinematics import damping_to_joint
from seactl.systems.mobile_base.model import ARCHS, TRIKEY, MobileBaseParams
from seactl.systems.mobile_base.simulation import BaseTrajectories, Circle, simulate


# -------------------------------------------------------------------- criterion
@dataclass(frozen=True)
class Vibration:
    """The measurable "vibrates or oscillates" criterion of one batch of test runs.

    Over the final ``criterion_window`` seconds of a :func:`criterion_test` run,
    ``oscillation`` is the RMS of the chassis velocity (x, y and ``L * yaw rate``) after
    removing a straight-line fit per component (so a slow drift or creep does not count),
    and ``vibration`` the RMS of the wheel torque ripple (torques minus a straight-line fit
    per wheel, RMS over the wheels): the drivetrain buzz an operator hears and feels. The
    base *vibrates* when either exceeds its threshold (``criterion_oscillation_threshold``
    [m/s], ``criterion_vibration_threshold`` [N m]); the same test and thresholds are used
    for both architectures.
    """

    oscillation: np.ndarray
    vibration: np.ndarray
    fired: np.ndarray


def vibration_criterion(p: MobileBaseParams, result: BaseTrajectories) -> Vibration:
    """Evaluate :class:`Vibration` on a :func:`criterion_test` :class:`BaseTrajectories`."""
    m = result.t >= result.t[-1] - p.criterion_window + 1e-12
    t = result.t[m]
    v = result.v[m].copy()                                 # (n, B, 3)
    v[..., 2] *= p.wheel_distance
    tc = t - t.mean()

    def detrend(y: np.ndarray) -> np.ndarray:
        slope = np.einsum("n,nbc->bc", tc, y) / np.sum(tc**2)
        return y - y.mean(axis=0) - tc[:, None, None] * slope

    osc = np.sqrt(np.mean(np.sum(detrend(v) ** 2, axis=-1), axis=0))
    vib = np.sqrt(np.mean(detrend(result.tau[m]) ** 2, axis=(0, 2)))
    fired = (osc > p.criterion_oscillation_threshold) | (vib > p.criterion_vibration_threshold)
    return Vibration(osc, vib, fired)


@dataclass(frozen=True)
class Drive:
    """Constant-velocity reference ``x_d = (s t, s t, 0)`` used by the criterion test runs.

    Driving keeps the encoders counting, so quantization noise excites the loops all the
    time, as the floor and the operator's hand do on the real robot.
    """

    speed: float

    def __call__(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        t = np.asarray(t, float)
        z = np.zeros_like(t)
        s = self.speed
        return (np.stack([s * t, s * t, z], axis=-1),
                np.stack([z + s, z + s, z], axis=-1), np.zeros(t.shape + (3,)))


def criterion_test(p: MobileBaseParams, kx, dx, bq) -> Vibration:
    """Start at rest, drive at ``criterion_speed`` and evaluate the criterion, batched."""
    r = simulate(p, kx, dx, bq, reference=Drive(p.criterion_speed),
                 duration=p.criterion_duration)
    return vibration_criterion(p, r)


# -------------------------------------------------------------------- tuning procedure
@dataclass(frozen=True)
class Search:
    """One gain search: every candidate tried (sorted), whether it fired, and the limit.

    ``limit`` is the largest candidate below the first one that fired; ``reached`` is False
    when no candidate fired (the limit is then the top of the range, a lower bound), and
    ``limit`` is 0 when even the smallest candidate fired.
    """

    gains: np.ndarray
    fired: np.ndarray
    oscillation: np.ndarray
    vibration: np.ndarray
    limit: float
    reached: bool


def _limit(g: np.ndarray, fired: np.ndarray) -> tuple[float, float | None]:
    """(largest gain below the first firing one, first firing gain or None)."""
    idx = np.flatnonzero(fired)
    if idx.size == 0:
        return float(g[-1]), None
    i = idx[0]
    return (float(g[i - 1]) if i > 0 else 0.0), float(g[i])


def _search(p: MobileBaseParams, archs: tuple[str, ...], which: str, lo: float, hi: float,
            fixed: dict[str, np.ndarray], stage: progress.Stage) -> dict[str, Search]:
    """Coarse log grid then a linear refinement, all architectures in one batch each (two
    steps of ``stage``)."""
    def run(grids: dict[str, np.ndarray]) -> dict[str, Vibration]:
        kx, dx, bq, owner = [], [], [], []
        for a in grids:
            g = grids[a]
            d_op = fixed.get(a, 0.0)
            if which == "damping":
                kx.append(np.zeros_like(g))
                dx.append(g if a == "cosc" else np.zeros_like(g))
                bq.append(damping_to_joint(p, g) if a == "dosc" else np.zeros_like(g))
            else:
                kx.append(g)
                dx.append(np.full_like(g, d_op if a == "cosc" else 0.0))
                bq.append(np.full_like(g, float(damping_to_joint(p, d_op)) if a == "dosc"
                                       else 0.0))
            owner += [a] * g.size
        vib = criterion_test(p, np.concatenate(kx), np.concatenate(dx), np.concatenate(bq))
        owner_a = np.asarray(owner)
        return {a: Vibration(vib.oscillation[owner_a == a], vib.vibration[owner_a == a],
                             vib.fired[owner_a == a]) for a in grids}

    grids = {a: np.geomspace(lo, hi, p.grid_points) for a in archs}
    first = run(grids)
    stage.advance(item=f"{which}: coarse grid")
    refine: dict[str, np.ndarray] = {}
    for a in archs:
        ok, bad = _limit(grids[a], first[a].fired)
        if bad is not None and p.refine_points > 0:
            refine[a] = np.linspace(ok if ok > 0 else bad / 10, bad, p.refine_points + 2)[1:-1]
    second = run(refine) if refine else {}
    stage.advance(item=f"{which}: refined")
    out = {}
    for a in archs:
        g = grids[a]
        osc, vib, fired = first[a].oscillation, first[a].vibration, first[a].fired
        if a in second:
            g = np.r_[g, refine[a]]
            osc = np.r_[osc, second[a].oscillation]
            vib = np.r_[vib, second[a].vibration]
            fired = np.r_[fired, second[a].fired]
        order = np.argsort(g, kind="stable")
        g, osc, vib, fired = g[order], osc[order], vib[order], fired[order]
        lim, bad = _limit(g, fired)
        out[a] = Search(g, fired, osc, vib, lim, bad is not None)
    return out


@dataclass(frozen=True)
class ArchResult(Result):
    """The tuning procedure's outcome for one architecture (gains as acceleration gains).

    Parameters
    ----------
    arch : str
        ``"cosc"`` or ``"dosc"``.
    max_damping, max_joint_damping, max_kx, damping, kx : float
        The limits found and the gains used (see Attributes).
    damping_search, kx_search : Search
        The two searches.
    rms_position_m, rms_velocity_mps : float
        RMS tracking errors of the circle [m], [m/s].
    saturation : float
        Fraction of wheel-samples saturated while tracking.

    Attributes
    ----------
    arch : str
        ``"cosc"`` or ``"dosc"``.
    max_damping : float
        Damping limit, an acceleration gain [N s/(m kg)] (DOSC: the Cartesian
        equivalent of ``max_joint_damping``).
    max_joint_damping : float
        DOSC's joint damping limit [N m s/rad].
    max_kx : float
        Stiffness limit found with the damping at ``damping``, an acceleration gain
        [N/(m kg)].
    damping : float
        The damping used: safety factor x ``max_damping`` [N s/(m kg)].
    kx : float
        The stiffness tracking the circle: safety factor x ``max_kx`` [N/(m kg)].
    damping_search, kx_search : Search
        Every candidate of the two searches.
    rms_position_m, rms_velocity_mps : float
        RMS tracking errors of the circle [m], [m/s] (NaN without tracking).
    saturation : float
        Fraction of wheel-samples saturated while tracking.
    """

    arch: str
    max_damping: float
    max_joint_damping: float
    max_kx: float
    damping: float
    kx: float
    damping_search: Search
    kx_search: Search
    rms_position_m: float
    rms_velocity_mps: float
    saturation: float

    def records(self) -> list[dict[str, Any]]:
        """One flat row: the limits, gains and tracking errors.

        Returns
        -------
        list of dict
            ``arch`` and every scalar attribute.
        """
        return [{"arch": self.arch, **{k: json_value(getattr(self, k)) for k in ARCH_COLUMNS}}]

    def to_dict(self) -> dict[str, Any]:
        """The row of :meth:`records`.

        Returns
        -------
        dict
            ``arch`` and every scalar attribute.
        """
        return self.records()[0]

    def plot(self, ax: Any = None) -> Any:
        """The vibration measure of every candidate of both searches.

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
        for name, srch in (("damping", self.damping_search), ("kx", self.kx_search)):
            ax.loglog(srch.gains, np.maximum(srch.vibration, 1e-18), "o-", label=name)
            ax.axvline(srch.limit, ls=":", color="0.5")
        ax.set_xlabel("gain")
        ax.set_ylabel("vibration")
        ax.set_title(self.arch.upper())
        ax.legend(loc="best")
        return ax


ARCH_COLUMNS = ("max_damping", "max_joint_damping", "max_kx", "damping", "kx",
                "rms_position_m", "rms_velocity_mps", "saturation")
"""The scalar attributes of :class:`ArchResult` (its records' columns after ``arch``)."""


@dataclass(frozen=True)
class MobileBaseComparison(Result):
    """COSC versus DOSC: limits, tracking errors and the paper's ratios.

    Parameters
    ----------
    params : MobileBaseParams
        The base.
    results : dict
        Architecture -> :class:`ArchResult`.
    circle : Circle
        The tracked reference.
    track : BaseTrajectories, optional
        The circle-tracking simulation (one trajectory per architecture).

    Attributes
    ----------
    params : MobileBaseParams
        The base.
    results : dict
        Architecture -> :class:`ArchResult`.
    circle : Circle
        The tracked reference.
    track : BaseTrajectories or None
        The circle-tracking simulation.
    kx_ratio : float
        ``max_kx(DOSC) / max_kx(COSC)`` (dimensionless).
    position_rms_reduction_pct, velocity_rms_reduction_pct : float
        How much smaller DOSC's RMS errors are than COSC's [%].
    """

    params: MobileBaseParams
    results: dict[str, ArchResult]
    circle: Circle
    track: BaseTrajectories | None = field(default=None, repr=False)

    @property
    def kx_ratio(self) -> float:
        """``max_kx(DOSC) / max_kx(COSC)`` (inf when COSC's limit is 0)."""
        c, d = self.results["cosc"].max_kx, self.results["dosc"].max_kx
        return d / c if c > 0 else math.inf

    def _reduction(self, key: str) -> float:
        c = getattr(self.results["cosc"], key)
        d = getattr(self.results["dosc"], key)
        return 100.0 * (1.0 - d / c) if c > 0 else math.nan   # nan: COSC tracks exactly

    @property
    def position_rms_reduction_pct(self) -> float:
        """How much smaller DOSC's RMS position error is than COSC's [%]."""
        return self._reduction("rms_position_m")

    @property
    def velocity_rms_reduction_pct(self) -> float:
        """How much smaller DOSC's RMS velocity error is than COSC's [%]."""
        return self._reduction("rms_velocity_mps")

    def records(self) -> list[dict[str, Any]]:
        """One flat row per architecture.

        Returns
        -------
        list of dict
            As :meth:`ArchResult.records`.
        """
        return [row for r in self.results.values() for row in r.records()]

    def to_dict(self) -> dict[str, Any]:
        """The rows and the ratios as JSON-ready values.

        Returns
        -------
        dict
            ``base`` (the parameter set's name), ``archs`` (:meth:`records`),
            ``kx_ratio``, ``position_rms_reduction_pct``, ``velocity_rms_reduction_pct``
            (None where not computed).
        """
        both = {"cosc", "dosc"} <= set(self.results)
        return {"base": self.params.name, "archs": self.records(),
                "kx_ratio": json_value(self.kx_ratio) if both else None,
                "position_rms_reduction_pct":
                    json_value(self.position_rms_reduction_pct) if both else None,
                "velocity_rms_reduction_pct":
                    json_value(self.velocity_rms_reduction_pct) if both else None}

    def plot(self, ax: Any = None) -> Any:
        """The tracked circle per architecture (with tracking), else the stiffness limits.

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
        if self.track is None:
            ax.bar([a.upper() for a in self.results], [r.max_kx for r in self.results.values()])
            ax.set_ylabel("stiffness limit K_x [N/(m kg)]")
            return ax
        tr = self.track
        ax.plot(tr.x_d[:, 0], tr.x_d[:, 1], "k:", label="reference")
        for i, a in enumerate(self.results):
            ax.plot(tr.x[:, i, 0], tr.x[:, i, 1], label=a.upper())
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_aspect("equal")
        ax.legend(loc="best")
        return ax


def tune(p: MobileBaseParams = TRIKEY, archs: tuple[str, ...] = ARCHS, *, track: bool = True
         ) -> MobileBaseComparison:
    """Run the paper's tuning procedure, automated, for the given architectures.

    1. ``K_x = 0``: raise the damping (COSC: Cartesian on the central process; DOSC: joint
       damping on the embedded processes) until :func:`vibration_criterion` fires.
    2. Damping at ``safety_factor`` x its limit: raise ``K_x`` until the criterion fires.
    3. Track the circle with ``K_x`` at ``safety_factor`` x its limit; RMS errors after the
       ramp-in.

    Each search is a log-spaced grid (``grid_points``) refined linearly (``refine_points``)
    between the last quiet and the first firing candidate, every candidate of every
    architecture in one batched simulation (progress: :mod:`seactl.base.progress`).
    """
    for a in archs:
        if a not in ARCHS:
            raise InputError("arch", a, "cosc, dosc or both")
    archs = tuple(a for a in ARCHS if a in archs)
    with progress.stage("tuning the mobile base", total=5 if track else 4,
                        unit="batched simulations") as stage:
        return _tune(p, archs, track, stage)


def _tune(p: MobileBaseParams, archs: tuple[str, ...], track: bool, stage: progress.Stage
          ) -> MobileBaseComparison:
    sf = p.safety_factor
    dsearch = _search(p, archs, "damping", p.damping_min, p.damping_max, {}, stage)
    d_op = {a: sf * dsearch[a].limit for a in archs}
    ksearch = _search(p, archs, "kx", p.kx_min, p.kx_max, d_op, stage)
    circle = Circle(p.circle_radius, p.circle_period, p.circle_ramp)
    k_op = {a: sf * ksearch[a].limit for a in archs}
    res = None
    rms_p = {a: math.nan for a in archs}
    rms_v = dict(rms_p)
    sat = dict(rms_p)
    if track:
        kx = np.array([k_op[a] for a in archs])
        dx = np.array([d_op[a] if a == "cosc" else 0.0 for a in archs])
        bq = np.array([float(damping_to_joint(p, d_op[a])) if a == "dosc" else 0.0
                       for a in archs])
        res = simulate(p, kx, dx, bq, reference=circle, duration=p.circle_duration)
        stage.advance(item="circle tracking")
        ep, ev = res.rms(after=p.circle_ramp)
        for i, a in enumerate(archs):
            rms_p[a], rms_v[a], sat[a] = float(ep[i]), float(ev[i]), float(res.saturation[i])
    results = {a: ArchResult(a, dsearch[a].limit, float(damping_to_joint(p, dsearch[a].limit)),
                             ksearch[a].limit, d_op[a], k_op[a], dsearch[a], ksearch[a],
                             rms_p[a], rms_v[a], sat[a]) for a in archs}
    return MobileBaseComparison(p, results, circle, res)
