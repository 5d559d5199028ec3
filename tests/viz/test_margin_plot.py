"""The rig-margin figure (here the delay margin): both controllers' curves against the delay in ms, the failed delays as crosses, the
margins as dashed lines, written whole; drawn from a real delay_margin result."""
import numpy as np
import pytest

from cartpole.apps.lab import delay_margin
from cartpole.sim import LoopOptions
from cartpole.viz.margin_plot import margin_figure, plot_margin


@pytest.fixture(scope="module")
def found():
    # without delay compensation the LQR fails within a few tens of ms: a short, real curve with its failure
    return delay_margin(loop=LoopOptions(period=0.01, delay_compensation=False), max_delay=0.05)


def test_delay_figure_plots_each_delay_tried_and_marks_the_failure_and_the_margin(found, tmp_path):
    fig = margin_figure(found)
    ax_t, ax_e = fig.axes
    assert "settling time (s)" in ax_t.get_ylabel() and "(mrad)" in ax_e.get_ylabel()
    assert "(ms)" in ax_e.get_xlabel()
    runs = found["lqr_runs"]
    ok = [r for r in runs if r["balances"]]
    line = ax_t.get_lines()[0]
    np.testing.assert_allclose(line.get_xdata(), [1e3 * r["delay"] for r in ok])
    np.testing.assert_allclose(line.get_ydata(), [r["settling_time_seed_max"] for r in ok])
    np.testing.assert_allclose(ax_e.get_lines()[0].get_ydata(), [1e3 * r["residual_angle_max"] for r in ok])
    labels = [t.get_text() for t in ax_t.get_legend().get_texts()]
    assert f"LQR: fails at {1e3 * found['lqr_first_failure']:g} ms" in labels
    margins = [ln for ln in ax_t.get_lines() if ln.get_linestyle() == "--"]
    assert [ln.get_xdata()[0] for ln in margins] == pytest.approx([1e3 * found["lqr"]])
    out = plot_margin(found, tmp_path / "figures" / "delay.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
