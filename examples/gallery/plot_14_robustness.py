"""
Phase margin under plant uncertainty
====================================

The gains of one design (f_n = 14 Hz, 2 ms stiffness-loop and 0.5 ms damping-loop delays)
are designed for the nominal actuator; the joint inertia, motor damping and spring
stiffness are then drawn uniformly within +/-20 % of their nominal values, and each
sample's phase margin is computed with the nominal gains. Command line:
``seactl robust --fn 14 --t-qs 2 --t-qd 0.5 --ij 20% --bm 20% --k 20%``.
"""

import matplotlib.pyplot as plt
import numpy as np

import seactl as sc

nominal = sc.UT_SEA
within = {name: (0.8 * value, 1.2 * value) for name, value in
          {"Ij": nominal.joint_inertia, "bm": nominal.motor_damping,
           "k": nominal.spring_stiffness}.items()}
r = sc.parameter_robustness(fn_hz=14, t_qs_ms=2, t_qd_ms=0.5, n_samples=2000, seed=1,
                            **within)
lo, hi = r.p_unstable_ci95()
print(f"nominal phase margin {r.nominal_phase_margin_deg:.1f} deg")
print(f"unstable in {r.p_unstable:.1%} of {r.n_samples} samples "
      f"(95 % interval {lo:.1%} to {hi:.1%})")
stable_pm = r.phase_margin_deg[r.stable & np.isfinite(r.phase_margin_deg)]
print(f"phase margin of the stable samples: {np.percentile(stable_pm, 5):.1f} deg (5th "
      f"percentile) to {np.percentile(stable_pm, 95):.1f} deg (95th)")

# %%
fig, ax = plt.subplots()
ax.hist(stable_pm, bins=40)
ax.axvline(r.nominal_phase_margin_deg, color="k", ls="--", label="nominal")
ax.set_xlabel("phase margin [deg]")
ax.set_ylabel("samples")
ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1))
fig.tight_layout()
