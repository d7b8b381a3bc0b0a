"""
Z-region: the range of impedances a design set can render
=========================================================

The Z-region (this project's definition, see the Z-region page of the theory) is the band
between the largest and smallest impedance magnitude that the admissible designs of a set
render at each frequency; its height in dB is the Z-width. Here the set is the
critically-damped designs over ``f_n`` = 12-30 Hz and gain scales 0.5-2, with the paper's
delays and filters, and a design is admissible when it is stable with a phase margin of at
least 30 degrees. Command line: ``seactl zregion --fn 12:30:2 --gs 0.5:2:0.25``.
"""

import matplotlib.pyplot as plt
import numpy as np

import seactl as sc

f_hz = np.geomspace(0.1, 1000, 300)
d = sc.design(np.arange(12, 30.1, 2)[:, None], gs=np.arange(0.5, 2.01, 0.25),
              delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5}, filters_hz=(50, 100))
m = d.margins()
admissible = m.stable & (m.phase_margin_deg >= 30)
mag = np.abs(d.impedance(f_hz).z)[admissible]          # admissible designs x frequencies
upper, lower = mag.max(axis=0), mag.min(axis=0)
width_db = 20 * np.log10(upper / lower)
print(f"{admissible.sum()} of {admissible.size} designs admissible")
print(f"Z-width: {width_db[0]:.1f} dB at {f_hz[0]:g} Hz, {width_db[-1]:.1f} dB at {f_hz[-1]:g} Hz")

# %%
# The band is wide at low frequency, where each design renders its virtual spring ``K_q``,
# and closes at high frequency, where every design renders the physical spring. In between,
# around the 100 Hz torque-derivative filter, the designs' resonances spread it.
fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
a1.fill_between(f_hz, lower, upper, alpha=0.4, label="Z-region")
a1.loglog(f_hz, upper, f_hz, lower, color="C0")
a1.set_ylabel("|Z| [N m s/rad]")
a1.legend(loc="upper right")
a2.semilogx(f_hz, width_db)
a2.set_ylabel("Z-width [dB]")
a2.set_xlabel("frequency [Hz]")
