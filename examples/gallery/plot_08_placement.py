"""
Where to place each loop
========================

A high-level computer with 22 ms of feedback latency and an embedded processor with 0.5 ms:
the advisor scores each placement of the stiffness and damping loops by the largest natural
frequency that keeps a 45 degree phase margin for every latency up to 1.5 times each loop's
own. Command line: ``seactl place --high-latency 22 --low-latency 0.5``.
"""

import seactl as sc

advice = sc.place(22, 0.5)
print(f"recommended: {advice.recommended}")
for o in advice.to_dict()["options"]:
    print(f"{o['placement']:12s} score f_n = {o['fn_hz'] or 0:6.2f} Hz")
print(advice.advice.reason)

# %%
ax = advice.plot()
