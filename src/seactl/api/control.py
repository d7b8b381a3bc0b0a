"""Export transfers of a block diagram to python-control.

``frd``: the exact-delay frequency response, evaluated by the diagram itself.
``pade``: the diagram's derived expression (a rational function of its block
responses) evaluated with python-control transfer functions, each delayed block
multiplied by the Padé approximant of its delay; the result is then minimized.
Both come from the same derived transfer, so there is no second model.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from seactl.errors import InputError

KINDS = ("frd", "pade", "pade-ss")
SEA_TRANSFERS = ("loop", "inner", "closed", "impedance")
MAX_PADE_ORDER = 4
"""Beyond this, the SEA's polynomial coefficients exceed 1e60 and margins fail."""


RIGID_TRANSFERS = ("loop", "closed", "compliance")


def sea_transfer(name: str) -> tuple[Any, bool]:
    """The SEA transfer called ``name`` and whether it is divided by ``-s`` (impedance)."""
    from seactl.systems.sea import loops
    from seactl.systems.sea.impedance import impedance_transfer

    table = {"loop": loops.outer_loop, "inner": loops.inner_loop,
             "closed": loops.closed_loop, "impedance": impedance_transfer}
    if name not in table:
        raise InputError("transfer", name, "one of " + ", ".join(SEA_TRANSFERS))
    return table[name](), name == "impedance"


def rigid_transfer(name: str) -> tuple[Any, bool]:
    """The rigid-actuator transfer called ``name`` (never divided by ``-s``)."""
    from seactl.systems.rigid.model import rigid_closed_loop, rigid_compliance, rigid_loop

    table = {"loop": rigid_loop, "closed": rigid_closed_loop, "compliance": rigid_compliance}
    if name not in table:
        raise InputError("transfer", name, "one of " + ", ".join(RIGID_TRANSFERS))
    return table[name](), False


def block_tf(block: Any, design: Any, order: int) -> Any:
    """One block as a python-control transfer function, its delay as a Padé approximant."""
    import control as ct

    num, den = block.coefficients(design)
    g = ct.tf([float(c) for c in num], [float(c) for c in den])
    if block.delay is not None:
        delay = float(getattr(design, block.delay))
        if delay > 0:
            g = g * ct.tf(*ct.pade(delay, order))
    return g


def pade_tf(transfer: Any, design: Any, order: int) -> Any:
    """The transfer as one rational python-control model (delays by Padé of ``order``)."""
    import control as ct
    import sympy as sp

    expr = transfer.expression()
    names = sorted(str(x) for x in expr.free_symbols)
    func = sp.lambdify([sp.Symbol(n) for n in names], expr, modules=[{}, "math"])
    value = func(*(block_tf(transfer.diagram.block(n), design, order) for n in names))
    if not isinstance(value, ct.TransferFunction):
        value = ct.tf([float(value)], [1.0])
    return ct.minreal(value, verbose=False)


def to_control(design: Any, kind: str, transfer: str, f_hz: Any, order: int,
               transfers: Any = sea_transfer) -> Any:
    """Export one design (a 0-d batch); see :meth:`seactl.api.sea.Design.to_control`.
    ``transfers`` maps a transfer name to ``(Transfer, divide by -s)``."""
    import control as ct

    if kind not in KINDS:
        raise InputError("kind", kind, "one of " + ", ".join(KINDS))
    T, integrate = transfers(transfer)
    if kind == "frd":
        f = np.geomspace(0.01, 1e4, 2000) if f_hz is None else np.asarray(f_hz, float)
        if f.ndim != 1 or f.size < 2 or not np.all(np.isfinite(f)) or np.any(f <= 0):
            raise InputError("f_hz", f_hz, "at least two finite frequencies > 0 [Hz]")
        s = 2j * np.pi * f
        resp = np.reshape(T(design, s), (-1,))
        if integrate:
            resp = resp / (-s)
        return ct.frd(resp, 2 * np.pi * f)
    if int(order) != order or not 1 <= order <= MAX_PADE_ORDER:
        raise InputError("order", order, f"an integer in [1, {MAX_PADE_ORDER}] (Padé order per "
                         "delay; higher orders overflow the polynomial coefficients)")
    sys = pade_tf(T, design, int(order))
    if integrate:
        sys = ct.minreal(sys * ct.tf([-1.0], [1.0, 0.0]), verbose=False)
    return ct.ss(sys) if kind == "pade-ss" else sys
