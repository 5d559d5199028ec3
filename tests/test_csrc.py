"""The package's hand-written C lives in real files under cartpole/csrc (issue 39): no C function body in a Python
string under cartpole/ (CasADi's generated code and short declarations aside), and the files ship in the wheel."""
import ast
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "cartpole"


#: A C function definition: a return type, a name, a parameter list and an opening brace.
C_DEFINITION = re.compile(r"^[ \t]*(?:static\s+|inline\s+|const\s+|extern\s+)*(?:void|int|long|double|float|char|"
                          r"cp_real|casadi_real|casadi_int|size_t|unsigned)\b[\w \t*]*?\b\w+\s*\([^;{}()]*\)\s*\{",
                          re.MULTILINE)
#: A C statement with a block: for (...) {, while (...) {, if (...) {.
C_BLOCK = re.compile(r"\b(?:for|while|if)\s*\([^\n]*\)\s*\{")


def _strings(tree):
    for node in ast.walk(tree):
        if isinstance(node, ast.JoinedStr):
            yield node.lineno, "".join(v.value if isinstance(v, ast.Constant) else "{}" for v in node.values)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            yield node.lineno, node.value


def c_in_strings(path: Path) -> list:
    """(line, text) of every string constant of the module at ``path`` that holds C code with a body."""
    found = []
    for line, text in _strings(ast.parse(path.read_text())):
        m = C_DEFINITION.search(text) or C_BLOCK.search(text)
        if m:
            found.append((line, m.group(0).strip()[:60]))
    return found


def test_the_detector_finds_a_c_function_in_a_string_and_not_a_declaration(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text('CODE = """\nstatic int f(const double* x)\n{\n    return 0;\n}\n"""\n'
                   'LOOP = f"for (i = 0; i < {3}; ++i) {{ x[i] = 0; }}"\n')
    assert len(c_in_strings(bad)) == 2
    ok = tmp_path / "ok.py"
    ok.write_text('DECL = "int cp_step(double t, const cp_real y[CP_NY], cp_real u[CP_NU]);"\n'
                  'MACRO = "#define lqr_eval(x, u) cp_linear_eval(K, X, U, LO, HI, (x), (u))"\n')
    assert c_in_strings(ok) == []


def test_no_c_function_body_lives_in_a_python_string_under_cartpole():
    offenders = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        offenders += [f"{rel}:{line}: {text}" for line, text in c_in_strings(path)]
    assert offenders == [], "C code in Python strings (move it to cartpole/csrc):\n" + "\n".join(offenders)


def test_every_c_source_and_template_under_csrc_is_package_data():
    import fnmatch

    try:
        import tomllib
    except ImportError:  # Python < 3.11
        import tomli as tomllib
    pyproject = tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text())
    patterns = pyproject["tool"]["setuptools"]["package-data"]["cartpole"]
    files = [p.relative_to(PACKAGE).as_posix() for p in (PACKAGE / "csrc").iterdir() if p.is_file()]
    assert any(f.endswith(".c") for f in files) and any(f.endswith(".jinja") for f in files)
    missing = [f for f in files if not any(fnmatch.fnmatch(f, pat) for pat in patterns)]
    assert missing == []


def test_each_algorithm_file_names_the_python_class_it_implements():
    named = {"cp_lqr.c": "LinearFeedback", "cp_pid.c": "CascadedPID", "cp_tvlqr.c": "TVLQRController",
             "cp_energy.c": "EnergyShapingController", "cp_kf.c": "KalmanFilter",
             "cp_ekf.c": "ExtendedKalmanFilter", "cp_rig.c": "RigRun"}
    for name, cls in named.items():
        head = (PACKAGE / "csrc" / name).read_text().split("*/", 1)[0]
        assert cls in head, f"{name}'s leading comment does not name {cls}"
