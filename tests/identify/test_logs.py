"""Logged runs: the CSV format and rollout JSON read back, and every bad log refused in one sentence."""
import json

import numpy as np
import pytest

from cartpole.identify.logs import LogError, read_log
from cartpole.models import SHIPPED_MJCF, read_params


@pytest.fixture(scope="module")
def params():
    return read_params(SHIPPED_MJCF)


def _write(path, header, rows):
    path.write_text(",".join(header) + "\n" + "\n".join(",".join(str(v) for v in r) for r in rows) + "\n")
    return path


def _rows(n=6, dt=0.01):
    return [[k * dt, 0.01 * k, 3.1 - 0.02 * k, 0.5, 7] for k in range(n)]


def test_csv_reads_positions_ctrl_and_ignores_other_columns(tmp_path, params):
    path = _write(tmp_path / "a.csv", ["t", "slider", "hinge", "motor", "note"], _rows())
    log = read_log(path, params)
    assert log.qpos.shape == (6, 2) and log.ctrl.shape == (6, 1) and log.qvel is None
    assert log.sample_time == pytest.approx(0.01)
    np.testing.assert_allclose(log.qpos[:, 1], [3.1 - 0.02 * k for k in range(6)])


def test_csv_rate_columns_are_read_when_present(tmp_path, params):
    rows = [r[:4] + [0.2] for r in _rows()]
    log = read_log(_write(tmp_path / "v.csv", ["t", "slider", "hinge", "motor", "hinge_vel"], rows), params)
    assert np.all(np.isnan(log.qvel[:, 0])) and np.all(log.qvel[:, 1] == 0.2)


def test_rollout_json_reads_rates_and_pads_the_unused_last_ctrl(tmp_path, params):
    doc = {"rollout": {"t": [0, 0.005, 0.01], "qpos": [[0, 3], [0, 3], [0, 3]], "qvel": [[0, 0]] * 3,
                       "ctrl": [[0.1], [0.2]]}}
    (tmp_path / "r.json").write_text(json.dumps(doc))
    log = read_log(tmp_path / "r.json", params)
    assert log.ctrl.shape == (3, 1) and log.qvel.shape == (3, 2)


@pytest.mark.parametrize("header, rows, words", [
    (["t", "slider", "hinj", "motor"], _rows(), "no column 'hinge'"),
    (["t", "slider", "hinge"], [r[:3] for r in _rows()], "no column 'motor'"),
    (["time", "slider", "hinge", "motor"], _rows(), "no column 't'"),
    (["t", "slider", "hinge", "motor"], [[0, 0, 0, 0], [0.02, 0, 0, 0], [0.01, 0, 0, 0]], "backwards"),
    (["t", "slider", "hinge", "motor"], [[0, 0, 0, 0], [0.01, 0, 0, 0], [0.03, 0, 0, 0], [0.04, 0, 0, 0]],
     "fixed sample time"),
    (["t", "slider", "hinge", "motor"], [[0, 0, 0, 0], [0.01, "nan", 0, 0], [0.02, 0, 0, 0]], "finite number"),
    (["t", "slider", "hinge", "motor"], [[0, 0, 0, 0], [0.01, "abc", 0, 0], [0.02, 0, 0, 0]], "not a number"),
])
def test_bad_csv_is_one_sentence(tmp_path, params, header, rows, words):
    path = _write(tmp_path / "bad.csv", header, rows)
    with pytest.raises(LogError, match=words) as exc:
        read_log(path, params)
    assert "\n" not in str(exc.value) and str(exc.value).endswith(".")


def test_misnamed_column_suggests_the_joint(tmp_path, params):
    with pytest.raises(LogError, match="is its column 'hinj' meant"):
        read_log(_write(tmp_path / "m.csv", ["t", "slider", "hinj", "motor"], _rows()), params)


def test_json_of_another_model_is_refused(tmp_path, params):
    doc = {"t": [0, 1, 2], "qpos": [[0, 0, 0]] * 3, "qvel": [[0, 0, 0]] * 3, "ctrl": [[0], [0]]}
    (tmp_path / "o.json").write_text(json.dumps(doc))
    with pytest.raises(LogError, match="another model"):
        read_log(tmp_path / "o.json", params)


def test_missing_file_is_refused(tmp_path, params):
    with pytest.raises(LogError, match="does not exist"):
        read_log(tmp_path / "none.csv", params)
