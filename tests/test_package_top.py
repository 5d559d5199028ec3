"""The package top is the API: its names import on first use (so the command line starts without NumPy, SciPy,
CasADi or MuJoCo), resolve to what they always were, no module shares a name with them (the LQR subpackage is
``cartpole.riccati``, so the function ``lqr`` needs no module-class patch), and the README's quick start runs;
``cartpole sweep --workers 2`` starts its fork server before the heavy imports."""
import json
import subprocess
import sys
from pathlib import Path


def _run(code: str) -> str:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()


def test_importing_the_command_line_imports_none_of_the_heavy_libraries():
    out = _run("import sys, cartpole.cli; print(sorted(m for m in ('numpy', 'scipy', 'casadi', 'mujoco') "
               "if m in sys.modules))")
    assert out == "[]"


def test_the_quick_start_names_resolve_and_lqr_stays_the_function():
    out = _run("import types, cartpole as cp, cartpole.riccati\nfrom cartpole.riccati import algebraic as r\n"
               "from cartpole import build_model, Q_LAB, R_LAB, lqr, simulate, linearize\n"
               "from cartpole import sim, models\n"
               "m = cp.build_model()\n"
               "K = cp.lqr(*m.linearize(), Q_LAB, R_LAB)[0]\n"
               "print(callable(cp.lqr), cp.lqr is lqr is r.lqr, cp.simulate is sim.simulate, "
               "cp.build_model is models.build_model, K.shape, sorted(cp.__all__) == sorted(dir(cp)) or 'dir', "
               "type(cp) is types.ModuleType)")
    assert out.startswith("True True True True (1, 4)") and out.endswith("True")


def test_every_public_name_resolves_and_none_is_shadowed_by_a_module():
    """Each name of ``__all__`` imports; none is also a module directly under ``cartpole`` (the old ``cartpole.lqr``
    subpackage hid the function ``lqr``), so importing any submodule cannot replace a public name."""
    out = _run("import json, pkgutil, types, cartpole as cp\n"
               "mods = {m.name for m in pkgutil.iter_modules(cp.__path__)}\n"
               "vals = {n: getattr(cp, n) for n in cp.__all__}\n"
               "print(json.dumps([sorted(set(cp.__all__) & mods), "
               "[n for n, v in vals.items() if isinstance(v, types.ModuleType)], len(vals)]))")
    clash, modules, n = json.loads(out)
    assert clash == [] and modules == [] and n >= 60


def test_importing_the_package_top_imports_no_figures():
    out = _run("import sys, cartpole as cp; cp.build_model; print(sorted(m for m in ('matplotlib', 'cartpole.viz') "
               "if m in sys.modules))")
    assert out == "[]"


def test_the_readme_quick_start_runs(tmp_path):
    """The README's ``Quickstart in Python`` block, run as written in a clean interpreter."""
    readme = (Path(__file__).resolve().parent.parent / "README.md").read_text()
    block = readme.split("## Quickstart in Python", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]
    assert "import cartpole as cp" in block and "cp.simulate(" in block
    done = subprocess.run([sys.executable, "-c", block], capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]


def test_an_unknown_name_is_an_attribute_error():
    import cartpole
    import pytest

    with pytest.raises(AttributeError, match="no attribute 'nonsense'"):
        cartpole.nonsense  # noqa: B018


def test_a_sweep_with_workers_starts_the_fork_server_before_building_its_parser(monkeypatch):
    import cartpole.apps.forkserver as fs
    from cartpole import cli

    started = []
    monkeypatch.setattr(fs, "start_server", lambda method: started.append(method))
    cli._start_sweep_workers_early(["sweep", "--workers", "2", "--method", "trajopt"])
    cli._start_sweep_workers_early(["sweep", "--workers", "1"])
    cli._start_sweep_workers_early(["sweep", "--workers", "2", "--address", "tcp://127.0.0.1:1"])
    cli._start_sweep_workers_early(["lqr", "--workers", "2"])
    cli._start_sweep_workers_early(["sweep", "--workers", "two"])
    assert started == ["trajopt"]


def test_the_package_namespace_lists_no_module_it_imports_for_itself():
    import cartpole

    assert not {"importlib", "os", "sys"} & set(dir(cartpole))
