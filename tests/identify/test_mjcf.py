"""The fitted MJCF: only the fitted attributes change, comments and formatting survive, MuJoCo-derived inertials
become an explicit <inertial>, and the compiled file holds every fitted value."""
import difflib

import mujoco
import numpy as np
import pytest

from cartpole.identify.mjcf import (
    FittedMJCFError,
    check_fitted,
    fitted_text,
    write_fitted_mjcf,
)
from cartpole.identify.parameters import hinge_moment, parse_parameters
from cartpole.models import SHIPPED_MJCF, read_params

TWO_POLE = SHIPPED_MJCF.parent / "cartpole_two_pole.xml"


def _compiled_value(fp, q):
    if q.kind == "mass":
        return fp.bodies[q.index].mass
    if q.kind == "com":
        return fp.bodies[q.index].ipos[q.component]
    if q.kind == "inertia":
        return hinge_moment(fp, q.index)
    if q.kind == "gear":
        return fp.actuators[q.index].transmission
    return getattr(fp.joints[q.index], q.kind)


@pytest.mark.parametrize("path", [SHIPPED_MJCF, TWO_POLE])
def test_fitted_file_compiles_to_the_fitted_values_and_changes_nothing_else(tmp_path, path):
    p = read_params(path)
    names = ["all", "armature:hinge"] + [f"mass:{b.name}" for b in p.bodies]
    pars = parse_parameters(p, names)
    vals = np.array([q.nominal * 1.17 + 0.003 for q in pars])
    out = write_fitted_mjcf(tmp_path / "fitted.xml", p, pars, vals)
    fp = read_params(out)
    for q, v in zip(pars, vals):  # an independent read of the compiled model
        assert _compiled_value(fp, q) == pytest.approx(v, rel=1e-9), q.name
    # the other principal moments scale with the fitted one: the body stays physical
    for q in pars:
        if q.kind == "inertia":
            np.testing.assert_allclose(fp.bodies[q.index].inertia, p.bodies[q.index].inertia * 1.0 *
                                       (vals[pars.index(q)] / q.nominal), rtol=1e-9)
    # every changed line is a fitted element; comments survive
    old, new = path.read_text().splitlines(), out.read_text().splitlines()
    changed = [ln for ln in difflib.unified_diff(old, new, lineterm="", n=0) if ln[:1] in "+-"
               and not ln.startswith(("+++", "---"))]
    assert all(any(w in ln for w in ("<joint", "<motor", "<inertial", "fitted by cartpole")) for ln in changed)
    assert [ln for ln in old if "<!--" in ln] == [ln for ln in new if "<!--" in ln and "fitted by" not in ln]


def test_an_existing_inertial_is_edited_in_place(tmp_path):
    text = SHIPPED_MJCF.read_text().replace(
        '<geom name="pole_geom"', '<inertial pos="0 0 0.3" mass="0.1" diaginertia="0.003 0.003 1e-5"/>\n'
        '        <geom name="pole_geom"')
    src = tmp_path / "inertial.xml"
    src.write_text(text)
    p = read_params(src)
    pars = parse_parameters(p, ["mass:pole", "com:pole:z"])
    new = fitted_text(p, pars, [0.12, 0.33])
    assert new.count("<inertial") == 1 and 'mass="0.12"' in new
    m = mujoco.MjModel.from_xml_string(new)
    assert m.body_mass[2] == pytest.approx(0.12) and m.body_ipos[2, 2] == pytest.approx(0.33)


def test_a_file_whose_defaults_override_the_edit_is_caught(tmp_path):
    p = read_params(SHIPPED_MJCF)
    pars = parse_parameters(p, ["damping:hinge"])
    path = tmp_path / "f.xml"
    path.write_text(fitted_text(p, pars, [0.02]).replace('damping="0.02"', 'damping="0.01"'))
    with pytest.raises(FittedMJCFError, match="compiles damping:hinge"):
        check_fitted(path, pars, [0.02])


def test_inertiafromgeom_true_is_refused(tmp_path):
    text = SHIPPED_MJCF.read_text().replace("<option ", '<compiler inertiafromgeom="true"/>\n  <option ')
    src = tmp_path / "ifg.xml"
    src.write_text(text)
    p = read_params(src)
    with pytest.raises(FittedMJCFError, match="inertiafromgeom"):
        fitted_text(p, parse_parameters(p, ["mass:pole"]), [0.2])
