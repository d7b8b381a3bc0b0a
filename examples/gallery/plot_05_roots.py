"""
Rightmost closed-loop roots
===========================

The rightmost characteristic roots of the closed loop with exact delays, each with a disc
that is proven to contain it, and the spectral abscissa (the slowest decay rate). The design
sits near the paper's stability boundary: a 15.93 Hz design with gain scale 1.867 and
delays of 1.99 ms (torque), 1.96 ms (stiffness) and 18.54 ms (damping). Command line:
``seactl roots --fn 15.93 --gs 1.867 --t-tau 1.99 --t-qs 1.96 --t-qd 18.54``.
"""

import numpy as np

import seactl as sc

d = sc.design(15.93, gs=1.867, delays_ms={"torque": 1.99, "stiffness": 1.96, "damping": 18.54})
roots = d.roots(count=6)
rec = roots.records()[0]
print("   Re [1/s]    Im [rad/s]   f [Hz]   disc radius")
for z in rec["roots"]:
    f_hz = z["im"] / (2 * np.pi)
    print(f"{z['re']:11.3f}  {z['im']:11.3f}  {f_hz:7.2f}  {z['radius']:.1e}")
print(f"spectral abscissa {rec['spectral_abscissa']:.3f} 1/s: "
      f"{'stable' if rec['stable'] else 'unstable'}, "
      f"{rec['right_half_plane_roots']} roots in the right half-plane")

# %%
# A root with a positive real part (counted with its conjugate) makes the closed loop
# unstable: this design oscillates at the frequency of its rightmost root, with an amplitude
# that grows at the rate of the spectral abscissa.
ax = roots.plot()
