"""The energy ceilings of docs/swingup.md ("When the planner says infeasible"), as one JSON document: the shipped cart
with gear 3 to 6 (the bound with the cart inside the planner's [-1.4, 1.4] m), and the bound beside what bang-bang
pumping reaches in MuJoCo in 40 s on the cart at gear 4 with a free, undamped slide (``F = -F_max sign(r theta_dot)``,
the law that attains the bound's rate). Used by claims.toml; run ``python tools/energy_ceilings.py``."""
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from cartpole.models import SHIPPED_MJCF, read_params
from cartpole.planning.energy_ceiling import energy_ceiling

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))


def main() -> None:
    from planning.test_energy_ceiling import _pump_in_mujoco  # the test's own MuJoCo loop

    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for gear in (3, 4, 5, 6):
            path = Path(tmp) / f"gear{gear}.xml"
            path.write_text(SHIPPED_MJCF.read_text().replace('gear="20"', f'gear="{gear}"'))
            ec = energy_ceiling(read_params(path), cart_range=(-1.4, 1.4))
            out[f"gear{gear}"] = {"proven": ec.proven, "ceiling": round(ec.ceiling, 4),
                                  "force_bound": round(ec.force_bound, 4),
                                  "speed_bound": None if ec.speed_bound is None else round(ec.speed_bound, 4)}
        free = Path(tmp) / "free.xml"
        free.write_text(SHIPPED_MJCF.read_text().replace('gear="20"', 'gear="4"').replace(
            'limited="true" range="-1.5 1.5" damping="0.1"', 'limited="false"'))
        ec = energy_ceiling(read_params(free))
        reached = _pump_in_mujoco(free, 40.0, lambda r, w: -np.sign(r * w) if w else 1.0)
        out["free_gear4"] = {"ceiling": round(ec.ceiling, 4), "bang_bang": round(float(reached), 4)}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
