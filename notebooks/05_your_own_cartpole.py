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
# # 5. Your own cart-pole, end to end
#
# Everything in the toolkit works on any MJCF of a cart on a slide carrying hinged poles, driven by motors (the
# swing-ups below are for one pole; notebook 6 balances two and three). This notebook takes the example shipped in
# the package, `cartpole/assets/examples/my_cartpole.xml` - a lighter cart on a shorter track, a longer pole with a
# ball at its tip, the hinge axis pointing $-y$, RK4 at 2 ms, gear 15 - and runs the whole pipeline on it:
# parameters, exact linearisation checked against MuJoCo, the LQR lab, both swing-ups, and a video. Replace `MJCF`
# with the path of yours.
#
# The same from a shell, in a checkout of the repository:
#
# ```bash
# cartpole linearize --mjcf cartpole/assets/examples/my_cartpole.xml
# cartpole lqr       --mjcf cartpole/assets/examples/my_cartpole.xml --out out/mine
# cartpole swingup   --mjcf cartpole/assets/examples/my_cartpole.xml --method energy  --out out/mine
# cartpole swingup   --mjcf cartpole/assets/examples/my_cartpole.xml --method trajopt --out out/mine
# ```

# %%
import os
from importlib.resources import files
from pathlib import Path
import numpy as np
import matplotlib.pyplot as plt
from IPython.display import Image, Video, display
import cartpole as cp

QUICK = os.environ.get("CARTPOLE_QUICK") == "1"
OUT = Path(os.environ.get("CARTPOLE_OUT", "out/notebook05"))
OUT.mkdir(parents=True, exist_ok=True)
MJCF = files("cartpole") / "assets" / "examples" / "my_cartpole.xml"   # shipped with the package
print(MJCF.name)
print(MJCF.read_text())

# %% [markdown]
# ## 1. Parameters, and what the reader refuses
#
# The reader compiles the MJCF with MuJoCo and takes every inertia from the compiled model (here MuJoCo composes
# the capsule and the tip ball into one body). A file the smooth model cannot describe is refused with one
# sentence: below, the same file without an actuator. Contacts are judged by whether they can happen, with MuJoCo's
# own geometry (`cartpole.models.contacts`): with the file's contacts switched back on, the floor can never reach
# the cart or the pole (listed, accepted); with the cart lowered into the floor it touches at upright (refused).

# %%
params = cp.read_params(MJCF)
print(f"cart {params.cart_mass} kg, pole {params.pole_mass:.3f} kg, COM {params.pole_com_distance:.4f} m from the hinge,")
hinge = params.joints[params.hinges[0]]
print(f"J_hinge {params.pole_inertia_about_hinge:.5f} kg m^2, hinge axis {hinge.axis.tolist()}, gear {params.gear},")
print(f"track {params.cart_range.tolist()} m, {params.integrator} at {params.timestep} s")
assert (params.nq, params.nu, params.integrator, params.gear) == (2, 1, "RK4", 15.0)
assert np.allclose(hinge.axis, [0, -1, 0]) and np.isclose(params.pole_mass, 0.13)   # capsule 0.08 + ball 0.05 kg

text = MJCF.read_text()
motor = text[text.index("<motor"):text.index("/>", text.index("<motor")) + 2]
contacts_on = text.replace('<flag contact="disable"/>', "")
print(cp.build_model(cp.read_params(xml=contacts_on)).contacts.summary())
for what, bad in (("no actuator", text.replace(motor, "")),
                  ("the cart in the floor", contacts_on.replace('<body name="cart" pos="0 0 1.3">',
                                                                '<body name="cart" pos="0 0 0.02">'))):
    try:
        cp.build_model(cp.read_params(xml=bad))
        raise AssertionError(f"the reader accepted the file with {what}")
    except cp.MJCFError as err:
        print(f"{what}: refused: {err}")

# %% [markdown]
# ## 2. Exact linearisation, checked against MuJoCo
#
# $A$ and $B$ are CasADi Jacobians of the derived equations; $A_d, B_d$ those of one RK4 step, which is what
# `mj_step` does for this file.

# %%

model = cp.build_model(params)
A, B = model.linearize()
Ad, Bd = model.linearize(discrete=True)
np.set_printoptions(precision=4, suppress=True)
print("A =\n", A, "\nB =", B.ravel())
states, inputs = cp.random_states(params, 10 if QUICK else 100, seed=0)
for discrete in (False, True):
    chk = cp.check_jacobians(model, states, inputs, discrete=discrete)
    print(f"{'Ad, Bd vs FD of mj_step' if discrete else 'A, B vs FD of mj_forward'}: worst relative error {chk.worst:.1e}")
    assert chk.worst < 1e-6

# %% [markdown]
# ## 3. The LQR lab on this cart-pole
#
# Same weights as the lab, $Q = \mathrm{diag}(1, 10, 0.1, 0.1)$, $R = 0.1$; five starts chosen inside this model's
# joint ranges; every number from a MuJoCo run.

# %%

lab = cp.run_lab(MJCF, duration=3.0 if QUICK else 6.0)
print("K =", lab.K.ravel())
for x0, m in zip(lab.x0s, lab.metrics):
    print(f"start {np.round(x0, 3)}: settling (|theta| <= 0.05 rad) {m.settling_time_seed:.3f} s, "
          f"strict {m.settling_time_strict:.2f} s, peak |ctrl| {m.peak_ctrl:.2f}")
assert all(lab.settled) and all(cp.replays_exactly(run) for run in lab.rollouts), "every start must settle"
display(Image(str(cp.plot_lab(lab, OUT / "lab.png"))))

# %% [markdown]
# ## 4. Swing-up: energy shaping with the LQR catch, and collocation + TVLQR
#
# Both run in MuJoCo on this file; `success` means upright and at rest for the last second, the cart never at its
# limit and the ctrl in range, and the logged ctrl replays exactly.

# %%

results = {}
for method in ("energy", "trajopt"):
    res = cp.run_swingup(MJCF, method=method)
    results[method] = res
    mt = res.metrics
    print(f"{method:8s} success={res.success}  caught at {res.caught_at:.3f} s  "
          f"time to upright {mt['time_to_upright']:.3f} s  replays exactly: {cp.replays_exactly(res.rollout)}")
    assert res.success and cp.swingup_success(res.rollout, params) and cp.replays_exactly(res.rollout), method
    display(Image(str(cp.plot_swingup(res.rollout, params, OUT / f"swingup_{method}.png", plan=res.plan,
                                   caught_at=res.caught_at, model=model))))

# %% [markdown]
# ## 5. Video
#
# Rendered offscreen with `mujoco.Renderer` from the logged rollout on its own 30 fps clock (H.264 via imageio-ffmpeg).

# %%

try:
    video = cp.VideoOptions(width=320, height=240, fps=10 if QUICK else 30)   # the test suite renders fewer frames
    path = cp.render_video(params, results["trajopt"].rollout, OUT / "my_cartpole_trajopt.mp4", options=video)
    display(Video(str(path), embed=True, width=480))
except cp.VideoUnavailable as err:
    print(err)
