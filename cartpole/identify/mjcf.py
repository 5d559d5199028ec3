"""The fitted MJCF: a copy of the nominal file's text with only the fitted attributes changed.

Attribute text is edited in place (comments, formatting, includes, defaults and everything else survive): a joint's
``damping``, ``frictionloss`` or ``armature`` and an actuator's ``gear`` (its first number) are replaced, or added
to the element when the file left them to a default. A body's mass, centre of mass and inertia are what MuJoCo
derived, usually from its geoms, so a fitted one is written where MuJoCo reads it first: the body's ``<inertial>``
(edited when the file has one, else added as the body's first child with the compiled ``pos``, ``quat``, ``mass``
and ``diaginertia``, the fitted values in place). The written file is compiled again and every fitted value
checked in the ``MjModel`` (:func:`check_fitted`).
"""
from __future__ import annotations

import re
from pathlib import Path

import mujoco
import numpy as np

from cartpole._files import atomic_write, short
from cartpole.errors import CartPoleError
from cartpole.identify.parameters import hinge_moment
from cartpole.models import CartPoleParams, mujoco_model, read_params

_TAG = r"<({kinds})\b([^<>]*?)(/?)>"
_ACTUATORS = "motor|general|position|velocity|intvelocity|damper|cylinder|muscle|adhesion|dcmotor"


class FittedMJCFError(CartPoleError):
    """The fitted values cannot be written into the MJCF text, or the written file does not compile to them."""


def _num(v: float) -> str:
    return f"{float(v):.12g}"


def _comments(text: str) -> list:
    return [(m.start(), m.end()) for m in re.finditer(r"<!--.*?-->", text, re.DOTALL)]


def _find_tag(text: str, kinds: str, name: str, what: str) -> re.Match:
    spans = _comments(text)
    for m in re.finditer(_TAG.format(kinds=kinds), text):
        if any(a <= m.start() < b for a, b in spans):
            continue
        nm = re.search(r'\bname\s*=\s*["\']([^"\']*)["\']', m.group(2))
        if nm and nm.group(1) == name:
            return m
    raise FittedMJCFError(f"The MJCF text has no <{what}> named '{name}' to edit (it may come from an <include>); "
                          "write the fitted values into the file that defines it by hand.")


def _set_attr(tag: str, attr: str, value: str) -> str:
    """The tag's text with ``attr="value"`` replaced, or added before its end."""
    pat = re.compile(r'(\s' + attr + r'\s*=\s*)(["\'])[^"\']*\2')
    if pat.search(tag):
        return pat.sub(lambda m: f"{m.group(1)}{m.group(2)}{value}{m.group(2)}", tag, count=1)
    end = len(tag) - (2 if tag.endswith("/>") else 1)
    return f'{tag[:end].rstrip()} {attr}="{value}"{tag[end:]}'


def _get_attr(tag: str, attr: str):
    m = re.search(r'\s' + attr + r'\s*=\s*["\']([^"\']*)["\']', tag)
    return m.group(1) if m else None


def _replace(text: str, m: re.Match, new: str) -> str:
    return text[:m.start()] + new + text[m.end():]


def fitted_text(p: CartPoleParams, params, values) -> str:
    """The nominal MJCF text (``p.xml``) with the parameters set to ``values``.

    Parameters
    ----------
    p : CartPoleParams
        The nominal model (its ``xml`` is edited).
    params : sequence of Parameter
    values : (np,) array, SI units

    Returns
    -------
    str

    Raises
    ------
    FittedMJCFError
        An element not found in the text, or a file that makes MuJoCo ignore ``<inertial>``.
    """
    text = p.xml
    m_nom = mujoco_model(p)
    body_vals: dict[int, dict] = {}
    for q, v in zip(params, values):
        if q.kind in ("damping", "frictionloss", "armature"):
            m = _find_tag(text, "joint", p.joints[q.index].name, "joint")
            text = _replace(text, m, _set_attr(m.group(0), q.kind, _num(v)))
        elif q.kind == "gear":
            m = _find_tag(text, _ACTUATORS, p.actuators[q.index].name, "actuator")
            old = (_get_attr(m.group(0), "gear") or "1").split()
            text = _replace(text, m, _set_attr(m.group(0), "gear", " ".join([_num(v), *old[1:]])))
        else:
            body_vals.setdefault(q.index, {})[q.kind if q.kind != "com" else ("com", q.component)] = (q, v)
    if body_vals and re.search(r'inertiafromgeom\s*=\s*["\']true["\']', text):
        raise FittedMJCFError("The MJCF sets inertiafromgeom=\"true\", so MuJoCo would ignore a fitted <inertial>; "
                              "set it to \"auto\" and fit again.")
    for b, vals in body_vals.items():
        text = _write_inertial(text, p, m_nom, b, vals)
    return text


def _write_inertial(text: str, p: CartPoleParams, m_nom, b: int, vals: dict) -> str:
    name = p.bodies[b].name
    bid = mujoco.mj_name2id(m_nom, mujoco.mjtObj.mjOBJ_BODY, name)
    mass = float(m_nom.body_mass[bid])
    ipos = np.array(m_nom.body_ipos[bid], float)
    inertia = np.array(m_nom.body_inertia[bid], float)
    for key, (q, v) in vals.items():
        if key == "mass":
            mass = float(v)
        elif key == "inertia":
            inertia = inertia * float(v) / q.nominal
        else:
            ipos[key[1]] = float(v)
    attrs = {"pos": " ".join(_num(c) for c in ipos), "quat": " ".join(_num(c) for c in m_nom.body_iquat[bid]),
             "mass": _num(mass), "diaginertia": " ".join(_num(c) for c in inertia)}
    body = _find_tag(text, "body", name, "body")
    if body.group(3) == "/":
        raise FittedMJCFError(f"Body '{name}' is an empty element in the MJCF text; give it an <inertial> child.")
    start = body.end()
    nxt = re.search(r"<body\b|</body\s*>", text[start:])
    stop = start + (nxt.start() if nxt else len(text) - start)
    inert = re.search(r"<inertial\b[^<>]*?/?>", text[start:stop])
    if inert:
        tag = inert.group(0)
        for attr in ("fullinertia",):
            tag = re.sub(r'\s' + attr + r'\s*=\s*["\'][^"\']*["\']', "", tag)
        for k, val in attrs.items():
            tag = _set_attr(tag, k, val)
        return text[:start + inert.start()] + tag + text[start + inert.end():]
    line_start = text.rfind("\n", 0, body.start()) + 1
    indent = re.match(r"[ \t]*", text[line_start:]).group(0) + "  "
    tag = "<inertial " + " ".join(f'{k}="{v}"' for k, v in attrs.items()) + "/>"
    return text[:start] + f"\n{indent}<!-- fitted by cartpole identify -->\n{indent}{tag}" + text[start:]


def check_fitted(path: str | Path, params, values, *, rtol: float = 1e-9) -> None:
    """Compile the written file and check that its ``MjModel`` holds every fitted value.

    Parameters
    ----------
    path : path
    params : sequence of Parameter
    values : (np,) array
    rtol : float
        Relative tolerance (the text holds 12 significant digits).

    Raises
    ------
    FittedMJCFError
        The file does not compile, or a value differs.
    """
    try:
        fp = read_params(path)
    except CartPoleError as exc:
        raise FittedMJCFError(f"The fitted MJCF {short(path)} does not load ({exc}); write it beside the nominal file "
                              "(relative includes) or report this.") from None
    for q, v in zip(params, values):
        if q.kind == "mass":
            got = fp.bodies[q.index].mass
        elif q.kind == "com":
            got = float(fp.bodies[q.index].ipos[q.component])
        elif q.kind == "inertia":
            got = hinge_moment(fp, q.index)
        elif q.kind == "gear":
            got = fp.actuators[q.index].transmission
        else:
            got = float(getattr(fp.joints[q.index], q.kind))
        if abs(got - v) > rtol * max(abs(v), q.scale) + 1e-15:
            raise FittedMJCFError(f"The fitted MJCF {short(path)} compiles {q.name} to {got:.9g}, not the fitted "
                                  f"{v:.9g}; the file's defaults override the edit, so set it by hand.")


def write_fitted_mjcf(path: str | Path, p: CartPoleParams, params, values) -> Path:
    """Write the fitted MJCF (:func:`fitted_text`) whole or not at all, and check it (:func:`check_fitted`).

    Parameters
    ----------
    path : path
        Where to write.
    p : CartPoleParams
        The nominal model.
    params : sequence of Parameter
    values : (np,) array, SI units

    Returns
    -------
    Path
    """
    text = fitted_text(p, params, values)
    path = Path(path)
    atomic_write(path, lambda fh: fh.write(text.encode()))
    check_fitted(path, params, values)
    return path
