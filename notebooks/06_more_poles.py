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
# # 6. More poles: balancing a double and a triple pendulum on the cart
#
# Nothing in the pipeline is specific to one pole. The package ships two more carts,
# `cartpole/assets/cartpole_two_pole.xml` and `cartpole_three_pole.xml`: the lab's cart carrying a chain of two or
# three of the lab's poles, each hinged at the tip of the one below. This notebook runs the same steps as notebooks
# 1 and 2 on both: read the MJCF, derive the model, find upright, linearise exactly and check against MuJoCo, design
# an LQR, and balance in MuJoCo from a tilt of the first pole.
#
# State $x = [s, \theta_1, \dots, \theta_n, \dot s, \dot\theta_1, \dots, \dot\theta_n]$ in MuJoCo's order, each
# $\theta_k$ the angle of link $k$ **relative to its parent link**, as MuJoCo measures it (so link 2's angle from
# vertical is $\theta_1 + \theta_2$); the input is still the one motor's `ctrl` on the cart.

# %%
import os
from importlib.resources import files
import numpy as np
import matplotlib.pyplot as plt
import cartpole as cp
from cartpole.control import LinearFeedback
from cartpole.lqr import is_controllable, lab_weights, lqr
from cartpole.sim import replays_exactly, simulate
from cartpole.validation.jacobians import check_jacobians, random_states
from cartpole.validation.metrics import summarize

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
    states, inputs = random_states(model.params, n_states, seed=n)
    states[0], inputs[0] = model.x_eq, model.u_eq
    cont = check_jacobians(model, states, inputs)
    disc = check_jacobians(model, states, inputs, discrete=True)
    checks[n] = (cont, disc)
    print(f"{n} poles, {n_states} states: worst relative error A, B {cont.worst:.1e}; Ad, Bd {disc.worst:.1e}")
    assert cont.worst < 1e-6 and disc.worst < 1e-6, "symbolic and finite-difference Jacobians disagree"

A2, B2 = models[2].linearize()
print("two poles, at upright:\nA =\n", A2, "\nB =", B2.ravel())

# %% [markdown]
# ## LQR with the lab's weight pattern
#
# `lab_weights(model)` extends the lab's $Q = \mathrm{diag}(1, 10, 0.1, 0.1)$, $R = 0.1$: 1 for the cart, 10 for
# each angle, 0.1 for each rate and 0.1 for the input. One motor on the cart controls the whole chain (the pair is
# controllable); the closed loop $A - BK$ has every eigenvalue in the left half-plane.

# %%
designs = {}
for n, model in models.items():
    A, B = model.linearize()
    Q, R = lab_weights(model)
    res = lqr(A, B, Q, R)
    designs[n] = res
    print(f"{n} poles: Q = diag({np.diag(Q).tolist()}), R = {R.ravel()}\n   K = {res.K.ravel()}\n"
          f"   eigenvalues of A - BK: {np.round(res.E, 2)}")
    assert is_controllable(A, B)
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
    ctrl = LinearFeedback(designs[n].K, model.x_eq, model.u_eq, hinges=model.hinges, u_limits=model.params.ctrl_range)
    x0 = model.x_eq.copy()
    x0[model.hinges[0]] += TILT
    run = simulate(model.params, ctrl, x0, 8.0)
    m = summarize(run, model)
    runs[n] = (run, m)
    print(f"{n} poles: settled {m.settled} (strict settling {m.settling_time_strict:.2f} s), peak |ctrl| "
          f"{m.peak_ctrl:.2f}, time at the ctrl limit {100 * m.saturation_fraction:.1f} %, cart clearance "
          f"{m.track_margin:.2f} m; replays exactly: {replays_exactly(run)}")
    assert m.settled and replays_exactly(run), f"the {n}-pole cart did not balance from a 2 deg tilt"
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
