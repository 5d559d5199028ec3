"""Work a file makes huge is estimated first (issue 38): `cartpole lqr` and `cartpole swingup` count their MuJoCo steps
before anything runs and refuse beyond --max-steps in one sentence naming it (and run when it is raised), and refuse
a numerically singular model (a 1e-9 kg pole) naming its physics."""
import pytest

from cartpole.cli import main
from cartpole.errors import CartPoleError
from cartpole.models import SHIPPED_MJCF
from cartpole.sim.budget import DEFAULT_MAX_STEPS


class Reached(CartPoleError):
    """Raised by the stand-in for the real work: the command got past every check before it."""


def _variant(tmp_path, name, old, new):
    text = SHIPPED_MJCF.read_text()
    assert old in text
    path = tmp_path / f"{name}.xml"
    path.write_text(text.replace(old, new))
    return str(path)


def _one_sentence(argv, capsys) -> str:
    assert main(argv) == 2
    cap = capsys.readouterr()
    lines = cap.err.strip().splitlines()
    assert cap.out == "" and len(lines) == 1 and "Traceback" not in cap.err, cap.err
    assert lines[0].startswith(f"cartpole {argv[0]}: ") and lines[0].endswith(".") and "..." not in lines[0]
    return lines[0]


@pytest.fixture
def no_real_work(monkeypatch):
    """The lab's and the swing-up's runs replaced by a sentinel error: a test sees whether a command got there."""
    import cartpole.apps.lab as lab
    import cartpole.apps.swingup as swingup

    def reached(*args, **kwargs):
        raise Reached("Reached the runs.")

    monkeypatch.setattr(lab, "run_lab", reached)
    monkeypatch.setattr(swingup, "run_swingup", reached)


def test_a_fine_time_step_with_a_long_lab_is_refused_before_it_runs_and_runs_when_the_budget_is_raised(
        tmp_path, capsys, no_real_work):
    mjcf = _variant(tmp_path, "fine", 'timestep="0.005"', 'timestep="5e-05"')
    argv = ["lqr", "--json", "--no-video", "--mjcf", mjcf, "--duration", "20", "--out", str(tmp_path / "out")]
    line = _one_sentence(argv, capsys)
    assert "MuJoCo steps" in line and f"{DEFAULT_MAX_STEPS:.2g}" in line and "--max-steps" in line
    assert not (tmp_path / "out").exists()
    raised = line.split("--max-steps ")[1].split()[0]
    assert float(raised) > DEFAULT_MAX_STEPS
    # the figure it names passes the gate: the command goes on to the runs (here the sentinel)
    assert _one_sentence(argv + ["--max-steps", raised], capsys) == "cartpole lqr: Reached the runs."
    # the default lab at that step is within the budget
    assert _one_sentence(argv[:-4] + ["--out", str(tmp_path / "out")], capsys) == "cartpole lqr: Reached the runs."


def test_a_long_swingup_at_a_fine_step_is_refused_naming_max_steps(tmp_path, capsys, no_real_work):
    mjcf = _variant(tmp_path, "finer", 'timestep="0.005"', 'timestep="1e-05"')
    argv = ["swingup", "--json", "--no-video", "--method", "trajopt", "--duration", "10", "--mjcf", mjcf,
            "--out", str(tmp_path / "out")]
    line = _one_sentence(argv, capsys)
    assert "1e-05 s time step" in line and "--max-steps" in line
    raised = line.split("--max-steps ")[1].split()[0]
    assert _one_sentence(argv + ["--max-steps", raised], capsys) == "cartpole swingup: Reached the runs."


@pytest.mark.parametrize("command", ["lqr", "swingup"])
def test_a_pole_of_a_billionth_of_a_kilogram_is_refused_naming_its_mass(tmp_path, capsys, command):
    mjcf = _variant(tmp_path, "tiny", 'mass="0.1"', 'mass="1e-9"')
    line = _one_sentence([command, "--json", "--no-video", "--mjcf", mjcf, "--out", str(tmp_path / "out")], capsys)
    assert "'pole', 1e-09 kg" in line and "'cart'" in line and "numerically singular" in line
    assert "mass of at least" in line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("value", ["0", "nan", "-5"])
def test_a_max_steps_that_is_not_a_count_is_one_sentence(tmp_path, capsys, value):
    line = _one_sentence(["lqr", "--json", "--no-video", "--max-steps", value, "--out", str(tmp_path / "out")],
                         capsys)
    assert "--max-steps" in line and "give e.g." in line


@pytest.mark.parametrize("value", ["0", "-2", "inf"])
def test_an_lqr_duration_that_is_not_a_time_is_one_sentence(tmp_path, capsys, value):
    line = _one_sentence(["lqr", "--json", "--no-video", "--duration", value, "--out", str(tmp_path / "out")], capsys)
    assert "--duration" in line
    assert not (tmp_path / "out").exists()


#: Every other command that runs MuJoCo, as typed at a 1e-5 s step (a run of each would take tens of minutes), with
#: the function its real work starts in (replaced by the sentinel) and what its estimate must say.
OTHERS = {
    "feedforward": (["--no-video"], "cartpole.apps.feedforward", "run_feedforward", "2 plans of 100 collocation"),
    "sweep": (["--n", "40"], "cartpole.apps.sweep", "recorded_sweep", "40 energy runs"),
    "export": (["--controller", "tvlqr", "--verify"], "cartpole.apps.export", "run_export",
               "1 plan of 100 collocation"),
    "bench": (["--no-plan", "--no-mpc"], "cartpole.apps.bench.trajopt", "run", "replay of 256 x 7"),
    "excite": (["--duration", "60"], "cartpole.apps.excite", "run_excite", "the experiment"),
}


@pytest.mark.parametrize("command", list(OTHERS))
def test_every_command_that_runs_mujoco_estimates_its_work_and_refuses_beyond_max_steps(
        tmp_path, capsys, monkeypatch, command):
    import importlib

    extra, module, name, said = OTHERS[command]
    monkeypatch.setattr(importlib.import_module(module), name,
                        lambda *a, **k: (_ for _ in ()).throw(Reached("Reached the runs.")))
    mjcf = _variant(tmp_path, "finest", 'timestep="0.005"', 'timestep="1e-05"')
    argv = [command, "--json", *extra, "--mjcf", mjcf, "--out", str(tmp_path / "out")]
    if command == "bench":
        argv.remove("--out"), argv.remove(str(tmp_path / "out"))
    line = _one_sentence(argv, capsys)
    assert "1e-05 s time step" in line and "--max-steps" in line and said in line, line
    assert not (tmp_path / "out").exists()
    raised = line.split("--max-steps ")[1].split()[0]
    assert float(raised) > DEFAULT_MAX_STEPS
    assert _one_sentence(argv + ["--max-steps", raised], capsys) == f"cartpole {command}: Reached the runs."
    # and a numerically singular model is refused by each, naming its mass
    tiny = _variant(tmp_path, "tiny", 'mass="0.1"', 'mass="1e-9"')
    line = _one_sentence([a if a != mjcf else tiny for a in argv], capsys)
    assert "numerically singular" in line and "1e-09 kg" in line
