"""Building a user loop: from a loop file (:func:`load_loop`) or in code (:class:`LoopBuilder`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from seactl.api.userloop import UserLoop
from seactl.errors import LoopFileError
from seactl.userloop.expressions import parse_expr
from seactl.userloop.loopfile import check_name, compile_loop, parse_block
from seactl.userloop.schema import read_toml_file

_BUILDER = "<builder>"


class LoopBuilder:
    """Build a loop in Python, with the same blocks, checks and errors as a loop file.

    Each call validates what it adds at once (a :class:`~seactl.LoopFileError` names
    the block and field); :meth:`build` checks the structure and returns a
    :class:`UserLoop`.

    Parameters
    ----------
    name : str
        The loop's name.
    description : str
        Free text.

    Examples
    --------
    A rigid mass under PD control with the stiffness on a slow process:

    >>> import seactl as sc
    >>> loop = (sc.LoopBuilder("rigid")
    ...         .variables(m=256.0, b=1250.0, fn=8.0)
    ...         .parameters(K="m * (2*pi*fn)^2", B="2*m*2*pi*fn - b")
    ...         .process("embedded", rate_hz=1000).process("high", rate_hz=1000)
    ...         .block("x_sensor", "sensor", input="x", output="x_s")
    ...         .block("K_ref", "gain", input="x_des", output="F", gain="K", process="high")
    ...         .block("K_fb", "gain", input="x_s", output="F", gain="-K", process="high",
    ...                delay_ms=1.5)
    ...         .block("B_fb", "pd", input="x_s", output="F", kd="-B",
    ...                process="embedded", delay_ms=1.5)
    ...         .block("mass", "inertia", input=["F", "F_ext"], output="x", inertia="m",
    ...                damping="b")
    ...         .signals(inputs=["x_des", "F_ext"], reference="x_des", output="x")
    ...         .break_at("position", "x_s").build())
    >>> round(float(loop.analyze()["position"].margins.phase_margin_deg), 1)  # as sc.rigid
    69.4
    """

    def __init__(self, name: str = "loop", description: str = ""):
        self._data: dict[str, Any] = {"name": name, "description": description,
                                      "variables": {}, "parameters": {}, "processes": {},
                                      "blocks": [], "breaks": [], "ports": [], "signals": {}}

    def _known(self) -> list[str]:
        return [*self._data["variables"], *self._data["parameters"]]

    def variables(self, **values: float) -> LoopBuilder:
        """Add design variables (numbers; ``--set`` and :meth:`UserLoop.with_values`
        override them).

        Parameters
        ----------
        **values : float
            Name -> value.

        Returns
        -------
        LoopBuilder
            This builder.
        """
        for k, v in values.items():
            check_name(k, _BUILDER, f"variable name {k!r}")
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
                raise LoopFileError(_BUILDER, f"variable {k!r}", v, "a finite number "
                                    "(expressions go to parameters())")
            self._data["variables"][k] = float(v)
        return self

    def parameters(self, **exprs: float | str) -> LoopBuilder:
        """Add derived parameters: numbers or expressions of variables and earlier
        parameters (``"m * (2*pi*fn)^2"``).

        Parameters
        ----------
        **exprs : float or str
            Name -> number or expression.

        Returns
        -------
        LoopBuilder
            This builder.
        """
        for k, v in exprs.items():
            check_name(k, _BUILDER, f"parameter name {k!r}")
            parse_expr(v, _BUILDER, f"parameter {k!r}", self._known())
            self._data["parameters"][k] = v
        return self

    def process(self, name: str, rate_hz: float = 1000.0, latency_ms: float | str | None = None,
                latency_s: float | str | None = None) -> LoopBuilder:
        """Declare a process (a processor the controller blocks run on).

        Parameters
        ----------
        name : str
            Process name.
        rate_hz : float
            Its rate [Hz] (sampled simulations).
        latency_ms : float or str
            The delay of its blocks that say ``delay_ms="process"`` [ms] (number or
            expression; default 0).
        latency_s : float or str, optional
            The same in seconds (give one of the two).

        Returns
        -------
        LoopBuilder
            This builder.
        """
        self._data["processes"][name] = {"rate_hz": rate_hz, **{
            k: v for k, v in (("latency_ms", latency_ms), ("latency_s", latency_s))
            if v is not None}}
        return self

    def block(self, name: str, kind: str, *, input: str | Sequence[str], output: str,
              process: str | None = None, delay_ms: float | str | None = None,
              measurement: str | None = None, **params: Any) -> LoopBuilder:
        """Add a block (see docs/loops.md for the kinds and their fields).

        Parameters
        ----------
        name : str
            Unique block name.
        kind : str
            ``inertia``, ``load``, ``spring``, ``damper``, ``current_to_torque``, ``gain``,
            ``sum``, ``sensor``, ``delay``, ``pd``, ``pid``, ``lowpass1``, ``lowpass2``,
            ``notch``, ``leadlag``, ``tf`` or ``dob``.
        input : str or sequence of str
            Input signal, or signed signals summed in front of the block (``"-y"``).
        output : str
            Output signal (the block adds into it).
        process : str, optional
            The process a controller block runs on.
        delay_ms : float or str, optional
            Exact delay [ms]: number, expression, or ``"process"`` (its latency); or
            ``delay_s=`` (in ``params``) in seconds, not both.
        measurement : str, optional
            The measured signal of a ``dob`` block.
        **params : Any
            The kind's fields (numbers or expressions).

        Returns
        -------
        LoopBuilder
            This builder.
        """
        if not isinstance(input, str) and not (isinstance(input, Sequence) and all(
                isinstance(x, str) for x in input)):
            raise LoopFileError(_BUILDER, f"block {name!r}, field 'input'", input,
                                "a signal name or a sequence of signed signal names")
        data = {"name": name, "kind": kind, "input": input if isinstance(input, str)
                else list(input), "output": output, **params}
        for key, val in (("process", process), ("delay_ms", delay_ms),
                         ("measurement", measurement)):
            if val is not None:
                data[key] = val
        procs = self._data["processes"]
        parse_block(data, _BUILDER, self._known(), procs, self._data.get("default_process"))
        self._data["blocks"].append(data)
        return self

    def break_at(self, name: str, signal: str) -> LoopBuilder:
        """Name a loop-break point (list inner loops first).

        Parameters
        ----------
        name : str
            The loop's name.
        signal : str
            The signal where the loop is broken (usually a sensor's output).

        Returns
        -------
        LoopBuilder
            This builder.
        """
        self._data["breaks"].append({"name": name, "signal": signal})
        return self

    def port(self, name: str, position: str, force: str, sign: float = -1.0) -> LoopBuilder:
        """Name an impedance port ``Z = sign * force / (s position)``, position imposed.

        Parameters
        ----------
        name : str
            Port name.
        position, force : str
            Signals: the imposed motion and the force (torque) measured.
        sign : float
            -1 (default) when ``force`` acts on the moving body.

        Returns
        -------
        LoopBuilder
            This builder.
        """
        self._data["ports"].append({"name": name, "position": position, "force": force,
                                    "sign": sign})
        return self

    def signals(self, inputs: Sequence[str] = (), reference: str | None = None,
                disturbance: str | None = None, output: str | None = None, *,
                reference_step: float | None = None, reference_unit: str | None = None
                ) -> LoopBuilder:
        """Declare the exogenous inputs and the default signals of the responses.

        Parameters
        ----------
        inputs : sequence of str
            Signals fed by no block (references, disturbances).
        reference, disturbance : str, optional
            The inputs a step and an impulse drive by default.
        output : str, optional
            The response's default output signal.
        reference_step : float, optional
            The default step amplitude (:attr:`UserLoop.default_step`; default 0.01).
        reference_unit : str, optional
            The reference's unit (:attr:`UserLoop.step_unit`).

        Returns
        -------
        LoopBuilder
            This builder.
        """
        sig = {"inputs": list(inputs), "reference": reference, "disturbance": disturbance,
               "output": output, "reference_step": reference_step,
               "reference_unit": reference_unit}
        self._data["signals"] = {k: v for k, v in sig.items() if v is not None}
        return self

    def build(self) -> UserLoop:
        """Check the whole structure and compile the loop.

        Returns
        -------
        UserLoop
            The loop at the variables' values.
        """
        return UserLoop(compile_loop(self._data, _BUILDER))


def load_loop(path: str | Path, **values: Any) -> UserLoop:
    """Load a loop file (TOML, docs/loops.md).

    Parameters
    ----------
    path : str or Path
        The ``.toml`` loop file.
    **values : float or array_like
        Overrides of design variables or parameters (arrays make a design batch).

    Returns
    -------
    UserLoop
        The validated, compiled loop.

    Raises
    ------
    LoopFileError
        The file is missing or invalid; the message names the file, the block and field,
        the value and what is valid.

    Examples
    --------
    An integrator ``K/s`` with a 10 ms delay in unity feedback (PM = 90 - K T deg):

    >>> import seactl, tempfile, pathlib
    >>> lines = [
    ...     'variables = { K = 10.0 }',
    ...     'processes = { cpu = { rate_hz = 1000 } }',
    ...     'signals = { inputs = ["r"], reference = "r", output = "y" }',
    ...     'breaks = [ { name = "main", signal = "y_m" } ]',
    ...     '[[blocks]]',
    ...     'name = "ctrl"',
    ...     'kind = "gain"',
    ...     'input = ["r", "-y_m"]',
    ...     'output = "u"',
    ...     'gain = "K"',
    ...     'delay_ms = 10',
    ...     '[[blocks]]',
    ...     'name = "plant"',
    ...     'kind = "plant_tf"',
    ...     'input = "u"',
    ...     'output = "y"',
    ...     'num = [1]',
    ...     'den = [1, 0]',
    ...     '[[blocks]]',
    ...     'name = "sensor"',
    ...     'kind = "sensor"',
    ...     'input = "y"',
    ...     'output = "y_m"']
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "integrator.toml"
    >>> _ = path.write_text(chr(10).join(lines))
    >>> m = seactl.load_loop(path, K=[5.0, 10.0]).analyze()["main"].margins
    >>> m.phase_margin_deg.round(4).tolist(), (90 - np.degrees([0.05, 0.1])).round(4).tolist()
    ([87.1352, 84.2704], [87.1352, 84.2704])
    """
    data = read_toml_file(path, "loop file")
    loop = UserLoop(compile_loop(data, str(path)))
    return loop.with_values(**values) if values else loop
