"""The exported NMPC (real-time iteration, the condensed QP solved in C) in the MuJoCo swing-up: the Python
controller's ctrl at every control step in double, swung up and held in float32, both runs replaying bit for bit."""
from pathlib import Path

import numpy as np
import pytest
from mj_replay import replay_with_mj_step

from cartpole.export import design_export, load_design, run_lockstep
from cartpole.export.folder import discard
from cartpole.models import build_model, read_params
from cartpole.validation.metrics import swingup_success

TWO_POLE = "cartpole/assets/cartpole_two_pole.xml"


def _replays(rollout):
    qpos, qvel = replay_with_mj_step(rollout.mjcf, rollout.qpos[0], rollout.qvel[0], rollout.ctrl)
    return np.array_equal(qpos, rollout.qpos) and np.array_equal(qvel, rollout.qvel)


def _double_and_float(design, x0, duration):
    """The lockstep MuJoCo runs of the double and the float build of ``design`` from ``x0`` for ``duration`` s."""
    runs = []
    for real in ("double", "float"):
        ctl, folder = load_design(design, real)
        try:
            runs.append(run_lockstep(design, ctl, x0, duration))
        finally:
            discard(folder)
    return runs


def test_nmpc_export_swings_up_step_for_step_like_python():
    model = build_model(None)
    design = design_export(model, "nmpc", None)
    assert design.program.period == 0.02 and design.program.steps == 4  # the NMPC's own period
    d, f = _double_and_float(design, model.x_hanging, 8.0)
    # the in-loop controller runs the same C (cartpole/csrc/nmpc.c.jinja) with the same floating-point semantics
    assert design.make_controller().step_implementation == "c"
    assert d.max_ctrl_diff <= 1e-14 and np.all(d.codes == 0)
    for run in (d, f):
        assert swingup_success(run.rollout, model.params) and _replays(run.rollout)
        assert run.rollout.info["diverged"] is None


def test_two_pole_nmpc_export_is_prestabilised_and_swings_up_in_float32_too():
    # plain condensing's Hessian had a condition number ~1e6 here and the float32 build's QPs failed; pre-stabilised
    # (~5) float32 swings up. The in-loop controller runs the export's C, so double agrees to the last bit (the
    # Python step with DAQP agreed to 2.5e-7 only: the real-time iteration's carried iterate amplifies rounding)
    model = build_model(TWO_POLE)
    design = design_export(model, "nmpc", None)
    assert design.make_controller().prestabilize
    d, f = _double_and_float(design, model.x_hanging, 8.0)
    assert d.max_ctrl_diff <= 1e-14 and np.all(d.codes == 0)
    for run in (d, f):
        assert swingup_success(run.rollout, model.params) and _replays(run.rollout)
        assert run.rollout.info["diverged"] is None


_GN_HARNESS = r"""
#include <stdio.h>
#include "cp_legacy.c" /* the NMPC part, its state S and mp_gn_step; the rest linked */
int main(void)
{
    static cp_real x[NX], Sx[(MP_N + 1) * NX], Ux[MP_NZU];
    cp_real step;
    int i;
    cp_reset();
    for (;;) {
        for (i = 0; i < NX; ++i) if (scanf("%lf", &x[i]) != 1) return 0;
        for (i = 0; i < (MP_N + 1) * NX; ++i) if (scanf("%lf", &Sx[i]) != 1) return 1;
        for (i = 0; i < MP_NZU; ++i) if (scanf("%lf", &Ux[i]) != 1) return 1;
        printf("%d", mp_gn_step(x, Sx, Ux, &step));
        for (i = 0; i < MP_NZU; ++i) printf(" %.17g", S.mp_Un[i]);
        for (i = 0; i < (MP_N + 1) * NX; ++i) printf(" %.17g", S.mp_Sn[i]);
        printf("\n");
    }
}
"""


def _c_steps_equal_pythons(monkeypatch, tmp_path, design, x0, duration):
    """Record every Python Gauss-Newton step of a lockstep run of ``design`` from ``x0``, replay each from the same
    iterate through the exported C's ``mp_gn_step`` and check they agree (applied input 1e-9, iterate 1e-8); the
    number of steps compared."""
    import subprocess

    from cartpole.export.build import find_compiler
    from cartpole.mpc.nmpc import NMPCController

    seen = []
    gn = NMPCController._gn_step

    def recording(self, x, S, U):
        out = gn(self, x, S, U)
        seen.append((np.array(x), np.array(S), np.array(U), np.array(out[0]), np.array(out[1])))
        return out

    monkeypatch.setattr(NMPCController, "_gn_step", recording)
    ctl, folder = load_design(design, "double")
    try:
        run_lockstep(design, ctl, x0, duration)
        (tmp_path / "gn.c").write_text(_GN_HARNESS)
        exe = tmp_path / "gn"
        others = sorted(str(c) for c in Path(folder, "src").glob("*.c") if c.name != "cp_legacy.c")
        subprocess.run([find_compiler(), "-O2", f"-I{folder}/include", f"-I{folder}/src", "-o", str(exe),
                        str(tmp_path / "gn.c"), *others, "-lm"], check=True)
    finally:
        discard(folder)
    text = "\n".join(" ".join(repr(float(v)) for v in np.concatenate([x.ravel(), S.ravel(), U.ravel()]))
                     for x, S, U, _, _ in seen)
    lines = subprocess.run([str(exe)], input=text, capture_output=True, text=True, check=True).stdout.splitlines()
    assert len(lines) == len(seen)
    for line, (_, S, U, S_py, U_py) in zip(lines, seen):
        vals = line.split()
        assert vals[0] == "0"
        c = np.array([float(v) for v in vals[1:]])
        U_c, S_c = c[:U.size], c[U.size:]
        nu = U_py.shape[1]
        assert np.abs(U_c[:nu] - U_py[0]).max() <= 1e-9  # the applied input
        assert np.abs(U_c - U_py.ravel()).max() <= 1e-8 and np.abs(S_c - S_py.ravel()).max() <= 1e-8
    return len(seen)


def test_two_pole_c_gauss_newton_step_equals_pythons_from_the_same_iterate(monkeypatch, tmp_path):
    # the white-box half of the lockstep: each C step, from the Python controller's own iterate, is its step to
    # 1e-9 (the Python step, the no-compiler path, is the reference: the controller here runs it)
    import cartpole.mpc.nmpc as nmpc

    monkeypatch.setattr(nmpc, "compiled_nmpc", lambda ctl, plan: None)
    model = build_model(TWO_POLE)
    design = design_export(model, "nmpc", None)
    assert _c_steps_equal_pythons(monkeypatch, tmp_path, design, model.x_hanging, 0.6) >= 25  # every period


@pytest.mark.parametrize("prestabilize", [False, True])
def test_two_motor_c_gauss_newton_step_equals_pythons_in_both_condensings(monkeypatch, tmp_path, chain_dir,
                                                                          prestabilize):
    # nu = 2 (the cart and the elbow driven): the condensing's per-input blocks, and pre-stabilised the Cholesky
    # of R + B'PB; balanced from a tilt, in both condensings (GROWTH_LIMIT decides which the controller takes)
    import cartpole.mpc.nmpc as nmpc

    model = build_model(read_params(chain_dir / "two_motors.xml"))
    assert model.nu == 2
    monkeypatch.setattr(nmpc, "GROWTH_LIMIT", 1.0 if prestabilize else np.inf)
    monkeypatch.setattr(nmpc, "compiled_nmpc", lambda ctl, plan: None)  # the Python step, the reference
    x0 = np.array(model.x_eq, float)
    x0[list(model.hinges)] += 0.1
    design = design_export(model, "nmpc", None, x0=x0)
    assert design.make_controller().prestabilize is prestabilize
    assert _c_steps_equal_pythons(monkeypatch, tmp_path, design, x0, 0.4) >= 15
