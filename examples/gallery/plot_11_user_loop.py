"""
Your own loop from a loop file
==============================

A loop file (TOML) names the blocks, delays, processes and break points of any loop; seactl
compiles it onto the same block diagram and gives it every analysis. Here the paper's SEA loop
as a loop file (``examples/loops/paper-sea.toml``): margins at each break point, then a
loop with a disturbance observer (``examples/loops/sea-dob.toml``) stepped at three observer
bandwidths. Command line: ``seactl analyze --loop examples/loops/paper-sea.toml``.
"""

from pathlib import Path

import seactl as sc

try:
    HERE = Path(__file__).resolve().parent
except NameError:        # sphinx-gallery runs the script in its folder without __file__
    HERE = Path.cwd()
LOOPS = HERE.parent / "loops"

paper = sc.load_loop(LOOPS / "paper-sea.toml")
for r in paper.analyze().records():
    print(f"torque loop: PM {r['torque_phase_margin_deg']:.1f} deg, "
          f"delay margin {r['torque_delay_margin_ms']:.2f} ms")
    print(f"outer loop:  PM {r['outer_phase_margin_deg']:.1f} deg, "
          f"delay margin {r['outer_delay_margin_ms']:.2f} ms")
    print("stable" if r["stable"] else "unstable")

# %%
# The disturbance-observer loop, its observer bandwidth ``q_hz`` a design variable:
dob = sc.load_loop(LOOPS / "sea-dob.toml", q_hz=[5, 10, 20])
step = dob.step(mode="sampled")
for q, v in zip([5, 10, 20], step.verdict().verdict):
    print(f"q_hz = {q:2d} Hz: {v}")
ax = step.plot()
