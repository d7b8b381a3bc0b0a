"""
Rigid actuator: gains and per-loop delay margins
================================================

The rigid linear actuator (no spring), critically damped at 8 Hz with a 15 ms stiffness-loop
delay and a 1 ms damping-loop delay: its gains, how much extra latency each loop tolerates
alone, and the step response. Command line: ``seactl rigid --fn 8 --t-s 15 --t-d 1``.
"""

import seactl as sc

r = sc.rigid(8, delays_ms={"stiffness": 15, "damping": 1})
m = r.margins().records()[0]
print(f"K = {m['K']:.0f} N/m, B = {m['B']:.0f} N s/m, "
      f"phase margin {m['phase_margin_deg']:.1f} deg, "
      f"delay margin {m['delay_margin_ms']:.1f} ms: {'stable' if m['stable'] else 'unstable'}")
dm = r.delay_margins()
print(f"delay margin of the stiffness loop alone: {float(dm.stiffness_s) * 1e3:.1f} ms")
print(f"delay margin of the damping loop alone:   {float(dm.damping_s) * 1e3:.1f} ms")

# %%
# The damping loop tolerates far less latency than the stiffness loop: it is the one to run
# next to the actuator.
ax = r.step(t_end_s=0.6).plot()
