"""Bring your own loop: user-defined loops (TOML loop files or :class:`LoopBuilder`) with
every view seactl has for its built-in loops.

A loop is compiled (:mod:`seactl.userloop.loopfile`) onto the one
:class:`~seactl.diagram.blockdiagram.BlockDiagram`; the views below are the generic ones the
built-in SEA and rigid loops use: loop transfers broken at named signals with exact delays
and :func:`seactl.analysis.margins.loop_margins` (the open loop's right-half-plane poles counted by
closing the other breaks one at a time, :func:`seactl.latency.maps.path_margins`), impedance
from a transfer with the port's motion imposed, and :func:`seactl.simulate.engine.simulate`
(continuous with delay buffers, or sampled with each process at its rate).
"""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Mapping, Sequence
from functools import cached_property
from typing import Any

import numpy as np

from seactl.api.loopresults import (
    BreakMargins,
    LoopAnalysis,
    LoopImpedanceResult,
    LoopJitterResult,
    LoopResponseResult,
    LoopSampledMargins,
    Placements,
    UserLoopResponse,
)
from seactl.api.results import RootsResult, SampledMarginsResult
from seactl.api.system import System
from seactl.base.validate import frequencies_hz
from seactl.codegen.protocol import run_doc
from seactl.errors import InputError, LoopFileError
from seactl.userloop.analysis import (
    break_margins,
    characteristic_range,
    extend_down,
    jitter_grid,
    jitter_margin,
)
from seactl.userloop.loopfile import CompiledLoop


class UserLoop(System):
    """A user-defined loop at given values of its design variables (a batch if arrays).

    A :class:`~seactl.System`: the same views, keywords and result types as
    :func:`seactl.design` (:meth:`margins`, :meth:`roots`, :meth:`impedance`,
    :meth:`step`, :meth:`impulse`, :meth:`jitter_margins`, :meth:`monte_carlo`,
    :meth:`to_control`, :meth:`export`, :meth:`run`, :meth:`sweep`), each derived from
    the compiled block diagram; the loop's own extras are :meth:`analyze` (margins and
    jitter margins at every named break), :meth:`frequency_response` of any transfer,
    :meth:`loop_transfer`, :meth:`placements`, :meth:`with_values` and
    :meth:`with_latencies`.  Its ``loops`` (the keys of the responses' requested and
    effective delays) are its delayed blocks.

    Parameters
    ----------
    compiled : seactl.userloop.loopfile.CompiledLoop
        From :func:`load_loop` or :meth:`LoopBuilder.build`.
    values : dict, optional
        Overrides of variables or parameters (arrays broadcast into a design batch).
    latency_ms : dict, optional
        Overrides of the processes' latencies [ms].

    Examples
    --------
    >>> import seactl as sc
    >>> loop = (sc.LoopBuilder("int").variables(K=10.0).process("cpu")
    ...         .block("c", "gain", input=["r", "-y_m"], output="u", gain="K", delay_ms=10)
    ...         .block("p", "plant_tf", input="u", output="y", num=[1], den=[1, 0])
    ...         .block("s", "sensor", input="y", output="y_m")
    ...         .signals(inputs=["r"], reference="r", output="y")
    ...         .break_at("main", "y_m").build())
    >>> loop.with_values(K=[5.0, 20.0]).shape
    (2,)
    >>> isinstance(loop, sc.System), loop.default_step, loop.step_unit
    (True, 0.01, 'reference units')
    """

    kind = "loop"
    DEFAULT_STEP = 0.01
    """The step of a loop file that declares no ``[signals] reference_step``."""
    default_impulse = 0.05
    """The impulse area of :meth:`impulse` (the file's disturbance unit times seconds),
    the SEA's 0.05 N m s."""
    impulse_unit = "disturbance units x s"
    """The unit of an impulse: the file's disturbance unit times seconds."""

    def __init__(self, compiled: CompiledLoop, values: Mapping[str, Any] | None = None,
                 latency_ms: Mapping[str, Any] | None = None):
        self.compiled = compiled
        self.values = dict(values or {})
        self.latency_ms = dict(latency_ms or {})

    @property
    def default_step(self) -> float:  # type: ignore[override]
        """The step amplitude of :meth:`step` and :meth:`run`: the file's ``[signals]
        reference_step``, else 0.01.
        """
        step = self.compiled.model.signals.reference_step
        return self.DEFAULT_STEP if step is None else float(step)

    @property
    def step_unit(self) -> str:  # type: ignore[override]
        """The unit of the step: the file's ``[signals] reference_unit``, else
        ``"reference units"``.
        """
        return self.compiled.model.signals.reference_unit or "reference units"

    @property
    def output_unit(self) -> str:
        """``""``: a loop file names its output signal, not the output's unit.
        """
        return ""

    @property
    def loops(self) -> tuple[str, ...]:  # type: ignore[override]
        """The delayed blocks: the keys of the responses' requested and effective
        delays (and the links of :meth:`monte_carlo`).
        """
        return tuple(b.name for b in self.diagram.blocks if b.delay is not None)

    @property
    def links(self) -> dict[str, str]:
        """Loop -> delayed block: a loop file's loops are its delayed blocks."""
        return {name: name for name in self.loops}

    @property
    def delays_s(self) -> dict[str, np.ndarray]:
        """Delayed block -> its delay [s] (batch shape)."""
        arrays = self.design._arrays
        return {b.name: np.broadcast_to(arrays[b.delay], self.shape)
                for b in self.diagram.blocks if b.delay is not None}

    # ------------------------------------------------------------ structure
    @property
    def name(self) -> str:
        """The loop's name."""
        return self.compiled.model.name

    @property
    def file(self) -> str:
        """The loop file (``<builder>`` for a built loop)."""
        return self.compiled.file

    @property
    def diagram(self) -> Any:
        """The compiled :class:`~seactl.diagram.blockdiagram.BlockDiagram`."""
        return self.compiled.diagram

    @property
    def breaks(self) -> dict[str, str]:
        """Break name -> signal, inner loops first."""
        return {b.name: b.signal for b in self.compiled.model.breaks}

    @property
    def ports(self) -> dict[str, Any]:
        """Port name -> its definition (position, force, sign)."""
        return {p.name: p for p in self.compiled.model.ports}

    @property
    def processes(self) -> dict[str, Any]:
        """Process name -> its definition (rate_hz, latency_ms)."""
        return dict(self.compiled.model.processes)

    def with_values(self, **values: Any) -> UserLoop:
        """The same loop with variables or parameters overridden (``--set``).

        Parameters
        ----------
        **values : float or array_like
            Name -> value(s); arrays broadcast together into a design batch.

        Returns
        -------
        UserLoop
            A new loop sharing the compiled diagram (no new derivation).
        """
        loop = UserLoop(self.compiled, {**self.values, **values}, self.latency_ms)
        loop.design  # noqa: B018 - validate the values now
        return loop

    def with_latencies(self, **latency_ms: Any) -> UserLoop:
        """The same loop with the processes' latencies overridden [ms].

        Parameters
        ----------
        **latency_ms : float or array_like
            Process name -> latency [ms].

        Returns
        -------
        UserLoop
            A new loop sharing the compiled diagram.
        """
        for p in latency_ms:
            if p not in self.processes:
                raise LoopFileError(self.file, f"process {p!r}", None,
                                    "a declared process: " + ", ".join(self.processes))
        return UserLoop(self.compiled, self.values, {**self.latency_ms, **latency_ms})

    @cached_property
    def design(self) -> Any:
        """The design batch (:class:`~seactl.userloop.loopfile.LoopDesign`) the views evaluate."""
        return self.compiled.design(self.values, self.latency_ms)

    @property
    def shape(self) -> tuple[int, ...]:
        """Shape of the design batch."""
        return self.design.shape

    def __getitem__(self, idx: Any) -> UserLoop:
        """The designs ``idx`` selects (numpy indexing of the batch), as a loop whose
        multi-valued variables and latencies hold just those."""
        shape = self.shape
        if not shape and not (idx is None or idx is Ellipsis
                              or (isinstance(idx, tuple) and idx == ())):
            raise IndexError(f"index {idx!r} of a single design (its shape is (); "
                             "loop[()] is the loop itself)")

        probe = np.broadcast_to(np.zeros(()), shape)[idx]
        if np.size(probe) == 0:
            raise InputError("index", idx, "a selection of at least one design")

        def pick(v: Any) -> Any:
            return np.broadcast_to(np.asarray(v, float), shape)[idx] if np.size(v) > 1 else v

        sel = {k: pick(v) for k, v in self.values.items()}
        lat = {k: pick(v) for k, v in self.latency_ms.items()}
        loop = UserLoop(self.compiled, sel, lat)
        if loop.shape != np.shape(probe):  # a new axis, or every value a single one
            env = self.environment()
            if not env:
                raise InputError("index", idx, "an index of the batch (a loop without "
                                 "variables has no batch axes to add)")
            k = next(iter(self.compiled.model.variables), None) or next(iter(env))
            sel[k] = np.broadcast_to(np.asarray(env[k], float), shape)[idx]
            loop = UserLoop(self.compiled, sel, lat)
        return loop

    def __repr__(self) -> str:
        return f"UserLoop(name={self.name!r}, file={self.file!r}, shape={self.shape}, " \
               f"values={ {k: np.asarray(v).tolist() for k, v in self.values.items()} })"

    def label_columns(self, gains: bool = True) -> dict[str, np.ndarray]:
        """The per-design columns that label the results' records: the variables set to
        several values.

        Parameters
        ----------
        gains : bool
            Unused (a loop's gains are its variables).

        Returns
        -------
        dict
            Name -> array of the batch shape.
        """
        return {k: np.broadcast_to(np.asarray(v, float), self.shape)
                for k, v in self.values.items() if np.size(v) > 1}

    def labels(self) -> list[str]:
        """One short label per design (flattened batch), for legends.

        Returns
        -------
        list of str
            ``"K=5, fn=8"`` style labels of the variables set to several values (the
            loop's name for a single design).

        Examples
        --------
        >>> import seactl as sc
        >>> sc.load_loop("examples/loops/rigid.toml", fn=[8, 12]).labels()   # doctest: +SKIP
        ['fn=8', 'fn=12']
        """
        cols = {k: np.ravel(v) for k, v in self.label_columns().items()}
        n = int(np.prod(self.shape, dtype=int))
        return [", ".join(f"{k}={v[i]:g}" for k, v in cols.items()) or self.name
                for i in range(n)]

    def environment(self) -> dict[str, np.ndarray]:
        """Every variable and parameter at this loop's values.

        Returns
        -------
        dict
            Name -> array (broadcast to the batch shape).
        """
        return {k[5:]: np.broadcast_to(v, self.shape) for k, v in self.design._arrays.items()
                if k.startswith("var__")}

    # ------------------------------------------------------------ code and processes
    def _export_rates(self, rates_hz: Any) -> Any:
        return rates_hz if rates_hz is not None else {
            name: float(p.rate_hz) for name, p in self.processes.items()}

    def export(self, out: Any, *, lang: Any = ("c", "python", "json"), rates_hz: Any = None,
               verify: bool = False, emulate_latency: bool = False,
               real: str = "double") -> Any:
        """Write the discrete controller of each process of the file (C99, Python, JSON).

        As :meth:`seactl.Design.export`, for one design of the loop (every ``--set``
        variable single-valued); each process at the file's rate unless ``rates_hz``.
        ``verify`` runs the step response at :attr:`default_step`.

        Parameters
        ----------
        out : str or path
            A new or empty directory (or one an earlier export wrote).
        lang : sequence of str or str
            Any of ``"c"``, ``"python"``, ``"json"``.
        rates_hz : float or mapping, optional
            Rate of every process [Hz], or per process (default: the file's).
        verify : bool
            Compile and run the C and the Python against seactl's sampled controller.
        emulate_latency : bool
            Keep the file's delays in the code as whole-sample buffers (for bench tests);
            by default the code holds no delay (on the robot the latency is the
            platform's), as :meth:`seactl.System.export`.
        real : {"double", "float"}
            Floating-point type of the C's signals and states.

        Returns
        -------
        seactl.codegen.export.ExportResult
            ``files``, ``controllers`` and ``verification``.

        Examples
        --------
        >>> import tempfile
        >>> import seactl as sc
        >>> loop = sc.load_loop("examples/loops/sea-velocity.toml")   # doctest: +SKIP
        >>> res = loop.export(tempfile.mkdtemp(), lang="json")          # doctest: +SKIP
        >>> [p.name for p in res.controllers.processes]                 # doctest: +SKIP
        ['high-level', 'embedded', 'drive']
        """
        from seactl.codegen.export import export_design

        return export_design(self.diagram, self.design, out, languages=lang,
                             rates_hz=self._export_rates(rates_hz), verify_export=verify,
                             step=self.default_step, emulate_latency=emulate_latency,
                             real=real)

    @run_doc
    def run(self, *, duration_s: float = 2.0, rates_hz: Any = None,
            amplitude: float | None = None, transport: str = "zenoh",
            extra_latency_s: float = 0.0, loss: float = 0.0, seed: int = 0,
            step: float | None = None, realtime: bool = False, latency: Any = None) -> Any:
        """Run the exported controllers as three OS processes on loopback.

        As :meth:`seactl.Design.run`, for a loop file whose processes are ``embedded`` and
        ``high-level`` (e.g. ``examples/loops/paper-sea.toml``).  With ``realtime`` the
        measured step is judged against the band of sampled steps of the file's own
        ``[signals] reference`` and ``output`` (its loops: :attr:`links`); a file without
        a reference, or whose output is not the signal the run measures, gets the verdict
        ``"not computed: ..."`` saying why.

        Parameters
        ----------
        duration_s : float
            Run time [s], 0.1 to 60.
        rates_hz : float or mapping, optional
            As :meth:`export` (at most 5000 Hz).
        amplitude : float, optional
            Step of the file's reference signal (default :attr:`default_step`).
        {link_parameters}
        step : float, optional
            Deprecated spelling of ``amplitude``.
        realtime : bool
            Free-running processes running the exported C (as :meth:`seactl.Design.run`).
        latency : dict, optional
            With ``realtime``: delayed block -> latency model of the prediction band (as
            :meth:`monte_carlo`; default: the run's measured latency of every loop; ``{}``:
            the file's delays, one nominal response).

        Returns
        -------
        seactl.codegen.runtime.RunResult
            ``summary``, the responses and the latency samples; with ``realtime``,
            ``summary["prediction_band"]`` (as :meth:`seactl.Design.run`).

        Examples
        --------
        >>> import seactl as sc
        >>> loop = sc.load_loop("examples/loops/paper-sea.toml")      # doctest: +SKIP
        >>> loop.run(duration_s=0.2).summary["replay_max_diff"] < 1e-9  # doctest: +SKIP
        True
        """
        from seactl.codegen.runtime import run_distributed

        if step is not None:
            warnings.warn("run(step=) is deprecated; use amplitude=", DeprecationWarning,
                          stacklevel=2)
            amplitude = step if amplitude is None else amplitude
        lat = None
        if realtime:
            from seactl.latency.band import band_latency

            lat = band_latency(latency, self.links)
        elif latency is not None:
            raise InputError("latency", latency, "used with realtime=True")
        rates = self._export_rates(rates_hz)
        res = run_distributed(self.diagram, self.design, saturation=None,
                              step=self.default_step if amplitude is None else amplitude,
                              duration_s=duration_s, rates_hz=rates, transport=transport,
                              extra_latency_s=extra_latency_s, loss=loss, seed=seed,
                              realtime=bool(realtime))
        if realtime:
            self._run_band(res, lat, rates, seed)
        return res

    def _run_band(self, res: Any, latency: Any, rates_hz: Any, seed: int) -> None:
        """The run's prediction band on the file's own reference and output, or why
        there is none (``summary["prediction_band"]``)."""
        from seactl.latency.band import run_band

        sig = self.compiled.model.signals
        measured = res.summary["output"]
        if sig.reference is None:
            why = "the loop file declares no [signals] reference"
        elif sig.output != measured:
            why = (f"the run measures {measured}, the loop file's [signals] output is "
                   f"{sig.output or 'not declared'}")
        else:
            run_band(res, self.diagram, self.design, reference=sig.reference,
                     links=self.links, latency=latency, rates_hz=rates_hz, seed=seed)
            return
        res.summary["prediction_band"] = {"verdict": f"not computed: {why}", "within": None}

    def _transfer(self, name: str) -> tuple[Any, bool]:
        """The transfer :meth:`to_control` exports and whether it is divided by ``-s``."""
        if name == "loop":
            if not self.breaks:
                raise LoopFileError(self.file, "[[breaks]]", None, "at least one named break")
            return self.loop_transfer(list(self.breaks)[-1]), False
        if name in self.breaks:
            return self.loop_transfer(name), False
        if name == "closed":
            inp, out = self._io("reference", None, None)
            return self.diagram.transfer(out, inp), False
        if name == "impedance" and self.ports:
            p = next(iter(self.ports.values()))
            if p.sign == -1:
                return self.diagram.transfer(p.force, p.position, cut=(p.position,)), True
        raise InputError("transfer", name, "'loop' (the outermost break), a break name ("
                         + ", ".join(self.breaks) + "), 'closed' (reference to output) or "
                         "'impedance' (the first port, sign -1)")

    def to_control(self, kind: str = "frd", *, transfer: str = "loop", f_hz: Any = None,
                   order: int = 3) -> Any:
        """Export to python-control: exact-delay frequency response or a Padé model.

        Parameters
        ----------
        kind : {"frd", "pade", "pade-ss"}
            As :meth:`seactl.Design.to_control`.
        transfer : str
            ``"loop"``: the loop broken at the outermost (last) break, the others closed;
            a break name: the loop broken there; ``"closed"``: reference to output;
            ``"impedance"``: the first port's (sign -1).
        f_hz : array_like, optional
            Frequencies of the FRD [Hz] (default: 2000 points from 0.01 Hz to 10 kHz).
        order : int
            Padé order per delay, 1 to 4.

        Returns
        -------
        control.FrequencyResponseData or control.TransferFunction or control.StateSpace
            For a single design; a list of them (flattened batch order) for a batch.

        Examples
        --------
        >>> import control as ct
        >>> import seactl as sc
        >>> L = sc.load_loop("examples/loops/paper-sea.toml").to_control()  # doctest: +SKIP
        >>> round(float(ct.margin(L)[1]), 2)                                  # doctest: +SKIP
        43.26
        """
        from seactl.api.control import to_control

        self._transfer(transfer)  # an unknown name fails before any work
        if not self.shape:
            return to_control(self.design, kind, transfer, f_hz, order, self._transfer)
        n = int(np.prod(self.shape, dtype=int))
        flat = self.reshape(n)
        return [to_control(flat[i].design, kind, transfer, f_hz, order, self._transfer)
                for i in range(n)]

    def sweep(self, out: Any, *, values: Mapping[str, Any] | None = None,
              chunk_size: int = 5000, overwrite: bool = False, sampling: str = "grid",
              n_samples: int = 0, seed: int = 0) -> dict[str, Any]:
        """Margins at every break over a grid (or random sample) of the loop's variables,
        written as a Parquet dataset (:func:`seactl.sweep.loops.sweep_loop`, what
        ``seactl sweep --loop`` runs; :func:`seactl.read_sweep` reads it).

        Parameters
        ----------
        out : str or path
            A new or empty directory.
        values : dict, optional
            Variable -> values (arrays broadcast together; default: this loop's
            multi-valued variables).
        chunk_size : int
            Points per vectorized chunk.
        overwrite : bool
            Replace a loop sweep seactl wrote there.
        sampling : {"grid", "random", "lhs"}
            Every combination, or ``n_samples`` random / Latin-hypercube points over the
            interval each multi-valued variable spans.
        n_samples : int
            Points of a random or LHS sampling.
        seed : int
            Seed of the sampling.

        Returns
        -------
        dict
            The summary (also written to ``_summary.json``).
        """
        from seactl.sweep.loops import sweep_loop

        vals = {k: v for k, v in self.values.items() if np.size(v) > 1} \
            if values is None else dict(values)
        base = UserLoop(self.compiled, {k: v for k, v in self.values.items()
                                        if np.size(v) == 1}, self.latency_ms)
        return sweep_loop(base, vals, out, chunk_size=chunk_size, overwrite=overwrite,
                          sampling=sampling, n_samples=n_samples, seed=seed)

    # ------------------------------------------------------------ frequency domain
    def grid(self) -> np.ndarray:
        """The bracketing frequency grid [rad/s] of the margin scan: a decade beyond the
        slowest and fastest block pole, zero and spring resonance (or ``[analysis]``'s
        range), 12 points per decade; the scan refines it where the loop moves fast, extends
        it upwards while ``|L| > 0.5`` at its top and :meth:`analyze` extends it downwards
        while a loop still grows there below ``|L| = 2``.

        Returns
        -------
        ndarray
            Log-spaced angular frequencies.
        """
        return self._grid(self.design)

    def _grid(self, design: Any) -> np.ndarray:
        a = self.compiled.model.analysis
        lo, hi = characteristic_range(self.compiled, design)
        with np.errstate(over="ignore"):
            w_lo = 2 * np.pi * a.f_min_hz if a.f_min_hz else lo / 10
            w_hi = 2 * np.pi * a.f_max_hz if a.f_max_hz else hi * 10
        if not (0 < w_lo and w_hi < np.inf):
            raise LoopFileError(self.file, "values", None, "block poles and zeros a decade "
                                f"inside the floating-point range (they span {lo:.3g} to "
                                f"{hi:.3g} rad/s); or give [analysis] f_min_hz and f_max_hz")
        if not w_hi > w_lo:
            raise LoopFileError(self.file, "[analysis] f_max_hz", a.f_max_hz,
                                f"> f_min_hz ({w_lo / (2 * np.pi):g} Hz)")
        n = int(np.ceil(12 * (np.log10(w_hi) - np.log10(w_lo)))) + 1
        return np.logspace(np.log10(w_lo), np.log10(w_hi), n)

    def _signal(self, name: str, what: str) -> str:
        if name not in self.diagram.signals:
            raise LoopFileError(self.file, what, name, "a signal of the loop: "
                                + ", ".join(s for s in self.diagram.signals if "__" not in s))
        return name

    def loop_transfer(self, name: str) -> Any:
        """The loop transfer ``L`` broken at a named break, every other loop closed.

        Parameters
        ----------
        name : str
            A break name.

        Returns
        -------
        seactl.diagram.blockdiagram.Transfer
            Callable ``L(design, s)`` with exact delays.
        """
        if name not in self.breaks:
            raise LoopFileError(self.file, "break", name, "one of " + ", ".join(self.breaks))
        return self.diagram.loop(self.breaks[name])

    def frequency_response(self, output: str, input: str, f_hz: Any,
                           cut: Sequence[str] = ()) -> np.ndarray:
        """``output / input`` at ``s = j 2 pi f`` (every loop closed, ``cut`` signals held).

        Parameters
        ----------
        output, input : str
            Signal names.
        f_hz : array_like
            Frequencies [Hz], finite and > 0 (last axis of the result).
        cut : sequence of str
            Signals held at zero (or imposed, if ``input`` is one of them).

        Returns
        -------
        ndarray
            Complex, shape ``batch + (F,)``.
        """
        self._signal(output, "output")
        self._signal(input, "input")
        for c in cut:
            self._signal(c, "cut")
        s = 2j * np.pi * frequencies_hz("f_hz", f_hz)
        return self.diagram.transfer(output, input, cut=tuple(cut))(self.design, s)

    def impedance(self, f_hz: Any, *, port: str | None = None) -> LoopImpedanceResult:
        """Impedance ``Z = sign * force / (s position)`` at a port, its motion imposed and
        the exogenous inputs at zero.

        Parameters
        ----------
        f_hz : array_like
            Frequencies [Hz], finite and > 0.
        port : str, optional
            Port name (default: the first).

        Returns
        -------
        LoopImpedanceResult
            An :class:`~seactl.ImpedanceResult`: ``z`` (complex, shape ``batch + (F,)``),
            ``f_hz``, ``magnitude``,
            ``magnitude_db``, ``phase_deg``, ``stiffness``, ``port``; ``to_dict()``,
            ``plot()``.
        """
        from seactl.api.loopresults import LoopImpedanceResponse

        if not self.ports:
            raise LoopFileError(self.file, "[[ports]]", None, "at least one impedance port")
        name = port or next(iter(self.ports))
        if name not in self.ports:
            raise LoopFileError(self.file, "port", name, "one of " + ", ".join(self.ports))
        p = self.ports[name]
        f = frequencies_hz("f_hz", f_hz)
        T = self.frequency_response(p.force, p.position, f, cut=(p.position,))
        z = p.sign * T / (2j * np.pi * f)
        return LoopImpedanceResult(LoopImpedanceResponse("block-diagram", f, z, "SI", False),
                                   self.labels(), name)

    def analyze(self, jitter: bool = True) -> LoopAnalysis:
        """Margins at every named break, with every other loop closed.

        The right-half-plane poles of each broken loop are counted by Nyquist, closing the
        other breaks one at a time (inner first), so ``stable`` is the stability of the whole
        loop.  The delay margin is the extra latency at that break that destabilizes; the
        jitter margin is the Kao-Lincoln bound ``1 / max_w (w |L/(1+L)|)`` on a time-varying
        extra delay there (scanned, refined, then proven: :mod:`seactl.certify.supremum`).

        Parameters
        ----------
        jitter : bool
            Also compute the jitter margins.

        Returns
        -------
        LoopAnalysis
            Per break: phase, gain, delay and jitter margins; overall stability.
        """

        return self._analyze(self.design, jitter)

    def _analyze(self, design: Any, jitter: bool) -> LoopAnalysis:
        if not self.breaks:
            raise LoopFileError(self.file, "[[breaks]]", None, "at least one named break")
        omega = self._grid(design)
        items = list(self.breaks.items())
        if not self.compiled.model.analysis.f_min_hz:
            for _, sig in items:
                omega = extend_down(self.diagram.loop(sig), design, omega)
        out = []
        for name, sig in items:
            others = [s for n, s in items if n != name]
            m = break_margins(self.compiled, design, omega, sig, others)
            jit = jitter_margin(self.diagram.loop(sig), design,
                                jitter_grid(self.compiled, design, omega)) if jitter \
                else np.full(m.stable.shape, np.nan)
            out.append(BreakMargins(name, sig, m, np.where(m.stable, jit, 0.0)))
        env = {k[5:]: np.broadcast_to(v, design.shape) for k, v in design._arrays.items()
               if k.startswith("var__")}
        return LoopAnalysis(self.name, out, out[-1].margins.stable, env)

    def margins(self, rate_hz: Any = None) -> LoopAnalysis | LoopSampledMargins:
        """Margins at every named break: of the continuous loop (``rate_hz`` None, as
        :meth:`analyze` without jitter), or of the loop sampled at its process rates.

        Parameters
        ----------
        rate_hz : float or dict, optional
            A rate [Hz] for every process, or process -> rate overriding the file's rates
            (``{}``: the file's own rates).  The sampled loop is the one
            ``step(mode="sampled")`` runs; its verdict is certified and its margins come
            from the discrete frequency response up to Nyquist
            (:func:`seactl.simulate.sampled.sampled_margins`; a multi-rate loop: verdict only).

        Returns
        -------
        LoopAnalysis or LoopSampledMargins
            Continuous: the :meth:`analyze` result (``result["outer"].margins``,
            ``records()``: one row per design and break).  Sampled: break name ->
            :class:`~seactl.SampledMarginsResult` (one verdict, the whole loop's), with
            ``records()``.

        Examples
        --------
        >>> import seactl as sc
        >>> loop = sc.load_loop("examples/loops/rigid.toml")      # doctest: +SKIP
        >>> m = loop.margins(rate_hz={})                            # doctest: +SKIP
        """
        if rate_hz is None:
            return self._analyze(self.design, False)
        from seactl.simulate.sampled import sampled_margins

        rates = self._rates(rate_hz)
        if not self.breaks:
            raise LoopFileError(self.file, "[[breaks]]", None, "at least one named break")
        w_ref = 100 * self._grid(self.design)[0]
        return LoopSampledMargins(self.name, {name: SampledMarginsResult(
            sampled_margins(self.diagram, self.design, sig, rates, w_ref),
            self.label_columns()) for name, sig in self.breaks.items()})

    def jitter_margins(self, rate_hz: Any = None) -> LoopJitterResult:
        """Jitter margins at every named break (Kao-Lincoln small-gain bound with exact
        delays), with the delay margins and stability of :meth:`analyze`.

        Parameters
        ----------
        rate_hz : None
            The sampled loop's jitter margin is not available for loop files (only for
            the SEA and the rigid actuator): any rate is refused.

        Returns
        -------
        LoopJitterResult
            ``break_jitter_margins_s`` (break -> jitter margin [s]),
            ``jitter_margin_s`` (the outermost break's), ``delay_margin_s``, ``stable``,
            ``records()``.
        """
        if rate_hz is not None:
            raise self.unsupported("jitter_margins(rate_hz=...)", "the SEA or the rigid "
                                   "actuator (loop files: continuous jitter margins only)")
        a = self._analyze(self.design, True)
        return LoopJitterResult(self.name, {b.name: b.jitter_margin_s for b in a.breaks},
                                {b.name: b.margins.delay_margin_s for b in a.breaks},
                                a.stable, self.label_columns())

    def roots(self, count: int = 6) -> RootsResult:
        """Rightmost roots of the whole loop's characteristic quasi-polynomial (every
        break closed, exact delays), per design, as :meth:`seactl.Design.roots`
        (:func:`seactl.analysis.roots.characteristic_roots`: collocation, Newton, inclusion discs
        and the argument principle's count).

        Parameters
        ----------
        count : int
            Roots per design (a conjugate pair counts once).

        Returns
        -------
        RootsResult
            ``roots`` [rad/s] of shape ``shape + (count,)`` by decreasing real part,
            ``spectral_abscissa`` [1/s], each root's disc, ``stable``, ``uncertain``,
            ``right_half_plane_roots``, ``records()``.

        Examples
        --------
        >>> import seactl as sc
        >>> r = sc.load_loop("examples/loops/paper-sea.toml").roots(count=2)  # doctest: +SKIP
        >>> round(r.records()[0]["spectral_abscissa"], 2)                      # doctest: +SKIP
        -39.85
        """
        from seactl.analysis.roots import characteristic_roots
        from seactl.base.limits import check_roots

        delayed = any(np.any(np.asarray(v) > 0) for k, v in self.design._arrays.items()
                      if k.endswith("__T"))
        check_roots(int(np.prod(self.shape, dtype=int)), count, delayed)
        return RootsResult(characteristic_roots(self.diagram, self.design, count=count),
                           self.label_columns())

    def placements(self, max_options: int = 4096) -> Placements:
        """Every assignment of the blocks whose delay is their process's latency
        (``delay_ms = "process"``) to the declared processes, analysed as one batch.

        Parameters
        ----------
        max_options : int
            Refuse more assignments than this.

        Returns
        -------
        Placements
            The options ranked: stable first, then by the smallest phase margin over the
            breaks (largest first).
        """
        if self.shape != ():
            raise LoopFileError(self.file, "--set", None, "single values for place (no "
                                "ranges)")
        movable = [b.name for b in self.compiled.blocks if b.delay_ms == "process"]
        if not movable:
            raise LoopFileError(self.file, "blocks", None, "at least one block with "
                                "delay_ms = 'process' (a loop that can move between processes)")
        procs = list(self.processes)
        if len(procs) ** len(movable) > max_options:
            raise LoopFileError(self.file, "blocks", None, f"at most {max_options} placements "
                                f"({len(procs)} processes ^ {len(movable)} movable blocks)")
        combos = list(itertools.product(procs, repeat=len(movable)))
        env = {k: np.asarray(v) for k, v in self.environment().items()}
        lat = {p: float(v) for p, v in self.compiled.latencies(env, self.latency_ms).items()}
        arrays = dict(self.design._arrays)
        for j, blk in enumerate(movable):
            for e in self.compiled.edges:
                if e.block == blk and e.delay_ms == "process":
                    arrays[f"{e.name}__T"] = np.array([lat[c[j]] for c in combos]) / 1e3
        from seactl.userloop.loopfile import LoopDesign

        a = self._analyze(LoopDesign(arrays), jitter=False)
        pm_min = np.min([b.margins.phase_margin_deg for b in a.breaks], axis=0)
        order = np.lexsort((-pm_min, ~a.stable))
        options = [dict(zip(movable, combos[i])) for i in order]
        return Placements(movable, lat, options, a, order)

    # ------------------------------------------------------------ time domain
    def _rates(self, rates_hz: Any) -> dict[str, float]:
        """Process -> rate [Hz]: the file's, overridden by a mapping, or one rate for
        every process."""
        from seactl.base.limits import check_range

        rates = {p: m.rate_hz for p, m in self.processes.items()}
        if rates_hz is not None and not isinstance(rates_hz, Mapping):
            rate = check_range("rate_hz", rates_hz, "rate_hz")
            return {p: rate for p in rates} or rate
        for p, r in (rates_hz or {}).items():
            if p not in rates:
                raise LoopFileError(self.file, "rate", p, "a declared process: "
                                    + ", ".join(rates))
            rates[p] = check_range(f"rate_hz[{p!r}]", r, "rate_hz")
        return rates

    def _io(self, which: str, input: str | None, output: str | None) -> tuple[str, str]:
        """The excited input and the output signal of a response (the file's by default)."""
        sig = self.compiled.model.signals
        inp = input or getattr(sig, which)
        out = output or sig.output
        if inp is None:
            raise LoopFileError(self.file, f"[signals] {which}", None,
                                "set (or pass input=...) to simulate")
        if out is None:
            raise LoopFileError(self.file, "[signals] output", None,
                                "set (or pass output=...) to simulate")
        if inp not in self.diagram.inputs:
            raise LoopFileError(self.file, "input", inp, "an exogenous input: "
                                + ", ".join(self.diagram.inputs))
        return inp, self._signal(out, "output")

    def _current_signal(self) -> str | None:
        """The input of the loop's ``current_to_torque`` block, if it has exactly one."""
        amps = [b for b in self.compiled.blocks if b.kind == "current_to_torque"]
        if len(amps) != 1 or len(amps[0].inputs) != 1:
            return None
        sign, signal = amps[0].inputs[0]
        return signal if sign > 0 else None

    def _check_loop_simulation(self, mode: str, rates: Mapping[str, float], t_end_s: float,
                          record_dt: float | None, runs: int = 1) -> None:
        from seactl.base.limits import check_simulation

        if mode not in ("continuous", "sampled"):
            raise InputError("mode", mode, "'continuous' or 'sampled'")
        delays = [float(np.max(v)) for k, v in self.design._arrays.items()
                  if k.endswith("__T")]
        check_simulation(runs * int(np.prod(self.shape, dtype=int)), mode,
                         max(rates.values(), default=1000.0), t_end_s, delays,
                         record_dt_s=record_dt,
                         rate_name="rate_hz (the loop's fastest process)")

    def _loop_response(self, kind: str, size: float, t_end_s: float, mode: str, rate_hz: Any,
                  input: str | None, output: str | None, record_dt: Any,
                  band: float | None = None) -> LoopResponseResult:
        from seactl.simulate.engine import simulate
        from seactl.simulate.inputs import Impulse, Step
        from seactl.simulate.metrics import impulse_metrics, step_metrics
        from seactl.simulate.verdict import RECOVERY_BAND

        step = kind == "step"
        size = _amplitude(size)
        inp, out = self._io("reference" if step else "disturbance", input, output)
        rates = self._rates(rate_hz)
        self._check_loop_simulation(mode, rates, t_end_s, record_dt)
        cur = self._current_signal()
        res = simulate(self.diagram, self.design, {inp: Step(size) if step else Impulse(size)},
                       t_end_s, mode=mode, outputs=(out,) + ((cur,) if cur and cur != out
                                                             else ()),
                       rates_hz=rates, record_dt=record_dt)
        if mode == "sampled":
            self._sampled_verdict(res, rates)
        res.info["excitation"] = {"kind": kind, "size": float(size)}
        y = res.outputs[out]
        m = step_metrics(res.t_s, y / size, res.stable, res.left_bounds_s) if step else \
            impulse_metrics(res.t_s, y, res.stable, res.left_bounds_s,
                            RECOVERY_BAND if band is None else band)
        return LoopResponseResult(UserLoopResponse(kind, res, m, out, float(size), cur),
                                  self.labels(), self._right_roots,
                                  self.step_unit if step else self.impulse_unit)

    def _sampled_verdict(self, res: Any, rates: Mapping[str, float]) -> None:
        """The sampled loop's certified verdict in ``res.info`` beside the response
        (``sampled_verdict``, ``sampled_unstable_modes``, ``sampled_rate``); where it is
        certified it also replaces the simulation's own count of growing modes
        (``unstable_modes``), which the verdict reads."""
        from seactl.simulate.sampled import sampled_roots

        r = sampled_roots(self.diagram, self.design, rates)
        res.info.update(sampled_verdict=r.verdict, sampled_unstable_modes=r.unstable_modes,
                        sampled_rate=r.rate_label)
        own = np.asarray(res.info.get("unstable_modes", r.unstable_modes))
        res.info["unstable_modes"] = np.where(r.unstable_modes >= 0, r.unstable_modes, own)

    def _right_roots(self) -> np.ndarray:
        """Certified count of the whole diagram's closed-loop roots with ``Re s > 0`` per
        design (the exact-delay loop the continuous simulation runs; -1 where uncertain)."""
        from seactl.analysis.margins import closed_loop_right_roots

        g = self.grid()
        return closed_loop_right_roots(self.diagram, self.design, np.sqrt(g[..., 0] * g[..., -1]))

    def right_half_plane_roots(self) -> np.ndarray:
        """Deprecated: ``roots().right_half_plane_roots`` (the same certified count).

        Returns
        -------
        numpy.ndarray
            Integer counts of closed-loop roots with ``Re s > 0``, the batch's shape (-1
            where uncertain).
        """
        warnings.warn("UserLoop.right_half_plane_roots() is deprecated; use "
                      "roots().right_half_plane_roots", DeprecationWarning, stacklevel=2)
        return self._right_roots()

    def verdict(self, result: Any, band: float | None = None) -> Any:
        """The verdict of a response of this loop: ``result.verdict(band)``.

        Parameters
        ----------
        result : LoopResponseResult
            From :meth:`step` or :meth:`impulse` of this loop.
        band : float, optional
            As :meth:`LoopResponseResult.verdict`.

        Returns
        -------
        seactl.simulate.verdict.TimeVerdict
            The verdicts, the warnings and the evidence per design.
        """
        if not isinstance(result, LoopResponseResult):
            raise InputError("result", type(result).__name__,
                             "a result of this loop's step() or impulse()")
        return result.verdict(band)

    def step(self, _t_end_s: float | None = None, /, *, t_end_s: float | None = None,
             amplitude: float | None = None, mode: str = "continuous", rate_hz: Any = None,
             input: str | None = None, output: str | None = None,
             record_dt: float | None = None, rates_hz: Any = None) -> LoopResponseResult:
        """Step response (``[signals] reference`` to ``output`` by default).

        Parameters
        ----------
        _t_end_s : float, optional
            Deprecated: ``t_end_s`` given by position.
        t_end_s : float, optional
            Simulated time [s] (default 0.5).
        amplitude : float, optional
            Step size in the reference's unit (:attr:`step_unit`; default
            :attr:`default_step`).  ``position`` is divided by it.
        mode : str
            ``"continuous"`` (exact delays, delay buffers) or ``"sampled"`` (each process at
            its rate, Tustin controllers, zero-order hold).
        rate_hz : float or dict, optional
            One rate [Hz] for every process, or process -> rate (default: the file's).
        input, output : str, optional
            Override the file's reference and output signals.
        record_dt : float, optional
            Recording interval [s] (continuous mode).
        rates_hz : dict, optional
            Deprecated spelling of ``rate_hz``.

        Returns
        -------
        LoopResponseResult
            ``t_s``, ``position`` (the output / step), ``metrics``, ``verdict()``, the
            requested and effective delays per delayed block, and in sampled mode the
            loop's certified verdict.

        Examples
        --------
        >>> import seactl as sc
        >>> loop = sc.load_loop("examples/loops/paper-sea.toml")      # doctest: +SKIP
        >>> r = loop.with_values(T_high=[2.0, 30.0]).step(t_end_s=0.3)  # doctest: +SKIP
        >>> r.verdict().verdict                                        # doctest: +SKIP
        ['settled', 'unstable']
        """
        t_end_s, rate_hz = self._old_arguments(_t_end_s, t_end_s, rates_hz, rate_hz)
        t_end_s = 0.5 if t_end_s is None else t_end_s
        return self._loop_response("step", self.default_step if amplitude is None else amplitude,
                              t_end_s, mode, rate_hz, input, output, record_dt)

    def impulse(self, _t_end_s: float | None = None, /, *, t_end_s: float | None = None,
                amplitude: float | None = None, mode: str = "continuous", rate_hz: Any = None,
                input: str | None = None, output: str | None = None,
                record_dt: float | None = None, band: float | None = None,
                area: float | None = None, rates_hz: Any = None) -> LoopResponseResult:
        """Impulse response (``[signals] disturbance`` to ``output`` by default).

        Parameters
        ----------
        _t_end_s : float, optional
            Deprecated: ``t_end_s`` given by position.
        t_end_s : float, optional
            Simulated time [s] (default 1).
        amplitude : float, optional
            Impulse area, the disturbance's unit times seconds (default
            :attr:`default_impulse`, 0.05: the SEA's 0.05 N m s).
        mode : str
            ``"continuous"`` or ``"sampled"``.
        rate_hz : float or dict, optional
            As :meth:`step`.
        input, output : str, optional
            Override the file's disturbance and output signals.
        record_dt : float, optional
            Recording interval [s] (continuous mode).
        band : float, optional
            Recovery band of the metrics, relative to the peak deviation (default 0.05).
        area, rates_hz : optional
            Deprecated spellings of ``amplitude`` and ``rate_hz``.

        Returns
        -------
        LoopResponseResult
            As :meth:`step`; ``position`` in the output's unit.
        """
        t_end_s, rate_hz = self._old_arguments(_t_end_s, t_end_s, rates_hz, rate_hz)
        t_end_s = 1.0 if t_end_s is None else t_end_s
        if area is not None:
            warnings.warn("impulse(area=) is deprecated; use amplitude=", DeprecationWarning,
                          stacklevel=2)
            amplitude = area if amplitude is None else amplitude
        size = self.default_impulse if amplitude is None else amplitude
        return self._loop_response("impulse", size, t_end_s, mode, rate_hz, input, output,
                              record_dt, band)

    @staticmethod
    def _old_arguments(t_pos: Any, t_end_s: float | None, rates_hz: Any, rate_hz: Any
                       ) -> tuple[float | None, Any]:
        """Positional ``t_end_s`` and ``rates_hz=``: deprecated spellings."""
        if t_pos is not None:
            warnings.warn("a positional t_end_s is deprecated; pass t_end_s=",
                          DeprecationWarning, stacklevel=3)
            t_end_s = t_pos
        if rates_hz is not None:
            warnings.warn("rates_hz= is deprecated; use rate_hz=", DeprecationWarning,
                          stacklevel=3)
            rate_hz = rates_hz if rate_hz is None else rate_hz
        return t_end_s, rate_hz

    def monte_carlo(self, kind: str = "step", *, latency: Any = None, loss: Any = None,
                    runs: int = 100, seed: int = 0, rate_hz: Any = None,
                    t_end_s: float | None = None, amplitude: float | None = None) -> Any:
        """Sampled step or impulse responses under random latency and message loss.

        Parameters
        ----------
        kind : {"step", "impulse"}
            Step of :attr:`default_step` on the reference, or impulse of
            :attr:`default_impulse` on the disturbance.
        latency : dict, optional
            Delayed block (one of :attr:`loops`) -> latency model of
            :mod:`seactl.latency.models` (seconds), or its text form in ms
            (``"uniform:0.5:3"``).
        loss : dict, optional
            Delayed block -> loss probability, loss model, or text (``"ge:0.01:0.3"``).
        runs : int
            Timing realizations per design.
        seed : int
            Seed (each run has its own stream: reproducible).
        rate_hz : float or dict, optional
            As :meth:`step` (default: the file's rates).
        t_end_s : float, optional
            Window [s] (default 0.5 for steps, 1 for impulses).
        amplitude : float, optional
            Step or impulse size (default :attr:`default_step` or
            :attr:`default_impulse`).

        Returns
        -------
        seactl.latency.montecarlo.MonteCarloSummary
            ``fraction_stable``, ``rms_error_mean``, ``rms_error_worst``,
            ``peak_current_worst_a`` (NaN without a current signal), ``worst_run``, the
            per-run arrays and the batched simulation.

        Examples
        --------
        >>> import seactl as sc
        >>> loop = sc.load_loop("examples/loops/paper-sea.toml")      # doctest: +SKIP
        >>> mc = loop.monte_carlo(latency={"Bq_fb": "uniform:0.5:3"}, runs=10)  # doctest: +SKIP
        >>> float(mc.fraction_stable)                                  # doctest: +SKIP
        1.0
        """
        from seactl.latency.models import parse_latency, parse_loss
        from seactl.latency.montecarlo import MonteCarloSummary, timed_simulation
        from seactl.simulate.inputs import Impulse, Step

        if kind not in ("step", "impulse"):
            raise InputError("kind", kind, "'step' or 'impulse'")
        step = kind == "step"
        t_end_s = (0.5 if step else 1.0) if t_end_s is None else t_end_s
        size = _amplitude((self.default_step if step else self.default_impulse)
                          if amplitude is None else amplitude)
        inp, out = self._io("reference" if step else "disturbance", None, None)
        rates = self._rates(rate_hz)
        if isinstance(runs, bool) or not isinstance(runs, (int, np.integer)) \
                or not 1 <= runs <= 100_000:
            raise InputError("runs", runs, "an integer in [1, 100000]")
        self._check_loop_simulation("sampled", rates, t_end_s, None, int(runs))
        lat = {k: parse_latency(v, f"latency {k}") if isinstance(v, str) else v
               for k, v in (latency or {}).items()}
        los = {k: parse_loss(v, f"loss {k}") if isinstance(v, str) else v
               for k, v in (loss or {}).items()}
        cur = self._current_signal()
        res = timed_simulation(self.diagram, self.design, {inp: Step(size) if step
                                                           else Impulse(size)}, t_end_s,
                               latency=lat, loss=los, runs=runs, seed=seed, rates_hz=rates,
                               outputs=(out,) + ((cur,) if cur and cur != out else ()))
        y = res.outputs[out]
        rms = np.sqrt(np.mean((y / size - 1.0 if step else y) ** 2, axis=-1))
        peak = np.max(np.abs(res.outputs[cur]), axis=-1) if cur else np.full(rms.shape,
                                                                             np.nan)
        return MonteCarloSummary(kind, int(runs), res.stable, np.where(res.stable, rms, np.nan),
                                 np.where(res.stable, peak, np.nan), res)


# ------------------------------------------------------------------ helpers
def _amplitude(value: Any) -> float:
    """A step or impulse size: a finite non-zero number (in the loop file's units)."""
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        v = float("nan")
    if not (np.isfinite(v) and v != 0):
        raise InputError("amplitude", value, "a finite non-zero number (the loop file's "
                         "units)")
    return v
