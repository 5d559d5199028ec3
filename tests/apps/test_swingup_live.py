"""cartpole.apps.swingup with a live page: the run tells the page which law is in charge (``attach``) and the page's
pushes join the run's logged push column, so the run still replays exactly."""
from __future__ import annotations

import numpy as np

from cartpole.apps.live import controller_status
from cartpole.apps.swingup import SwingupOptions, run_swingup
from cartpole.sim import replays_exactly
from cartpole.sim.options import LoopOptions


class _Page:
    """What a web page is to the run: a step hook with ``attach(controller, push) -> push``."""

    def __init__(self):
        self.attached = []
        self.lines = []
        self.closed = self.interrupted = False

    def attach(self, controller, push=None):
        self.attached.append(controller)

        def both(t):
            return (0.0 if push is None else push(t)) + (4.0 if 0.1 <= t < 0.2 else 0.0)
        return both

    def __call__(self, m, d):
        self.lines = controller_status(self.attached[-1], float(d.time), None)
        return True


def test_the_swingup_attaches_its_law_and_logs_the_pages_push_with_the_scheduled_one():
    page = _Page()
    res = run_swingup(None, "energy", SwingupOptions(loop=LoopOptions(duration=0.5, push=((0.3, -2.0),))),
                      on_step=page)
    assert len(page.attached) == 1 and hasattr(page.attached[0], "switches")
    assert page.lines[0].startswith("energy shaping + LQR catch: swing-up")
    push = res.rollout.info["push"]
    h = res.rollout.t[1] - res.rollout.t[0]
    t = res.rollout.t[:-1]
    assert np.all(push[(t >= 0.1 - h / 2) & (t < 0.2 - h / 2)] == 4.0)
    assert np.all(push[(t >= 0.3 - h / 2) & (t < 0.4 - h / 2)] == -2.0)
    assert replays_exactly(res.rollout)
