"""What several commands share about a logged MuJoCo run: its JSON document and showing it in the live viewer."""
from __future__ import annotations

import sys

import numpy as np

from cartpole.commands._flags import as_flags
from cartpole.errors import CartPoleError, first_line
from cartpole.viz.viewer import LiveViewer, ViewerUnavailable, require_display, watch


def show_logged(params, rollout, *, command: str, watcher=None):
    """Show ``rollout`` in MuJoCo's live viewer, in real time (:func:`cartpole.viz.viewer.watch`), by replaying its
    logged ctrl step for step from its first state; returns the rollout the viewer ran, or None without a display
    (its one sentence printed on stderr).

    ``watcher`` replaces :func:`~cartpole.viz.viewer.watch` (the same call shape; e.g. a run on the web page).

    Raises
    ------
    CartPoleError
        The viewer's run differs from the log (it would not be the run logged).
    """
    ctrl = np.asarray(rollout.ctrl)
    h = float(params.timestep)
    last = len(ctrl) - 1

    def logged_ctrl(t, x):
        return ctrl[min(last, int(round(t / h)))]

    pushes = rollout.info.get("push") if isinstance(rollout.info, dict) else None
    push = None if pushes is None else (lambda t: float(pushes[min(last, int(round(t / h)))]))
    try:
        shown = (watch if watcher is None else watcher)(params, logged_ctrl, rollout.x[0], float(rollout.t[-1]),
                                                        push=push)
    except ViewerUnavailable as exc:
        print(f"cartpole {command}: no live view: {as_flags(first_line(exc))}.", file=sys.stderr)
        return None
    k = len(shown.t)
    if not (np.array_equal(shown.qpos, rollout.qpos[:k]) and np.array_equal(shown.qvel, rollout.qvel[:k])):
        raise CartPoleError("The live viewer's run differs from the logged run; report this with the MJCF.")
    return shown


def rollout_doc(rollout) -> dict:
    """The JSON contract's rollout: ``t``, ``qpos``, ``qvel`` (n+1 rows), ``ctrl`` (n rows) and ``push`` (n entries:
    the world-x force in N on the cart during each step; zeros when nothing pushed), only for a run that touched,
    ``contact``: the first contact MuJoCo found (``t``, ``geom1``, ``geom2``, ``dist``, ``steps`` in contact), and
    only for a run knocked down or thrown, ``qfrc_applied`` (n rows of nv generalized forces, N or N m, applied
    during each step)."""
    doc = rollout.to_dict()
    info = rollout.info if isinstance(rollout.info, dict) else {}
    push = info.get("push")
    doc.setdefault("push", [0.0] * len(doc["ctrl"]) if push is None else [float(f) for f in push])
    if info.get("contact") is not None:  # only a run that touched has the key (the contract's rows stay as they were)
        doc.setdefault("contact", info["contact"])
    if info.get("qfrc_applied") is not None:  # knocked or thrown: the generalized forces, so the log replays
        doc.setdefault("qfrc_applied", [[float(f) for f in row] for row in info["qfrc_applied"]])
    return doc


def live_viewer(command: str):
    """A :class:`~cartpole.viz.viewer.LiveViewer` to pass as a run's ``on_step``, or None without a display (its one
    sentence printed on stderr, so the command goes on without the viewer)."""
    try:
        require_display()
    except ViewerUnavailable as exc:
        print(f"cartpole {command}: no live view: {as_flags(first_line(exc))}.", file=sys.stderr)
        return None
    return LiveViewer()
