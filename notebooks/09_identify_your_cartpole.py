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
# # 9. Identify your cart-pole: excite, fit, redesign
#
# Everything the toolkit designs is only as good as the MJCF it reads. Here a hidden "rig"
# (`cartpole/assets/examples/cartpole_rig_truth.xml`: the shipped cart with its pole 30 % heavier and 15 % longer,
# its dampings and gear off) plays the real cart-pole. We only read it through encoders, the way a student reads
# their own hardware:
#
# 1. log an informative experiment (`excite`: a multisine around the hanging pole's natural frequency);
# 2. fit the shipped MJCF's parameters to the log (`identify`), with standard errors, and check the fit on a run it
#    did not see;
# 3. redesign the swing-up on the fitted MJCF and run it on the rig: where the design on the drawing fails, the one
#    on the fitted file swings up and holds.
#
# Every run is a MuJoCo rollout of the rig that replays exactly from its logged ctrl.

# %%
import os
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import cartpole as cp

QUICK = os.environ.get("CARTPOLE_QUICK") == "1"
RIG = cp.SHIPPED_MJCF.parent / "examples" / "cartpole_rig_truth.xml"   # the hidden truth: only MuJoCo reads it
NOMINAL = cp.SHIPPED_MJCF                                              # the drawing
out = Path(tempfile.mkdtemp(prefix="identify_"))
print("nominal:", NOMINAL.name, " rig:", RIG.name, " outputs in the scratch folder", out.name)

# %% [markdown]
# ## 1. Excite the rig
#
# Open loop from hanging rest: eight frequencies from 0.7 to 2.5 times the hanging pole's natural frequency, its
# amplitude the largest that keeps the (nominal) cart within 60 % of its rail, read through 2048-count hinge and
# 0.1 mm slide encoders. Two runs: one to fit, one (another noise seed, another length) to check.

# %%
enc = dict(encoder_cpr=2048, encoder_resolution=1e-4)
fit_run = cp.run_excite(RIG, out, cp.ExciteOptions(duration=10.0 if QUICK else 20.0, **enc), csv_name="run1.csv")
check_run = cp.run_excite(RIG, out, cp.ExciteOptions(duration=6.0 if QUICK else 10.0, seed=1, **enc),
                          csv_name="run2.csv")
log = fit_run.log
print(f"{log.n} samples every {log.sample_time * 1e3:g} ms; columns written to {fit_run.csv.name}")

fig, axes = plt.subplots(3, 1, sharex=True, figsize=(9, 6))
axes[0].plot(log.t, log.qpos[:, 0])
axes[0].set_ylabel("cart (m)")
axes[1].plot(log.t, log.qpos[:, 1])
axes[1].set_ylabel("pole angle (rad)")
axes[2].step(log.t, log.ctrl[:, 0], where="post")
axes[2].set_ylabel("ctrl")
axes[2].set_xlabel("time (s)")
fig.suptitle("The excitation logged on the rig (encoder readings)")
plt.show()

# %% [markdown]
# ## 2. Fit the drawing to the log
#
# `--fit all`: the gear, the pole's centre of mass and inertia, every joint's damping and the hinge's
# frictionloss (masses taken as weighed). Multiple shooting over 0.1 s segments, the rates states of the fit, the
# parameters regularised toward the nominal; the standard errors come from the Gauss-Newton Hessian at the optimum.

# %%
res = cp.run_identify(NOMINAL, [fit_run.csv], out, holdout=[check_run.csv])
for name, v in res.fit.as_dict().items():
    print(f"{name:24s} nominal {v['nominal']:10.5g}   fitted {v['fitted']:10.5g} +- {v['std']:.2g}")
for w in res.fit.warnings:
    print("warning:", w)
print("held-out open-loop RMS error, nominal:", {k: f"{v:.3g}" for k, v in res.holdout_rms["nominal"].items()})
print("held-out open-loop RMS error, fitted: ", {k: f"{v:.3g}" for k, v in res.holdout_rms["fitted"].items()})
for joint in res.holdout_rms["fitted"]:
    assert res.holdout_rms["fitted"][joint] * 5 <= res.holdout_rms["nominal"][joint]

# %% [markdown]
# The fitted values are not the rig's own numbers: the drawing's pole mass is wrong and was not fitted, and a
# cart-pole's motion depends on gear, masses, centre of mass and inertia only through a few ratios. The fitted model
# moves like the rig (the held-out error is at the encoders' quantisation), and that is what a design needs. The
# fitted MJCF is a copy of the nominal file with only those attributes changed:

# %%
import difflib

diff = difflib.unified_diff(NOMINAL.read_text().splitlines(), res.mjcf.read_text().splitlines(), lineterm="", n=0)
print("\n".join(line for line in diff if line.startswith(("+", "-")) and not line.startswith(("+++", "---"))))

# %% [markdown]
# ## 3. Redesign on the fitted file, run on the rig
#
# The same trajectory optimisation and TVLQR, designed on the drawing and on the fitted MJCF, both run in MuJoCo on
# the rig (`--plan-mjcf` on the command line: `cartpole swingup --method trajopt --mjcf RIG --plan-mjcf fitted.xml`).

# %%

rig = cp.read_params(RIG)
runs = {}
for label, design in (("designed on the drawing", NOMINAL), ("designed on the fitted MJCF", res.mjcf)):
    r = cp.run_swingup(rig, method="trajopt", plan_model=cp.build_model(cp.read_params(design)))
    assert cp.replays_exactly(r.rollout)
    runs[label] = r
    print(f"{label}: success {r.success}, time to upright {r.metrics['time_to_upright']}")
assert runs["designed on the fitted MJCF"].success

fig, ax = plt.subplots(figsize=(9, 4))
for label, r in runs.items():
    ax.plot(r.rollout.t, np.unwrap(r.rollout.qpos[:, 1]), label=f"{label} ({'holds' if r.success else 'fails'})")
ax.axhline(0.0, color="k", lw=0.5)
ax.set_xlabel("time (s)")
ax.set_ylabel("pole angle on the rig (rad, 0 upright)")
ax.legend()
ax.set_title("The same swing-up on the rig: designed on the drawing vs on the fitted MJCF")
plt.show()
