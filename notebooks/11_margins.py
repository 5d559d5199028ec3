# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#       jupytext_version: 1.19.6
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # 11. Margins: what LQR guarantees and LQG does not
#
# A control engineer judges a loop first in the frequency domain: how much gain, phase and delay it tolerates at
# the plant input before it goes unstable, and how close its Nyquist curve comes to -1. This notebook reads those
# margins for the lab's designs with [python-control](https://python-control.readthedocs.io), on the model derived
# from the MJCF, and checks them in MuJoCo:
#
# 1. the continuous LQR keeps its textbook guarantees: at least 60 degrees of phase, every gain from 1/2 to
#    infinity (Kalman's inequality `|1 + L(jw)| >= 1`);
# 2. sampled at the MJCF's step the upper gain margin becomes finite, and MuJoCo agrees to the percent;
# 3. an LQG (the same gain on a Kalman filter's estimate from encoders, 10 ms period, 5 ms delay) loses margin:
#    LQG guarantees nothing (Doyle, 1978);
# 4. loop-transfer recovery (process noise raised on the input channel by a parameter `q`) gives it back.
#
# The cart-pole's loop is unstable open loop (the upright pole), so the Nyquist curve must encircle -1 once
# counter-clockwise, and the stable gains form a band `(low, high)` rather than a single number.

# %%
import os

import control
import matplotlib.pyplot as plt
import numpy as np

import cartpole as cp

QUICK = os.environ.get("CARTPOLE_QUICK") == "1"
model = cp.build_model()
sys = model.statespace()  # a python-control StateSpace, signals named from the MJCF
print(sys.state_labels, sys.input_labels)

# %% [markdown]
# ## 1. The continuous LQR's loop
#
# Broken at the plant input, the loop of `u = -K x` is `L(s) = K (sI - A)^-1 B`. The toolkit's gain is
# python-control's on the same matrices.

# %%
Q, R = cp.default_weights(model)
K = cp.lqr(sys.A, sys.B, Q, R).K
assert np.allclose(K, control.lqr(sys, Q, R)[0], rtol=1e-8)
lqr_loop = cp.continuous_loop(model, K)
m_lqr = cp.loop_margins(lqr_loop)
print(m_lqr.to_dict())
low, high = m_lqr.gain_margin
assert m_lqr.phase_margin_deg >= 60 and low <= 0.5 and high == np.inf and m_lqr.ms <= 1 + 1e-9
unstable = int(np.sum(np.linalg.eigvals(lqr_loop.L.A).real > 0))
print(f"open-loop unstable poles: {unstable}; the curve must encircle -1 {unstable} time(s) counter-clockwise")

# %% [markdown]
# python-control's `stability_margins` lists the gain at every phase crossover; for a loop that is unstable open
# loop the smallest of them is not necessarily the boundary. `loop_margins` cuts the gains there into intervals and
# asks the closed-loop eigenvalues which are stable.

# %%
print("python-control's gains at phase crossovers:", control.stability_margins(lqr_loop.L, returnall=True)[0])
for k in (0.9 * low, 1.1 * low, 1e3):
    cl = np.linalg.eigvals(model.without_friction().linearize()[0] - k * sys.B @ K)
    print(f"k = {k:.4g}: closed loop {'stable' if cl.real.max() < 0 else 'UNSTABLE'}")

# %% [markdown]
# ## 2. Sampled at the MJCF's step: what MuJoCo runs
#
# MuJoCo holds the ctrl over each 5 ms step. The loop of the same gain on the exact discrete model has less phase
# and a finite upper gain margin. In MuJoCo (from a 1 mrad tilt; stable = the error decays and the ctrl stays off
# its limits) the band is where the sampled loop says.

# %%
m_s = cp.loop_margins(cp.sampled_loop(model, K))
print(m_s.to_dict())
low_s, high_s = m_s.gain_margin
checks = [(0.95 * low_s, False), (1.05 * low_s, True)] + ([] if QUICK else [(0.95 * high_s, True),
                                                                             (1.05 * high_s, False)])
for k, expected in checks:
    got = cp.mujoco_stable(model, K, k)
    print(f"MuJoCo with the gain scaled by {k:.4g}: {'stable' if got else 'unstable'}")
    assert got == expected

# %% [markdown]
# ## 3. LQG on the rig: the margins shrink
#
# The lab's rig: a 10 ms period, 2048-count encoders on the pole, 1 mm on the cart, a 5 ms delay predicted across
# through the model. The gain is designed over the period; the Kalman filter estimates the rates. Broken at the
# plant input (the filter keeps the ctrl it sent), its loop is not the LQR's.

# %%
steps, lag = 2, 1
res = cp.LinearFeedback.for_model(model, Q, R, period=steps * model.dt)
lin = model.without_friction()
spec = cp.sensor_spec(lin, encoder_cpr=2048, encoder_resolution=0.001)
h = cp.measurement_function(lin, spec)
V = spec.measurement_covariance()
W0 = cp.process_noise(lin, steps * lin.dt)
Bd = lin.hold(steps).linearize()[1]


def lqg(q):
    """The LQG loop with process noise q^2 Bd Bd' added on the input channel (q = 0: the rig's filter)."""
    kf = cp.KalmanFilter(lin, steps, h, V, W=W0 + q ** 2 * Bd @ Bd.T)
    return cp.sampled_loop(model, res.K, steps=steps, delay_steps=lag, kalman=kf, name=f"lqg q={q:g}")


rig_lqr = cp.sampled_loop(model, res.K, steps=steps, delay_steps=lag)
m_rig, m_lqg = cp.loop_margins(rig_lqr), cp.loop_margins(lqg(0.0))
for mg in (m_rig, m_lqg):
    print(f"{mg.name}: GM {mg.gain_margin}, PM {mg.phase_margin_deg:.1f} deg, Ms {mg.ms:.3f}")
assert m_lqg.phase_margin_deg < m_rig.phase_margin_deg and m_lqg.ms > m_rig.ms

# %% [markdown]
# ## 4. Loop-transfer recovery
#
# Telling the filter that unknown forces enter where the ctrl does (process noise `q^2 Bd Bd'`) makes its
# estimate follow the input channel, and as `q` grows the LQG's loop returns towards the LQR's (Doyle and Stein).
# The price is a noisier estimate: the filter trusts the encoders more.

# %%
qs = [0.0, 10.0, 100.0, 1000.0] if QUICK else [0.0, 3.0, 10.0, 30.0, 100.0, 300.0, 1000.0]
recovered = [cp.loop_margins(lqg(q)) for q in qs]
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.5))
ax1.semilogx([max(q, 1.0) for q in qs], [m.phase_margin_deg for m in recovered], "o-", label="LQG")
ax1.axhline(m_rig.phase_margin_deg, color="k", linestyle="--", label="LQR on the same rig")
ax1.set_xlabel("q (input-channel process noise; 0 plotted at 1)")
ax1.set_ylabel("phase margin (deg)")
ax2.semilogx([max(q, 1.0) for q in qs], [m.ms for m in recovered], "o-", label="LQG")
ax2.axhline(m_rig.ms, color="k", linestyle="--", label="LQR on the same rig")
ax2.set_xlabel("q (input-channel process noise; 0 plotted at 1)")
ax2.set_ylabel("Ms = max |S|")
for ax in (ax1, ax2):
    ax.legend()
    ax.grid(True, alpha=0.3)
fig.tight_layout()
assert abs(recovered[-1].phase_margin_deg - m_rig.phase_margin_deg) < 0.5 * abs(m_lqg.phase_margin_deg
                                                                                  - m_rig.phase_margin_deg)

# %% [markdown]
# The three loops side by side: Nyquist curves (the red circle of radius `1/Ms` about -1) and sensitivities.

# %%
pairs = [(lqr_loop, m_lqr), (rig_lqr, m_rig), (lqg(0.0), m_lqg), (lqg(qs[-1]), recovered[-1])]
cp.loop_figure(pairs, "nyquist")

# %%
cp.loop_figure(pairs, "sensitivity")
