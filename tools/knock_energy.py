"""What one knockdown does on each shipped model, measured in MuJoCo (docs/recovery.md, "What knocks it down";
claims.toml).

For each model and seed, the model starts upright at rest under its LQR catch (``LinearFeedback.for_model``, the lab's
weights), which fights the knock; ``Knockdown(0.5, LENGTH, seed, energy=ENERGY)`` knocks it once, and the run goes on
2 s after the push. Per model, over the seeds (min and max): the swing-up energy ``E(upright) - E(hanging)`` (J), the
knock's budget and the work it did on the hinges (J, ``sum max(tau dq, 0)`` from the logged ``qfrc_applied``), the
energy ``model.energy`` before the knock and when its push stopped (J; the catch's own work is in it), how long it
pushed (s), how many knocks took the poles out of the upright band and past horizontal, the largest hinge rate in the
2 s after (rad/s), and whether every run replayed exactly. ``--energy 100`` shows the torque rule alone (its budget,
50-100 swing-ups, never binds within 0.3 s on these models). Prints one JSON document, or with ``--table`` a Markdown
table.

    python tools/knock_energy.py [--seeds 0 1 2 3 4 5] [--length 0.3] [--energy 1.0] [--table]
"""
import argparse
import json

import numpy as np

from cartpole.control import LinearFeedback
from cartpole.models import build_model, read_params, wrap_angle
from cartpole.sim import KNOCK_ENERGY, Knockdown, replays_exactly, simulate

MODELS = ("cartpole.xml", "cartpole_two_pole.xml", "cartpole_three_pole.xml", "dmc_pendulum.xml",
          "dmc_acrobot.xml", "dmc_cartpole.xml")


def one_knock(params, model, seed: int, length: float, energy: float) -> dict:
    """One knock against the catch from upright rest: its budget, work, energies, push time, fall and peak rate."""
    force = Knockdown(0.5, length, seed=seed, energy=energy).start(params, x_eq=model.x_eq, hinges=model.hinges,
                                                                   model=model)
    run = simulate(params, LinearFeedback.for_model(model), np.asarray(model.x_eq, float), 0.5 + length + 2.0,
                   disturbance=force)
    knock = force.knocks[0]
    t = np.asarray(run.t)
    k0, k1 = np.searchsorted(t, knock.start - 1e-9), np.searchsorted(t, knock.end - 1e-9)
    k2 = np.searchsorted(t, knock.end + 2.0 - 1e-9)
    x = np.hstack([run.qpos, run.qvel])
    qfrc = np.asarray(run.info["qfrc_applied"])
    work = float(np.sum(np.maximum(qfrc[k0:k1] * np.diff(np.asarray(run.qpos), axis=0)[k0:k1], 0.0)))
    hinges = list(model.hinges)
    err = np.abs(wrap_angle(x[k0:k2 + 1, hinges] - np.asarray(model.x_eq)[hinges]))
    rates = np.abs(x[k0:k2 + 1, [model.nq + h for h in hinges]])
    return {"budget": knock.budget, "work": work, "E_before": float(model.energy(x[k0])),
            "E_after": float(model.energy(x[k1])), "push_s": knock.end - knock.start, "out_of_band": bool(knock.downed),
            "past_horizontal": bool(err.max() > np.pi / 2), "peak_rate": float(rates.max()),
            "replays": bool(replays_exactly(run)), "diverged": run.info.get("diverged") is not None}


def measure(seeds, length: float, energy: float) -> dict:
    """Per model (file name without ``.xml``): the swing-up energy and each quantity's ``[min, max]`` over the seeds."""
    out = {}
    for name in MODELS:
        params = read_params(f"cartpole/assets/{name}")
        model = build_model(params)
        rows = [one_knock(params, model, s, length, energy) for s in seeds]
        span = {k: [round(min(r[k] for r in rows), 4), round(max(r[k] for r in rows), 4)]
                for k in ("budget", "work", "E_before", "E_after", "push_s", "peak_rate")}
        out[name[:-4]] = {"swingup_energy": round(float(model.energy(model.x_eq)) - float(model.energy(model.x_hanging)),
                                                  4),
                          **span, "out_of_band": sum(r["out_of_band"] for r in rows),
                          "past_horizontal": sum(r["past_horizontal"] for r in rows), "n": len(rows),
                          "replays": all(r["replays"] for r in rows), "diverged": sum(r["diverged"] for r in rows)}
    return out


def table(result: dict) -> str:
    """The Markdown table of :func:`measure`'s result."""
    lines = ["| model | swing-up energy (J) | budget (J) | work done (J) | E after the push (J) | pushed (s) | "
             "out of the band / past horizontal | peak hinge rate (rad/s) |", "|---|---|---|---|---|---|---|---|"]
    for name, r in result.items():
        if not isinstance(r, dict):
            continue
        rng = lambda k, f: f"{r[k][0]:{f}}-{r[k][1]:{f}}"  # noqa: E731
        lines.append(f"| {name} | {r['swingup_energy']:.2f} | {rng('budget', '.2f')} | {rng('work', '.2f')} | "
                     f"{rng('E_after', '.2f')} | {rng('push_s', '.3f')} | {r['out_of_band']}/{r['n']}, "
                     f"{r['past_horizontal']}/{r['n']} | {rng('peak_rate', '.0f')} |")
    return "\n".join(lines)


def main() -> None:
    """Command line: measure and print JSON (or the table)."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4, 5])
    ap.add_argument("--length", type=float, default=0.3)
    ap.add_argument("--energy", type=float, default=KNOCK_ENERGY)
    ap.add_argument("--table", action="store_true")
    args = ap.parse_args()
    result = measure(args.seeds, args.length, args.energy)
    result["seeds"], result["energy"], result["length"] = args.seeds, args.energy, args.length
    print(table(result) if args.table else json.dumps(result))


if __name__ == "__main__":
    main()
