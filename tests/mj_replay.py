"""A plain MuJoCo replay for the command-line tests: independent of the package on purpose, so a JSON rollout is
checked against ``mj_step`` itself, not against the toolkit's own replay."""
from __future__ import annotations

import numpy as np


def replay_with_mj_step(mjcf, qpos0, qvel0, ctrl) -> tuple[np.ndarray, np.ndarray]:
    """``(qpos (n+1, nq), qvel (n+1, nv))`` of ``ctrl`` (n, nu) applied step by step from ``(qpos0, qvel0)``."""
    import mujoco

    m = mujoco.MjModel.from_xml_path(str(mjcf))
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = qpos0, qvel0
    mujoco.mj_forward(m, d)
    qpos, qvel = [d.qpos.copy()], [d.qvel.copy()]
    for u in ctrl:
        d.ctrl[:] = u
        mujoco.mj_step(m, d)
        qpos.append(d.qpos.copy())
        qvel.append(d.qvel.copy())
    return np.array(qpos), np.array(qvel)
