"""The omnidirectional base in the public API: its parameters and architectures compared."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from seactl.api.arguments import resolve_actuator


# ------------------------------------------------------------------ mobile base
def compare_mobile_base(params: Any = "trikey", *, archs: Sequence[str] = ("cosc", "dosc"),
                track: bool = True) -> Any:
    """Tune the omnidirectional base's controllers, centralized (COSC) vs distributed (DOSC).

    Runs the paper's procedure: raise damping until the base vibrates, then stiffness,
    then track a circle at a safety factor of both limits.

    Parameters
    ----------
    params : str or path or MobileBaseParams
        Preset (``"trikey"``), TOML file, or
        :class:`~seactl.systems.mobile_base.model.MobileBaseParams`.
    archs : sequence of {"cosc", "dosc"}
        Architectures to tune.
    track : bool
        Also simulate the circle tracking (RMS errors).

    Returns
    -------
    seactl.systems.mobile_base.tuning.MobileBaseComparison
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
    from seactl.systems.mobile_base.tuning import tune

    return tune(mobile_base_params(params), tuple(archs), track=track)


def mobile_base_params(params: Any = "trikey") -> Any:
    """The mobile base's parameters: a preset name, a TOML file, or the object itself.

    Parameters
    ----------
    params : str or path or MobileBaseParams
        ``"trikey"`` (default), a TOML file, or a
        :class:`~seactl.systems.mobile_base.model.MobileBaseParams`.

    Returns
    -------
    seactl.systems.mobile_base.model.MobileBaseParams
        Validated parameters.

    Examples
    --------
    >>> import seactl as sc
    >>> round(sc.mobile_base_params().base_mass, 1)
    32.7
    """
    from seactl.systems.mobile_base.model import MobileBaseParams, load_base

    return resolve_actuator(params, load_base, MobileBaseParams)
