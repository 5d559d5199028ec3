"""An exported controller as C text: the rig's loop (estimate, delay prediction, ctrl history, saturation) around
one estimator part and one controller part, assembled into ``src/cartpole_controller.c`` and
``include/cartpole_controller.h``.

The step ``cp_step(t, y, u)`` does what :class:`cartpole.sim.rig.RigRun` and :func:`cartpole.sim.rollout.simulate`
do around a Python controller, in the same order and with the same arithmetic:

1. the first call starts the estimate from ``y`` (``est_reset``), later ones update it with the ctrl MuJoCo applied
   during each physics step since the last call (``est_update``);
2. with a delay of ``LAG`` physics steps (and compensation on) the estimate is predicted over the delay through the
   exact discrete model with the ctrl already sent (CasADi-generated ``cp_predict``);
3. the controller part gives ``u`` at ``t + CP_DELAY`` (the instant it takes effect); ``u`` is clipped to the
   MJCF's ``ctrlrange`` and remembered: it acts on the ``CP_STEPS`` physics steps from ``LAG`` steps on.

A part is a :class:`CPart`: its ``static const`` tables, the fields it adds to the one static state struct ``S``,
its C functions, its reset statements and the CasADi Functions it calls.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from cartpole.export.csource import call, generate, table, work_sizes

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
    tables : str
        ``static const`` arrays.
    fields : tuple of str
        Members of the state struct ``S`` (``"cp_real z;"``).
    code : str
        Static C functions.
    reset : str
        Statements run by ``cp_reset`` after ``S`` is zeroed.
    functions : tuple of casadi.Function
        CasADi Functions the code calls (generated into ``src/cp_generated.c``).
    """

    tables: str = ""
    fields: tuple = ()
    code: str = ""
    reset: str = ""
    functions: tuple = field(default=())


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


def header(prog: CProgram, version: str) -> str:
    """The public header ``include/cartpole_controller.h`` of ``prog``."""
    codes = "\n".join(f" *   {k}  {v}" for k, v in RETURN_CODES.items())
    names = {0: "CP_OK", 1: "CP_BAD_MEASUREMENT", 2: "CP_BAD_STATE", 3: "CP_FALLBACK"}
    defs = "\n".join(f"#define {names[k]} {k}" for k in RETURN_CODES)
    return f"""/* cartpole_controller.h: {prog.title}
 * Exported by cartpole {version}. C99, static memory, no malloc; link with libm.
 *
 * Call cp_reset() once before a run, then cp_step() once every CP_PERIOD seconds with the measurements y
 * (CP_NY entries, in the order manifest.json lists, sensor units); it writes the ctrl u (CP_NU entries,
 * MuJoCo ctrl units, clipped to the MJCF's ctrlrange) and returns one of:
{codes}
 * t is the sample time in s since the start of the run (used by time-varying laws).
 */
#ifndef CARTPOLE_CONTROLLER_H
#define CARTPOLE_CONTROLLER_H

#ifdef __cplusplus
extern "C" {{
#endif

typedef {prog.real} cp_real;

#define CP_NY {prog.ny}
#define CP_NU {prog.nu}
#define CP_PERIOD {prog.period!r}
#define CP_DELAY {prog.delay!r}
#define CP_REAL_IS_FLOAT {1 if prog.real == "float" else 0}
{defs}

void cp_reset(void);
int cp_step(double t, const cp_real y[CP_NY], cp_real u[CP_NU]);

#ifdef __cplusplus
}}
#endif

#endif /* CARTPOLE_CONTROLLER_H */
"""


_HELPERS = """
static cp_real cp_clip(cp_real v, cp_real lo, cp_real hi)
{
    return v < lo ? lo : (v > hi ? hi : v);
}

/* (-pi, pi], as numpy: mod(a + pi, 2 pi) - pi with -pi mapped to pi */
static cp_real cp_wrap(cp_real a)
{
    cp_real w = fmod(a + CP_PI_, 2 * CP_PI_);
    if (w != 0 && w < 0) {
        w += 2 * CP_PI_;
    }
    w -= CP_PI_;
    return w == -CP_PI_ ? CP_PI_ : w;
}

/* e = x - ref with the hinge entries wrapped */
static void cp_error(const cp_real* x, const cp_real* ref, cp_real* e)
{
    int i;
    for (i = 0; i < NX; ++i) {
        e[i] = x[i] - ref[i];
        if (WRAP[i]) {
            e[i] = cp_wrap(e[i]);
        }
    }
}
"""


def _struct(prog: CProgram) -> str:
    w, iw = work_sizes(prog.functions)
    fields = ["int started;", "cp_real x_hat[NX];", "cp_real planned[(CP_STEPS + LAG) * CP_NU];",
              "cp_real last[CP_NU];", *prog.estimator.fields, *prog.controller.fields]
    if prog.functions:
        fields += [f"cp_real w[{w}];", f"casadi_int iw[{iw}];"]
    body = "\n".join(f"    {f}" for f in fields)
    return f"static struct cp_state {{\n{body}\n}} S;\n"


def source(prog: CProgram, version: str) -> str:
    """``src/cartpole_controller.c`` of ``prog`` (see the module doc)."""
    nu = prog.nu
    wrap = [1 if i < prog.nq and i in prog.hinges else 0 for i in range(prog.nx)]
    includes = '#include <math.h>\n#include <string.h>\n\n#include "cartpole_controller.h"\n'
    if prog.functions:
        includes += '#include "cp_generated.h"\n'
    defines = (f"#define NX {prog.nx}\n#define NQ {prog.nq}\n#define CP_STEPS {prog.steps}\n#define LAG {prog.lag}\n"
               "#define CP_PI_ ((cp_real)3.14159265358979323846)\n")
    tables = (table("U_LOW", prog.u_low) + table("U_HIGH", prog.u_high) + table("WRAP", wrap, "int")
              + prog.estimator.tables + prog.controller.tables)
    if prog.predict is not None:
        predict = ("    " + call(prog.predict, ["S.x_hat", "S.planned + CP_STEPS * CP_NU"], ["xu"]) + "\n")
    else:
        predict = "    for (i = 0; i < NX; ++i) {\n        xu[i] = S.x_hat[i];\n    }\n"
    keep = prog.lag * nu
    step = f"""
void cp_reset(void)
{{
    int i;
    memset(&S, 0, sizeof S);
    for (i = 0; i < (CP_STEPS + LAG) * CP_NU; ++i) {{
        S.planned[i] = cp_clip(0, U_LOW[i % CP_NU], U_HIGH[i % CP_NU]);
    }}
    for (i = 0; i < CP_NU; ++i) {{
        S.last[i] = S.planned[i];
    }}
{prog.estimator.reset}{prog.controller.reset}}}

int cp_step(double t, const cp_real y[CP_NY], cp_real u[CP_NU])
{{
    int i, code;
    cp_real xu[NX];
    for (i = 0; i < CP_NY; ++i) {{
        if (!isfinite(y[i])) {{
            for (i = 0; i < CP_NU; ++i) {{
                u[i] = S.last[i];
            }}
            return CP_BAD_MEASUREMENT;
        }}
    }}
    if (!S.started) {{
        est_reset(y, S.x_hat);
        S.started = 1;
    }} else {{
        est_update(y, S.planned, S.x_hat);
    }}
{predict}    code = ctrl_eval(t + CP_DELAY, xu, u);
    for (i = 0; i < CP_NU; ++i) {{
        if (!isfinite(u[i])) {{
            code = CP_BAD_STATE;
        }}
    }}
    for (i = 0; i < CP_NU; ++i) {{
        u[i] = code == CP_BAD_STATE ? cp_clip(0, U_LOW[i], U_HIGH[i]) : cp_clip(u[i], U_LOW[i], U_HIGH[i]);
        S.last[i] = u[i];
    }}
    /* the window of planned ctrl: steps [k - CP_STEPS, k + LAG) becomes [k, k + CP_STEPS + LAG) */
    for (i = 0; i < {keep}; ++i) {{
        S.planned[i] = S.planned[i + CP_STEPS * CP_NU];
    }}
    for (i = {keep}; i < (CP_STEPS + LAG) * CP_NU; ++i) {{
        S.planned[i] = u[i % CP_NU];
    }}
    return code;
}}
"""
    return (f"/* cartpole_controller.c: {prog.title}\n * Exported by cartpole {version}; do not edit (re-export "
            "instead). */\n" + includes + "\n" + defines + "\n" + tables + "\n" + _struct(prog) + _HELPERS
            + prog.estimator.code + prog.controller.code + step)


def sources(prog: CProgram, version: str) -> dict:
    """Relative path -> text of every C file of ``prog``: the header, ``src/cartpole_controller.c`` and, when the
    program calls CasADi Functions, ``src/cp_generated.c`` and ``src/cp_generated.h``."""
    from cartpole.export.csource import float_maths

    main = source(prog, version)
    if prog.real == "float":
        main = float_maths(main)
    out = {"include/cartpole_controller.h": header(prog, version), "src/cartpole_controller.c": main}
    if prog.functions:
        gen_c, gen_h = generate(prog.functions, prog.real)
        out["src/cp_generated.c"] = gen_c
        out["src/cp_generated.h"] = gen_h
    return out
