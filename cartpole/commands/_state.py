"""How the commands name a model's state and input in prose: from the MJCF's own joint and actuator names."""
from __future__ import annotations


def state_labels(params) -> list[str]:
    """One label per state entry (2 nq), MuJoCo order: ``"<joint> (m)"`` / ``"<joint> (rad)"`` for each qpos,
    then ``"<joint> rate (m/s)"`` / ``"<joint> rate (rad/s)"`` for each qvel."""
    units = ["m" if j.kind == "slide" else "rad" for j in params.joints]
    pos = [f"{j.name} ({u})" for j, u in zip(params.joints, units)]
    vel = [f"{j.name} rate ({u}/s)" for j, u in zip(params.joints, units)]
    return pos + vel


def state_sentence(params) -> str:
    """``State x = [...]; u = MuJoCo ctrl [...]``: the layout line the prose modes print first."""
    acts = ", ".join(f"{a.name} on {params.joints[a.joint].name}, gear {a.gear:g}" for a in params.actuators)
    return (f"State x = [qpos, qvel] = [{', '.join(state_labels(params))}]; "
            f"u = MuJoCo ctrl [{acts}] (generalized force = gear * ctrl)")
