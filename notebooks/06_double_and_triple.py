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
# # 6. The double and the triple pendulum on a cart: balance, then swing up from hanging
#
# Nothing in the pipeline is specific to one pole. The package ships two more carts,
# `cartpole/assets/cartpole_two_pole.xml` and `cartpole_three_pole.xml`: the lab's cart carrying a chain of two or
# three of the lab's poles, each hinged at the tip of the one below. This notebook runs the same steps as notebooks
# 1 and 2 on both: read the MJCF, derive the model, find upright, linearise exactly and check against MuJoCo, design
# an LQR, and balance in MuJoCo from a tilt of the first pole. Then the classic hard benchmark: **swing both chains
# up from hanging** by trajectory optimisation, track the plan with time-varying LQR and hand over to the LQR,
# proven in MuJoCo (notebook 4 did this for one pole).
#
# State $x = [s, \theta_1, \dots, \theta_n, \dot s, \dot\theta_1, \dots, \dot\theta_n]$ in MuJoCo's order, each
# $\theta_k$ the angle of link $k$ **relative to its parent link**, as MuJoCo measures it (so link 2's angle from
# vertical is $\theta_1 + \theta_2$); the input is still the one motor's `ctrl` on the cart.

# %%
import os
from importlib.resources import files
import numpy as np
import matplotlib.pyplot as plt
from IPython.display import display
import cartpole as cp

QUICK = os.environ.get("CARTPOLE_QUICK") == "1"   # the test suite sets this: fewer Jacobian states
np.set_printoptions(precision=3, suppress=True, linewidth=120)

ASSETS = files("cartpole") / "assets"             # shipped with the package
models = {n: cp.build_model(cp.read_params(ASSETS / f"cartpole_{name}.xml"))
          for n, name in ((2, "two_pole"), (3, "three_pole"))}
for n, model in models.items():
    p = model.params
    print(f"{n} poles: nq = {model.nq}, nu = {model.nu}, joints {p.joint_names}, hinges at qpos {model.hinges}, "
          f"{p.integrator} at {p.timestep} s, gear {p.gear:g}")
    assert model.nq == n + 1 and model.nu == 1 and len(model.hinges) == n and model.slide == 0

# %% [markdown]
# ## Upright: the computed equilibrium
#
# `model.x_eq`, `model.u_eq` solve $f(x^*, u^*) = 0$ with every link's centre of mass above its hinge. For these
# files, built straight, it is $q = 0$ with zero ctrl; a file built slightly off vertical would give a nonzero
# $x^*$ (notebook 5's reader takes any such file).

# %%
for n, model in models.items():
    residual = np.abs(model.dynamics(model.x_eq, model.u_eq)).max()
    print(f"{n} poles: x* = {model.x_eq}, u* = {model.u_eq}, |f(x*, u*)| = {residual:.1e}")
    assert residual < 1e-9
    assert np.allclose(model.x_eq, 0) and np.allclose(model.u_eq, 0)

# %% [markdown]
# ## Exact A, B against MuJoCo's finite differences
#
# $A = \partial f/\partial x$, $B = \partial f/\partial u$ are CasADi Jacobians of the derived equations, exact at
# any state; $A_d, B_d$ those of one step of the MJCF's integrator. `check_jacobians` compares them with central
# differences of `mj_forward` (and of `mj_step`) at upright and at random states across the joint ranges.

# %%
n_states = 20 if QUICK else 200
checks = {}
for n, model in models.items():
    states, inputs = cp.random_states(model.params, n_states, seed=n)
    states[0], inputs[0] = model.x_eq, model.u_eq
    cont = cp.check_jacobians(model, states, inputs)
    disc = cp.check_jacobians(model, states, inputs, discrete=True)
    checks[n] = (cont, disc)
    print(f"{n} poles, {n_states} states: worst relative error A, B {cont.worst:.1e}; Ad, Bd {disc.worst:.1e}")
    assert cont.worst < 1e-6 and disc.worst < 1e-6, "symbolic and finite-difference Jacobians disagree"

A2, B2 = models[2].linearize()
print("two poles, at upright:\nA =\n", A2, "\nB =", B2.ravel())

# %% [markdown]
# ## LQR with the lab's weight pattern
#
# `default_weights(model)` extends the lab's $Q = \mathrm{diag}(1, 10, 0.1, 0.1)$, $R = 0.1$: 1 for the cart, 10 for
# each angle, 0.1 for each rate and 0.1 for the input. One motor on the cart controls the whole chain (the pair is
# controllable); the closed loop $A - BK$ has every eigenvalue in the left half-plane.

# %%
designs = {}
for n, model in models.items():
    A, B = model.linearize()
    Q, R = cp.default_weights(model)
    res = cp.lqr(A, B, Q, R)
    designs[n] = res
    print(f"{n} poles: Q = diag({np.diag(Q).tolist()}), R = {R.ravel()}\n   K = {res.K.ravel()}\n"
          f"   eigenvalues of A - BK: {np.round(res.E, 2)}")
    assert cp.is_controllable(A, B)
    assert res.K.shape == (model.nu, model.nx)
    assert np.all(np.linalg.eigvals(A - B @ res.K).real < 0)
    residual = A.T @ res.S + res.S @ A - res.S @ B @ np.linalg.solve(R, B.T) @ res.S + Q
    assert np.abs(residual).max() < 1e-8 * np.abs(res.S).max()

# %% [markdown]
# ## Balancing in MuJoCo from a tilt of the first pole
#
# Each cart starts at rest with the first pole tilted by 2° (the others straight on it) and runs
# $u = u^* - K (x - x^*)$, clipped to the ctrl range, for 8 s in MuJoCo on the MJCF, every physics step logged. The
# run must settle (the whole state within 0.01 of upright, the cart never at its limit), and the logged ctrl must
# replay it exactly with `mj_step`.

# %%
TILT = np.deg2rad(2.0)
runs = {}
for n, model in models.items():
    ctrl = cp.LinearFeedback(designs[n].K, model.x_eq, model.u_eq, hinges=model.hinges, u_limits=model.params.ctrl_range)
    x0 = model.x_eq.copy()
    x0[model.hinges[0]] += TILT
    run = cp.simulate(model.params, ctrl, x0, 8.0)
    m = cp.summarize(run, model)
    runs[n] = (run, m)
    print(f"{n} poles: settled {m.settled} (strict settling {m.settling_time_strict:.2f} s), peak |ctrl| "
          f"{m.peak_ctrl:.2f}, time at the ctrl limit {100 * m.saturation_fraction:.1f} %, cart clearance "
          f"{m.track_margin:.2f} m; replays exactly: {cp.replays_exactly(run)}")
    assert m.settled and cp.replays_exactly(run), f"the {n}-pole cart did not balance from a 2 deg tilt"
    assert np.abs(model.state_error(run.x[-1])).max() < 0.01

# %% [markdown]
# One panel per pole: each link's angle relative to its parent (as MuJoCo logs it), then the cart and the ctrl.
# To catch the tilt, the first kick of the cart bends the second link back the other way ($\theta_2 < 0$) while the
# first link leans further for a moment; then the cart runs out under the chain, toward the tilt, and brings it back.

# %%
fig, axes = plt.subplots(5, 2, figsize=(12, 11), sharex=True)
for col, (n, (run, m)) in enumerate(runs.items()):
    model = models[n]
    ax = axes[:, col]
    for k, h in enumerate(model.hinges):
        ax[k].plot(run.t, np.rad2deg(run.qpos[:, h]), color=f"C{k}")
        ax[k].set_ylabel(fr"$\theta_{k + 1}$ (deg)")
        ax[k].set_title(f"{n} poles: link {k + 1} ({model.params.joint_names[h]})", fontsize=9)
    for k in range(len(model.hinges), 3):
        ax[k].axis("off")
    ax[3].plot(run.t, run.qpos[:, model.slide], color="k")
    ax[3].set_ylabel("cart s (m)")
    ax[4].step(run.t[:-1], run.ctrl[:, 0], where="post", color="C3", lw=.8)
    ax[4].set_ylabel("ctrl (-)"); ax[4].set_xlabel("time (s)")
    for a in ax:
        if a.axison:
            a.grid(alpha=.3); a.axhline(0, color="gray", lw=.6)
    ax[4].tick_params(labelbottom=True)
    assert run.qpos[:, model.hinges[1]].min() < 0 and run.qpos[:, model.slide].max() > 0   # what the text says
fig.suptitle("LQR balance in MuJoCo from a 2° tilt of the first pole (lab weight pattern)")
fig.tight_layout()
plt.show()

# %% [markdown]
# The same from a shell: `cartpole linearize` and `cartpole lqr` take `--mjcf` with either file (in a checkout,
# `cartpole/assets/cartpole_two_pole.xml`).

# %% [markdown]
# ## Swing-up from hanging: the plans
#
# `trajopt_swingup` plans from every pole hanging at rest (`model.x_hanging`) to upright rest (`x_eq`) by
# Hermite-Simpson collocation, inside the rail and the ctrl range of the file: first the minimum time the bounds
# allow, then the minimum-effort motion in 1.2 times that. It tries a deterministic set of initial guesses and
# keeps the best feasible solution (`solve_info` says which won, with each attempt's status and iterations). Nothing
# here is tuned per model: the same call plans one, two or three poles.

# %%
import time

plans = {}
for n, model in models.items():
    tic = time.perf_counter()
    plans[n] = cp.trajopt_swingup(model.params, plan_model=model)
    sp = plans[n]
    info = sp.solve_info
    print(f"{n} poles: planned in {time.perf_counter() - tic:.1f} s: T_min = {sp.T_min:.3f} s, plan T = {sp.T:.3f} s, "
          f"{info.solver} {info.status} after {info.iterations} iterations (guess {info.start}), "
          f"peak |ctrl| {np.abs(sp.trajectory.u).max():.3f}")
    assert info.success
    np.testing.assert_allclose(sp.trajectory.x[0], model.x_hanging, atol=1e-8)
    assert np.abs(model.state_error(sp.trajectory.x[-1])).max() < 1e-6       # ends at upright rest
    lo, hi = model.params.ctrl_range[0]
    assert lo - 1e-6 <= sp.trajectory.u.min() and sp.trajectory.u.max() <= hi + 1e-6

# %% [markdown]
# ## The TVLQR gains along the plan
#
# TVLQR is the exact discrete Riccati recursion along the plan at the MJCF's step, on the planning model's exact
# discrete step, with the upright LQR's $S$ as terminal cost, so the gain runs into the LQR's without a jump at the
# hand-over. One panel per pole (its angle's and its rate's gain), then the cart's. The gains peak where the chain
# passes through its most sensitive configurations, in the middle of the swing.

# %%
fig, axes = plt.subplots(4, 2, figsize=(12, 9), sharex="col")
for col, (n, sp) in enumerate(plans.items()):
    model, g = models[n], plans[n].gains
    ax = axes[:, col]
    for k, h in enumerate(model.hinges):
        ax[k].plot(g.t, g.K[:, 0, h], color=f"C{k}", label=fr"$K_{{	heta_{k + 1}}}$ (ctrl/rad)")
        ax[k].plot(g.t, g.K[:, 0, model.nq + h], color=f"C{k}", ls=":", label=fr"$K_{{\dot	heta_{k + 1}}}$ (ctrl s/rad)")
        ax[k].set_title(f"{n} poles: link {k + 1}", fontsize=9)
        ax[k].legend(fontsize=8, loc="upper left")
    for k in range(len(model.hinges), 3):
        ax[k].axis("off")
    ax[3].plot(g.t, g.K[:, 0, model.slide], color="k", label="$K_s$ (ctrl/m)")
    ax[3].plot(g.t, g.K[:, 0, model.nq + model.slide], color="k", ls=":", label=r"$K_{\dot s}$ (ctrl s/m)")
    ax[3].legend(fontsize=8); ax[3].set_xlabel("time along the plan (s)")
    for a in ax:
        if a.axison:
            a.grid(alpha=.3)
    ax[3].tick_params(labelbottom=True)
    assert g.K.shape == (g.t.size, model.nu, model.nx) and np.all(np.isfinite(g.K))
fig.suptitle("TVLQR gains along the swing-up plans (u = u_plan - K (x - x_plan))")
fig.tight_layout()
plt.show()

# %% [markdown]
# ## MuJoCo tracking and the hold
#
# MuJoCo runs the TVLQR controller on the MJCF from hanging rest for the plan and 3 s more (the LQR holds after the
# hand-over); every physics step is logged and replays exactly. The figure draws the plan dashed over MuJoCo solid,
# one angle panel per pole (angles wrapped to upright for display only; the states never wrap).

# %%

swings = {}
for n, sp in plans.items():
    model = models[n]
    run = cp.simulate(model.params, sp.controller, model.x_hanging, sp.T + 3.0)
    met = cp.swingup_metrics(run, model)
    swings[n] = run
    err = np.abs(model.state_error(run.x[-1]))
    print(f"{n} poles: success {met['success']}, upright at {met['time_to_upright']} s, peak |ctrl| "
          f"{np.abs(run.ctrl).max():.3f}, cart in [{run.qpos[:, model.slide].min():.2f}, "
          f"{run.qpos[:, model.slide].max():.2f}] m, final max |error| {err.max():.1e}; replays exactly: "
          f"{cp.replays_exactly(run)}")
    assert met["success"] and cp.replays_exactly(run)
    hold = run.t >= sp.T                            # the 3 s after the hand-over: within 0.05 rad of upright
    assert np.abs(model.state_error(run.x[hold])[:, model.hinges]).max() < 0.05
    display(cp.swingup_figure(run, model.params, plan=sp.trajectory, caught_at=sp.T, model=model,
                           title=f"{n} poles: trajopt + TVLQR from hanging, then LQR"))

# %% [markdown]
# ## A frame strip of the triple swing-up
#
# Frames rendered offscreen from the logged MuJoCo states (the video's camera and overlay), every few tenths of a
# second through the swing.

# %%

run3, sp3 = swings[3], plans[3]
times = np.linspace(0.0, sp3.T + 0.5, 6)
try:
    fig, axes = plt.subplots(1, len(times), figsize=(16, 3.2))
    for ax, t in zip(axes, times):
        ax.imshow(cp.render_frame(models[3].params, run3, t, options=cp.VideoOptions(width=320, height=360),
                                  model=models[3]))
        ax.set_title(f"t = {t:.2f} s", fontsize=9); ax.axis("off")
    fig.suptitle("Triple pendulum on a cart: swing-up from hanging in MuJoCo")
    fig.tight_layout()
    plt.show()
except cp.VideoUnavailable as err:
    print(err)

# %% [markdown]
# From a shell: `cartpole swingup --method trajopt --mjcf cartpole/assets/cartpole_three_pole.xml` (figure, video
# and the JSON log of the same run).
