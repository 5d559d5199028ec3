"""An exported controller as C files: the rig step (``cartpole/csrc/cp_rig.c``: estimate, delay prediction, ctrl
history, saturation) around one estimator part and one controller part, each a C file of ``cartpole/csrc/``
copied as it is, with the export's sizes, constants and tables rendered from Jinja2 templates
(``cp_config.h.jinja``, ``cp_data.c.jinja``) and its model maths CasADi-generated (``src/cp_generated.c``).

The step ``cp_step(t, y, u)`` does what :class:`cartpole.sim.rig.RigRun` and :func:`cartpole.sim.rollout.simulate`
do around a Python controller, in the same order and with the same arithmetic (see ``cp_rig.c``).

A part is a :class:`CPart`: the C files it is made of (``sources``), its tables and constants, and the CasADi
Functions it calls. Parts the NMPC and MHE modules still write as C text (``code``, ``tables``, ``fields``,
``reset``) are rendered into ``src/cp_legacy.c`` (``cp_legacy.c.jinja``) and bound to the same part interface
(``cp_parts.h``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from cartpole.codegen import CSRC, render
from cartpole.export.csource import float_maths, generate, work_sizes

#: ``cp_step``'s return codes, as the header and the manifest document them.
RETURN_CODES = {
    0: "CP_OK: the ctrl was computed by the exported law",
    1: "CP_BAD_MEASUREMENT: an entry of y was not finite; the previous ctrl was repeated and the estimate was not "
       "updated this period",
    2: "CP_BAD_STATE: the estimate or the ctrl became non-finite; the ctrl was set to zero (clipped to ctrlrange); "
       "call cp_reset() before the next run",
    3: "CP_FALLBACK: the optimiser did not converge and the fallback law ran (NMPC only)",
}


@dataclass(frozen=True)
class CPart:
    """A piece of an exported controller (see the module doc).

    Attributes
    ----------
    sources : tuple of str
        Files of ``cartpole/csrc/`` the part is made of (copied into ``src/`` as they are).
    data : tuple
        Its tables: ``(name, ctype, values)`` with ``ctype`` ``"cp_real"``, ``"double"`` or ``"int"`` (declared in
        ``cp_config.h``, defined in ``cp_data.c``; values flattened in C order).
    constants : tuple
        Its scalars: ``(name, ctype, value)``, each ``#define NAME ((ctype)value)`` in ``cp_config.h``.
    defines : tuple
        Integer switches and sizes: ``(name, int)``, each ``#define NAME value``.
    functions : tuple of casadi.Function
        CasADi Functions the code calls (generated into ``src/cp_generated.c``).
    plan : bool
        Its defines, constants and table declarations go to ``src/cp_plan.h`` (``cp_plan.h.jinja``), which its
        sources include, rather than to ``cp_config.h``, which every file includes: a new plan (other tables,
        another length) then changes ``cp_data.c``, ``cp_plan.h`` and the part's own file, and the cached objects
        of the rest (the model's CasADi-generated code above all) serve it as they are
        (:func:`cartpole.codegen.build_sources`).
    tables, fields, code, reset : str, tuple of str, str, str
        A part written as C text (``static const`` tables, members of the struct ``S``, static functions
        ``est_reset``/``est_update`` or ``ctrl_eval``, statements run on reset): rendered into ``src/cp_legacy.c``.
    """

    sources: tuple = ()
    data: tuple = ()
    constants: tuple = ()
    defines: tuple = ()
    functions: tuple = field(default=())
    plan: bool = False
    tables: str = ""
    fields: tuple = ()
    code: str = ""
    reset: str = ""

    @property
    def legacy(self) -> bool:
        """Whether the part is C text (rendered into ``src/cp_legacy.c``) rather than files of ``cartpole/csrc``."""
        return bool(self.code)


@dataclass(frozen=True)
class CProgram:
    """Everything ``cp_step`` needs, for :func:`sources`.

    Attributes
    ----------
    nx, nq, nu, ny : int
        State, joint, input and measurement sizes.
    steps : int
        Physics steps per control period.
    lag : int
        Physics steps from a sample to its ctrl taking effect.
    dt : float
        The MJCF's physics step, s.
    real : str
        ``"double"`` or ``"float"``.
    u_low, u_high : (nu,) arrays
        MuJoCo's ctrl clamp (``-inf``/``inf`` without ctrlrange).
    hinges : tuple of int
        qpos indices whose errors are wrapped.
    estimator : CPart
        Defines ``est_reset(y, x)`` and ``est_update(y, U, x)``.
    controller : CPart
        Defines ``ctrl_eval(t, x, u)`` returning a code.
    predict : casadi.Function or None
        ``(x (nx,), U (nu, lag)) -> x`` over the delay, None without compensation.
    title : str
        One line naming the export, for the file headers.
    """

    nx: int
    nq: int
    nu: int
    ny: int
    steps: int
    lag: int
    dt: float
    real: str
    u_low: np.ndarray
    u_high: np.ndarray
    hinges: tuple
    estimator: CPart
    controller: CPart
    predict: ca.Function | None = None
    title: str = ""

    @property
    def period(self) -> float:
        """Control period in s."""
        return self.steps * float(self.dt)

    @property
    def delay(self) -> float:
        """Delay from sample to ctrl in s."""
        return self.lag * float(self.dt)

    @property
    def functions(self) -> tuple:
        """Every CasADi Function the program calls."""
        extra = () if self.predict is None else (self.predict,)
        return tuple(self.estimator.functions) + tuple(self.controller.functions) + extra


#: The names of :data:`RETURN_CODES` in C.
CODE_NAMES = {0: "CP_OK", 1: "CP_BAD_MEASUREMENT", 2: "CP_BAD_STATE", 3: "CP_FALLBACK"}
#: Files of ``cartpole/csrc`` every export carries (relative path in the export -> file): the rig step, the shared
#: helpers and the part interface.
COMMON_FILES = {"src/cartpole_controller.c": "cp_rig.c", "src/cp_common.c": "cp_common.c",
                "src/cp_common.h": "cp_common.h", "src/cp_parts.h": "cp_parts.h", "src/cp_linalg.c": "cp_linalg.c",
                "src/cp_linalg.h": "cp_linalg.h"}


def header(prog: CProgram, version: str) -> str:
    """The public header ``include/cartpole_controller.h`` of ``prog`` (``cartpole_controller.h.jinja``)."""
    return render("cartpole_controller.h.jinja", title=prog.title, version=version, real=prog.real, ny=prog.ny,
                  nu=prog.nu, period=repr(prog.period), delay=repr(prog.delay),
                  return_codes=list(RETURN_CODES.items()), code_names=list(CODE_NAMES.items()))


def _tables(prog: CProgram) -> list:
    wrap = [1 if i < prog.nq and i in prog.hinges else 0 for i in range(prog.nx)]
    rows = [("U_LOW", "cp_real", prog.u_low, False), ("U_HIGH", "cp_real", prog.u_high, False),
            ("WRAP", "int", wrap, False)]
    out, seen = [], set()
    for part in (prog.estimator, prog.controller):
        rows += [(*row, part.plan) for row in part.data]
    for name, ctype, values, plan in rows:
        if name in seen:
            raise ValueError(f"two tables named {name} in one export")
        seen.add(name)
        flat = np.asarray(values).ravel(order="C")
        if flat.size == 0:
            raise ValueError(f"table {name} would be empty (C99 forbids zero-length arrays)")
        out.append({"name": name, "ctype": ctype, "size": int(flat.size), "data": flat,
                    "kind": "int" if ctype == "int" else "real", "plan": plan})
    return out


def config(prog: CProgram) -> tuple[str, str, str | None]:
    """``(src/cp_config.h, src/cp_data.c, src/cp_plan.h)`` of ``prog``: sizes, switches, constants and the extern
    tables, the tables' definitions, and the same for the parts with :attr:`CPart.plan` (None without one),
    rendered from ``cp_config.h.jinja``, ``cp_data.c.jinja`` and ``cp_plan.h.jinja``."""
    tables = _tables(prog)
    defines, constants = {False: [], True: []}, {False: [], True: []}
    for part in (prog.estimator, prog.controller):
        defines[part.plan] += [(n, int(v)) for n, v in part.defines]
        constants[part.plan] += [(n, c, float(v)) for n, c, v in part.constants]
    plan = any(t["plan"] for t in tables) or bool(defines[True] or constants[True])
    values = {"title": prog.title, "nx": prog.nx, "nq": prog.nq, "steps": prog.steps, "lag": prog.lag,
              "predict": prog.predict is not None, "plan": plan}
    plan_h = None
    if plan:
        plan_h = render("cp_plan.h.jinja", **values, defines=defines[True], constants=constants[True],
                        tables=[t for t in tables if t["plan"]])
    return (render("cp_config.h.jinja", **values, defines=defines[False], constants=constants[False],
                   tables=[t for t in tables if not t["plan"]]),
            render("cp_data.c.jinja", **values, tables=tables), plan_h)


def legacy_source(prog: CProgram) -> str | None:
    """``src/cp_legacy.c``: the parts of ``prog`` written as C text (:attr:`CPart.legacy`), or None."""
    est = prog.estimator if prog.estimator.legacy else None
    ctl = prog.controller if prog.controller.legacy else None
    if est is None and ctl is None:
        return None
    parts = [p for p in (est, ctl) if p is not None]
    funcs = [f for p in parts for f in p.functions]
    w, iw = work_sizes(funcs)
    return render("cp_legacy.c.jinja", title=prog.title, generated=bool(funcs), work=w, iwork=iw,
                  tables="".join(p.tables for p in parts), fields=[f for p in parts for f in p.fields],
                  code="".join(p.code for p in parts), estimator=est, controller=ctl)


def sources(prog: CProgram, version: str) -> dict:
    """Relative path -> text of every C file of ``prog``: the header, the rig step and the parts' files of
    ``cartpole/csrc`` as they are, the rendered ``src/cp_config.h`` and ``src/cp_data.c`` (and ``src/cp_plan.h``
    for a part with :attr:`CPart.plan`), ``src/cp_legacy.c``
    for parts written as C text, and, when the program calls CasADi Functions, ``src/cp_generated.c`` and
    ``src/cp_generated.h``."""
    out = {"include/cartpole_controller.h": header(prog, version)}
    for rel, name in COMMON_FILES.items():
        out[rel] = (CSRC / name).read_text()
    for part in (prog.estimator, prog.controller):
        for name in part.sources:
            out[f"src/{name}"] = (CSRC / name).read_text()
    out["src/cp_config.h"], out["src/cp_data.c"], plan_h = config(prog)
    if plan_h is not None:
        out["src/cp_plan.h"] = plan_h
    legacy = legacy_source(prog)
    if legacy is not None:
        out["src/cp_legacy.c"] = float_maths(legacy) if prog.real == "float" else legacy
    if prog.functions:
        gen_c, gen_h = generate(prog.functions, prog.real)
        out["src/cp_generated.c"] = gen_c
        out["src/cp_generated.h"] = gen_h
    return out
