from nbgen import write

cells = [
("md", r"""
# 5. Your own cart-pole, end to end

Everything in the toolkit works on any MJCF with one slide joint carrying one hinged pole, driven by one motor.
This notebook takes `examples/my_cartpole.xml` - a lighter cart on a shorter track, a longer pole with a ball at its
tip, the hinge axis pointing $-y$, RK4 at 2 ms, gear 15 - and runs the whole pipeline on it: parameters, exact
linearisation checked against MuJoCo, the LQR lab, both swing-ups, and a video. Replace the path with yours.

The same from a shell:

```bash
cartpole linearize --mjcf examples/my_cartpole.xml
cartpole lqr       --mjcf examples/my_cartpole.xml --out out/mine
cartpole swingup   --mjcf examples/my_cartpole.xml --method energy  --out out/mine
cartpole swingup   --mjcf examples/my_cartpole.xml --method trajopt --out out/mine
```
"""),
("code", r"""
import os
from pathlib import Path
import numpy as np
import matplotlib.pyplot as plt
from IPython.display import Image, Video, display
import cartpole as cp

QUICK = os.environ.get("CARTPOLE_QUICK") == "1"
OUT = Path(os.environ.get("CARTPOLE_OUT", "out/notebook05"))
OUT.mkdir(parents=True, exist_ok=True)
MJCF = (Path(cp.__file__).resolve().parent.parent / "examples" / "my_cartpole.xml")
print(MJCF.read_text())
"""),
("md", r"""
## 1. Parameters, and what the reader refuses

The reader compiles the MJCF with MuJoCo and lumps every body below the hinge (here the capsule and the tip ball)
into one rigid pole. A file that is not a cart-pole is refused with one sentence.
"""),
("code", r"""
params = cp.read_params(MJCF)
print(f"cart {params.cart_mass} kg, pole {params.pole_mass:.3f} kg, COM {params.pole_com_distance:.4f} m from the hinge,")
print(f"J_hinge {params.pole_inertia_about_hinge:.5f} kg m^2, hinge axis {params.hinge_axis}, gear {params.gear},")
print(f"track {params.cart_range.tolist()} m, {params.integrator} at {params.timestep} s")

bad = MJCF.read_text().replace('type="slide" axis="1 0 0"', 'type="hinge" axis="0 0 1"')
try:
    cp.read_params(xml=bad)
except cp.MJCFError as err:
    print("refused:", err)
"""),
("md", r"""
## 2. Exact linearisation, checked against MuJoCo

$A$ and $B$ are CasADi Jacobians of the derived equations; $A_d, B_d$ those of one RK4 step, which is what
`mj_step` does for this file.
"""),
("code", r"""
from cartpole.validation.jacobians import check_jacobians, random_states

model = cp.build_model(params)
A, B = model.linearize()
Ad, Bd = model.linearize(discrete=True)
np.set_printoptions(precision=4, suppress=True)
print("A =\n", A, "\nB =", B.ravel())
states, inputs = random_states(params, 10 if QUICK else 100, seed=0)
for discrete in (False, True):
    chk = check_jacobians(model, states, inputs, discrete=discrete)
    print(f"{'Ad, Bd vs FD of mj_step' if discrete else 'A, B vs FD of mj_forward'}: worst relative error {chk.worst:.1e}")
"""),
("md", r"""
## 3. The LQR lab on this cart-pole

Same weights as the lab, $Q = \mathrm{diag}(1, 10, 0.1, 0.1)$, $R = 0.1$; five starts chosen inside this model's
joint ranges; every number from a MuJoCo run.
"""),
("code", r"""
from cartpole.lab import run_lab
from cartpole.viz import plot_lab

lab = run_lab(MJCF, duration=3.0 if QUICK else 6.0)
print("K =", lab.K.ravel())
for x0, m in zip(lab.x0s, lab.metrics):
    print(f"start {np.round(x0, 3)}: settling (|theta| <= 0.05 rad) {m.settling_time_seed:.3f} s, "
          f"strict {m.settling_time_strict:.2f} s, peak |ctrl| {m.peak_ctrl:.2f}")
display(Image(str(plot_lab(lab, OUT / "lab.png"))))
"""),
("md", r"""
## 4. Swing-up: energy shaping with the LQR catch, and collocation + TVLQR

Both run in MuJoCo on this file; `success` means upright and at rest for the last second, the cart never at its
limit and the ctrl in range, and the logged ctrl replays exactly.
"""),
("code", r"""
from cartpole.swingup import run_swingup
from cartpole.sim import replays_exactly
from cartpole.viz import plot_swingup

results = {}
for method in ("energy", "trajopt"):
    res = run_swingup(MJCF, method=method)
    results[method] = res
    mt = res.metrics
    print(f"{method:8s} success={res.success}  caught at {res.caught_at:.3f} s  "
          f"time to upright {mt['time_to_upright']:.3f} s  replays exactly: {replays_exactly(res.rollout)}")
    display(Image(str(plot_swingup(res.rollout, params, OUT / f"swingup_{method}.png", plan=res.plan,
                                   caught_at=res.caught_at, model=model))))
"""),
("md", r"""
## 5. Video

Rendered offscreen with `mujoco.Renderer` from the logged rollout on its own 30 fps clock (H.264 via imageio-ffmpeg).
"""),
("code", r"""
from cartpole.viz import VideoUnavailable, render_video

try:
    path = render_video(params, results["trajopt"].rollout, OUT / "my_cartpole_trajopt.mp4", width=320, height=240)
    display(Video(str(path), embed=True, width=480))
except VideoUnavailable as err:
    print(err)
"""),
]
write("notebooks/05_your_own_cartpole.ipynb", cells)
