"""MPCOptions: the NMPC's settings as one validated value; NMPCController and nmpc_swingup taking it."""
import json

import numpy as np
import pytest

from cartpole.errors import CartPoleError
from cartpole.models import build_model, read_params
from cartpole.mpc.nmpc import NMPCController, NMPCError
from cartpole.mpc.options import DEFAULT_HORIZON, MPCOptions


@pytest.mark.parametrize("changes, words", [
    (dict(period=0.0), "period = 0.0 must be a finite number > 0 s"), (dict(horizon=np.inf), "horizon"),
    (dict(iterations=0), "iterations"), (dict(iterations=1.5), "whole number"), (dict(init_iterations=-1), r"in \[0, 1000\]"),
    (dict(iterations=10**9), r"in \[1, 100\]"),
    (dict(tol=-1e-3), "tol"), (dict(rail_penalty=0.0), "rail_penalty"), (dict(qp_solver="osqp"), "daqp, qpoases"),
    (dict(prestabilize="yes"), "True, False or None"), (dict(R=[np.nan]), "R must be finite"),
    (dict(N=60), "MPCOptions has no field 'N'; the fields are period, horizon, iterations"),
])
def test_bad_nmpc_settings_are_one_sentence(changes, words):
    with pytest.raises(NMPCError, match=words) as err:
        MPCOptions().replace(**changes)
    assert isinstance(err.value, CartPoleError)
    assert "\n" not in str(err.value) and str(err.value).endswith(".")


def test_sweeping_a_setting_by_name_and_the_json_echo():
    opts = MPCOptions(Q=np.diag([1.0, 10, 0.1, 0.1]))
    assert {"period", "horizon"} <= set(MPCOptions.scalar_names()) <= set(MPCOptions.names())
    assert opts.replace(**{"horizon": 0.8}).horizon == 0.8 and opts.horizon == DEFAULT_HORIZON
    doc = opts.replace(period=0.04).as_dict()
    assert doc["period"] == 0.04 and doc["Q"][1][1] == 10.0 and set(doc) == set(MPCOptions.names())
    assert json.loads(json.dumps(doc)) == doc
    with pytest.raises(ValueError):
        opts.Q[0, 0] = 2.0


def test_the_controller_takes_its_settings_as_one_options_value_and_no_loose_keywords():
    params = read_params(None)
    model = build_model(params)
    opts = MPCOptions(period=0.04, horizon=0.6, iterations=2)
    new = NMPCController(model, params, options=opts)
    assert new.options == opts and (new.period, new.horizon, new.iterations) == (0.04, 0.6, 2)
    assert new.N == round(0.6 / 0.04)
    with pytest.raises(TypeError, match="horizon"):  # no keyword shim: the options value is the one way
        NMPCController(model, params, horizon=0.4)
    with pytest.raises(NMPCError, match="no field 'steps'"):
        opts.replace(steps=4)
