"""C text for an exported controller: numbers and tables as C literals, CasADi Functions code-generated with the
export's real type and made warning-free under ``-std=c99 -Wall -Wextra -Werror -pedantic``.

Everything here returns strings; nothing is compiled or written (see :mod:`cartpole.export.folder`).
"""
from __future__ import annotations

import re

import casadi as ca
import numpy as np

from cartpole.codegen import c_list, c_real

#: The real types an export can use (``cp_real``), by the name ``--float32`` chooses.
REALS = ("double", "float")

#: The libm functions CasADi's generated code and the export's own code call; in a float build each is replaced by
#: its C99 single-precision variant (``cosf``...), so a Cortex-M4F never runs double-precision software maths.
MATH_FUNCTIONS = ("sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "exp", "log",
                  "sqrt", "pow", "fabs", "fmod", "floor", "ceil", "fmin", "fmax", "rint", "erf", "expm1", "log1p",
                  "copysign", "round", "trunc", "hypot", "cbrt", "asinh", "acosh", "atanh")

_MATH = re.compile(r"(?<![\w.])(" + "|".join(MATH_FUNCTIONS) + r")\(")
_DEF = re.compile(r"^((?:static\s+)?(?:const\s+)?[A-Za-z_][\w \*]*?[\s\*])([A-Za-z_]\w*)\(([^()]*)\)\s*\{\s*$")


def literal(value: float) -> str:
    """A finite or infinite float as an exact C literal: :func:`cartpole.codegen.c_real`, the one formatting the
    Jinja2 templates use too (``repr`` round-trips a double; ``INFINITY`` from C99 ``<math.h>``; NaN refused)."""
    return c_real(value)


def table(name: str, values, ctype: str = "cp_real", *, per_line: int = 6) -> str:
    """``static const <ctype> name[n] = {...};`` of ``values`` flattened row-major (C order), n >= 1.

    Parameters
    ----------
    name : str
        C identifier.
    values : array_like
        Any shape; flattened in C (row-major) order.
    ctype : str
        C element type (``cp_real`` for reals, ``int`` for indices).
    per_line : int
        Literals per source line.

    Returns
    -------
    str
    """
    flat = np.asarray(values).ravel(order="C")
    if flat.size == 0:
        raise ValueError(f"table {name} would be empty (C99 forbids zero-length arrays)")
    body = c_list(flat, ctype, per_line)
    return f"static const {ctype} {name}[{flat.size}] = {{\n    {body}\n}};\n"


def float_maths(src: str) -> str:
    """``src`` with every libm call of :data:`MATH_FUNCTIONS` renamed to its single-precision ``...f`` form."""
    return _MATH.sub(lambda m: m.group(1) + "f(", src)


def silence_unused(src: str) -> str:
    """``(void)`` every parameter of every function defined in ``src`` (one definition per line, brace at its end):
    CasADi's generated functions take work arrays and a memory index that small ones never use, which
    ``-Wextra -Werror`` refuses."""
    out = []
    for line in src.splitlines():
        out.append(line)
        m = _DEF.match(line)
        if not m or m.group(2) in ("if", "for", "while", "switch"):
            continue
        params = m.group(3).strip()
        if not params or params == "void":
            continue
        names = []
        for p in params.split(","):
            ident = re.findall(r"[A-Za-z_]\w*", p)
            if ident:
                names.append(ident[-1])
        if names:
            out.append("  " + " ".join(f"(void){n};" for n in names))
    return "\n".join(out) + "\n"


def generate(functions, real: str, *, name: str = "cp_generated") -> tuple[str, str]:
    """C source and header of CasADi Functions for an export: ``(source, header)``.

    The functions keep their names (give them a ``cp_`` prefix); CasADi's internal symbols get ``name``'s prefix.
    Real type ``real``; in a float build libm calls become their ``...f`` forms (:func:`float_maths`); unused
    parameters are ``(void)``-ed (:func:`silence_unused`).

    Parameters
    ----------
    functions : sequence of casadi.Function
        SX or MX Functions with dense inputs and outputs.
    real : {"double", "float"}
        ``casadi_real``, which the export's header makes ``cp_real``.
    name : str
        File stem: the source is ``<name>.c`` including ``<name>.h``.

    Returns
    -------
    (str, str)
    """
    if real not in REALS:
        raise ValueError(f"real type {real!r} is not one of {REALS}")
    gen = ca.CodeGenerator(f"{name}.c", {"with_header": True, "casadi_real": real, "with_export": False,
                                         "main": False, "casadi_int": "long int"})
    for fn in functions:
        gen.add(fn)
    src = gen.dump()
    header = _header_text(functions, real, name)
    src = silence_unused(src)
    if real == "float":
        src = float_maths(src)
    return f'#include "{name}.h"\n' + src, header


def _header_text(functions, real: str, name: str) -> str:
    guard = name.upper() + "_H"
    lines = [f"/* {name}.h: CasADi {ca.__version__} generated functions of the exported controller (internal). */",
             f"#ifndef {guard}", f"#define {guard}", "", f"#ifndef casadi_real\n#define casadi_real {real}\n#endif",
             "#ifndef casadi_int\n#define casadi_int long int\n#endif", ""]
    for fn in functions:
        n = fn.name()
        lines.append(f"int {n}(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, int mem);")
        lines.append(f"#define {n.upper()}_SZ_ARG {fn.sz_arg()}")
        lines.append(f"#define {n.upper()}_SZ_RES {fn.sz_res()}")
        lines.append(f"#define {n.upper()}_SZ_IW {max(1, fn.sz_iw())}")
        lines.append(f"#define {n.upper()}_SZ_W {max(1, fn.sz_w())}")
    lines += ["", f"#endif /* {guard} */", ""]
    return "\n".join(lines)


def call(fn: ca.Function, args, results, work: str = "S.w", iwork: str = "S.iw") -> str:
    """C statements calling generated ``fn`` with argument and result pointer expressions (static work arrays
    ``work`` and ``iwork`` of at least its sizes; see :func:`work_sizes`)."""
    n = fn.name()
    a = ", ".join(args)
    r = ", ".join(results)
    return (f"{{ const cp_real* arg_[{max(1, fn.sz_arg())}] = {{{a}}}; cp_real* res_[{max(1, fn.sz_res())}] = "
            f"{{{r}}}; {n}(arg_, res_, {iwork}, {work}, 0); }}")


def work_sizes(functions) -> tuple[int, int]:
    """The largest ``(sz_w, sz_iw)`` over generated ``functions`` (at least 1 each): one static work area serves
    every call, as they never run at the same time."""
    w = max([1] + [int(f.sz_w()) for f in functions])
    iw = max([1] + [int(f.sz_iw()) for f in functions])
    return w, iw
