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
# # 1. The model: a cart-pole derived symbolically from its MJCF
#
# This notebook builds the cart-pole's equations of motion in CasADi **from the MJCF MuJoCo runs**, linearises them
# exactly, and proves the result against MuJoCo itself: the symbolic Jacobians against finite differences of
# `mj_forward`, and the discrete model against `mj_step`.
#
# State $x = [s, \theta, \dot s, \dot\theta]$ (MuJoCo's `[qpos, qvel]`), $\theta = 0$ upright, input $u$ = MuJoCo
# `ctrl` (cart force $= \text{gear}\cdot u$).

# %%
import os
import numpy as np
import matplotlib.pyplot as plt
import casadi as ca
import cartpole as cp

QUICK = os.environ.get("CARTPOLE_QUICK") == "1"   # the test suite sets this to shorten the sweeps
params = cp.read_params()          # the shipped asset: the lab's MJCF with the rail raised
os.path.basename(params.mjcf)   # the file read (params.mjcf holds its absolute path)

# %% [markdown]
# ## Parameters come from the compiled `MjModel`, not the XML
#
# MuJoCo derives the capsule's centre of mass and inertia from its geometry; the reader takes them from the
# compiled model and lumps everything below the hinge into one rigid pole.

# %%
rows = [("cart mass (kg)", params.cart_mass), ("pole mass (kg)", params.pole_mass),
        ("hinge -> pole COM (m)", round(params.pole_com_distance, 6)),
        ("pole inertia about hinge (kg m^2)", params.pole_inertia_about_hinge),
        ("slide damping (N s/m)", params.damping[0]), ("hinge damping (N m s/rad)", params.damping[1]),
        ("gear (N per ctrl)", params.gear), ("ctrl range", params.ctrl_range[0].tolist()),
        ("track (m)", params.cart_range.tolist()), ("time step (s)", params.timestep), ("integrator", params.integrator)]
for name, value in rows:
    print(f"{name:36s} {value}")

# %% [markdown]
# ## Lagrangian
#
# With $a$ the slide axis, $n$ the hinge axis, $r_0$ the pole's COM offset from the hinge at $\theta=0$ and
# $R_n(\theta)$ the rotation about $n$ (Rodrigues), the pole's COM is $p(s,\theta) = s\,a + R_n(\theta) r_0$ and
#
# $$T = \tfrac12 m_c \dot s^2 + \tfrac12 m_p \|\dot p\|^2 + \tfrac12 I_n \dot\theta^2,\qquad
# V = -m_p\, g\cdot p,\qquad M(q) = \nabla^2_{\dot q} T + \operatorname{diag}(\text{armature}).$$
#
# The equations $M(q)\ddot q + C(q,\dot q)\dot q + g(q) = \tau$ with $\tau = [\text{gear}\,u - d_s \dot s,\; -d_\theta\dot\theta]$
# are formed symbolically; $A = \partial f/\partial x$ and $B = \partial f/\partial u$ are `casadi.jacobian`s: exact at
# any state. The mass matrix, as CasADi prints it:

# %%
model = cp.build_model(params)
x = ca.SX.sym("x", model.nx)
print(model.mass_matrix(x))

# %%
A, B = model.linearize()          # upright rest, zero ctrl
np.set_printoptions(precision=4, suppress=True)
print("A =\n", A, "\nB =\n", B)
assert np.allclose(model.x_eq, 0) and np.allclose(model.u_eq, 0)   # upright rest is qpos = 0 for this file
assert abs(A[3, 1] - 25.67) < 5e-3 and np.allclose(B.ravel(), [0, 0, 19.48, -47.57], atol=5e-3)   # the text below

# %% [markdown]
# The handout printed `A[3,1] = 33` and `B = [.., .., 0.95, -0.99]`. Its own MJCF gives $A_{3,1} \approx 25.67$ and
# $B$ per unit **ctrl** $\approx [0, 0, 19.48, -47.57]$, i.e. $[0.974, -2.378]$ per newton with gear 20.
#
# ## Symbolic vs finite-difference Jacobians
#
# A table at a few states (relative error = max entry error / max entry), then the error over many states.

# %%
states, inputs = cp.random_states(params, 6, seed=0)
states[0], inputs[0] = 0.0, 0.0
check = cp.check_jacobians(model, states, inputs)
print(f"{'s':>6} {'theta':>7} {'s_dot':>7} {'th_dot':>7} {'u':>6} | {'err A':>9} {'err B':>9}")
for xk, uk, ea, eb in zip(check.states, check.inputs, check.err_A, check.err_B):
    print(f"{xk[0]:6.2f} {xk[1]:7.2f} {xk[2]:7.2f} {xk[3]:7.2f} {uk[0]:6.2f} | {ea:9.1e} {eb:9.1e}")

# %%
n = 40 if QUICK else 300
states, inputs = cp.random_states(params, n, seed=1)
cont = cp.check_jacobians(model, states, inputs)
disc = cp.check_jacobians(model, states, inputs, discrete=True)

fig, axes = plt.subplots(1, 2, figsize=(11, 3.8))
bins = np.logspace(-14, -5, 40)
axes[0].hist(cont.err_A, bins, alpha=.6, label="A vs FD of mj_forward")
axes[0].hist(cont.err_B, bins, alpha=.6, label="B vs FD of mj_forward")
axes[0].hist(disc.err_A, bins, alpha=.6, label="Ad vs FD of mj_step")
axes[0].set_xscale("log"); axes[0].axvline(1e-6, color="k", ls="--", label="1e-6 tolerance")
axes[0].set_xlabel("relative error (-)"); axes[0].set_ylabel("states"); axes[0].legend(fontsize=8)
axes[0].set_title(f"{n} random states, eps = 1e-6")

# Finite differences trade truncation for round-off: the exact Jacobian is what they approach at best.
x0, u0 = states[3], inputs[3]
A_exact, _ = model.linearize(x0, u0)
eps_grid = np.logspace(-10, -1, 19)
errs = [np.abs(cp.mujoco_fd_jacobians(params, x0, u0, eps=e)[0] - A_exact).max() / np.abs(A_exact).max()
        for e in eps_grid]
axes[1].loglog(eps_grid, errs, "o-")
axes[1].set_xlabel("finite-difference step eps"); axes[1].set_ylabel("relative error of FD A (-)")
axes[1].set_title("FD error vs step, against the exact A")
fig.tight_layout()
print(f"worst continuous {cont.worst:.1e}, worst discrete {disc.worst:.1e}")
assert cont.worst < 1e-6 and disc.worst < 1e-6, "symbolic and finite-difference Jacobians disagree"
assert min(errs) < 1e-6   # at its best step, finite differencing lands on the exact A

# %% [markdown]
# ## The discrete model is one `mj_step`
#
# MuJoCo's `Euler` is semi-implicit and treats joint damping implicitly; `RK4`, `implicit` and `implicitfast` differ
# again. The model reproduces each.

# %%
import mujoco

for integ in ("Euler", "RK4", "implicit", "implicitfast"):
    p = params.replace(xml=params.xml.replace('<option timestep="0.005"', f'<option integrator="{integ}" timestep="0.005"'), mjcf="")
    m, d = cp.make_mujoco(p)
    mdl = cp.build_model(cp.read_params(xml=p.xml))
    worst = 0.0
    for xk, uk in zip(*cp.random_states(params, 50, seed=2)):
        mujoco.mj_resetData(m, d)
        d.qpos[:], d.qvel[:], d.ctrl[:] = xk[:mdl.nq], xk[mdl.nq:], uk
        mujoco.mj_step(m, d)
        worst = max(worst, np.abs(np.r_[d.qpos, d.qvel] - mdl.step_np(xk, uk)).max())
    print(f"{mdl.integrator:13s} max |step - mj_step| = {worst:.1e}")
    assert mdl.integrator == integ and worst < 1e-9, f"the discrete model does not reproduce mj_step for {integ}"
