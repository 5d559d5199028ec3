"""Many closed-loop MuJoCo runs at once: linear feedback over a batch, stepped in lockstep.

A Python loop of ``mj_step`` per rollout spends most of its time in the interpreter. Here all ``B`` runs advance
together: each physics step is one call of MuJoCo's threaded ``mujoco.rollout`` with ``nstep=1`` over the whole
batch (one persistent thread pool, one reused ``MjData`` per thread, preallocated state buffers), and the
feedback law ``u = u* - K (x - x*)`` (hinge-angle errors wrapped) is evaluated for all runs at once in numpy
between calls. Any model the reader accepts: ``nq`` joints (``nx = 2 nq`` states), ``nu`` motors. The physics is
MuJoCo's own ``mj_step``, so each run equals :func:`~cartpole.sim.rollout.simulate` with
:class:`~cartpole.control.linear.LinearFeedback` (a test checks 1e-12).

Divergence: when a run blows up MuJoCo warns (a NaN, inf or huge position, velocity or acceleration) and resets that
run's state to ``qpos0`` at rest and its clock to 0. The batch's clocks start at :data:`CLOCK_START` s, so a reset
shows in the run's own clock after the step (``h`` instead of the previous time plus ``h``): that run is diverged
from that step (``diverged_at``, s from the start), its states after that step are NaN (the reset state of the
step itself is kept, as :func:`~cartpole.sim.rollout.simulate` logs it) and it is never a success.

One caveat: ``mujoco.rollout`` restores the physics state but not the constraint solver's warm start, which
stays per thread; while a joint limit is active the solver may therefore land a few ulp (within its tolerance)
from a single-``MjData`` run. Runs that stay off their limits are identical.
"""
from __future__ import annotations

import os

import mujoco
import mujoco.rollout
import numpy as np

from cartpole.control.linear import LinearFeedback, ctrl_limits
from cartpole.errors import CartPoleError
from cartpole.models import wrap_angle
from cartpole.progress import stage
from cartpole.sim.rollout import ctrl_bounds, make_mujoco

#: s: the batch's physics clock at the start of every run (any value well above one step; the dynamics do not
#: depend on time), so that MuJoCo's divergence reset, which sets the clock to 0, is seen in each run's state.
CLOCK_START = 1.0


class BatchRollouts(tuple):
    """What :func:`simulate_batch_linear` returns: unpacks as ``(states, ctrl)``, with ``diverged_at`` beside.

    Attributes
    ----------
    states : (B, n+1, nx) array
        ``[qpos, qvel]`` at every physics step, row 0 the start; NaN after a run's divergence step.
    ctrl : (B, n, nu) array
        ctrl applied (after clipping) during each step; NaN after a run's divergence step.
    diverged_at : (B,) array
        s: the end of the step in which MuJoCo reset each run as blown up; NaN for a run that did not diverge.
    """

    def __new__(cls, states, ctrl, diverged_at):
        self = super().__new__(cls, (states, ctrl))
        self.states, self.ctrl, self.diverged_at = states, ctrl, diverged_at
        return self

    @property
    def diverged(self) -> np.ndarray:
        """(B,) bool: which runs diverged."""
        return np.isfinite(self.diverged_at)


def default_threads() -> int:
    """The CPUs this process may run on (its affinity on Linux, else the CPU count): the default thread count."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def initial_states(m, X0: np.ndarray, t0: float = 0.0) -> np.ndarray:
    """Full physics states (B, nstate) at time ``t0`` (s) for starts X0 (B, nq + nv)."""
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    d = mujoco.MjData(m)
    S0 = np.empty((X0.shape[0], mujoco.mj_stateSize(m, spec)))
    for i, x in enumerate(X0):
        mujoco.mj_resetData(m, d)
        d.qpos[:] = x[:m.nq]
        d.qvel[:] = x[m.nq:]
        d.time = t0
        mujoco.mj_getState(m, d, S0[i], spec)
    return S0


def _checked_law(m, K, X0, x_eq, u_eq, u_limits, hinges) -> tuple:
    """The law's arrays for MuJoCo model ``m`` (from a :class:`LinearFeedback` or given apart), checked: ``K``
    (nu, nx), ``X0`` (B, nx), ``x_eq`` (nx,), ``u_eq`` (nu,), ``u_limits`` and the hinge indices."""
    nu, nx = m.nu, m.nq + m.nv
    if isinstance(K, LinearFeedback):
        if not (x_eq is None and u_eq is None and u_limits is None and hinges is None):
            raise CartPoleError("Give either a LinearFeedback or K with x_eq, u_eq, u_limits and hinges, not both.")
        law = K
        K, x_eq, u_eq, u_limits, hinges = law.K, law.x_eq, law.u_eq, law.u_limits, law.hinges
    K = np.asarray(K, dtype=float)
    K = K.reshape(1, -1) if K.ndim == 1 else K
    X0 = np.atleast_2d(np.asarray(X0, dtype=float))
    if K.shape != (nu, nx) or X0.ndim != 2 or X0.shape[1] != nx:
        raise CartPoleError(f"Need K of shape ({nu}, {nx}) and X0 of shape (B, {nx}) for this model; got K "
                            f"{K.shape} and X0 {X0.shape}.")
    if not (np.all(np.isfinite(X0)) and np.all(np.isfinite(K))):
        raise CartPoleError("K or X0 contains NaN or inf; give finite gains and start states.")
    x_eq = np.zeros(nx) if x_eq is None else np.asarray(x_eq, dtype=float).ravel()
    u_eq = np.zeros(nu) if u_eq is None else np.asarray(u_eq, dtype=float).ravel()
    u_eq = np.full(nu, u_eq[0]) if u_eq.size == 1 else u_eq
    if x_eq.shape != (nx,) or u_eq.shape != (nu,):
        raise CartPoleError(f"Need x_eq with {nx} entries and u_eq with {nu} for this model; got {x_eq.size} and "
                            f"{u_eq.size}.")
    if hinges is None:
        hinges = [int(m.jnt_qposadr[j]) for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    return K, X0, x_eq, u_eq, u_limits, [int(i) for i in hinges]


def simulate_batch_linear(plant, K, X0, duration: float, *, x_eq=None, u_eq=None, u_limits=None,
                          hinges=None, nthread: int | None = None, progress=None) -> BatchRollouts:
    """Run ``u = u* - K (x - x*)`` (hinge-angle errors wrapped, ctrl clipped to ``ctrlrange``) from every row of
    ``X0``.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The model (None = shipped asset).
    K : (nu, nx) array, (nx,) for one actuator, or LinearFeedback
        Gain in ctrl per state unit (m, rad, m/s, rad/s). A :class:`~cartpole.control.linear.LinearFeedback`
        brings its own ``x_eq``, ``u_eq``, ``u_limits`` and ``hinges`` (the keywords must then be left out).
    X0 : (B, nx) array
        Start states ``[qpos, qvel]``.
    duration : float, s
        Rounded to whole physics steps ``n``.
    x_eq : (nx,) array, optional
        Equilibrium (default the origin).
    u_eq : (nu,) array or float, optional
        Equilibrium ctrl (default 0).
    u_limits : (2,) or (nu, 2) array, optional
        ``[low, high]`` ctrl clip per actuator applied before MuJoCo's ``ctrlrange`` clip, as
        :class:`~cartpole.control.linear.LinearFeedback` does (default none).
    hinges : sequence of int, optional
        qpos indices whose errors are wrapped to (-pi, pi]; default the model's hinge joints.
    nthread : int, optional
        Threads of MuJoCo's rollout pool (default: the CPUs this process may use; 0 = calling thread).
    progress : callable, optional
        Called with the fraction of physics steps done (about every 5 %); the batch is also a
        :func:`cartpole.progress.stage` ("batch rollouts"), silent inside another stage.

    Returns
    -------
    BatchRollouts
        Unpacks as ``(states, ctrl)``: ``states`` (B, n+1, nx) ``[qpos, qvel]`` at every physics step, row 0 the
        start; ``ctrl`` (B, n, nu) applied (after clipping) during each step; and ``diverged_at`` (B,) s, the step
        in which MuJoCo reset a blown-up run (NaN: it did not), after which that run's rows are NaN (see the
        module notes).
    """
    m, _ = make_mujoco(plant)
    nu, nx = m.nu, m.nq + m.nv
    K, X0, x_eq, u_eq, u_limits, hinges = _checked_law(m, K, X0, x_eq, u_eq, u_limits, hinges)
    h = float(m.opt.timestep)
    n = int(round(duration / h))
    if n < 1:
        raise CartPoleError(f"Duration {duration} s is shorter than one physics step ({h} s); give a longer one.")
    lo, hi = ctrl_bounds(m)
    lim = ctrl_limits(u_limits, nu)
    u_lo, u_hi = lim[:, 0], lim[:, 1]
    nthread = default_threads() if nthread is None else int(nthread)
    nb = X0.shape[0]
    # two state buffers used in turn: the output of one step is the input of the next, no copies
    bufs = (initial_states(m, X0, CLOCK_START), np.empty((nb, mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_FULLPHYSICS))))
    states = np.empty((nb, n + 1, nx))
    ctrl = np.empty((nb, n, nu))
    states[:, 0] = bufs[0][:, 1:1 + nx]  # full physics state layout: [time, qpos (nq), qvel (nv), ...]
    u = np.empty((nb, 1, nu))
    models = [m] * nb
    datas = [mujoco.MjData(m) for _ in range(max(1, nthread))]
    chunk = max(1, nb // max(1, nthread))
    spec = int(mujoco.mjtState.mjSTATE_CTRL)
    every = max(1, n // 20)
    Kt = K.T
    diverged_at = np.full(nb, np.nan)
    alive = np.ones(nb, dtype=bool)
    with stage("batch rollouts", size=f"{nb} x {n * h:g} s", callback=progress) as tick, \
            mujoco.rollout.Rollout(nthread=nthread) as pool:
        for k in range(n):
            S, nxt = bufs[k % 2], bufs[(k + 1) % 2]
            e = S[:, 1:1 + nx] - x_eq
            if hinges:
                e[:, hinges] = wrap_angle(e[:, hinges])
            # same arithmetic as LinearFeedback: u* - K e clipped to its limits, then MuJoCo's clip to ctrlrange
            with np.errstate(over="ignore", invalid="ignore"):  # a blown-up start: MuJoCo resets it below
                u[:, 0] = np.clip(np.clip(u_eq - e @ Kt, u_lo, u_hi), lo, hi)
            pool.rollout(models, datas, S, u, nstep=1, state=nxt, skip_checks=True, chunk_size=chunk,
                         control_spec=spec)
            ctrl[:, k] = u[:, 0]
            states[:, k + 1] = nxt[:, 1:1 + nx]
            # a reset sets the clock to 0 (then one step: h); every other step adds h to the clock
            reset = alive & (np.abs(nxt[:, 0] - (S[:, 0] + h)) > 0.5 * h)
            if reset.any():
                diverged_at[reset] = (k + 1) * h
                alive &= ~reset
            if not alive.all():
                dead = ~alive & ~reset
                states[dead, k + 1] = np.nan
                ctrl[dead, k] = np.nan
            if (k + 1) % every == 0 or k + 1 == n:
                tick((k + 1) / n)
    if not np.all(np.isfinite(states[alive])):
        raise CartPoleError("MuJoCo's state became NaN/inf in the batch; the gain or the model is unstable.")
    return BatchRollouts(states, ctrl, diverged_at)


def random_starts(rollouts: int, *, seed: int = 0, model=None) -> np.ndarray:
    """(rollouts, nx) starts ``x_eq + uniform(-span, span)``, reproducible from ``seed``.

    ``span`` is 0.5 m per slide, 0.15 rad divided by the number of hinges per hinge, 0.3 m/s or rad/s (divided
    likewise for hinge rates) per rate; without ``model`` (a CartPoleModel) the one-pole layout
    ``+-[0.5 m, 0.15 rad, 0.3 m/s, 0.3 rad/s]`` about the origin.
    """
    if model is None:
        span, centre = np.array([0.5, 0.15, 0.3, 0.3]), np.zeros(4)
    else:
        nh = max(1, len(model.hinges))
        q = np.zeros(model.nq)
        v = np.zeros(model.nq)
        q[list(model.slides)], v[list(model.slides)] = 0.5, 0.3
        q[list(model.hinges)], v[list(model.hinges)] = 0.15 / nh, 0.3 / nh
        span, centre = np.concatenate([q, v]), np.asarray(model.x_eq, dtype=float)
    return centre + np.random.default_rng(seed).uniform(-span, span, size=(rollouts, span.size))
