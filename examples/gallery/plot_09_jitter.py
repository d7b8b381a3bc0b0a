"""
Jitter margins per loop
=======================

How much latency jitter each loop tolerates on top of its nominal delay before the loop may
lose stability (Kao-Lincoln), for a 14 Hz design with the paper's delays and filters. Command
line: ``seactl jitter --fn 14 --t-tau 0.5 --t-qs 2 --t-qd 0.5 --f-qd 50 --f-taud 100``.
"""

import seactl as sc

d = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
              filters_hz=(50, 100))
j = d.jitter_margins()
r = j.records()[0]
for loop in ("torque", "stiffness", "damping"):
    print(f"{loop:9s} loop alone: jitter margin {r[loop + '_jitter_margin_ms']:6.2f} ms")
print(f"all loops together: {r['jitter_margin_ms']:.2f} ms "
      f"(delay margin {r['delay_margin_ms']:.2f} ms)")

# %%
# The torque loop, closed on the drive, tolerates the least jitter.
ax = j.plot()
