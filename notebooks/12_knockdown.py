# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#       jupytext_version: 1.19.7
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Knocked down, it swings up again
#
# Every swing-up so far was one episode: plan, track, catch, hold. A cart-pole shown to visitors gets poked. The
# **supervisor** (`method="supervisor"`) decides at run time, every control step:
#
# * inside the catch's verified basin: the LQR catch;
# * one pole driven by the cart: the energy law, which swings up from anywhere;
# * a chain: a **brake** while any hinge is fast (a passive spring and damper on the driven joints, so it can only
#   remove energy), then a **plan** from the state it will be in when the plan is ready, **TVLQR** along it, and the
#   catch at its end; a state that leaves the tracking funnel is planned from again.
#
# The **knockdown** (`LoopOptions(knockdown="AFTER:LENGTH:SEED")`) pushes every hinge with random torques each time
# the poles have been upright for AFTER s, for at most LENGTH s and only until they have done half a swing-up's energy
# to one in work (`E(upright) - E(hanging)`, the model's own; an optional fourth field scales it); the **throw** (`throw="EVERY:RATE:SEED"`) changes
# every hinge rate by up to RATE rad/s at random times, whatever the controller is doing, also mid swing-up. The
# score is the **uptime**: the fraction of the run with every pole within the upright band.

# %%
import os
from importlib.resources import files

import matplotlib.pyplot as plt
import numpy as np

import cartpole as cp

QUICK = os.environ.get("CARTPOLE_QUICK") == "1"
OUT = os.environ.get("CARTPOLE_OUT", ".")
DURATION = 20.0 if QUICK else 60.0
params = cp.read_params()  # the shipped one-pole cart
model = cp.build_model(params)

# %% [markdown]
# ## A minute of knockdowns on one pole
#
# Knocked 0.3 s long after every 3 s upright. The log holds the generalized forces MuJoCo applied
# (`rollout.info["qfrc_applied"]`), so the run replays exactly from its logged ctrl.

# %%
res = cp.run_swingup(params, "supervisor", cp.SwingupOptions(loop=cp.LoopOptions(duration=DURATION, knockdown="3:0.3:1")))
m = res.metrics
print(f"uptime {m['uptime']:.3f} (band {m['upright_band']} rad), {m['knockdowns']} knockdowns, "
      f"{m['swingups']} swing-ups, {m['recoveries']} knockdowns followed by a swing-up")
assert cp.replays_exactly(res.rollout, params)
assert m["knockdowns"] >= 2 and m["recoveries"] >= m["knockdowns"] - 1  # the last may lack the time

# %% [markdown]
# The figure marks each knockdown (shaded), each swing-up (held 1 s) and each catch.

# %%
decisions = m["supervisor"]["decisions"]
marks = {"knockdowns": res.rollout.info["disturbances"], "swingups": m["swingup_times"],
         "catches": [d["t"] for d in decisions if d["kind"] == "catch"]}
path = cp.plot_swingup(res.rollout, params, os.path.join(OUT, "knockdown.png"), model=model, marks=marks,
                       title=f"knocked {m['knockdowns']} times, uptime {m['uptime']:.2f}")
plt.imshow(plt.imread(path))
plt.axis("off")
plt.show()

# %% [markdown]
# What the supervisor decided, and when (one pole: the energy law and the catch, no plans):

# %%
kinds = [d["kind"] for d in decisions]
print({k: kinds.count(k) for k in dict.fromkeys(kinds)})
print([(round(d["t"], 2), d["kind"]) for d in decisions[:8]])

# %% [markdown]
# ## Thrown at random times, also mid swing-up
#
# As the public benchmark for underactuated swing-up does: every 2 s on average each hinge's rate is changed by up
# to 15 rad/s at once, whether the pole is up or not. A throw that lands during a swing-up is simply one more
# state to swing up from.

# %%
thrown = cp.run_swingup(params, "supervisor", cp.SwingupOptions(loop=cp.LoopOptions(duration=DURATION, throw="2:15:3")))
mt = thrown.metrics
up = np.abs(np.angle(np.exp(1j * (np.asarray(thrown.rollout.qpos)[:, model.hinges[0]]
                                  - model.x_eq[model.hinges[0]])))) < mt["upright_band"]
mid = [a for a, _ in thrown.rollout.info["disturbances"] if not up[np.searchsorted(thrown.rollout.t, a)]]
print(f"thrown {mt['knockdowns']} times ({len(mid)} while not upright), {mt['swingups']} swing-ups, "
      f"uptime {mt['uptime']:.3f}")
assert cp.replays_exactly(thrown.rollout, params) and mt["swingups"] >= 2

# %% [markdown]
# ## Chains: brake, plan, track, catch
#
# On the two-pole cart no law swings up from anywhere, so the supervisor plans: the first plan from hanging is
# cold (a minimum-time search, then the effort problem), the later ones start from the plans it has already made
# (its library of plans, `cartpole library --build N` stores one on disk for the next run). A plan's wall time is
# charged to the run here as a fixed 2 s (`charged_latency`), so the run is the same on any machine. Skipped in the
# shortened run (the first cold plan takes tens of seconds).

# %%
if not QUICK:
    two = cp.read_params(files("cartpole") / "assets" / "cartpole_two_pole.xml")
    chain = cp.run_swingup(two, "supervisor", cp.SwingupOptions(loop=cp.LoopOptions(duration=60.0, knockdown="3:0.3:1")))
    mc = chain.metrics
    print(f"two poles: uptime {mc['uptime']:.3f}, {mc['knockdowns']} knockdowns, {mc['recoveries']} recovered, "
          f"{mc['supervisor']['plans']} plans ({mc['supervisor']['warm_plans']} warm)")
    assert cp.replays_exactly(chain.rollout, two)

# %% [markdown]
# ## The video
#
# `cartpole swingup --knockdown 3:0.3:1 --duration 60` writes the same run's figure and video
# (`videos/swingup_supervisor.mp4`). Here, outside the shortened run:

# %%
if not QUICK:
    video = cp.render_video(params, res.rollout, os.path.join(OUT, "knockdown.mp4"), model=model)
    print(video)
