"""The NMPC's C (cartpole/csrc/nmpc.c.jinja): one rendering for the MuJoCo loop and the export, the QP solver's file
copied as it is."""
import numpy as np
import pytest

from cartpole.codegen import CSRC, qp_source
from cartpole.models import build_model, read_params
from cartpole.mpc.nmpc import NMPCController
from cartpole.mpc.nmpc_c import nmpc_source
from cartpole.ocp.trajectory import Trajectory
from cartpole.mpc.options import MPCOptions


@pytest.fixture(scope="module")
def ctl():
    params = read_params(None)
    return NMPCController(build_model(params), params, options=MPCOptions(horizon=0.2, c_step=False))


def _plan(model):
    n = 11
    return Trajectory(t=np.linspace(0.0, 1.0, n), x=np.zeros((n, model.nx)), u=np.zeros((n, model.nu)),
                      xdot=np.zeros((n, model.nx)))


@pytest.mark.parametrize("with_plan", [False, True])
def test_the_loop_and_the_export_render_the_same_step_and_differ_only_in_where_the_first_iterate_lives(ctl,
                                                                                                      with_plan):
    plan = _plan(ctl.model) if with_plan else None
    export, loop = nmpc_source(ctl, plan).code, nmpc_source(ctl, plan, runtime_data=True).code
    start = "static void mlqr_eval"
    assert export[export.index(start):] == loop[loop.index(start):]
    assert "static const cp_real MP_S0[" in export and "static const cp_real* MP_S0;" in loop
    assert ("static const double* NP_T;" in loop) is with_plan


def test_the_qp_solver_is_its_file_as_it_is():
    text = (CSRC / "qp_dual.c").read_text()
    assert text in qp_source(7, 3)
    renamed = qp_source(7, 3, prefix="mq", sized=True)
    assert "mq_solve(" in renamed and "qp_solve(" not in renamed and "S.mq_nz" in renamed
