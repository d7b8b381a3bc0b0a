"""Public entry points beyond the SEA batch: rigid actuator, latency maps, placement,
sweeps and the mobile base.

Each function is a thin, documented front to the module that does the work
(:mod:`seactl.rigid`, :mod:`seactl.latency`, :mod:`seactl.placement`,
:mod:`seactl.sweep`, :mod:`seactl.mobile_base`), with the units in its keyword names
(milliseconds for delays, hertz for frequencies) and results that have ``to_dict()``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from ._results import (
    ImpedanceResult,
    MarginsResult,
    ResponseResult,
    _axes,
    json_array,
    json_value,
)
from ._validate import finite_array
from .api import check_batch, delays_from_ms, resolve_actuator
from .errors import InputError
from .runtime import run_doc

KINDS = ("sea", "rigid")


def _jsonify(obj: Any) -> Any:
    """Dataclass dicts, tuples and arrays to JSON-ready values."""
    if isinstance(obj, dict):
        return {str(k): _jsonify(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonify(v) for v in obj]
    if isinstance(obj, (str, type(None))):
        return obj
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, np.ndarray):
        return json_array(obj) if obj.dtype.kind in "biuf" else obj.tolist()
    if isinstance(obj, (bool, int, float, np.generic)):
        return json_value(obj)
    return str(obj)


# ------------------------------------------------------------------ rigid actuator
@dataclass(frozen=True, eq=False)
class RigidBatch:
    """A batch of critically-damped rigid-actuator designs (build with :func:`rigid`).

    Parameters
    ----------
    rigid : seactl.rigid.RigidDesign
        The underlying batch (actuator, gains ``K`` [N/m], ``B`` [N s/m], delays [s]).
    fn_hz : numpy.ndarray
        Natural frequencies [Hz] the gains were designed for.

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.rigid([8, 12], delays_ms=(15, 1))
    >>> r.shape, r.margins().stable.tolist()
    ((2,), [True, True])
    """

    default_step: ClassVar[float] = 0.004
    step_unit: ClassVar[str] = "m"
    rigid: Any
    fn_hz: np.ndarray

    @property
    def shape(self) -> tuple[int, ...]:
        """The batch shape."""
        return self.rigid.shape

    def __getitem__(self, idx: Any) -> RigidBatch:
        from dataclasses import replace

        from .rigid import RigidGains

        shape = self.shape

        def pick(x: Any) -> Any:
            return None if x is None else np.broadcast_to(np.asarray(x, float), shape)[idx]

        if np.size(pick(self.fn_hz)) == 0:
            raise InputError("index", idx, "a selection of at least one design")
        g = self.rigid.gains
        sub = replace(self.rigid, gains=RigidGains(pick(g.K), pick(g.B)),
                      T_s=pick(self.rigid.T_s), T_d=pick(self.rigid.T_d),
                      f_v=pick(self.rigid.f_v))
        return RigidBatch(sub, pick(self.fn_hz))

    def margins(self, rate_hz: Any = None) -> Any:
        """Whole-loop phase, gain and delay margins and Nyquist stability.

        Parameters
        ----------
        rate_hz : float or dict, optional
            ``None`` (default): the continuous loop.  A rate [Hz] (both processes) or
            ``{"embedded": ..., "high-level": ...}``: the sampled-data loop that
            ``step(mode="sampled")`` runs, with a certified verdict and margins from its
            discrete frequency response (:func:`seactl.sampled.sampled_margins`).

        Returns
        -------
        MarginsResult or SampledMarginsResult
            Arrays of the batch shape, labelled by ``fn_hz``, ``K`` and ``B``.

        Examples
        --------
        >>> import seactl as sc
        >>> round(float(sc.rigid(8, delays_ms=(1.5, 1.5)).margins().phase_margin_deg), 1)
        52.6
        """
        r = self.rigid
        labels = {"fn_hz": self.fn_hz, "K": r.K, "B": r.B}
        if rate_hz is not None:
            from ._results import SampledMarginsResult
            from .rigid import RIGID_DIAGRAM
            from .sampled import sampled_margins

            return SampledMarginsResult(sampled_margins(RIGID_DIAGRAM, r, "x_sens", rate_hz,
                                                        r.wn), labels)
        from .rigid import rigid_margins

        return MarginsResult(rigid_margins(r), labels)

    def roots(self, count: int = 6) -> Any:
        """Rightmost roots of the closed loop (exact delays), per design.

        Parameters
        ----------
        count : int
            Roots per design (a conjugate pair counts once).

        Returns
        -------
        RootsResult
            ``roots`` [rad/s], ``spectral_abscissa`` [1/s], labelled by ``fn_hz``.

        Examples
        --------
        >>> import seactl as sc
        >>> r = sc.rigid(8, delays_ms=(1.5, 1.5)).roots(count=1)
        >>> bool(r.spectral_abscissa < 0)
        True
        """
        from ._results import RootsResult
        from .limits import check_roots
        from .rigid import RIGID_DIAGRAM
        from .roots import characteristic_roots

        r = self.rigid
        check_roots(int(np.prod(self.shape)), count,
                    any(np.any(np.asarray(x) > 0) for x in (r.T_s, r.T_d)))
        return RootsResult(characteristic_roots(RIGID_DIAGRAM, self.rigid, count=count),
                           {"fn_hz": self.fn_hz})

    def delay_margins(self) -> Any:
        """Extra latency the stiffness loop alone, the damping loop alone, and both tolerate.

        Returns
        -------
        seactl.latency.LoopDelayMargins
            ``stiffness_s``, ``damping_s``, ``overall_s`` [s] and their ``ratio``.

        Examples
        --------
        >>> import seactl as sc
        >>> dm = sc.rigid(8, delays_ms=(1.5, 1.5)).delay_margins()
        >>> round(float(dm.stiffness_s) * 1e3, 2), round(float(dm.damping_s) * 1e3, 2)
        (55.47, 9.55)
        """
        from .latency import rigid_model

        model = rigid_model(self.rigid.actuator)
        return model.delay_margins(self.rigid)

    def labels(self) -> list[str]:
        """One legend label per design (flattened batch).

        Returns
        -------
        list of str
            ``"f_n=8 Hz, T_s=1.5 ms, T_d=1.5 ms"`` style labels.

        Examples
        --------
        >>> import seactl as sc
        >>> sc.rigid(8, delays_ms=(1.5, 1.5)).labels()
        ['f_n=8 Hz, T_s=1.5 ms, T_d=1.5 ms']
        """
        r = self.rigid
        cols = [np.ravel(np.broadcast_to(x, self.shape)) for x in (self.fn_hz, r.T_s, r.T_d)]
        return [f"f_n={f:g} Hz, T_s={ts * 1e3:g} ms, T_d={td * 1e3:g} ms"
                for f, ts, td in zip(*cols)]

    def step(self, *, t_end_s: float = 1.0, mode: str = "continuous", rate_hz: float = 1000.0,
             saturate: bool = False) -> ResponseResult:
        """Response of the position ``x`` to a unit step of ``x_des`` (normalized).

        Parameters
        ----------
        t_end_s : float
            Simulated time [s].
        mode : {"continuous", "sampled"}
            Exact continuous-time delays, or both loops sampled at ``rate_hz`` with
            whole-sample delay buffers (Tustin velocity filter, zero-order hold).
        rate_hz : float
            Controller rate of the sampled mode [Hz].
        saturate : bool
            Sampled mode: clip the force at ``beta * max_current`` (the response is then
            that of a 1 m step; use :func:`seactl.rigid.step_experiment` for the paper's
            4 mm step).

        Returns
        -------
        ResponseResult
            ``t_s``, ``position`` (``x / step``), ``current`` (force command / ``beta``
            [A]) and ``metrics`` (rise, overshoot, settling).

        Examples
        --------
        >>> import seactl as sc
        >>> r = sc.rigid([8, 12], delays_ms=(1.5, 1.5)).step(t_end_s=1.0)
        >>> r.metrics.stable.tolist(), bool(abs(r.position[0, -1] - 1) < 1e-3)
        ([True, True], True)
        """
        from .margins import closed_loop_right_roots
        from .rigid import RIGID_DIAGRAM
        from .simulate import SEAResponse, SimResult, Step, simulate, step_metrics
        from .timing import MODEL_LINKS

        r = self.rigid
        limit = r.actuator.max_force if (saturate and mode == "sampled") else None
        res = simulate(RIGID_DIAGRAM, r, {"x_des": Step(1.0)}, t_end_s, mode=mode,
                       rates_hz=rate_hz, outputs=("x", "F_des"),
                       saturation={"F_des": limit} if limit else None)
        if mode == "sampled":   # the simulated loop's certified verdict beside it
            from .sampled import sampled_roots

            sr = sampled_roots(RIGID_DIAGRAM, r, rate_hz)
            res.info.update(sampled_verdict=sr.verdict, sampled_unstable_modes=sr.unstable_modes,
                            sampled_rate=sr.rate_label, unstable_modes=np.where(
                                sr.unstable_modes >= 0, sr.unstable_modes,
                                res.info.get("unstable_modes", -1)))
        force = res.outputs["F_des"] if limit is None else np.clip(res.outputs["F_des"],
                                                                   -limit, limit)
        res = SimResult(res.mode, res.t_s, {"q_j": res.outputs["x"],
                                            "i_m": force / r.actuator.beta},
                        res.stable, res.left_bounds_s, res.bound, res.info)
        met = step_metrics(res.t_s, res.outputs["q_j"], res.stable, res.left_bounds_s)
        return ResponseResult(SEAResponse("step", res, met), self.labels(),
                              lambda: closed_loop_right_roots(RIGID_DIAGRAM, r, r.wn),
                              links=MODEL_LINKS["rigid"])

    def impedance(self, f_hz: Any) -> ImpedanceResult:
        """Impedance ``Z(j 2 pi f) = F_ext / (j 2 pi f x)`` [N s/m] felt at the output.

        The inverse of the closed-loop compliance ``x / F_ext`` divided by ``s``, from
        :data:`seactl.rigid.RIGID_DIAGRAM` with exact delays; it includes the mass.

        Parameters
        ----------
        f_hz : array_like
            Frequencies [Hz] > 0 (the last axis of the result).

        Returns
        -------
        ImpedanceResult
            ``z`` of shape ``shape + (len(f_hz),)`` [N s/m], ``magnitude``, ``stiffness``...

        Examples
        --------
        >>> import seactl as sc
        >>> r = sc.rigid(8, delays_ms=(1.5, 1.5))
        >>> z = r.impedance([1e-4])               # s Z -> K at low frequency
        >>> round(float(z.stiffness[..., 0].real) / float(r.rigid.K), 6)
        1.0
        """
        from .impedance import ImpedanceResponse
        from .rigid import rigid_compliance

        f = finite_array("f_hz [Hz]", f_hz, minimum=0.0, strict=True).reshape(-1)
        s = 2j * np.pi * f
        z = 1.0 / (s * rigid_compliance()(self.rigid, s))
        return ImpedanceResult(ImpedanceResponse("block-diagram", f, z, "linear", True),
                               self.labels())

    def export(self, out: Any, *, lang: Any = ("c", "python", "json"),
               rates_hz: Any = 1000.0, saturate: bool = True, verify: bool = False) -> Any:
        """Write the discrete controller of each process as C99, Python and JSON.

        Stiffness (``K``, with the reference) on ``high-level``, damping (filtered velocity)
        on ``embedded``, which sums them into the force command (docs/export.md).

        Parameters
        ----------
        out : str or path
            A new or empty directory (or one an earlier export wrote).
        lang : sequence of str or str
            Any of ``"c"``, ``"python"``, ``"json"``.
        rates_hz : float or mapping
            Rate of every process [Hz], or per process (integer divisors of the fastest).
        saturate : bool
            Clip the force command at ``actuator.max_force``.
        verify : bool
            Compile and run the C and the Python against seactl's own sampled controller
            (a 4 mm step response and random signals) before writing.

        Returns
        -------
        seactl.export.ExportResult
            ``files``, ``controllers`` and ``verification`` (``max_error``, ``compiler``).

        Examples
        --------
        >>> import tempfile
        >>> import seactl as sc
        >>> res = sc.rigid(8, delays_ms=(1.5, 1.5)).export(tempfile.mkdtemp(), lang="json")
        >>> [p.name for p in res.controllers.processes]
        ['high-level', 'embedded']
        """

        from .export import export_design
        from .rigid import RIGID_DIAGRAM

        return export_design(RIGID_DIAGRAM, self.rigid, out, languages=lang,
                             rates_hz=rates_hz, saturation=self._force_limit(saturate),
                             verify_export=verify, step=0.004)

    def _force_limit(self, saturate: bool) -> dict[str, float]:
        """The force limit of ``export`` and ``run`` (``inf``: none)."""
        import math

        return {"F_des": self.rigid.actuator.max_force if saturate else math.inf}

    @run_doc
    def run(self, *, duration_s: float = 2.0, rates_hz: Any = 1000.0, step_m: float = 0.004,
            transport: str = "zenoh", extra_latency_s: float = 0.0, loss: float = 0.0,
            seed: int = 0, saturate: bool = True) -> Any:
        """Run the exported controllers as three OS processes on loopback.

        As :meth:`seactl.Design.run`: a plant process (the mass integrated exactly), the
        exported ``embedded`` (damping) and ``high-level`` (stiffness) controllers over
        Zenoh or UDP on 127.0.0.1, and the comparison with the sampled simulation.

        Parameters
        ----------
        duration_s : float
            Run time [s], 0.1 to 60.
        rates_hz : float or mapping
            As :meth:`export` (at most 5000 Hz).
        step_m : float
            Step of ``x_des`` [m].
        {link_parameters}
        saturate : bool
            Clip the force command at ``actuator.max_force``.

        Returns
        -------
        seactl.runtime.RunResult
            ``summary`` (latency per link with histograms, ``replay_max_diff``, ...), the
            responses and the latency samples.

        Examples
        --------
        >>> import seactl as sc
        >>> res = sc.rigid(8, delays_ms=(1.5, 1.5)).run(duration_s=0.2)  # doctest: +SKIP
        >>> res.summary["links"]["high-level->embedded"]["count"]         # doctest: +SKIP
        200
        """

        from .rigid import RIGID_DIAGRAM
        from .runtime import run_distributed

        return run_distributed(RIGID_DIAGRAM, self.rigid,
                               saturation=self._force_limit(saturate),
                               step=step_m, duration_s=duration_s, rates_hz=rates_hz,
                               transport=transport, extra_latency_s=extra_latency_s,
                               loss=loss, seed=seed)

    def to_control(self, kind: str = "frd", *, transfer: str = "loop", f_hz: Any = None,
                   order: int = 3) -> Any:
        """Export to python-control: exact-delay frequency response or a Padé model.

        Parameters
        ----------
        kind : {"frd", "pade", "pade-ss"}
            As :meth:`seactl.Design.to_control`.
        transfer : {"loop", "closed", "compliance"}
            Whole loop ``L`` (broken at the sensor), ``x / x_des``, or ``x / F_ext``
            [m/N].
        f_hz : array_like, optional
            Frequencies of the FRD [Hz] (default: 2000 points from 0.01 Hz to 10 kHz).
        order : int
            Padé order per delay, 1 to 4.

        Returns
        -------
        control.FrequencyResponseData or control.TransferFunction or control.StateSpace
            For a single design; a list (flattened batch order) for a batch.

        Examples
        --------
        >>> import control as ct
        >>> import seactl as sc
        >>> L = sc.rigid(8, delays_ms=(1.5, 1.5)).to_control("frd")
        >>> round(float(ct.margin(L)[1]), 1)
        52.6
        """
        from ._export import rigid_transfer, to_control

        if not self.shape:
            return to_control(self.rigid, kind, transfer, f_hz, order, rigid_transfer)
        n = int(np.prod(self.shape))
        flat = self[np.unravel_index(np.arange(n), self.shape)]
        return [to_control(flat[i].rigid, kind, transfer, f_hz, order, rigid_transfer)
                for i in range(n)]


def rigid(fn_hz: Any, *, actuator: Any = "ut-linear", delays_ms: Sequence[Any] = (0.0, 0.0),
          velocity_filter_hz: float | None = 50.0, passive_damping: bool = True) -> RigidBatch:
    """Critically-damped rigid-actuator designs ``K = m w_n^2``, ``B = 2 m w_n - b``.

    Parameters
    ----------
    fn_hz : array_like
        Natural frequency [Hz].
    actuator : str or path or RigidParams
        Preset (``"ut-linear"``), TOML file or :class:`~seactl.rigid.RigidParams`.
    delays_ms : tuple of array_like
        ``(T_s, T_d)``: stiffness-loop and damping-loop delays [ms].
    velocity_filter_hz : float or None
        Cut-off of the first-order velocity filter [Hz]; None: no filter.
    passive_damping : bool
        Subtract the actuator's own damping ``b`` from ``B``.

    Returns
    -------
    RigidBatch
        The batch, of the broadcast shape of ``fn_hz`` and the delays.

    Examples
    --------
    >>> import seactl as sc
    >>> r = sc.rigid(12, delays_ms=(1, 15))
    >>> bool(r.margins().stable)                # 15 ms on the damping loop: unstable
    False
    >>> bool(sc.rigid(12, delays_ms=(15, 1)).margins().stable)
    True
    """
    from .rigid import RigidDesign, RigidParams, load_rigid

    act = resolve_actuator(actuator, load_rigid, RigidParams)
    fn = finite_array("fn_hz [Hz]", fn_hz, minimum=0.0, strict=True, nonempty=True)
    t_s, t_d = delays_from_ms(delays_ms, ("T_s", "T_d"))
    check_batch(fn_hz=fn, delays_ms=(np.asarray(t_s) * 1e3, np.asarray(t_d) * 1e3))
    d = RigidDesign.from_fn(act, fn, T_s=t_s, T_d=t_d, f_v=velocity_filter_hz,
                            passive_damping=passive_damping)
    if 0 in d.shape:
        raise InputError("fn_hz, delays_ms, velocity_filter_hz", f"a batch of shape "
                         f"{d.shape}", "arrays with at least one value")
    return RigidBatch(d, np.broadcast_to(fn, d.shape))


# ------------------------------------------------------------------ latency maps
def loop_model(kind: str = "sea", actuator: Any = None, *, torque_delay_ms: float = 0.5,
               filters_hz: Sequence[Any] = (50.0, 100.0)) -> Any:
    """How designs of one actuator depend on ``(f_n, T_s, T_d)`` (for maps and placement).

    Parameters
    ----------
    kind : {"sea", "rigid"}
        SEA (stiffness ``K_q``, damping ``B_q`` around a torque loop) or rigid actuator.
    actuator : str or path or parameters, optional
        Default: the UT-SEA, or the UT linear actuator for ``"rigid"``.
    torque_delay_ms : float
        SEA only: torque-loop delay [ms].
    filters_hz : tuple
        SEA: ``(f_qd, f_taud)`` [Hz]; rigid: only the first (velocity filter) is used.

    Returns
    -------
    seactl.latency.LoopModel
        The model.

    Examples
    --------
    >>> import seactl as sc
    >>> sc.loop_model("rigid").name
    'ut-linear'
    """
    from .latency import rigid_model, sea_model

    if kind not in KINDS:
        raise InputError("kind", kind, " or ".join(KINDS))
    if kind == "rigid":
        from .rigid import RigidParams, load_rigid

        act = None if actuator is None else resolve_actuator(actuator, load_rigid, RigidParams)
        return rigid_model(act, f_v=filters_hz[0])
    from .actuators import SEAParams, load_sea

    act = None if actuator is None else resolve_actuator(actuator, load_sea, SEAParams)
    (t_tau,) = delays_from_ms((torque_delay_ms,), ("T_tau",))
    return sea_model(act, T_tau=float(t_tau), f_qd=filters_hz[0], f_taud=filters_hz[1])


@dataclass(frozen=True)
class LatencyMapResult:
    """Phase margin and stability over (stiffness delay, damping delay) at one ``f_n``.

    Parameters
    ----------
    map : seactl.latency.LatencyMap
        The computed map; arrays indexed ``[i_stiffness, i_damping]``.

    Examples
    --------
    >>> import seactl as sc
    >>> m = sc.latency_map(14, [0, 5, 10], [0, 1], torque_delay_ms=0.5)
    >>> m.to_dict()["damping_delay_ms"], m.map.phase_margin_deg.shape
    ([0.0, 1.0], (3, 2))
    """

    map: Any

    def to_dict(self) -> dict[str, Any]:
        """The map as JSON-ready lists (delays in ms).

        Returns
        -------
        dict
            ``actuator``, ``fn_hz``, ``stiffness_delay_ms``, ``damping_delay_ms``,
            ``phase_margin_deg``, ``stable``.
        """
        m = self.map
        return {"actuator": m.actuator, "kind": m.kind, "fn_hz": m.fn_hz,
                "stiffness_delay_ms": json_array(m.T_s * 1e3),
                "damping_delay_ms": json_array(m.T_d * 1e3),
                "phase_margin_deg": json_array(m.phase_margin_deg),
                "stable": json_array(m.stable)}

    def plot(self, ax: Any = None) -> Any:
        """Phase-margin contours over the two delays; unstable region hatched.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Where to draw (default: a new figure).

        Returns
        -------
        matplotlib.axes.Axes
            The axes drawn on.
        """
        ax = _axes(ax)
        m = self.map
        x, y = m.T_d * 1e3, m.T_s * 1e3
        pm = np.where(m.stable, m.phase_margin_deg, np.nan)
        cs = ax.contourf(x, y, pm, levels=12, cmap="viridis")
        ax.figure.colorbar(cs, ax=ax, label="phase margin [deg]")
        if (~m.stable).any():
            ax.contourf(x, y, (~m.stable).astype(float), levels=[0.5, 1.5], colors="none",
                        hatches=["//"])
        ax.set_xlabel("damping-loop delay [ms]")
        ax.set_ylabel("stiffness-loop delay [ms]")
        ax.set_title(f"{m.actuator}, f_n = {m.fn_hz:g} Hz")
        return ax


def latency_map(fn_hz: float, stiffness_delays_ms: Any, damping_delays_ms: Any, *,
                kind: str = "sea", actuator: Any = None, torque_delay_ms: float = 0.5,
                filters_hz: Sequence[Any] = (50.0, 100.0)) -> LatencyMapResult:
    """Phase margin and Nyquist stability on a grid of (stiffness delay, damping delay).

    Parameters
    ----------
    fn_hz : float
        Natural frequency [Hz] of the (critically-damped) design.
    stiffness_delays_ms, damping_delays_ms : array_like
        The grid's axes [ms].
    kind : {"sea", "rigid"}
        Actuator kind.
    actuator : str or path or parameters, optional
        As for :func:`loop_model`.
    torque_delay_ms : float
        SEA only: torque-loop delay [ms].
    filters_hz : tuple
        SEA: ``(f_qd, f_taud)`` [Hz]; rigid: the velocity filter first.

    Returns
    -------
    LatencyMapResult
        ``map.phase_margin_deg[i, j]`` at stiffness delay ``i`` and damping delay ``j``.

    Examples
    --------
    >>> import seactl as sc
    >>> m = sc.latency_map(12, [1, 15], [1, 15], kind="rigid")
    >>> m.map.stable.tolist()                 # rows: stiffness delay, columns: damping
    [[True, False], [True, False]]
    """
    model = loop_model(kind, actuator, torque_delay_ms=torque_delay_ms, filters_hz=filters_hz)
    ts = delays_from_ms((stiffness_delays_ms,), ("stiffness_delays",))[0]
    td = delays_from_ms((damping_delays_ms,), ("damping_delays",))[0]
    check_batch(stiffness_delays_ms=ts.ravel() * 1e3,
                damping_delays_ms=td.ravel()[:, None] * 1e3)
    from .latency import latency_map as compute

    return LatencyMapResult(compute(model, float(fn_hz), np.ravel(ts), np.ravel(td)))


# ------------------------------------------------------------------ placement
@dataclass(frozen=True)
class PlacementResult:
    """Which loop to run on which processor (see :func:`place`).

    Parameters
    ----------
    advice : seactl.placement.Advice
        The advisor's answer: ``recommended``, ``options`` per placement, ``reason``.

    Examples
    --------
    >>> import seactl as sc
    >>> p = sc.place(22, 0.5)
    >>> [o["placement"] for o in p.to_dict()["options"]]
    ['centralized', 'distributed', 'embedded']
    """

    advice: Any

    @property
    def recommended(self) -> str | None:
        """``"centralized"``, ``"distributed"``, ``"embedded"`` or None."""
        return self.advice.recommended

    def to_dict(self) -> dict[str, Any]:
        """The advice as JSON-ready values (delays in seconds, as in the advice).

        Returns
        -------
        dict
            Every field of :class:`seactl.placement.Advice`.
        """
        return _jsonify(asdict(self.advice))


def place(high_latency_ms: float, low_latency_ms: float, *, kind: str = "rigid",
          actuator: Any = None, min_pm_deg: float = 45.0,
          stiffness_embeddable: bool = False, timing: Any = None,
          latency_margin: float = 0.5) -> PlacementResult:
    """Recommend where the stiffness and damping loops should run.

    Parameters
    ----------
    high_latency_ms, low_latency_ms : float
        Feedback latency of the high-level and of the embedded process [ms].
    kind : {"rigid", "sea"}
        Actuator kind (see :func:`loop_model`).
    actuator : str or path or parameters, optional
        Default: the UT linear actuator (rigid) or the UT-SEA.
    min_pm_deg : float
        Whole-loop phase margin [deg] required at every latency of the box.
    stiffness_embeddable : bool
        Whether the stiffness loop may run on the embedded process too.
    timing : dict, optional
        ``"high-level"`` / ``"embedded"`` -> :class:`seactl.placement.ProcessTiming`
        (latency distribution and loss): the nominal latency replaces the constant one and
        every loop's jitter margin must cover its process's jitter.
    latency_margin : float
        Fraction of its latency each loop must tolerate on top of it: placements are
        ranked by the largest ``f_n`` that is stable with ``min_pm_deg`` for every loop
        latency from 0 to ``1 + latency_margin`` times its own
        (:mod:`seactl.latency_box`); a longer latency never raises that score.

    Returns
    -------
    PlacementResult
        ``recommended`` and, per placement, its score ``f_n``, gains and bottleneck.

    Examples
    --------
    >>> import seactl as sc
    >>> sc.place(22, 0.5).recommended
    'distributed'
    """
    model = loop_model(kind, actuator)
    high, low = delays_from_ms((high_latency_ms, low_latency_ms), ("high latency",
                                                                    "low latency"))
    from .placement import advise

    return PlacementResult(advise(model, float(high), float(low), min_pm_deg=min_pm_deg,
                                  stiffness_embeddable=stiffness_embeddable, timing=timing,
                                  latency_margin=latency_margin))


# ------------------------------------------------------------------ sweeps
def sweep(out: str | Path, *, actuator: Any = "ut-sea", sampling: str = "grid",
          n_samples: int = 0, seed: int = 0, chunk_size: int = 5000,
          z_freqs_hz: Sequence[float] = (), workers: int | None = None,
          scheduler: str | None = None, client: Any = None, resume: bool = False,
          overwrite: bool = False, **axes: Any) -> Any:
    """Sweep the SEA design space into a resumable Parquet dataset.

    Parameters
    ----------
    out : str or path
        Output directory (created; refused if it holds something else).
    actuator : str or path or SEAParams
        Nominal actuator.
    sampling : {"grid", "random", "lhs"}
        Cartesian grid, or ``n_samples`` random / Latin-hypercube points in the axes'
        ranges.
    n_samples, seed : int
        Sample count and seed of the sampling modes.
    chunk_size : int
        Points per chunk (one Parquet file each).
    z_freqs_hz : sequence of float
        Frequencies [Hz] at which to store ``|Z|``.
    workers : int, optional
        Local Dask worker processes (default: all cores; 0: in this process).
    scheduler : str, optional
        Address of a Dask scheduler, e.g. ``"tcp://10.0.0.5:8786"``.
    client : distributed.Client, optional
        An existing Dask client.
    resume, overwrite : bool
        Finish an interrupted sweep / replace a previous one.
    **axes : array_like
        Values per axis, units in the names: ``fn_hz``, ``gs``, ``zeta1``, ``zeta2``,
        ``ratio``, ``t_tau_ms``, ``t_qs_ms``, ``t_qd_ms``, ``f_qd_hz``, ``f_taud_hz`` and
        plant parameters ``Im``, ``Ij``, ``bm``, ``bj``, ``k``, ``beta`` (rotary SI).

    Returns
    -------
    seactl.sweep.SweepResult
        Where the data went, counts, timing; read it with :func:`read_sweep`.

    Examples
    --------
    >>> import tempfile, seactl as sc
    >>> out = tempfile.mkdtemp() + "/s"
    >>> res = sc.sweep(out, fn_hz=[12, 14, 16], t_qs_ms=[0, 2], workers=0)
    >>> res.n_points, len(sc.read_sweep(out))
    (6, 6)
    """
    from .actuators import SEAParams, load_sea
    from .sweep import SweepSpec, run_sweep

    act = resolve_actuator(actuator, load_sea, SEAParams)
    spec = SweepSpec(act, axes=tuple((k, tuple(np.ravel(v))) for k, v in axes.items()),
                     sampling=sampling, n_samples=n_samples, seed=seed, chunk_size=chunk_size,
                     z_freqs_hz=tuple(z_freqs_hz))
    return run_sweep(spec, out, resume=resume, overwrite=overwrite, workers=workers,
                     scheduler=scheduler, client=client)


def read_sweep(out: str | Path, columns: Sequence[str] | None = None) -> Any:
    """Read a sweep dataset as one table sorted by point index.

    Parameters
    ----------
    out : str or path
        The sweep's output directory.
    columns : sequence of str, optional
        Columns to read (default: all).

    Returns
    -------
    pyarrow.Table
        One row per design point; ``.to_pandas()`` if pandas is installed.

    Examples
    --------
    >>> import tempfile, seactl as sc
    >>> out = tempfile.mkdtemp() + "/s"
    >>> _ = sc.sweep(out, fn_hz=[12, 14], workers=0)
    >>> [round(x, 2) for x in sc.read_sweep(out).column("phase_margin_deg").to_pylist()]
    [54.37, 55.51]
    """
    from .sweep import read_sweep as read

    return read(out, columns)


# ------------------------------------------------------------------ mobile base
def compare_mobile_base(params: Any = "trikey", *, archs: Sequence[str] = ("cosc", "dosc"),
                track: bool = True) -> Any:
    """Tune the omnidirectional base's controllers, centralized (COSC) vs distributed (DOSC).

    Runs the paper's procedure: raise damping until the base vibrates, then stiffness,
    then track a circle at a safety factor of both limits.

    Parameters
    ----------
    params : str or path or MobileBaseParams
        Preset (``"trikey"``), TOML file, or :class:`~seactl.mobile_base.MobileBaseParams`.
    archs : sequence of {"cosc", "dosc"}
        Architectures to tune.
    track : bool
        Also simulate the circle tracking (RMS errors).

    Returns
    -------
    seactl.mobile_base.MobileBaseComparison
        Per architecture: damping and stiffness limits, gains, RMS tracking errors;
        ``kx_ratio`` DOSC/COSC.

    Examples
    --------
    >>> import seactl as sc
    >>> sc.mobile_base_params().name
    'trikey'
    >>> c = sc.compare_mobile_base()                    # doctest: +SKIP
    >>> round(c.kx_ratio, 1)                    # doctest: +SKIP
    6.4
    """
    from .mobile_base import tune

    return tune(mobile_base_params(params), tuple(archs), track=track)


def mobile_base_params(params: Any = "trikey") -> Any:
    """The mobile base's parameters: a preset name, a TOML file, or the object itself.

    Parameters
    ----------
    params : str or path or MobileBaseParams
        ``"trikey"`` (default), a TOML file, or a :class:`~seactl.mobile_base.MobileBaseParams`.

    Returns
    -------
    seactl.mobile_base.MobileBaseParams
        Validated parameters.

    Examples
    --------
    >>> import seactl as sc
    >>> round(sc.mobile_base_params().base_mass, 1)
    32.7
    """
    from .mobile_base import MobileBaseParams, load_base

    return resolve_actuator(params, load_base, MobileBaseParams)
