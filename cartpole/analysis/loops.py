"""The loop of every linear design, broken at the plant input, as a python-control ``StateSpace``.

A loop ``L`` is the transfer from a signal ``v`` injected at the plant input (the ctrl MuJoCo applies) around the
plant, the sensors, the estimator and the controller back to the ctrl ``u`` the controller computes, with the sign
of negative feedback: closing ``v = u`` is the design's closed loop, whose characteristic equation is
``1 + L = 0``; a gain ``k`` or a delay ``tau`` inserted at the break makes it ``1 + k L`` or ``1 + e^(-s tau) L``.
What the controller knows of its own past ctrl (the Kalman filter's prediction, the prediction over the rig's
delay) it takes from its own output, not from ``v``: the textbook place to break an LQG loop, where Doyle's
counterexample lives.

Loops:

* :func:`continuous_loop`: state feedback ``u = -K x`` on the continuous linearisation,
  ``L(s) = K (sI - A)^-1 B`` (the LQR of the lab; a TVLQR frozen at one time along its plan).
* :func:`sampled_loop`: the rig as :mod:`cartpole.sim.rig` runs it, over a control period of ``m`` physics steps
  ``h`` with a delay of ``d`` physics steps from the sample to the ctrl taking effect (``d`` need not be a
  multiple of ``m``: the ctrl then changes inside a period), the plant the exact discrete model of the MJCF's
  integrator (one physics step ``A1``, ``B1`` composed), and a controller that is state feedback on the true state
  or on a :class:`~cartpole.estimation.kalman.KalmanFilter` estimate (LQG), with or without the rig's prediction
  of the estimate over the delay through the model with the ctrl already sent.
* :func:`pid_loop`: the cascaded PID (:mod:`cartpole.control.pid`) on the state it measures, continuous or sampled
  as :class:`~cartpole.control.pid.CascadedPID` runs it (integrator and filtered rate advanced once a period).

A model with several inputs gives one loop per input channel, the other channels closed (:func:`channel_loop`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from cartpole.control.pid import check_cascade
from cartpole.errors import CartPoleError


class AnalysisError(CartPoleError, ValueError):
    """A design that has no linear loop to analyse, or arguments that do not describe one."""


@dataclass(frozen=True)
class Loop:
    """One design's loop broken at one plant input.

    Attributes
    ----------
    name : str
        The design's key (``lqr``, ``lqg``, ``pid``, ...).
    L : control.StateSpace
        SISO loop transfer (ctrl per unit ctrl), continuous (``dt = 0``) or discrete (``dt`` the period in s).
    channel : str
        The actuator whose input the loop is broken at.
    period : float or None
        Control period in s; None for a continuous loop.
    delay : float
        Delay from sample to ctrl already inside the loop, s.
    description : str
        One line saying what the loop is (for tables and figure titles).
    noise : control.StateSpace or None
        The closed loop (every channel closed) from the sensors' noise ``n`` (``y = C x + n``, sensor units) to
        the ctrl: the control sensitivity of a design that reads sensors (LQG); None for one on the true state.
        Its first ``nx`` states are the plant's at the samples (:func:`state_noise_std`).
    nx : int
        The plant's state dimension (0 when unknown).
    """

    name: str
    L: object
    channel: str
    period: float | None
    delay: float
    description: str
    noise: object = None
    nx: int = 0

    @property
    def continuous(self) -> bool:
        """True for a continuous-time loop."""
        return self.period is None


def _plant_matrices(model, x=None, u=None):
    """Continuous ``(A, B)`` and one physics step ``(A1, B1)`` of ``model`` without dry friction (linear designs
    ignore it: :meth:`~cartpole.models.CartPoleModel.without_friction`) at ``(x, u)`` (default upright)."""
    lin = model.without_friction()
    x = lin.x_eq if x is None else np.asarray(x, float)
    u = lin.u_eq if u is None else np.atleast_1d(u).astype(float)
    A, B = lin.linearize(x, u)
    A1, B1 = lin.linearize(x, u, discrete=True)
    return np.asarray(A, float), np.asarray(B, float), np.asarray(A1, float), np.asarray(B1, float)


def _check_gain(K, nu: int, nx: int) -> np.ndarray:
    K = np.atleast_2d(np.asarray(K, dtype=float))
    if K.shape != (nu, nx) or not np.all(np.isfinite(K)):
        raise AnalysisError(f"The gain K has shape {K.shape}; a state feedback of this model needs a finite ({nu}, "
                        f"{nx}) matrix.")
    return K


def channel_loop(A, B, C, D, dt, channel: int):
    """The SISO loop at input ``channel`` of the MIMO ``G: v -> u`` (``x+ = A x + B v``, ``u = C x + D v``; the
    loop ``L = -G`` at that channel with every other channel closed, ``v_j = u_j``).

    Parameters
    ----------
    A, B, C, D : arrays
        ``(n, n)``, ``(n, nu)``, ``(nu, n)``, ``(nu, nu)``: the map from the injected ctrl to the computed ctrl.
    dt : float
        0 for continuous, else the sample time in s.
    channel : int
        Input index.

    Returns
    -------
    control.StateSpace
        SISO ``L``.
    """
    import control  # python-control takes seconds to import: only loop users pay for it

    nu = B.shape[1]
    if np.any(D):
        raise AnalysisError("A loop with a direct path from the plant input to the ctrl is not supported.")
    others = [j for j in range(nu) if j != channel]
    Acl = A + B[:, others] @ C[others, :]
    return control.ss(Acl, B[:, [channel]], -C[[channel], :], np.zeros((1, 1)), dt)


def continuous_loop(model, K, *, x=None, u=None, name: str = "lqr", channel: int = 0,
                    description: str | None = None) -> Loop:
    """State feedback ``u = u* - K (x - x*)`` on the continuous linearisation: ``L(s) = K (sI - A)^-1 B``.

    Parameters
    ----------
    model : CartPoleModel
        The plant (linearised without dry friction at ``(x, u)``).
    K : (nu, nx) array
        The gain, ctrl per state unit.
    x : (nx,) array, optional
        Operating state, m, rad, m/s, rad/s (default upright ``x_eq``); a TVLQR frozen at a time passes its plan's.
    u : (nu,) array, optional
        Operating ctrl, ctrl units (default ``u_eq``).
    name : str
        The design's key.
    channel : int
        Input index the loop is broken at.
    description : str, optional
        One line for tables.

    Returns
    -------
    Loop
    """
    A, B, _, _ = _plant_matrices(model, x, u)
    K = _check_gain(K, model.nu, model.nx)
    L = channel_loop(A, B, -K, np.zeros((model.nu, model.nu)), 0, channel)
    return Loop(name, L, model.params.actuators[channel].name, None, 0.0,
                description or "state feedback, continuous")


def frozen_tvlqr_loop(model, gains, plan, t: float, *, channel: int = 0) -> Loop:
    """A TVLQR frozen at time ``t`` along its plan: the continuous loop of ``K(t)`` on the linearisation at the
    plan's ``(x(t), u(t))``. A frozen-time picture of a time-varying loop (it guarantees nothing about the
    time-varying one), the way a designer reads the gains at a point of the plan.

    Parameters
    ----------
    model : CartPoleModel
    gains : TVLQRGains
        ``K(t)`` (:meth:`~cartpole.riccati.tvlqr.TVLQRGains.gain`).
    plan : Trajectory
        What the gains track: ``plan.state(t)`` and ``plan.input(t)`` (or the gains' own ``x_ref``, ``u_ref``).
    t : float
        Time along the plan, s.
    channel : int

    Returns
    -------
    Loop
    """
    t = float(t)
    if gains.has_reference:
        k = gains.index(t)
        x, u = gains.x_ref[k], gains.u_ref[k]
    else:
        x, u = np.asarray(plan.state(t), float), np.asarray(plan.input(t), float)
    return continuous_loop(model, gains.gain(t), x=x, u=u, name="tvlqr", channel=channel,
                           description=f"TVLQR frozen at t = {t:g} s")


def _period_inputs(A1, B1, m: int, d: int):
    """Per physics step ``j`` of a period (0..m-1): ``A1^(m-1-j) B1`` and the offset ``floor((j - d) / m)`` of the
    sample whose ctrl is in effect then (0: this sample's)."""
    return [(np.linalg.matrix_power(A1, m - 1 - j) @ B1, (j - d) // m) for j in range(m)]


def _ahead(A1, B1, m: int, d: int, N: int, compensate: bool):
    """The rig's prediction over the delay as ``x_ahead = Pd x_hat + Pu ub`` (``ub = [u_{k-1} .. u_{k-N}]`` the
    controller's own past ctrl): ``A1^d x_hat + sum_i A1^(d-1-i) B1 u[k + floor((i - d) / m)]``, or ``x_hat``."""
    nx, nu = B1.shape
    Pd = np.linalg.matrix_power(A1, d) if compensate else np.eye(nx)
    Pu = np.zeros((nx, N * nu))
    if compensate:
        for i in range(d):
            pos = -((i - d) // m) - 1
            Pu[:, pos * nu:(pos + 1) * nu] += np.linalg.matrix_power(A1, d - 1 - i) @ B1
    return Pd, Pu


def _assemble(Ap, per, N: int, nu: int, parts):
    """The open loop ``v -> u`` of a sampled controller on the delayed plant, on the state ``[x_k, xc_{k-1}, ub_k,
    vb_k]`` (plant, controller, its own last N ctrls, the last N injected ctrls): ``(A, B, C)``.

    ``parts = (Ac, Bcy, Bcu, Cc, Dy, Du)``: at sample k the controller does ``xc_k = Ac xc_{k-1} + Bcy x_k +
    Bcu ub_k`` and ``u_k = Cc xc_k + Dy x_k + Du ub_k``; the plant ``x_{k+1} = Ap x_k + sum_j Bj v[k + off_j]``
    (``per``: the pairs ``(Bj, off_j)`` of :func:`_period_inputs`)."""
    Ac, Bcy, Bcu, Cc, Dy, Du = parts
    nx, nc = Ap.shape[0], Ac.shape[0]
    n = nx + nc + 2 * N * nu
    ix, ic, iu, iv = 0, nx, nx + nc, nx + nc + N * nu
    Cu = np.zeros((nu, n))
    Cu[:, ix:ix + nx] = Cc @ Bcy + Dy
    Cu[:, ic:ic + nc] = Cc @ Ac
    Cu[:, iu:iu + N * nu] = Cc @ Bcu + Du
    Aol = np.zeros((n, n))
    Bol = np.zeros((n, nu))
    Aol[ix:ix + nx, ix:ix + nx] = Ap
    for Bj, off in per:
        if off == 0:
            Bol[ix:ix + nx] += Bj
        else:
            pos = -off - 1
            Aol[ix:ix + nx, iv + pos * nu:iv + (pos + 1) * nu] += Bj
    Aol[ic:ic + nc, ix:ix + nx] = Bcy
    Aol[ic:ic + nc, ic:ic + nc] = Ac
    Aol[ic:ic + nc, iu:iu + N * nu] = Bcu
    Aol[iu:iu + nu] = Cu  # ub_{k+1}[0] = u_k
    for p in range(1, N):
        Aol[iu + p * nu:iu + (p + 1) * nu, iu + (p - 1) * nu:iu + p * nu] = np.eye(nu)
        Aol[iv + p * nu:iv + (p + 1) * nu, iv + (p - 1) * nu:iv + p * nu] = np.eye(nu)
    Bol[iv:iv + nu] = np.eye(nu)  # vb_{k+1}[0] = v_k
    return Aol, Bol, Cu


def sampled_loop(model, K, *, steps: int = 1, delay_steps: int = 0, compensate: bool = True, kalman=None,
                 x=None, u=None, name: str | None = None, channel: int = 0) -> Loop:
    """The rig's loop of state feedback ``u = u* - K (x_ahead - x*)`` over a control period, broken at the plant
    input (see the module doc).

    Per sample ``k``: the estimate ``x_hat`` is the true state (``kalman`` None) or the Kalman filter's correction
    with this sample's measurement (its prediction from the ctrl the controller sent, each physics step's own);
    ``x_ahead`` is ``x_hat`` predicted over the delay through the one-step model with the ctrl already sent
    (``compensate``; else ``x_hat``); the ctrl takes effect ``delay_steps`` physics steps after the sample.

    Parameters
    ----------
    model : CartPoleModel
        The plant (one physics step ``model.dt``; linearised without dry friction at ``(x, u)``).
    K : (nu, nx) array
        The gain, ctrl per state unit.
    steps : int
        Physics steps per control period ``m`` (>= 1).
    delay_steps : int
        Physics steps from a sample to its ctrl taking effect (>= 0).
    compensate : bool
        Predict the estimate over the delay (the rig's default).
    kalman : KalmanFilter, optional
        The estimator (its ``A``, ``B`` over the period with a ctrl per physics step, ``C``, ``L``); built for the
        same ``steps``. None: the controller reads the true state.
    x : (nx,) array, optional
        Operating state, m, rad, m/s, rad/s (default upright ``x_eq``).
    u : (nu,) array, optional
        Operating ctrl, ctrl units (default ``u_eq``).
    name : str, optional
        Default ``lqg`` with a filter, else ``lqr``.
    channel : int

    Returns
    -------
    Loop
        Discrete with ``dt = steps * model.dt``.
    """
    m, d = int(steps), int(delay_steps)
    if m < 1 or d < 0:
        raise AnalysisError(f"A rig of {steps} physics steps per period and {delay_steps} steps of delay is not a "
                            "period >= 1 step and a delay >= 0 steps.")
    _, _, A1, B1 = _plant_matrices(model, x, u)
    nx, nu = model.nx, model.nu
    K = _check_gain(K, nu, nx)
    T = m * float(model.dt)
    per = _period_inputs(A1, B1, m, d)
    Ap = np.linalg.matrix_power(A1, m)
    q = d // m
    N = q + 2  # past ctrls kept: the filter's prediction reaches back to sample k - q - 2
    Pd, Pu = _ahead(A1, B1, m, d, N, compensate)
    # the controller: xc_k = Ac xc_{k-1} + Bcy x_k + Bcu ub_k, u_k = Cc xc_k + Dy x_k + Du ub_k
    # (ub_k = [u_{k-1} .. u_{k-N}] its own past ctrl; the state enters through the sensors y = C x)
    if kalman is None:
        Ac, Bcy, Bcu = np.zeros((0, 0)), np.zeros((0, nx)), np.zeros((0, N * nu))
        Cc, Dy, Du = np.zeros((nu, 0)), -K @ Pd, -K @ Pu
        label = "state feedback on the true state"
    else:
        if int(kalman.steps) != m:
            raise AnalysisError(f"The Kalman filter runs every {kalman.steps} physics steps but the loop every "
                                f"{m}; build it for the same period.")
        if np.any(np.asarray(kalman.D)):
            raise AnalysisError("A measurement that depends on the ctrl (D != 0) is not supported in the loop.")
        Ck, Lk = np.asarray(kalman.C, float), np.asarray(kalman.L, float)
        Ak, Bk = np.asarray(kalman.A, float), np.asarray(kalman.B, float)  # B: (nx, nu m), per physics step
        IKC = np.eye(nx) - Lk @ Ck
        # its prediction at sample k uses the ctrl of each physics step of period k-1: u[k-1+offset_j]
        Bbuf = np.zeros((nx, N * nu))
        for j, (_, off) in enumerate(per):
            pos = -off
            Bbuf[:, pos * nu:(pos + 1) * nu] += Bk[:, j * nu:(j + 1) * nu]
        Ac, Bcy, Bcu = IKC @ Ak, Lk @ Ck, IKC @ Bbuf
        Cc, Dy, Du = -K @ Pd, np.zeros((nu, nx)), -K @ Pu
        label = "state feedback on the Kalman filter's estimate (LQG)"
    Aol, Bol, Cu = _assemble(Ap, per, N, nu, (Ac, Bcy, Bcu, Cc, Dy, Du))
    L = channel_loop(Aol, Bol, Cu, np.zeros((nu, nu)), T, channel)
    noise = None
    if kalman is not None:
        import control  # python-control takes seconds to import: only loop users pay for it

        # n_k enters the estimate (xc_k += Lk n_k) and through it u_k; closed loop v = u
        ny = Ck.shape[0]
        Dn = Cc @ Lk
        Bn = np.zeros((Aol.shape[0], ny))
        Bn[nx:2 * nx] = Lk
        Bn[2 * nx:2 * nx + nu] = Dn
        noise = control.ss(Aol + Bol @ Cu, Bol @ Dn + Bn, Cu, Dn, T)
    rig = f"period {T * 1e3:g} ms, delay {d * float(model.dt) * 1e3:g} ms" + (
        " predicted over" if compensate and d else "")
    return Loop(name or ("lqr" if kalman is None else "lqg"), L, model.params.actuators[channel].name, T,
                d * float(model.dt), f"{label}; {rig}", noise, nx)


def pid_loop(model, gains, *, steps: int | None = None, delay_steps: int = 0, compensate: bool = True,
             name: str = "pid") -> Loop:
    """The cascaded PID's loop (one pole on a cart) on the state it measures, broken at the ctrl.

    Continuous (``steps`` None): the cascade of :func:`~cartpole.control.pid.closed_loop_matrix` opened at the
    ctrl. Sampled: as :class:`~cartpole.control.pid.CascadedPID` runs every ``steps`` physics steps (the integrator
    advanced by ``T e``, the rate filter by ``a = 1 - exp(-T / tau)``, as
    :func:`~cartpole.control.pid.sampled_closed_loop_matrix`), with a delay of ``delay_steps`` physics steps.

    Parameters
    ----------
    model : CartPoleModel
        One slide and one hinge.
    gains : PIDGains
    steps : int, optional
        Physics steps per period; None for the continuous loop.
    delay_steps : int
        Physics steps from a sample to its ctrl taking effect (sampled loop only).
    compensate : bool
        The rig predicts the state over the delay before the PID reads it (its default, as for every controller).
    name : str

    Returns
    -------
    Loop
    """
    import control  # python-control takes seconds to import: only loop users pay for it

    slide, hinge = check_cascade(model)
    A, B, A1, B1 = _plant_matrices(model)
    nx, nq = model.nx, model.nq
    c = np.zeros(nx)
    c[hinge], c[slide], c[nq + slide] = 1.0, gains.kp_cart, gains.kd_cart
    r = np.zeros(nx)
    r[nq + hinge] = 1.0
    act = model.params.actuators[0].name
    if steps is None:
        if delay_steps:
            raise AnalysisError("A continuous PID loop has no delay in physics steps; give steps for the sampled loop.")
        filt = gains.filter_tau > 0
        # controller states [z, y]: z' = c e, y' = (r e - y) / tau; u = -(kp c e + ki z + kd y)
        Acn = np.array([[0.0, 0.0], [0.0, -1.0 / gains.filter_tau if filt else 0.0]])
        Bcn = np.vstack([c, r / gains.filter_tau if filt else np.zeros(nx)])
        Ccn = np.array([[-gains.ki, -gains.kd if filt else 0.0]])
        Dcn = -(gains.kp * c + (0.0 if filt else gains.kd) * r)[None, :]
        n = nx + 2
        Aol = np.zeros((n, n))
        Aol[:nx, :nx], Aol[nx:, :nx], Aol[nx:, nx:] = A, Bcn, Acn
        Bol = np.vstack([B, np.zeros((2, 1))])
        Cu = np.hstack([Dcn, Ccn])
        L = control.ss(Aol, Bol, -Cu, np.zeros((1, 1)), 0)
        return Loop(name, L, act, None, 0.0, "cascaded PID on the state, continuous")
    m, dly = int(steps), int(delay_steps)
    T = m * float(model.dt)
    a = 1.0 - np.exp(-T / gains.filter_tau) if gains.filter_tau > 0 else 1.0
    N = dly // m + 2
    Pd, Pu = _ahead(A1, B1, m, dly, N, compensate)
    # controller state [z, y] advanced at each sample from the (predicted) state, then u_k from the new values
    Ac = np.diag([1.0, 1.0 - a])
    Bp = np.vstack([T * c, a * r])
    Cc = np.array([[-gains.ki, -gains.kd]])
    Dp = -(gains.kp * c)[None, :]
    parts = (Ac, Bp @ Pd, Bp @ Pu, Cc, Dp @ Pd, Dp @ Pu)
    Aol, Bol, Cu = _assemble(np.linalg.matrix_power(A1, m), _period_inputs(A1, B1, m, dly), N, 1, parts)
    L = control.ss(Aol, Bol, -Cu, np.zeros((1, 1)), T)
    rig = f"period {T * 1e3:g} ms, delay {dly * float(model.dt) * 1e3:g} ms" + (
        " predicted over" if compensate and dly else "")
    return Loop(name, L, act, T, dly * float(model.dt), f"cascaded PID on the state; {rig}")


def _noise_covariance(loop: Loop, V):
    """``(P, A, B, C, D, V)``: the stationary state covariance ``P = A P A' + B V B'`` of the closed loop from the
    sensors' white noise of covariance ``V`` (:attr:`Loop.noise`), with its matrices."""
    if loop.noise is None:
        raise AnalysisError(f"The loop '{loop.name}' reads the true state, so sensor noise does not reach its ctrl; "
                            "build it with a Kalman filter (kalman=...).")
    A, B, C, D = (np.asarray(M, float) for M in (loop.noise.A, loop.noise.B, loop.noise.C, loop.noise.D))
    V = np.atleast_2d(np.asarray(V, float))
    return scipy.linalg.solve_discrete_lyapunov(A, B @ V @ B.T), A, B, C, D, V


def ctrl_noise_std(loop: Loop, V) -> np.ndarray:
    """The steady standard deviation of each ctrl that white sensor noise of covariance ``V`` causes through the
    closed loop (:attr:`Loop.noise`): ``sqrt(diag(C P C' + D V D'))`` with ``P`` the stationary state covariance,
    ``P = A P A' + B V B'``.

    Parameters
    ----------
    loop : Loop
        A sampled loop that reads sensors (``sampled_loop(..., kalman=...)``).
    V : (ny, ny) array
        The noise covariance per sample, sensor units squared (e.g. an encoder of resolution ``q`` adds
        ``q**2 / 12``: :meth:`~cartpole.estimation.SensorSpec.measurement_covariance`).

    Returns
    -------
    (nu,) array
        ctrl units.

    Raises
    ------
    AnalysisError
        A loop without sensors.
    """
    P, _, _, C, D, V = _noise_covariance(loop, V)
    return np.sqrt(np.diag(C @ P @ C.T + D @ V @ D.T))


def state_noise_std(loop: Loop, V) -> np.ndarray:
    """The steady standard deviation of each of the plant's states (MuJoCo's true state, at the samples) that white
    sensor noise of covariance ``V`` causes through the closed loop (:attr:`Loop.noise`): the floor the sensors set
    under a hold's motion, whatever its transient did (``sqrt(diag(P))`` of the plant's block of the stationary
    covariance of :func:`ctrl_noise_std`).

    Parameters
    ----------
    loop : Loop
        A sampled loop that reads sensors (``sampled_loop(..., kalman=...)``).
    V : (ny, ny) array
        The noise covariance per sample, sensor units squared.

    Returns
    -------
    (nx,) array
        m, rad, m/s, rad/s, in the state's order.

    Raises
    ------
    AnalysisError
        A loop without sensors.
    """
    P = _noise_covariance(loop, V)[0]
    return np.sqrt(np.diag(P)[:loop.nx])
