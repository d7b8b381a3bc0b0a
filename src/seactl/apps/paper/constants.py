"""The paper's printed numbers and the timing they were computed with, declared once.

Every report section that compares with Table I or reuses its timing imports from here.
"""

from __future__ import annotations

TABLE_I: dict[int, tuple[float, float, float, float, float]] = {
    12: (65, 0.46, 1.18, 0.057, 45.1),
    14: (83, 0.76, 1.80, 0.067, 43.2),
    16: (103, 1.02, 2.56, 0.077, 40.0),
    18: (124, 1.26, 3.45, 0.087, 36.5),
    20: (148, 1.49, 4.48, 0.097, 33.2),
}
"""Table I: f_n [Hz] -> (K_q, B_q, K_tau, B_tau, PM [deg]) as printed."""

TABLE_I_DECIMALS = (0, 2, 2, 3, 1)
"""Decimals printed in each column of Table I."""

TABLE_I_FN = tuple(float(f) for f in TABLE_I)
"""The natural frequencies of Table I [Hz]."""

TABLE_I_PM = {float(f): row[4] for f, row in TABLE_I.items()}
"""Table I's printed phase margins [deg] by f_n [Hz]."""

FILTERS = dict(f_qd_hz=50.0, f_taud_hz=100.0)
"""The velocity and torque-derivative filter cut-offs of Table I [Hz]."""

TABLE_I_TIMING = dict(t_tau_ms=0.5, t_qs_ms=2.0, t_qd_ms=0.5, **FILTERS)
"""Table I's delays [ms] and filters [Hz] by name (:func:`design_keywords` makes them
the keywords of :func:`seactl.design`)."""


def design_keywords(t_tau_ms=0.0, t_qs_ms=0.0, t_qd_ms=0.0, f_qd_hz=None, f_taud_hz=None):
    """Delays [ms] and filters [Hz] given by name (as :data:`TABLE_I_TIMING`) as the
    keywords of :func:`seactl.design`: ``delays_ms={"torque": T_tau, "stiffness": T_qs,
    "damping": T_qd}``, ``filters_hz=(f_qd, f_taud)``."""
    return {"delays_ms": {"torque": t_tau_ms, "stiffness": t_qs_ms, "damping": t_qd_ms},
            "filters_hz": (f_qd_hz, f_taud_hz)}
