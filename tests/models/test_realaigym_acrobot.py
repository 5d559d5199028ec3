"""RealAIGym's acrobot (cartpole/assets/realaigym_acrobot.xml) against its source's equations, and the toolkit's model
of it against MuJoCo.

The physical numbers are cited from dfki-ric-underactuated-lab/double_pendulum:
data/system_identification/identified_parameters/design_C.1/model_1.1/model_parameters.yml (the parameters that
leaderboard/acrobot/simulation_v3/sim_parameters.py loads, with motor inertia, damping and Coulomb friction set to 0
and the torque limit to [0, 6] N m). Their mass matrix and gravity vector (src/python/double_pendulum/model/plant.py,
``mass_matrix`` and ``gravity_vector``, the "UnderactuatedLecture" formulas) are written out below and compared with
MuJoCo's on the file, through the change of angles the file's comment states (their q1 = pi - shoulder, q2 = -elbow:
their q1 = 0 hangs, this file's shoulder = 0 stands upright, and their angles turn the other way about y).
"""
import mujoco
import numpy as np

from cartpole.models import SHIPPED_MJCF, build_model, read_params
from cartpole.sim import make_mujoco
from cartpole.validation.jacobians import random_states

ACROBOT = SHIPPED_MJCF.with_name("realaigym_acrobot.xml")

# model_parameters.yml of design_C.1/model_1.1
M1, M2 = 0.5234602302310271, 0.6255677234174437
L1, L2 = 0.2, 0.3
R1, R2 = 0.2, 0.25569305436052964
I1, I2 = 0.031887199591513114, 0.05086984812807257
G = 9.81
# sim_parameters.py: mpar.set_torque_limit([0.0, 6.0]); dt = 0.002, integrator = "runge_kutta"
TORQUE_LIMIT, DT = 6.0, 0.002


def _theirs(q):
    """Their (q1, q2) for this file's (shoulder, elbow), rad."""
    return np.pi - q[0], -q[1]


def _their_mass_matrix(q1, q2):
    c2 = np.cos(q2)
    m00 = I1 + I2 + M2 * L1 ** 2 + 2 * M2 * L1 * R2 * c2
    m01 = I2 + M2 * L1 * R2 * c2
    return np.array([[m00, m01], [m01, I2]])


def _their_gravity(q1, q2):
    g0 = -M1 * G * R1 * np.sin(q1) - M2 * G * (L1 * np.sin(q1) + R2 * np.sin(q1 + q2))
    g1 = -M2 * G * R2 * np.sin(q1 + q2)
    return np.array([g0, g1])


def _mujoco():
    return make_mujoco(str(ACROBOT))


def test_mass_matrix_and_gravity_are_their_plants_at_random_poses():
    m, d = _mujoco()
    rng = np.random.default_rng(0)
    for q in rng.uniform(-np.pi, np.pi, (50, 2)):
        d.qpos[:], d.qvel[:] = q, 0.0
        mujoco.mj_forward(m, d)
        M = np.zeros((2, 2))
        mujoco.mj_fullM(m, d, M)
        q1, q2 = _theirs(q)
        # the sign change of both angles leaves M as it is (J = -I) and flips generalized forces
        np.testing.assert_allclose(M, _their_mass_matrix(q1, q2), rtol=1e-12, atol=1e-12)
        # MuJoCo: M qacc + qfrc_bias = tau, theirs: M qdd = G + B u - C qd: at rest qfrc_bias = -G in their angles,
        # and -(-G) = G in this file's
        np.testing.assert_allclose(d.qfrc_bias, _their_gravity(q1, q2), rtol=1e-12, atol=1e-12)


def test_file_runs_their_integrator_step_limit_and_no_damping_or_friction():
    m, _ = _mujoco()
    assert m.opt.timestep == DT and m.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    assert m.nu == 1 and m.actuator_trnid[0, 0] == m.joint("elbow").id
    assert np.all(m.actuator_ctrlrange[0] * m.actuator_gear[0, 0] == [-TORQUE_LIMIT, TORQUE_LIMIT])
    assert not np.any(m.dof_damping) and not np.any(m.dof_frictionloss) and not np.any(m.dof_armature)
    np.testing.assert_allclose(m.opt.gravity, [0, 0, -G])


def test_tip_is_the_chains_length_above_the_shoulder_upright():
    m, d = _mujoco()
    mujoco.mj_forward(m, d)
    assert np.isclose(d.site_xpos[m.site("tip").id][2] - d.xpos[m.body("upper_arm").id][2], L1 + L2)


def test_symbolic_step_equals_one_mj_step():
    params = read_params(ACROBOT)
    model = build_model(params)
    m, d = _mujoco()
    xs, us = random_states(params, 50, seed=5)
    for x, u in zip(xs, us):
        mujoco.mj_resetData(m, d)
        d.qpos[:], d.qvel[:], d.ctrl[:] = x[:model.nq], x[model.nq:], u
        mujoco.mj_step(m, d)
        np.testing.assert_allclose(model.step_np(x, u), np.concatenate([d.qpos, d.qvel]), rtol=0, atol=1e-9)
