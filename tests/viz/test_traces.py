"""Angle traces: wrapped errors from upright, broken where they wrap, so figures never draw a false vertical stroke."""
import numpy as np

from cartpole.viz.traces import wrapped_angle_trace


def test_a_pole_swinging_over_the_top_gets_a_gap_at_each_wrap_and_no_jump():
    t = np.linspace(0.0, 2.0, 401)
    angle = np.pi + 0.5 + 3.0 * t  # past hanging, turning forward over upright and on to hanging again: one wrap
    tt, y = wrapped_angle_trace(t, angle)
    gaps = np.flatnonzero(np.isnan(y))
    wraps = np.count_nonzero(np.abs(np.diff(np.mod(angle + np.pi, 2 * np.pi) - np.pi)) > np.pi)
    assert len(gaps) == wraps >= 1
    assert np.all(np.isnan(tt[gaps]))
    finite = ~np.isnan(y)
    for seg in np.split(y, gaps):
        seg = seg[~np.isnan(seg)]
        assert np.all(np.abs(np.diff(seg)) < 5.0)  # degrees per sample: continuous within a segment
    assert np.all(np.abs(y[finite]) <= 180.0)


def test_small_motion_about_upright_is_drawn_unchanged_in_radians():
    t = np.linspace(0.0, 1.0, 50)
    angle = 0.2 + 0.1 * np.sin(6 * t)
    tt, y = wrapped_angle_trace(t, angle, reference=0.2, degrees=False)
    np.testing.assert_array_equal(tt, t)
    np.testing.assert_allclose(y, 0.1 * np.sin(6 * t), atol=1e-15)
