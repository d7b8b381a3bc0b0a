"""
Latency map
===========

Phase margin of the rigid actuator's 8 Hz design over a grid of stiffness-loop and
damping-loop delays (hatched: unstable). Command line: ``seactl latency-map --plot maps.png``.
"""

import numpy as np

import seactl as sc

grid_ms = np.linspace(0, 25, 26)
lm = sc.latency_map(8, grid_ms, grid_ms, kind="rigid")
print(f"stable on {np.mean(lm.stable):.0%} of the grid")

# %%
# The stable region reaches far along the stiffness-delay axis and only a few milliseconds
# along the damping-delay axis.
ax = lm.plot()
