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
# # 4. Swing-up by trajectory optimisation, tracked by time-varying LQR
#
# Instead of a feedback law that pumps energy, plan the whole swing-up offline and track it:
#
# 1. **Direct collocation** (Hermite-Simpson) finds knots $x_k, u_k$ on $t_k = kh$, $h = T/N$, that minimise the
#    effort $\int_0^T u^2\,dt$ subject to the model's dynamics, $|u| \le u_{\max}$ (the ctrl range), the cart inside
#    its track less a margin, hanging at rest at $t = 0$ and upright at rest at $t = T$. On each interval, with
#    $f_k = f(x_k, u_k)$,
#
#    $$x_c = \tfrac12(x_k + x_{k+1}) + \tfrac{h}{8}(f_k - f_{k+1}),\quad u_c = \tfrac12(u_k + u_{k+1}),\quad
#    x_{k+1} - x_k = \tfrac{h}{6}\left(f_k + 4 f(x_c, u_c) + f_{k+1}\right),$$
#
#    so the state between knots is the cubic Hermite polynomial through $(x_k, f_k)$ and $(x_{k+1}, f_{k+1})$ and the
#    input is piecewise linear (first-order hold). $T$ is 1.2 times the minimum time the bounds allow.
# 2. **TVLQR** along the plan, on the exact discrete model at MuJoCo's 5 ms step: linearise $x_{k+1} \approx
#    A_k \delta x_k + B_k \delta u_k$ around the plan and run the backward Riccati recursion
#
#    $$S_k = Q\,dt + A_k^\top S_{k+1} A_k - A_k^\top S_{k+1} B_k (R\,dt + B_k^\top S_{k+1} B_k)^{-1} B_k^\top S_{k+1} A_k,
#    \qquad K_k = (R\,dt + B_k^\top S_{k+1} B_k)^{-1} B_k^\top S_{k+1} A_k,$$
#
#    from the LQR catch's cost-to-go at $T$; the law is $u = u_{\rm ff}(t) - K(t)\,(x - x_{\rm plan}(t))$.
# 3. After $T$ the lab's LQR holds the pole upright.
#
# All of it is `cartpole.planning.trajopt.trajopt_swingup`; MuJoCo runs the controller on the MJCF.

# %%
import os
from pathlib import Path
import numpy as np
import matplotlib.pyplot as plt
import cartpole as cp

QUICK = os.environ.get("CARTPOLE_QUICK") == "1"   # the test suite sets this to shorten the simulations
OUT = Path(os.environ.get("CARTPOLE_OUT", "out/notebook04"))
OUT.mkdir(parents=True, exist_ok=True)

params = cp.read_params()
x0 = (0.0, np.pi, 0.0, 0.0)                         # hanging at rest
sp = cp.trajopt_swingup(params, x0)
traj, info = sp.trajectory, sp.solve_info
print(f"minimum time {sp.T_min:.3f} s -> plan T = {sp.T:.3f} s with N = {traj.N} intervals; "
      f"{info.solver}: {info.status}, {info.iterations} iterations, {1e3 * info.solve_time_s:.0f} ms, "
      f"effort = {info.objective:.3f} ctrl^2 s")

# %% [markdown]
# ## The plan: knots and interpolation
#
# Markers are the knots the optimiser chose; lines are the trajectory's own interpolation (`Trajectory.state`, cubic
# Hermite; `Trajectory.input`, first-order hold), which is exactly what the collocation constraints enforce.

# %%
tf = np.linspace(traj.t[0], traj.t[-1], 2000)
xf, uf = traj.state(tf), traj.input(tf)
names = ["cart position s (m)", r"pole angle $\theta$ (rad)", r"cart velocity $\dot s$ (m/s)",
         r"pole rate $\dot\theta$ (rad/s)"]
fig, ax = plt.subplots(5, 1, figsize=(10, 11), sharex=True)
for i in range(4):
    ax[i].plot(tf, xf[:, i], lw=1.2, label="cubic Hermite interpolation")
    ax[i].plot(traj.t, traj.x[:, i], ".", ms=5, label="knots")
    ax[i].set_ylabel(names[i])
ax[1].axhline(0, color="k", lw=.6); ax[1].axhline(np.pi, color="gray", ls=":", lw=.8)
ax[4].plot(tf, uf[:, 0], lw=1.2, label="first-order hold")
ax[4].plot(traj.t, traj.u[:, 0], ".", ms=5, label="knots")
u_lo, u_hi = params.ctrl_range[0]                   # the one actuator's ctrl range
ax[4].axhline(u_lo, color="r", ls=":", label="ctrl range"); ax[4].axhline(u_hi, color="r", ls=":")
ax[4].set_ylabel(f"ctrl u (force = {params.gear:g} N x u)"); ax[4].set_xlabel("time (s)")
for a in ax:
    a.grid(alpha=.3); a.legend(fontsize=8, loc="upper right")
ins = ax[1].inset_axes([0.08, 0.12, 0.3, 0.55])
w = (tf > traj.t[40]) & (tf < traj.t[46])
ins.plot(tf[w], xf[w, 1]); ins.plot(traj.t[40:47], traj.x[40:47, 1], "o", ms=4)
ins.plot(traj.t_mid[40:46], traj.x_mid[40:46, 1], "x", ms=5, color="C3")
ins.set_title("zoom: knots (o), collocation midpoints (x)", fontsize=7); ins.tick_params(labelsize=6)
fig.suptitle(f"Planned swing-up (Hermite-Simpson, N = {traj.N}, T = {sp.T:.2f} s)")
fig.tight_layout()
plt.show()
print("midpoints on the interpolant:", np.abs(traj.state(traj.t_mid) - traj.x_mid).max())
assert info.status == "Solve_Succeeded"
assert np.allclose(traj.x[0], x0) and np.abs(sp.model.state_error(traj.x[-1])).max() < 1e-6   # hanging -> upright
assert np.all(traj.u >= u_lo - 1e-9) and np.all(traj.u <= u_hi + 1e-9)
assert np.abs(traj.state(traj.t_mid) - traj.x_mid).max() < 1e-9

# %% [markdown]
# ## TVLQR gains $K(t)$
#
# One gain per 5 ms step. They change a lot along the swing: while the pole hangs the angle gain has the opposite
# sign to the upright one (a hanging pendulum is pushed the other way), it peaks on the way up, with the pole some
# 60° from upright and moving fast, and near the top it lands on the catch's gain (dashed): the catch is the discrete
# LQR at the same 5 ms step and weights, and TVLQR's terminal cost is its cost-to-go, so at $T$ neither the gain nor
# the cost-to-go jumps. The continuous lab LQR (dotted) would be about 15 % stiffer at this step, although the two
# give practically the same closed loop (docs/lab.md, "The discrete design").

# %%
G = sp.gains
K_catch = sp.catch.K.ravel()
labels = [r"$K_s$ (ctrl/m)", r"$K_\theta$ (ctrl/rad)", r"$K_{\dot s}$ (ctrl/(m/s))", r"$K_{\dot\theta}$ (ctrl/(rad/s))"]
K_lqr = cp.lqr(*sp.model.linearize(), *cp.default_weights(sp.model)).K.ravel()
fig, ax = plt.subplots(2, 2, figsize=(12, 6), sharex=True)
for i, a in enumerate(ax.ravel()):
    a.step(G.t, G.K[:, 0, i], where="post", label="TVLQR K(t)")
    a.axhline(K_catch[i], color="k", ls="--", lw=.8, label=f"catch: discrete LQR (5 ms) {K_catch[i]:.2f}")
    a.axhline(K_lqr[i], color="C3", ls=":", lw=1.2, label=f"continuous lab LQR {K_lqr[i]:.2f}")
    a.set_ylabel(labels[i]); a.grid(alpha=.3); a.legend(fontsize=8)
    ax2 = a.twinx()
    ax2.plot(tf, np.rad2deg(xf[:, 1]), color="gray", lw=.6, alpha=.5)
    ax2.set_ylabel("plan angle (deg)", color="gray", fontsize=8); ax2.tick_params(labelsize=7, colors="gray")
for a in ax[1]:
    a.set_xlabel("time (s)")
print("TVLQR gain at the last step", np.round(G.K[-1, 0], 3), "vs the catch's", np.round(K_catch, 3))
assert np.allclose(G.K[-1, 0], K_catch, rtol=0.02, atol=1e-3)   # no jump in the gain at the hand-over
fig.suptitle(f"TVLQR gains along the plan ({G.method}, dt = {1e3 * G.dt:g} ms, {G.t.size} steps); grey: plan angle")
fig.tight_layout()
plt.show()

# %% [markdown]
# ## Tracking in MuJoCo: plan vs rollout
#
# MuJoCo runs the TVLQR controller on the MJCF for $T$ + 3 s (the catch holds after $T$). For contrast the plan's
# feed-forward alone is replayed open loop up to $T$ (`cartpole.replay` of the plan's input, the zero-order-hold mean
# over each step, exactly the feed-forward the controller uses). The planning model reproduces MuJoCo's step to machine
# precision, so the only mismatch is the collocation's own discretisation error (12 ms intervals against MuJoCo's 5 ms
# Euler steps): the open-loop run arrives within a few degrees of the top. The feedback keeps the angle within about
# 1° of the plan, paying with a few centimetres of cart position (the weights favour the angle, $Q_{\theta\theta} = 10$
# vs $Q_{ss} = 1$), which the catch removes afterwards. The real test of the feedback is a model that is wrong, below.

# %%
T_sim = sp.T + cp.TRAJOPT_EXTRA
run = cp.simulate(params, sp.controller, x0, T_sim)
dt = params.timestep
t_ol = np.arange(int(round(sp.T / dt))) * dt
u_ol = traj.input(np.minimum(t_ol + dt / 2, sp.T))          # the same feed-forward the controller uses
run_ol = cp.replay(params, x0, u_ol)

m = cp.swingup_metrics(run, params)
inplan = run.t <= sp.T
err = sp.model.state_error(run.x[inplan], traj.state(run.t[inplan]))
err_ol = sp.model.state_error(run_ol.x, traj.state(run_ol.t))
print(f"TVLQR: success {m['success']}, upright from {m['time_to_upright']:.3f} s, "
      f"max tracking error during the plan: s {np.abs(err[:, 0]).max() * 1e3:.2f} mm, "
      f"theta {np.rad2deg(np.abs(err[:, 1]).max()):.3f} deg; hand-over cost e'Se = "
      f"{sp.catch.cost_to_go(run.x[np.searchsorted(run.t, sp.T)]):.2e}")
print(f"open loop: angle error at T {np.rad2deg(abs(err_ol[-1, 1])):.1f} deg, cart error {abs(err_ol[-1, 0]):.3f} m")
assert m["success"] and cp.swingup_success(run, params) and cp.replays_exactly(run), "TVLQR + catch must swing up in MuJoCo"
assert np.rad2deg(np.abs(err[:, 1]).max()) < 2.0   # the angle stays within about a degree of the plan

fig, ax = plt.subplots(3, 1, figsize=(10, 9), sharex=True)
ax[0].plot(tf, np.rad2deg(xf[:, 1]), "k--", lw=1.2, label="plan")
ax[0].plot(run.t, np.rad2deg(run.qpos[:, 1]), lw=1, label="MuJoCo, TVLQR + catch")
ax[0].plot(run_ol.t, np.rad2deg(run_ol.qpos[:, 1]), lw=1, label="MuJoCo, feed-forward only (open loop)")
ax[0].set_ylabel("pole angle (deg)")
ax[1].plot(tf, xf[:, 0], "k--", lw=1.2, label="plan")
ax[1].plot(run.t, run.qpos[:, 0], lw=1, label="MuJoCo, TVLQR + catch")
ax[1].plot(run_ol.t, run_ol.qpos[:, 0], lw=1, label="MuJoCo, open loop")
ax[1].set_ylabel("cart position (m)")
ax[2].semilogy(run.t[inplan], np.abs(np.rad2deg(err[:, 1])) + 1e-9, label=r"TVLQR $|\theta - \theta_{\rm plan}|$ (deg)")
ax[2].semilogy(run.t[inplan], np.abs(err[:, 0]) * 1e3 + 1e-9, label=r"TVLQR $|s - s_{\rm plan}|$ (mm)")
ax[2].semilogy(run_ol.t, np.abs(np.rad2deg(err_ol[:, 1])) + 1e-9, "--", label=r"open loop $|\theta - \theta_{\rm plan}|$ (deg)")
ax[2].semilogy(run_ol.t, np.abs(err_ol[:, 0]) * 1e3 + 1e-9, "--", label=r"open loop $|s - s_{\rm plan}|$ (mm)")
ax[2].set_ylim(1e-3, 1e3)
ax[2].set_ylabel("tracking error"); ax[2].set_xlabel("time (s)")
for a in ax:
    a.axvline(sp.T, color="g", lw=1, label=f"plan ends, catch takes over ({sp.T:.2f} s)")
    a.grid(alpha=.3); a.legend(fontsize=8, loc="upper right")
fig.tight_layout()
plt.show()

# %% [markdown]
# ## Robustness to model error
#
# Now plan **and** design TVLQR on a deliberately wrong model - the pole 10 % heavier and 10 % longer
# (`params.scaled_pole(1.1, 1.1)`), or 10 % lighter and shorter (`scaled_pole(0.9, 0.9)`) - while MuJoCo still runs the
# true MJCF (the full, non-quick run adds $\pm 20$ %). Success is the package's metric (`swingup_success`): upright and at rest for the last second, cart never at
# its limit, ctrl in range.

# %%
cases = {}
factors = (0.9, 1.0, 1.1) if QUICK else (0.8, 0.9, 1.0, 1.1, 1.2)
for f in factors:
    plan_params = params.scaled_pole(f, f)
    spf = sp if f == 1.0 else cp.trajopt_swingup(params, x0, plan_model=cp.build_model(plan_params))
    rf = cp.simulate(params, spf.controller, x0, spf.T + cp.TRAJOPT_EXTRA)
    cases[f] = (spf, rf)
    mf = cp.swingup_metrics(rf, params)
    print(f"planned on pole x{f:.1f} (mass {plan_params.pole_mass:.3f} kg, COM {plan_params.pole_com_distance:.3f} m): "
          f"T = {spf.T:.3f} s, success {cp.swingup_success(rf, params)}, upright from "
          f"{mf['time_to_upright'] if mf['time_to_upright'] is None else round(mf['time_to_upright'], 3)} s, "
          f"peak |ctrl| {mf['peak_ctrl']:.2f}, cart [{mf['cart_min']:.2f}, {mf['cart_max']:.2f}] m")
    if not cp.swingup_success(rf, params):
        last = rf.t >= rf.t[-1] - 1.0
        print(f"    why not: held upright at rest over the last 1 s: {cp.held_upright(rf)} (max |theta| "
              f"{np.rad2deg(np.abs(cp.wrap_angle(rf.qpos[last, 1])).max()):.2f} deg, max |s_dot| "
              f"{np.abs(rf.qvel[last, 0]).max():.3f} m/s, max |theta_dot| {np.abs(rf.qvel[last, 1]).max():.3f} rad/s); "
              f"cart clearance {cp.track_margin(rf.qpos, params.cart_range):.2f} m")
    if abs(f - 1.0) <= 0.1 + 1e-9:   # the claim below: a 10 % error in the pole is still swung up and held
        assert cp.swingup_success(rf, params) and cp.replays_exactly(rf), f"plan on pole x{f:.1f} failed in MuJoCo"

fig, ax = plt.subplots(1, 2, figsize=(13, 4.5))
for i, (f, (spf, rf)) in enumerate(cases.items()):
    c = f"C{i}"
    ok = cp.swingup_success(rf, params)
    tp = np.linspace(0, spf.T, 500)
    ax[0].plot(tp, np.rad2deg(spf.trajectory.state(tp)[:, 1]), "--", color=c, lw=1)
    ax[0].plot(rf.t, np.rad2deg(rf.qpos[:, 1]), color=c, label=f"planned on pole x{f:.1f}: {'success' if ok else 'FAILED'}")
    ax[1].plot(rf.t[:-1], rf.ctrl[:, 0], color=c, lw=.8, label=f"pole x{f:.1f}")
ax[0].set_ylabel("pole angle (deg)"); ax[0].set_title("MuJoCo on the true MJCF (solid) vs each plan (dashed)")
ax[1].set_ylabel(f"ctrl applied (force = {params.gear:g} N x ctrl)"); ax[1].set_title("ctrl MuJoCo applied")
for a in ax:
    a.set_xlabel("time (s)"); a.grid(alpha=.3); a.legend(fontsize=8)
fig.tight_layout()
plt.show()

# %% [markdown]
# With a 10 % error in the pole's mass and length the feedback still brings the pole to the top: each rollout
# leaves its (wrong) plan and the gains pull it back, with the catch finishing the job after $T$. (In the full run the
# $\pm 20$ % plans also end with the pole upright, but the metric, which asks for rest over the last second, says no:
# the bigger miss at $T$ leaves the cart rolling back faster than 0.1 m/s at the end of the 3 s after the plan - the
# "why not" lines above - since the catch's slow cart mode has a time constant of about 0.7 s.) The plans
# differ in duration because the minimum time depends on the pole.
#
# ## Replay exactness
#
# Every claim above comes from a logged MuJoCo rollout: `ctrl[k]` is what MuJoCo applied from `t[k]` to `t[k+1]`.
# Replaying the logged ctrl open loop with `mj_step` from the logged start reproduces every logged state bit for bit.

# %%
for name, r in [("nominal TVLQR", run), ("open loop", run_ol)] + [(f"planned on pole x{f:.1f}", rf) for f, (_, rf) in cases.items()]:
    again = cp.replay(params, r.x[0], r.ctrl)
    print(f"{name:24s} {r.ctrl.shape[0]:5d} steps  replays_exactly: {cp.replays_exactly(r)}  "
          f"max |replayed - logged| = {np.abs(again.x - r.x).max():.1e}")
    assert cp.replays_exactly(r) and np.array_equal(again.x, r.x)
