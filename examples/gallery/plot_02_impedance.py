"""
Impedance Bode plot
===================

The impedance ``Z(jw)`` rendered at the joint by a 30 Hz design with long delays (1 ms
torque loop, 10 ms stiffness loop, 3 ms damping loop), from the block diagram with exact
delays. Command line: ``seactl impedance --fn 30 --t-tau 1 --t-qs 10 --t-qd 3 --plot z.png``.
"""

import numpy as np

import seactl as sc

d = sc.design(30, delays_ms={"torque": 1, "stiffness": 10, "damping": 3})
z = d.impedance(np.geomspace(0.1, 1000, 400))
print(f"static stiffness {z.stiffness[0].real:.1f} N m/rad (K_q = {d.gains.Kq:.1f} N m/rad)")
print(f"stable: {bool(d.margins().stable)}")

# %%
# At low frequency the joint renders the virtual spring ``K_q``; at high frequency the
# physical spring takes over.
ax = z.plot()
