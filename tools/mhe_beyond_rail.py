"""The exported LQR + MHE against the Python one (the MHE's numpy reference step) with measurements past the rail's end (docs/deploy.md, the MHE's
bounded window QP), as one JSON document: the shipped cart at a 10 ms period from 2048-count encoders, 40 control
steps whose cart reading is 10-14 cm beyond the rail, the same inputs to both. Used by claims.toml; run
``python tools/mhe_beyond_rail.py``."""
import json

import numpy as np

from cartpole.export import design_export, load_design
from cartpole.export.folder import discard
from cartpole.models import build_model
from cartpole.sim.options import LoopOptions


def main() -> None:
    model = build_model(None)
    design = design_export(model, "lqr", LoopOptions(period=0.01, estimator="mhe", encoder_cpr=2048))
    ctl, folder = load_design(design, "double")
    try:
        mhe, fb = design.rig.make_estimator(), design.make_controller()
        mhe.c = None  # the numpy reference step (the estimator otherwise runs the export's own C)
        steps, T = design.program.steps, design.program.period
        lo, hi = model.params.ctrl_range[0]
        ctl.reset()
        u_prev, diff, codes = np.zeros(model.nu), 0.0, []
        for k in range(40):
            y = np.array([1.62 + 0.02 * np.sin(0.4 * k), 0.05])
            x_hat = mhe.reset(y) if k == 0 else mhe.update(y, np.tile(u_prev, (steps, 1)).T)
            u_py = np.clip(fb(k * T, x_hat), lo, hi)
            code, u_c = ctl.step(k * T, y)
            codes.append(int(code))
            diff = max(diff, float(np.abs(u_c - u_py).max()))
            u_prev = u_c
    finally:
        discard(folder)
    print(json.dumps({"max_ctrl_diff": diff, "codes": sorted(set(codes)), "x_hat_cart": float(x_hat[model.slide]),
                      "rail_end": float(model.params.joint_ranges[model.slide][1]), "python_failures": mhe.failures}))


if __name__ == "__main__":
    main()
