"""seactl: distributed impedance control of series elastic and rigid actuators.

Implements Zhao & Sentis, "Distributed Impedance Control of Latency-Prone Robotic Systems
with Series Elastic Actuation": the SEA cascaded loop with exact delays and filters
(:mod:`seactl.loops`), critically-damped gain design (:mod:`seactl.design`), exact-delay
margins (:mod:`seactl.margins`) and the paper's reproduction (``seactl reproduce``).
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("seactl")
except PackageNotFoundError:  # pragma: no cover - running from a source tree
    __version__ = "0+unknown"
