"""
A sampled step response and its verdict
=======================================

A 14 Hz design with gain scale 2, simulated with each controller running at 1 kHz (delays as
whole sample buffers, the motor current limited), next to the certified verdict of the
linear sampled-data loop. Command line: ``seactl step --fn 14 --t-tau 0.5 --t-qs 1.5 --t-qd
0.5 --f-qd 50 --f-taud 100 --gs 2 --mode sampled --plot s.png``.
"""

import seactl as sc

d = sc.design(14, gs=2, delays_ms={"torque": 0.5, "stiffness": 1.5, "damping": 0.5},
              filters_hz=(50, 100))
r = d.step(t_end_s=0.4, mode="sampled", rate_hz=1000)
v = r.verdict()
print(f"simulated response at 1 kHz: {v.verdict[0]}")
print(f"sampled loop at 1 kHz, certified: {d.margins(rate_hz=1000).records()[0]['verdict']}")

ax = r.plot()

# %%
# Run the same controllers at 27.5 Hz instead and the sampled-data loop is unstable,
# although the continuous loop is stable: the hold and the sample buffers add delay on the
# order of a sample period, far more than the continuous loop's delay margin.
cont = d.margins().records()[0]
slow = d.margins(rate_hz=27.5).records()[0]
print(f"continuous loop: {'stable' if cont['stable'] else 'unstable'}, "
      f"delay margin {cont['delay_margin_ms']:.2f} ms")
print(f"sample period at 27.5 Hz: {1e3 / 27.5:.1f} ms; sampled-data loop: {slow['verdict']}")

# %%
# The simulated step at 27.5 Hz agrees: it grows instead of settling, and the current
# spends most of the time at its limit.
r_slow = d.step(t_end_s=1.0, mode="sampled", rate_hz=27.5)
v_slow = r_slow.verdict()
print(f"simulated response at 27.5 Hz: {v_slow.verdict[0]} "
      f"(growth rate {v_slow.growth_rate_per_s[0]:.2f} 1/s, current at its limit "
      f"{v_slow.saturated_fraction[0]:.0%} of the time)")
ax = r_slow.plot()
ax.set_title("sampled at 27.5 Hz: unstable")
