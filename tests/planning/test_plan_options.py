"""PlanOptions: the planner's settings as one validated value, and trajopt_swingup taking it (old keywords too)."""
import json

import numpy as np
import pytest

from cartpole.errors import CartPoleError
from cartpole.ocp.bounds import OCPError
from cartpole.planning.options import PlanOptions, PlanOptionsError


@pytest.mark.parametrize("changes, words", [
    (dict(N=1), r"N = 1 must be a finite number in \[2, 2000\]"), (dict(N=40.5), "whole number"),
    (dict(T=0.0), r"in \(0, 60\] s"), (dict(N=10**9), r"\[2, 2000\]"), (dict(T=1e308), r"\(0, 60\] s"),
    (dict(time_margin=-0.1), "time_margin"), (dict(cart_margin=np.nan), "cart_margin"),
    (dict(u_margin=1.0), "fraction in \\[0, 1\\)"), (dict(solver="snopt"), "ipopt, fatrop, sqp"),
    (dict(starts=0), "starts"), (dict(exact_discrete="sometimes"), "True, False or 'auto'"),
    (dict(objective=3), "neither a name nor a function"), (dict(Q=[[1, np.inf]]), "Q must be finite"),
    (dict(solver_options=["max_iter"]), "must be a dict"), (dict(mesh=10), "PlanOptions has no field 'mesh'"),
])
def test_bad_planner_settings_are_one_sentence(changes, words):
    with pytest.raises(PlanOptionsError, match=words) as err:
        PlanOptions().replace(**changes)
    assert isinstance(err.value, OCPError) and isinstance(err.value, CartPoleError)
    assert "\n" not in str(err.value) and str(err.value).endswith(".")


def test_an_unknown_field_lists_every_valid_name():
    with pytest.raises(PlanOptionsError) as err:
        PlanOptions().replace(horizon=2.0)
    for name in PlanOptions.names():
        assert name in str(err.value)


def test_plan_options_are_read_only_values_with_a_json_echo():
    opts = PlanOptions(N=40, Q=np.diag([1.0, 10, 0.1, 0.1]), solver_options={"ipopt.max_iter": 500},
                       objective="tracking")
    with pytest.raises(ValueError):
        opts.Q[0, 0] = 5.0
    with pytest.raises(TypeError):
        opts.solver_options["ipopt.max_iter"] = 1
    same = PlanOptions(N=40, Q=np.diag([1.0, 10, 0.1, 0.1]), solver_options={"ipopt.max_iter": 500},
                       objective="tracking")
    assert opts == same and hash(opts) == hash(same) and opts != opts.replace(Q=np.eye(4))
    doc = opts.as_dict()
    assert set(doc) == set(PlanOptions.names()) and doc["Q"][1][1] == 10.0 and doc["N"] == 40
    assert json.loads(json.dumps(doc)) == doc
    assert opts.replace(**{"N": 60}).N == 60 and opts.N == 40
    assert set(PlanOptions.scalar_names()) <= set(PlanOptions.names())


@pytest.fixture(scope="module")
def params():
    from cartpole.models import read_params

    return read_params(None)


def test_trajopt_swingup_takes_its_settings_as_one_options_value_and_no_loose_keywords(params):
    from cartpole.planning.trajopt import trajopt_swingup

    opts = PlanOptions(N=40, exact_discrete=False, time_margin=0.3)
    plan = trajopt_swingup(params, options=opts)
    assert plan.options == opts
    assert plan.trajectory.N == 40 and plan.T == pytest.approx(1.3 * plan.T_min)
    with pytest.raises(TypeError, match="N"):  # no keyword shim: the options value is the one way
        trajopt_swingup(params, N=40)
    with pytest.raises(PlanOptionsError, match="no field 'mesh'"):
        opts.replace(mesh=40)
