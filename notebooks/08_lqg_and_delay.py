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
# # 8. LQG and delay: the LQR lab from encoders only
#
# The lab's LQR read MuJoCo's exact `qpos` and `qvel` every physics step. A real cart-pole measures the cart and
# the pole with quantised encoders (no velocities), runs its controller every few milliseconds and acts some
# milliseconds after it sampled. This notebook runs the same lab that way, sees what breaks, and fixes it:
#
# 1. a control period: design the LQR on the exact discrete model over the hold;
# 2. encoders only: a Kalman filter on that model estimates the rates (LQR + Kalman filter = LQG);
# 3. a delay: predict the estimate across it through the model, with the ctrl already sent.
#
# Every run is a MuJoCo rollout that replays exactly from its logged ctrl.

# %%
import numpy as np
import matplotlib.pyplot as plt

import cartpole as cp

model = cp.build_model()
h = model.dt
print(f"physics step {h} s; state {model.params.joint_names}, positions then rates")

# %% [markdown]
# ## 1. A control period of 10 ms
#
# Holding the ctrl for two physics steps changes the plant: `model.hold(2)` is the exact discrete model over the
# hold, and the LQR designed on it (`dlqr(Ad, Bd, Q T, R T)`) is what a 10 ms controller should run.

# %%
Ad, Bd = model.hold(2).linearize()
print("Ad over 10 ms =\n", np.round(Ad, 5))
held = cp.run_lab(loop=cp.LoopOptions(period=0.01))
print("settling times (s):", np.round(held.settling_times_seed, 3))
assert cp.balances(held) and all(cp.replays_exactly(r) for r in held.rollouts)

# %% [markdown]
# ## 2. Encoders only: LQG
#
# 2048 counts per revolution on the pole, 1 mm a count on the cart, nothing else. The estimator starts from the
# first reading with zero rates, never from the true state.

# %%
rig = dict(period=0.01, encoder_cpr=2048, encoder_resolution=0.001, estimator="kf")
lqg = cp.run_lab(loop=cp.LoopOptions(delay=0.01, **rig))
print("settling times (s):", np.round(lqg.settling_times_seed, 3))
print("estimate RMS error:", {k: round(v, 5) for k, v in lqg.estimation["rms_error"].items()})
assert cp.balances(lqg) and all(cp.replays_exactly(r) for r in lqg.rollouts)
fig = cp.estimation_figure(lqg.rollouts[0], model.params, title="LQG: the Kalman filter's estimate against MuJoCo")
fig

# %% [markdown]
# ## 3. What a delay costs, and what fixes it
#
# The same LQG with 30 ms from sampling to the ctrl taking effect: acting on the stale estimate, and on the estimate
# predicted across the delay through the model with the ctrl already sent.

# %%
stale = cp.run_lab(loop=cp.LoopOptions(delay=0.03, delay_compensation=False, **rig))
predicted = cp.run_lab(loop=cp.LoopOptions(delay=0.03, **rig))
print(f"mean settling time: stale {stale.mean_settling_time_seed:.3f} s, predicted "
      f"{predicted.mean_settling_time_seed:.3f} s")
assert predicted.mean_settling_time_seed < stale.mean_settling_time_seed

fig, axes = plt.subplots(2, 1, sharex=True, figsize=(9, 5))
for res, name in ((stale, "30 ms, stale estimate"), (predicted, "30 ms, predicted across the delay")):
    ro = res.rollouts[2]
    axes[0].plot(ro.t, ro.qpos[:, model.hinges[0]], label=name)
    axes[1].plot(ro.t, ro.qpos[:, model.slide], label=name)
axes[0].set_ylabel("pole angle (rad)")
axes[1].set_ylabel("cart (m)")
axes[1].set_xlabel("time (s)")
axes[0].legend()
axes[0].set_title("Start 3 (8 degrees) with a 30 ms delay")
plt.show()

# %% [markdown]
# `cartpole lqr --delay-margin 0.15 --compare-pid ...` finds the largest delay each controller survives
# (the docs' page "A rig, not an oracle" has the table).
