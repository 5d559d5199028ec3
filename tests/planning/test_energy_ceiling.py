"""The energy ceiling: the planner's only proof of infeasibility. It refuses the weak carts with its numbers, never
fires where a swing-up exists, and bounds what the best pumping law reaches in MuJoCo."""
import mujoco
import numpy as np
import pytest

from cartpole.models import SHIPPED_MJCF, read_params
from cartpole.planning.energy_ceiling import CLAIM_BELOW, energy_ceiling

ASSETS = SHIPPED_MJCF.parent
RAIL = (-1.4, 1.4)  # the planner's: the rail shrunk by its 0.1 m margin


def _cart(tmp_path, gear, *, free_slide=False):
    xml = SHIPPED_MJCF.read_text().replace('gear="20"', f'gear="{gear}"')
    if free_slide:  # no rail end stops, no slide damper
        xml = xml.replace('limited="true" range="-1.5 1.5" damping="0.1"', 'limited="false"')
    path = tmp_path / f"cart_gear{gear}{'_free' if free_slide else ''}.xml"
    path.write_text(xml)
    return path


@pytest.mark.parametrize("gear", [3, 4])
def test_a_cart_too_weak_for_its_damping_is_proven_unable_to_swing_up(gear, tmp_path):
    ec = energy_ceiling(read_params(_cart(tmp_path, gear)), cart_range=RAIL)
    assert ec.proven and ec.kind == "cart" and ec.ceiling < CLAIM_BELOW
    assert ec.force == pytest.approx(gear) and ec.force < ec.force_bound < 1.2 * gear  # the damper's push counted
    words = ec.sentence()
    assert f"{gear} N" in words and f"{ec.ceiling:.2f}" in words and "0.01" in words and "0.1" in words
    assert len(words) < 240 and "\n" not in words


@pytest.mark.parametrize("where", ["gear5", "gear6", "dmc_pendulum.xml", "dmc_acrobot.xml", "cartpole.xml"])
def test_no_proof_where_a_swing_up_exists(where, tmp_path):
    path = _cart(tmp_path, int(where[-1])) if where.startswith("gear") else ASSETS / where
    ec = energy_ceiling(read_params(path), cart_range=RAIL if "acrobot" not in where else None)
    assert not ec.proven and ec.reason
    if "acrobot" not in where:  # a chain of two: the bound does not apply
        assert ec.ceiling > 1.0


def _pump_in_mujoco(path, seconds, law):
    """Best energy (centre-of-momentum frame, hanging -1, upright 1) MuJoCo reaches under ``law(r, theta_dot)``."""
    m = mujoco.MjModel.from_xml_path(str(path))
    m.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_ENERGY
    d = mujoco.MjData(m)
    h = m.nq - 1  # the hinge's index
    d.qpos[h] = np.pi
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    V_hang = float(d.energy[0])
    d.qpos[h] = 0.0
    mujoco.mj_forward(m, d)
    V_up = float(d.energy[0])
    d.qpos[h] = np.pi
    best = -np.inf
    for _ in range(int(seconds / m.opt.timestep)):
        mujoco.mj_forward(m, d)
        mujoco.mj_fullM(m, d, M)
        if m.nv == 2:
            r = M[0, 1] / M[0, 0]
            E = 0.5 * (M[1, 1] - M[0, 1] ** 2 / M[0, 0]) * d.qvel[1] ** 2 + d.energy[0]
        else:
            r = 1.0
            E = 0.5 * M[0, 0] * d.qvel[0] ** 2 + d.energy[0]
        best = max(best, 2 * (E - V_hang) / (V_up - V_hang) - 1)
        d.ctrl[0] = law(r, d.qvel[h])
        mujoco.mj_step(m, d)
    return best


def test_the_ceiling_bounds_bang_bang_pumping_on_the_cart_and_nearly_meets_it(tmp_path):
    # without a damper on the slide the bound needs no rail; F = -F_max sign(r theta_dot) attains its rate exactly
    path = _cart(tmp_path, 4, free_slide=True)
    ec = energy_ceiling(read_params(path))
    reached = _pump_in_mujoco(path, 40.0, lambda r, w: -np.sign(r * w) if w else 1.0)
    assert ec.proven and reached <= ec.ceiling + 0.02 and reached > ec.ceiling - 0.1


def test_the_ceiling_bounds_bang_bang_pumping_on_a_weak_pendulum(tmp_path):
    path = tmp_path / "weak_pendulum.xml"
    path.write_text((ASSETS / "dmc_pendulum.xml").read_text().replace('ctrlrange="-1 1"', 'ctrlrange="-0.3 0.3"'))
    ec = energy_ceiling(read_params(path))
    reached = _pump_in_mujoco(path, 40.0, lambda r, w: 0.3 * (np.sign(w) if w else 1.0))
    assert ec.kind == "hinge" and ec.proven and reached <= ec.ceiling + 0.02 and reached > ec.ceiling - 0.1
    assert "0.3 N m" in ec.sentence()


def test_a_start_in_motion_or_an_odd_model_gets_no_proof(tmp_path):
    p = read_params(_cart(tmp_path, 3))
    assert not energy_ceiling(p, [0.0, np.pi, 0.0, 1.0], cart_range=RAIL).proven  # not at rest
    two = read_params(ASSETS / "cartpole_two_pole.xml")
    assert "one hinge" in energy_ceiling(two).reason
