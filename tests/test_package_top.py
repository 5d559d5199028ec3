"""The package top: its quick-start names import on first use (so the command line starts without NumPy, SciPy,
CasADi or MuJoCo), resolve to what they always were, and the function ``lqr`` is not hidden by the subpackage
``cartpole.lqr``; ``cartpole sweep --workers 2`` starts its fork server before the heavy imports."""
import subprocess
import sys


def _run(code: str) -> str:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()


def test_importing_the_command_line_imports_none_of_the_heavy_libraries():
    out = _run("import sys, cartpole.cli; print(sorted(m for m in ('numpy', 'scipy', 'casadi', 'mujoco') "
               "if m in sys.modules))")
    assert out == "[]"


def test_the_quick_start_names_resolve_and_lqr_stays_the_function():
    out = _run("import cartpole as cp, cartpole.lqr\nfrom cartpole.lqr import riccati as r\n"
               "from cartpole import build_model, Q_LAB, R_LAB, lqr, sim, models\n"
               "m = cp.build_model()\n"
               "K = cp.lqr(*m.linearize(), Q_LAB, R_LAB)[0]\n"
               "print(callable(cp.lqr), cp.lqr is lqr is r.lqr, cp.simulate is sim.simulate, "
               "cp.build_model is models.build_model, K.shape, sorted(cp.__all__) == sorted(dir(cp)) or 'dir')")
    assert out.startswith("True True True True (1, 4)")


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
