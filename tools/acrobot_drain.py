"""How long dm_control's acrobot takes to calm after a knock, under each calming law, in MuJoCo (docs/recovery.md;
claims.toml).

For each seed, the acrobot starts upright under the supervisor (:func:`cartpole.supervise.supervisor_for`, its planner
off) and is knocked by ``Knockdown(3, 0.3, seed)``; from the state at the knock's end, each law runs alone in MuJoCo
for up to ``--horizon`` s and the time until the state is calm as the supervisor counts it (total energy at most the
upright's, every hinge rate at most ``calm_rate``) is recorded (null when not within the horizon). The laws: the
supervisor's calming law on a model driven at a hinge (``drain``: :class:`~cartpole.control.drain.EnergyDrain` down
to the upright's energy, the soft brake below), ctrl zero (``damping``: the joints' damping alone), and the passive
brakes alone, soft (``brake_soft``, time constant ``HINGE_BRAKE_TIME``) and stiff (``brake_stiff``, the default
``brake_time``). Prints one JSON document: ``energy`` (J at each knock's end), ``seconds`` (law -> one time per seed)
and ``median`` (law -> the median, null when a time is missing).

    python tools/acrobot_drain.py [--seeds 0 1 ... 11] [--horizon 100] [--laws drain damping brake_soft brake_stiff]
"""
import argparse
import json

import numpy as np

from cartpole.models import build_model, read_params
from cartpole.sim import Knockdown, simulate
from cartpole.sim.disturbance import joint_inertia_and_authority
from cartpole.supervise import PassiveBrake, SupervisorOptions, supervisor_for
from cartpole.supervise.supervisor import HINGE_BRAKE_TIME

ACROBOT = "cartpole/assets/dmc_acrobot.xml"
AFTER, LENGTH = 3.0, 0.3


def knocked_state(params, model, seed: int) -> np.ndarray:
    """(nx,) the state at the end of ``Knockdown(AFTER, LENGTH, seed)`` from upright under the supervisor."""
    sup = supervisor_for(params, model)
    sup.planner = None  # only the catch and the calming law act before the knock's end
    force = Knockdown(AFTER, LENGTH, seed=seed).start(params, x_eq=model.x_eq, hinges=model.hinges,
                                                      model=model)
    run = simulate(params, sup, np.asarray(model.x_eq, float), AFTER + LENGTH + 0.3, disturbance=force)
    (_, end), = force.events
    k = int(np.searchsorted(run.t, end - 1e-9)) + 1
    return np.concatenate([run.qpos[k], run.qvel[k]])


def laws(params, model) -> dict:
    """The calming laws compared, by name: ``(t, x) -> ctrl``."""
    sup = supervisor_for(params, model)
    inertia, _ = joint_inertia_and_authority(params, np.asarray(model.x_eq, float))
    limits = sup.catch.u_limits
    return {"drain": sup.calm_brake, "damping": lambda t, x: np.zeros(model.nu),
            "brake_soft": PassiveBrake(model, inertia, HINGE_BRAKE_TIME, limits),
            "brake_stiff": PassiveBrake(model, inertia, SupervisorOptions().brake_time, limits)}


def calm_after(params, model, law, x0, horizon: float, calm_rate: float):
    """s from ``x0`` until energy <= 0 and every hinge rate <= ``calm_rate`` under ``law`` in MuJoCo, or None."""
    run = simulate(params, law, x0, horizon)
    x = np.hstack([run.qpos, run.qvel])
    rates = np.abs(x[:, [model.nq + h for h in model.hinges]]).max(axis=1)
    for k in np.nonzero(rates <= calm_rate)[0]:
        if float(model.energy(x[k])) <= 0.0:
            return float(run.t[k])
    return None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(12)))
    ap.add_argument("--horizon", type=float, default=100.0, help="s of MuJoCo per law and seed")
    ap.add_argument("--laws", nargs="+", default=["drain", "damping", "brake_soft", "brake_stiff"])
    args = ap.parse_args()
    params = read_params(ACROBOT)
    model = build_model(params)
    states = [knocked_state(params, model, s) for s in args.seeds]
    table = laws(params, model)
    calm_rate = SupervisorOptions().calm_rate
    seconds = {name: [calm_after(params, model, table[name], x0, args.horizon, calm_rate) for x0 in states]
               for name in args.laws}
    print(json.dumps({"seeds": args.seeds, "energy": [float(model.energy(x)) for x in states], "seconds": seconds,
                      "median": {n: (None if None in v else float(np.median(v))) for n, v in seconds.items()}}))


if __name__ == "__main__":
    main()
