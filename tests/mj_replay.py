"""A plain MuJoCo replay for the command-line tests: independent of the package on purpose, so a JSON rollout is
checked against ``mj_step`` itself, not against the toolkit's own replay."""
from __future__ import annotations

import numpy as np


def replay_with_mj_step(mjcf, qpos0, qvel0, ctrl, push=None, qfrc_applied=None) -> tuple[np.ndarray, np.ndarray]:
    """``(qpos (n+1, nq), qvel (n+1, nv))`` of ``ctrl`` (n, nu) applied step by step from ``(qpos0, qvel0)``, with
    ``push`` (n,) the world-x force in N on the cart body (the first slide joint's) during each step, if given, and
    ``qfrc_applied`` (n, nv) the generalized forces on the joints during each step, if given."""
    import mujoco

    m = mujoco.MjModel.from_xml_path(str(mjcf))
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = qpos0, qvel0
    mujoco.mj_forward(m, d)
    cart = None if push is None else next(int(m.jnt_bodyid[j]) for j in range(m.njnt)
                                          if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE)  # none: no cart to push
    qpos, qvel = [d.qpos.copy()], [d.qvel.copy()]
    for k, u in enumerate(ctrl):
        if push is not None:
            d.xfrc_applied[cart, 0] = push[k]
        if qfrc_applied is not None:
            d.qfrc_applied[:] = qfrc_applied[k]
        d.ctrl[:] = u
        mujoco.mj_step(m, d)
        qpos.append(d.qpos.copy())
        qvel.append(d.qvel.copy())
    return np.array(qpos), np.array(qvel)
