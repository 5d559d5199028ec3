"""The lab and swing-up figures: one angle panel per pole, the cart, one ctrl panel per actuator, the right energy;
drawn from real MuJoCo runs (the lab's and an open-loop replay), saved whole."""
import numpy as np
import pytest

from cartpole.apps.lab import run_lab
from cartpole.models import SHIPPED_MJCF, build_model, wrap_angle
from cartpole.sim import replay
from cartpole.viz import lab_figure, plot_lab, plot_swingup, swingup_figure


def _labels(fig):
    return [ax.get_ylabel().replace("\n", " ") for ax in fig.axes]


@pytest.mark.parametrize("asset, poles", [("cartpole.xml", 1), ("cartpole_three_pole.xml", 3)])
def test_lab_figure_has_a_panel_per_pole_the_cart_and_the_ctrl(asset, poles, tmp_path):
    res = run_lab(SHIPPED_MJCF.with_name(asset), duration=1.0, start_scale=1.0)
    fig = lab_figure(res)
    labels = _labels(fig)
    assert len(labels) == poles + 2
    assert all("angle" in lab and "(deg)" in lab for lab in labels[:poles])
    assert labels[poles] == "Cart position (m)" and labels[-1].startswith("ctrl motor")
    # the first pole's traces are the wrapped angle errors of the MuJoCo runs, in degrees, one line per start
    h = res.params.hinges[0]
    lines = fig.axes[0].get_lines()[:5]
    assert [ln.get_label() for ln in lines][0].startswith("θ₀=5°")
    for ln, run in zip(lines, res.rollouts):
        np.testing.assert_allclose(ln.get_ydata(), np.rad2deg(wrap_angle(run.qpos[:, h] - res.x_eq[h])))
    out = plot_lab(res, tmp_path / "f" / "lab.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and [p.name for p in out.parent.iterdir()] == ["lab.png"]


def test_swingup_figure_of_a_chain_with_two_motors(chain_dir, tmp_path):
    path = chain_dir / "two_motors.xml"
    model = build_model(path)
    ctrl = np.tile([0.3, -0.2], (100, 1))
    run = replay(path, model.x_hanging, ctrl)
    fig = swingup_figure(run, model.params, model=model, caught_at=0.2)
    labels = _labels(fig)
    assert len(labels) == 2 + 1 + 2 + 1  # two poles, the cart, two actuators, energy
    assert labels[2] == "cart position (m)"
    assert labels[3].startswith("ctrl cart") and labels[4].startswith("ctrl wrist") and "N m" in labels[4]
    assert labels[5] == "total energy (J)"  # no single pole energy for a chain
    energy = fig.axes[5].get_lines()[0].get_ydata()
    np.testing.assert_allclose(energy, [float(model.energy(x)) for x in run.x], rtol=1e-9, atol=1e-12)
    assert energy[0] < 0  # hanging is below upright rest (0 J)
    np.testing.assert_array_equal(fig.axes[4].get_lines()[0].get_ydata()[:100], ctrl[:, 1])
    out = plot_swingup(run, model.params, tmp_path / "s.png", model=model)
    assert out.stat().st_size > 10_000


def test_swingup_figure_of_one_pole_draws_the_pole_energy():
    model = build_model()
    run = replay(None, model.x_hanging, np.full(50, 0.5))
    fig = swingup_figure(run, model.params, model=model)
    labels = _labels(fig)
    assert len(labels) == 4 and labels[-1] == "pole energy (J)"
    np.testing.assert_allclose(fig.axes[-1].get_lines()[0].get_ydata(),
                               [float(model.pole_energy(x)) for x in run.x], rtol=1e-9, atol=1e-12)


def test_a_knocked_runs_figure_marks_each_knockdown_swingup_and_catch_on_every_panel():
    model = build_model()
    run = replay(None, model.x_hanging, np.full(200, 0.5))
    marks = {"knockdowns": [(0.2, 0.3), (0.6, 0.7)], "swingups": [0.1, 0.5, 0.8], "catches": [0.12, 0.52]}
    fig = swingup_figure(run, model.params, model=model, marks=marks)
    for ax in fig.axes:
        labels = ax.get_legend_handles_labels()[1]
        assert {"knockdown (2)", "swing-up (3)", "catch (2)"} <= set(labels)
        spans = [p for p in ax.patches if p.get_label() == "knockdown (2)" or p.get_facecolor()[0] == 1.0]
        assert len(spans) >= 2
        xs = sorted(ln.get_xdata()[0] for ln in ax.get_lines() if ln.get_color() in ("g", "b"))
        assert xs == sorted(marks["swingups"] + marks["catches"])


def test_sweep_plot_preload_imports_what_the_success_map_needs_in_a_fresh_process():
    import subprocess
    import sys

    code = ("import sys; from cartpole.viz.sweep_plot import preload\n"
            "assert 'matplotlib.figure' not in sys.modules\n"
            "preload()\n"
            "print(all(m in sys.modules for m in ('matplotlib.figure', 'matplotlib.backends.backend_agg', "
            "'matplotlib.patches')))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "True"
