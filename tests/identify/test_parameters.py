"""Parameters by MJCF name, and the parametric sample step against mj_step on a model with those values edited."""
import mujoco
import numpy as np
import pytest

from cartpole.identify.parameters import (
    ParameterError,
    parse_parameters,
    sample_step,
    steps_per_sample,
)
from cartpole.models import SHIPPED_MJCF, read_params

TWO_POLE = SHIPPED_MJCF.parent / "cartpole_two_pole.xml"


def _edited(path, pars, theta):
    """The compiled MjModel with the parameters' values written into its fields (an independent route)."""
    m = mujoco.MjModel.from_xml_path(str(path))
    for q, v in zip(pars, theta):
        b = q.index + 1  # moving bodies follow the world body in these files
        if q.kind == "mass":
            m.body_mass[b] = v
        elif q.kind == "com":
            m.body_ipos[b, q.component] = v
        elif q.kind == "inertia":
            m.body_inertia[b] *= v / q.nominal
        elif q.kind == "gear":
            m.actuator_gear[q.index, 0] = v
        else:
            getattr(m, "dof_" + q.kind)[q.index] = v
    return m


@pytest.mark.parametrize("path", [SHIPPED_MJCF, TWO_POLE])
def test_parametric_step_equals_mj_step_with_edited_parameters(path):
    p = read_params(path)
    names = ["all", "armature:slider", "armature:hinge"] + [f"mass:{b.name}" for b in p.bodies]
    pars = [q for q in parse_parameters(p, names) if q.kind != "frictionloss"]
    rng = np.random.default_rng(3)
    theta = np.array([q.nominal * rng.uniform(0.7, 1.3) + (0.002 if q.nominal == 0 else 0) for q in pars])
    m = _edited(path, pars, theta)
    d = mujoco.MjData(m)
    F = sample_step(p, pars, 3 * p.timestep)
    for _ in range(10):
        x = rng.uniform(-2, 2, 2 * p.nq)
        x[0] = rng.uniform(-1, 1)  # inside the rail: no limit force
        u = rng.uniform(-1, 1, p.nu)
        d.qpos[:], d.qvel[:], d.ctrl[:] = x[:p.nq], x[p.nq:], u
        for _ in range(3):
            mujoco.mj_step(m, d)
        np.testing.assert_allclose(np.asarray(F(x, u, theta)).ravel(), np.r_[d.qpos, d.qvel], rtol=0, atol=1e-9)


def test_frictionloss_step_equals_mj_step_while_sliding():
    p = read_params(SHIPPED_MJCF)
    pars = parse_parameters(p, ["frictionloss:slider", "frictionloss:hinge"])
    theta = np.array([0.3, 0.002])
    m = _edited(SHIPPED_MJCF, pars, theta)
    d = mujoco.MjData(m)
    x, u = np.array([0.1, 2.0, 1.0, -3.0]), np.array([0.3])
    d.qpos[:], d.qvel[:], d.ctrl[:] = x[:2], x[2:], u
    mujoco.mj_step(m, d)
    F = sample_step(p, pars, p.timestep)
    np.testing.assert_allclose(np.asarray(F(x, u, theta)).ravel(), np.r_[d.qpos, d.qvel], rtol=0, atol=1e-9)


@pytest.mark.parametrize("path", [SHIPPED_MJCF, TWO_POLE])
def test_exact_friction_step_equals_mj_step_sticking_and_sliding(path):
    """MuJoCo's friction-loss constraint solved exactly (one box QP over every friction joint): the step equals
    mj_step on a model with the values edited (its invweight0 recomputed, as compiling a fitted file does) on
    states where the joints stick (slow, small ctrl) and where they slide."""
    p = read_params(path)
    pars = parse_parameters(p, ["all", "armature:hinge"])
    assert sum(q.kind == "frictionloss" for q in pars) == p.nq
    rng = np.random.default_rng(1)
    theta = np.array([q.nominal * rng.uniform(0.7, 1.3) + (rng.uniform(2, 5) * q.scale if q.nominal == 0 else 0)
                      for q in pars])
    m = _edited(path, pars, theta)
    d = mujoco.MjData(m)
    mujoco.mj_setConst(m, d)
    F = sample_step(p, pars, p.timestep)
    stuck = slid = 0
    for k in range(60):
        small = k % 3 != 0
        x = rng.uniform(-1, 1, 2 * p.nq) * (0.02 if small else 2)
        x[0] = rng.uniform(-1, 1)  # inside the rail
        u = rng.uniform(-1, 1, p.nu) * (0.01 if small else 1)
        d.qpos[:], d.qvel[:], d.ctrl[:] = x[:p.nq], x[p.nq:], u
        mujoco.mj_step(m, d)
        fr = d.efc_type == mujoco.mjtConstraint.mjCNSTR_FRICTION_DOF
        at_bound = np.isclose(np.abs(d.efc_force[fr]), m.dof_frictionloss[d.efc_id[fr]], rtol=1e-9)
        stuck += int(not np.all(at_bound))
        slid += int(np.any(at_bound))
        np.testing.assert_allclose(np.asarray(F(x, u, theta)).ravel(), np.r_[d.qpos, d.qvel], rtol=0, atol=1e-9)
    assert stuck >= 5 and slid >= 5


def test_more_friction_joints_than_the_exact_model_solves_is_one_sentence():
    p = read_params(SHIPPED_MJCF.parent / "cartpole_three_pole.xml")
    pars = parse_parameters(p, [f"frictionloss:{j}" for j in p.joint_names])
    with pytest.raises(ParameterError, match="more than the exact friction model solves") as exc:
        sample_step(p, pars, p.timestep)
    assert "\n" not in str(exc.value)
    assert sum(q.kind == "frictionloss" for q in parse_parameters(p, ["all"])) <= 3


def test_all_expands_to_the_documented_default_set():
    names = [q.name for q in parse_parameters(read_params(SHIPPED_MJCF), ["all"])]
    assert names == ["gear:motor", "com:pole:x", "com:pole:z", "inertia:pole", "damping:slider", "damping:hinge",
                     "frictionloss:slider", "frictionloss:hinge"]


def test_bounds_keep_the_model_physical():
    pars = parse_parameters(read_params(SHIPPED_MJCF), ["mass:pole", "inertia:pole", "damping:hinge"])
    assert all(q.lower == 0 and q.upper == np.inf for q in pars)


@pytest.mark.parametrize("name, words", [("mass:pol", "no moving body 'pol'"), ("damping:cart", "no joint"),
                                         ("gear:slider", "no actuator"), ("size:pole", "KIND:NAME"),
                                         ("com:pole:w", "axis 'w'")])
def test_unknown_parameter_is_one_sentence(name, words):
    with pytest.raises(ParameterError, match=words):
        parse_parameters(read_params(SHIPPED_MJCF), [name])


def test_steps_per_sample_uses_the_mjcf_step_when_it_divides():
    assert steps_per_sample(0.01, 0.005) == (2, 0.005)
    m, h = steps_per_sample(0.012, 0.005)
    assert m == 3 and h == pytest.approx(0.004)
