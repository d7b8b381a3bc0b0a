"""
Monte Carlo with random latency and packet loss
===============================================

A 14 Hz design simulated at 1 kHz many times, the torque loop's latency drawn uniformly
between 0.5 and 3 ms at each sample and 1 % of the damping loop's packets lost. Command
line: ``seactl step --fn 14 --t-tau 0.5 --t-qs 2 --t-qd 0.5 --mode sampled --latency
torque=uniform:0.5:3 --loss damping=0.01 --runs 1000 --seed 1``.
"""

import seactl as sc

d = sc.design(14, delays_ms={"torque": 0.5, "stiffness": 2, "damping": 0.5})
mc = d.monte_carlo(latency={"torque": "uniform:0.5:3"}, loss={"damping": 0.01}, runs=200,
                   seed=1, t_end_s=0.4)
print(f"{float(mc.fraction_stable):.1%} of 200 runs stable")
torque_jm = d.jitter_margins().records()[0]["torque_jitter_margin_ms"]
print(f"torque loop: latency jitter of {3 - 0.5:g} ms drawn, jitter margin {torque_jm:.2f} ms")

# %%
# With nominal timing the design is stable. The jitter margin is a guarantee: jitter below
# it cannot destabilize the loop. The drawn jitter exceeds it, so stability is no longer
# guaranteed, and the runs counted above as not stable are the ones that lost it.
ax = mc.plot()
