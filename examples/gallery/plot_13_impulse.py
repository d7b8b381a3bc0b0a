"""
Why the filters: a sampled impulse response
===========================================

An impulse of the external load on a 14 Hz design, simulated with the controllers at 1 kHz,
once with the paper's 50 Hz velocity filter and 100 Hz torque-derivative filter and once
without filters. Command line: ``seactl impulse --fn 14 --f-qd 50 --f-taud 100 --mode
sampled`` and ``seactl impulse --fn 14 --mode sampled``.
"""

import matplotlib.pyplot as plt

import seactl as sc

filtered = sc.design(14, filters_hz=(50, 100)).impulse(mode="sampled")
unfiltered = sc.design(14).impulse(mode="sampled")
for name, r in (("with filters", filtered), ("without filters", unfiltered)):
    v = r.verdict()
    extra = (f" at {v.oscillation_hz[0]:.0f} Hz in the {v.oscillating_signal[0]}"
             if v.verdict[0] == "limit cycle" else "")
    print(f"{name:16s}: {v.verdict[0]}{extra}")
print(f"Nyquist frequency of the 1 kHz controllers: {1000 / 2:g} Hz")

# %%
# Without filters the sampled loop does not settle: the motor current keeps switching
# between its limits at the Nyquist frequency (right, a solid band), a limit cycle the
# continuous-time analysis cannot show. The filters remove it.
fig, axs = plt.subplots(1, 2, figsize=(8.5, 3.4))
for name, r in (("without filters", unfiltered), ("with filters", filtered)):
    axs[0].plot(r.t_s, r.position, label=name)
    axs[1].plot(r.t_s, r.current_a, label=name, linewidth=0.6)
axs[0].set_ylabel("joint position q_j [rad]")
axs[1].set_ylabel("motor current [A]")
for ax in axs:
    ax.set_xlabel("time [s]")
axs[1].legend(loc="lower right")
