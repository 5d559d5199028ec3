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
# # 10. The controller as standalone C, proven in MuJoCo
#
# The LQR + Kalman filter of notebook 8 (a 10 ms period, 2048-count encoders) leaves Python here: exported as a
# folder of C99 with static memory, built with `make`, run as the shipped example on stdin, and then driven in
# MuJoCo through the same rig as the Python controller, step for step.

# %%
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import cartpole as cp

loop = cp.LoopOptions(period=0.01, estimator="kf", encoder_cpr=2048)
out = Path(os.environ.get("CARTPOLE_OUT") or tempfile.mkdtemp()) / "rig"
doc = cp.run_export(None, "lqr", cp.ExportOptions(verify=True, duration=3.0), loop=loop, out=out)
exp = doc["export"]
print(f"{len(exp['files'])} files, {exp['bytes']} bytes in the folder {out.name}/")
print(f"verified: {exp['verified']}; max |C - Python| ctrl {exp['max_ctrl_diff']:.2g} (double), "
      f"float32 balanced: {exp['float32']['success']}")
assert exp["verified"] and exp["max_ctrl_diff"] <= 1e-9

# %% [markdown]
# ## The header a rig's program includes

# %%
print((out / "include" / "cartpole_controller.h").read_text().split("#ifndef CARTPOLE_CONTROLLER_H")[1][:700])

# %% [markdown]
# ## Built with nothing but make and a C compiler, run on stdin
#
# Each line in is `t y_cart y_hinge` (m, rad); each line out is the return code and the ctrl.

# %%
if shutil.which("make") and shutil.which("cc"):
    subprocess.run(["make", "-s", "-C", str(out)], check=True)
    lines = "".join(f"{0.01 * k:.2f} 0.0 {0.05 - 0.005 * k}\n" for k in range(5))
    print(subprocess.run([str(out / "example" / "cartpole_example")], input=lines, capture_output=True, text=True,
                         check=True).stdout)

# %% [markdown]
# ## C and Python in the same MuJoCo loop
#
# The compiled library drives MuJoCo; at every control step the Python controller gets the same measurements and
# ctrl history and its ctrl is recorded beside the C's.

# %%
model = cp.build_model()
design = cp.design_export(model, "lqr", loop)
x0 = np.array([0.0, 0.1, 0.0, 0.0])
runs = {}
for real in ("double", "float"):
    ctl, folder = cp.load_design(design, real)
    runs[real] = cp.run_lockstep(design, ctl, x0, 3.0)
    shutil.rmtree(folder, ignore_errors=True)
    print(f"{real}: max |C - Python| = {runs[real].max_ctrl_diff:.3g}, replays exactly: "
          f"{cp.replays_exactly(runs[real].rollout)}")
assert runs["double"].max_ctrl_diff <= 1e-9 and cp.replays_exactly(runs["float"].rollout)

fig, ax = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
d = runs["double"]
ax[0].plot(d.t, d.py_ctrl[:, 0], label="Python")
ax[0].plot(d.t, d.c_ctrl[:, 0], "--", label="C (double)")
ax[0].plot(runs["float"].t, runs["float"].c_ctrl[:, 0], ":", label="C (float32, its own run)")
ax[0].set_ylabel("ctrl")
ax[0].legend()
ax[1].semilogy(d.t, np.abs(d.c_ctrl - d.py_ctrl)[:, 0] + 1e-18)
ax[1].set_ylabel("|C - Python| (double)")
ax[1].set_xlabel("t (s)")
plt.tight_layout()
plt.show()
