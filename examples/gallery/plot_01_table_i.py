"""
Gains and margins of Table I
============================

Critically-damped gains of the UT-SEA for natural frequencies of 12 to 20 Hz, with the
paper's delays (0.5 ms torque loop, 2 ms stiffness loop, 0.5 ms damping loop) and 50 / 100 Hz
filters, and the phase and delay margins of the exact-delay loop (Table I of Zhao &
Sentis). Command line: ``seactl gains --fn 12 14 16 18 20 --t-tau 0.5 --t-qs 2 --t-qd 0.5
--f-qd 50 --f-taud 100``.
"""

import seactl as sc

d = sc.design([12, 14, 16, 18, 20], delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5},
              filters_hz=(50, 100))
m = d.margins()
print(" f_n [Hz]  Kq [N m/rad]  Bq [N m s/rad]  Ktau [-]  Btau [s]  PM [deg]  DM [ms]  verdict")
for r in m.records():
    print(f"{r['fn_hz']:9.0f}  {r['Kq']:12.2f}  {r['Bq']:14.3f}  {r['Ktau']:8.3f}  "
          f"{r['Btau']:8.4f}  {r['phase_margin_deg']:8.2f}  {r['delay_margin_ms']:7.2f}  "
          f"{'stable' if r['stable'] else 'unstable'}")

# %%
# Every design of Table I is stable; the phase margin falls as the natural frequency rises.
ax = m.plot()

# %%
# Below the feasibility bound no critically-damped gain set with four positive gains exists,
# and the design is refused with the feasible range:
try:
    sc.design(8)
except sc.InfeasibleDesignError as exc:
    print(exc)
