"""A cascaded PID that balances one pole on a cart: the lab's classical baseline beside the LQR.

The cascade (``e = model.state_error(x)``: the error from the computed upright equilibrium ``x*``, angle wrapped)::

    outer (cart, PD):   theta_ref = clip(-(kp_cart e_s + kd_cart e_s_dot), -tilt_limit, tilt_limit)   [rad]
    inner (angle, PID): e_i = e_theta - theta_ref                                                     [rad]
                        u   = u* - (kp e_i + ki z + kd y),   z = int e_i dt,   tau y_dot = e_theta_dot - y

``y`` is the measured pole rate passed through a first-order low-pass filter of time constant ``tau``
(derivative on the measurement, so a step of the setpoint gives no derivative kick); ``u`` is clipped to the ctrl
range and the integrator is frozen whenever integrating would push a saturated ctrl further into saturation
(conditional integration), with ``|ki z|`` also clamped to half the ctrl span, so it cannot wind up.

Tuning rule (:func:`tune_pid`). Without integral, filter and tilt limit the cascade is the state feedback
``u = u* - K e`` with ``K = [kp kp_cart, kp, kp kd_cart, kd]`` (cart, angle, cart rate, angle rate), so the four
gains follow from pole placement on the exact continuous linearisation ``A, B = model.linearize()``: the poles are
a fourth-order Butterworth pattern of radius ``omega_c = bandwidth_factor * lambda_u``, ``lambda_u`` the unstable
eigenvalue of ``A`` (about ``sqrt(m g l / J)`` for a pole with inertia ``J`` about its hinge). Then
``kp_cart = K_s / K_theta`` and ``kd_cart = K_s_dot / K_theta``; the integral gain is ``ki = kp omega_c /
integral_factor`` (integral time ``integral_factor / omega_c``), the filter time constant ``tau = 1 / (filter_factor
omega_c)``, and the tilt limit is ``tilt_fraction`` of the tilt whose gravity torque the linearised pole needs full
ctrl to hold (``u_max |B_theta / A_theta,theta|``), capped at ``pi / 6``. The closed loop of the linearisation
*with* the integrator and the filter (six states) must be stable, or :class:`PIDError` says so.

Signs: the gains carry the MJCF's hinge-axis sign (on the shipped cart ``kp`` is negative: a pole leaning towards
+x is caught by pushing the cart towards +x). Units: m, rad, s; ``u`` is MuJoCo ctrl (force = gear * ctrl).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cartpole._arrays import readonly
from cartpole.errors import CartPoleError
from cartpole.models import CartPoleModel, plant_model, steps_per_period

#: Defaults of :func:`tune_pid` (dimensionless), chosen on the shipped cart and checked on the test variants.
DEFAULT_TUNING = dict(bandwidth_factor=1.0, integral_factor=10.0, filter_factor=10.0, tilt_fraction=0.1)

#: Largest tilt setpoint the rule gives whatever the actuator (rad): the linearisation is not trusted beyond it.
MAX_TILT = np.pi / 6

_USE_LQR = "use LQR (cartpole lqr)."


class PIDError(CartPoleError):
    """A model the cascaded PID cannot be built for, bad tuning settings, or a tuned loop that is not stable."""


@dataclass(frozen=True)
class PIDGains:
    """Gains and limits of a :class:`CascadedPID`, in SI units (signed: they carry the hinge axis's sign).

    Attributes
    ----------
    kp : float
        Angle-loop proportional gain, ctrl/rad.
    ki : float
        Angle-loop integral gain, ctrl/(rad s).
    kd : float
        Angle-loop derivative gain, ctrl/(rad/s) (acts on the filtered measured pole rate).
    kp_cart : float
        Cart-loop proportional gain, rad of tilt setpoint per m of cart error.
    kd_cart : float
        Cart-loop derivative gain, rad per (m/s) of cart velocity error.
    filter_tau : float
        Time constant of the first-order low-pass on the measured pole rate, s (0 = no filter).
    tilt_limit : float
        Largest tilt setpoint the cart loop may ask for, rad (``|theta_ref| <= tilt_limit``).
    bandwidth : float
        ``omega_c``, radius of the placed Butterworth pattern, rad/s.
    poles : (4,) complex array
        Poles placed for the equivalent state feedback ``K`` (rad/s), i.e. the eigenvalues of ``A - B K``.
    closed_loop_poles : (6,) complex array
        Eigenvalues of the linearised closed loop with the integrator and the filter states (rad/s), all stable
        (fewer when ``ki = 0`` or ``filter_tau = 0``; see :func:`closed_loop_matrix`).
    """

    kp: float
    ki: float
    kd: float
    kp_cart: float
    kd_cart: float
    filter_tau: float
    tilt_limit: float
    bandwidth: float
    poles: np.ndarray
    closed_loop_poles: np.ndarray

    def __post_init__(self):
        for name in ("poles", "closed_loop_poles"):
            object.__setattr__(self, name, readonly(getattr(self, name), dtype=complex))

    @property
    def K(self) -> np.ndarray:
        """(1, 4) state feedback the cascade equals without integral, filter and tilt limit, on
        ``[cart, angle, cart rate, angle rate]`` errors (ctrl per m, rad, m/s, rad/s)."""
        return readonly([[self.kp * self.kp_cart, self.kp, self.kp * self.kd_cart, self.kd]])

    def to_dict(self) -> dict:
        """JSON-ready dict (complex poles as ``[re, im]`` pairs)."""
        d = {k: float(getattr(self, k)) for k in ("kp", "ki", "kd", "kp_cart", "kd_cart", "filter_tau",
                                                   "tilt_limit", "bandwidth")}
        for k in ("poles", "closed_loop_poles"):
            d[k] = [[float(p.real), float(p.imag)] for p in getattr(self, k)]
        return d


def check_cascade(model: CartPoleModel) -> tuple[int, int]:
    """The qpos indices ``(slide, hinge)`` of a model a cascaded PID can balance, else :class:`PIDError`.

    A cascade needs exactly one pole (hinge) on a cart (slide) driven by one actuator on that slide.
    """
    p = model.params
    need = "A cascaded PID needs one pole on an actuated cart; this model has"
    if len(model.hinges) != 1:
        raise PIDError(f"{need} {len(model.hinges)} poles: {_USE_LQR}")
    if model.slide is None:
        raise PIDError(f"{need} no slide joint (no cart): {_USE_LQR}")
    if model.nq != 2:
        raise PIDError(f"{need} {model.nq} joints, not just the cart's slide and the pole's hinge: {_USE_LQR}")
    if model.nu != 1:
        raise PIDError(f"{need} {model.nu} actuators: {_USE_LQR}")
    if int(p.actuated[0]) != model.slide:
        raise PIDError(f"{need} its actuator on joint '{p.joint_names[int(p.actuated[0])]}', not on the cart's "
                       f"slide: {_USE_LQR}")
    return int(model.slide), int(model.hinges[0])


def butterworth_poles(omega: float, n: int = 4) -> np.ndarray:
    """The ``n`` (even) left-half-plane poles of a Butterworth filter of radius ``omega`` (rad/s), conjugate pairs."""
    ang = np.pi / 2 + np.pi * (2 * np.arange(n // 2) + 1) / (2 * n)
    p = omega * np.exp(1j * ang)
    return np.concatenate([p, p.conj()])


def closed_loop_matrix(A, B, gains: PIDGains, slide: int = 0, hinge: int = 1) -> np.ndarray:
    """The linear closed loop of the cascade on ``[e (4), z, y]`` (errors, integrator, filter), limits inactive.

    ``A`` (4, 4), ``B`` (4, 1) continuous, on ``[qpos, qvel]`` errors with the slide at qpos ``slide`` and the
    hinge at ``hinge``. The integrator state is left out when ``ki = 0`` and the filter state when
    ``filter_tau = 0`` (then the measured rate is used), so the matrix is (6, 6), (5, 5) or (4, 4).
    """
    A = np.asarray(A, float)
    b = np.asarray(B, float).reshape(-1)
    n = A.shape[0]
    nq = n // 2
    c_i = np.zeros(n)  # e_i = e_theta - theta_ref = e_theta + kp_cart e_s + kd_cart e_s_dot
    c_i[hinge] = 1.0
    c_i[slide] = gains.kp_cart
    c_i[nq + slide] = gains.kd_cart
    rate = np.zeros(n)
    rate[nq + hinge] = 1.0
    integ, filt = gains.ki != 0, gains.filter_tau > 0
    m = n + integ + filt
    M = np.zeros((m, m))
    # u = -(kp e_i + ki z + kd y)
    M[:n, :n] = A - np.outer(b, gains.kp * c_i + (0.0 if filt else gains.kd) * rate)
    if integ:
        M[:n, n] = -b * gains.ki
        M[n, :n] = c_i
    if filt:
        j = m - 1
        M[:n, j] = -b * gains.kd
        M[j, :n] = rate / gains.filter_tau
        M[j, j] = -1.0 / gains.filter_tau
    return M


def sampled_closed_loop_matrix(Ad, Bd, gains: PIDGains, period: float, slide: int = 0,
                               hinge: int = 1) -> np.ndarray:
    """The sampled closed loop of the cascade as :class:`CascadedPID` runs it every ``period`` s, limits inactive.

    Per sample ``k``: ``z_k = z_{k-1} + T e_i``, ``y_k = y_{k-1} + a (e_rate - y_{k-1})`` with ``a = 1 -
    exp(-T / tau)``, ``u_k = -(kp e_i + ki z_k + kd y_k)`` and ``e_{k+1} = Ad e_k + Bd u_k``, on the state
    ``[e_k, z_{k-1}, y_{k-1}]``.

    Parameters
    ----------
    Ad : (4, 4) array
        The held model over one period, errors ``[qpos, qvel]`` (slide at qpos ``slide``, hinge at ``hinge``).
    Bd : (4, 1) array
        Per unit ctrl.
    gains : PIDGains
    period : float
        ``T`` in s.

    Returns
    -------
    (6, 6) array
        Stable when every eigenvalue is inside the unit circle.
    """
    Ad = np.asarray(Ad, float)
    b = np.asarray(Bd, float).reshape(-1)
    n = Ad.shape[0]
    nq = n // 2
    T = float(period)
    c = np.zeros(n)
    c[hinge], c[slide], c[nq + slide] = 1.0, gains.kp_cart, gains.kd_cart
    r = np.zeros(n)
    r[nq + hinge] = 1.0
    a = 1.0 - np.exp(-T / gains.filter_tau) if gains.filter_tau > 0 else 1.0
    Ue = -(gains.kp * c + gains.ki * T * c + gains.kd * a * r)
    M = np.zeros((n + 2, n + 2))
    M[:n, :n] = Ad + np.outer(b, Ue)
    M[:n, n] = -b * gains.ki
    M[:n, n + 1] = -b * gains.kd * (1.0 - a)
    M[n, :n], M[n, n] = T * c, 1.0
    M[n + 1, :n], M[n + 1, n + 1] = a * r, 1.0 - a
    return M


def tune_pid(plant, *, bandwidth_factor: float = DEFAULT_TUNING["bandwidth_factor"],
             integral_factor: float = DEFAULT_TUNING["integral_factor"],
             filter_factor: float = DEFAULT_TUNING["filter_factor"],
             tilt_fraction: float = DEFAULT_TUNING["tilt_fraction"], period: float | None = None) -> PIDGains:
    """Cascaded-PID gains from the model by pole placement on its exact linearisation (see the module docstring).

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        One pole on a cart driven by one actuator on the slide (None = the shipped asset).
    bandwidth_factor : float
        ``omega_c / lambda_u``: radius of the Butterworth pattern as a multiple of the pole's unstable
        eigenvalue ``lambda_u`` (rad/s) of ``A``. Default 1.
    integral_factor : float
        Integral time in units of ``1 / omega_c``: ``ki = kp omega_c / integral_factor``; ``inf`` = no integral.
        Default 10.
    filter_factor : float
        Derivative-filter bandwidth as a multiple of ``omega_c``: ``tau = 1 / (filter_factor omega_c)`` s;
        ``inf`` = no filter. Default 10.
    tilt_fraction : float
        Tilt limit as a fraction of ``u_max |B_theta / A_theta,theta|`` (the tilt whose gravity torque the
        linearised pole needs full ctrl to hold), capped at :data:`MAX_TILT`. Default 0.1.
    period : float, optional
        Control period ``T`` in s, a whole number ``m`` of physics steps (the ctrl held in between). For ``m > 1``
        the Butterworth poles are mapped to ``exp(s T)`` and placed on the exact discrete model over the hold
        (:meth:`~cartpole.models.CartPoleModel.hold`), and the loop with integrator and filter is checked as the
        sampled loop :class:`CascadedPID` runs (:func:`sampled_closed_loop_matrix`).

    Returns
    -------
    PIDGains

    Raises
    ------
    PIDError
        When the model is not one pole on an actuated cart, a setting is out of range, the linearisation has no
        unstable pole to scale from or cannot be placed, or the loop with integrator and filter is not stable.
    """
    model = plant_model(plant)
    slide, hinge = check_cascade(model)
    settings = dict(bandwidth_factor=bandwidth_factor, integral_factor=integral_factor,
                    filter_factor=filter_factor, tilt_fraction=tilt_fraction)
    if not all(isinstance(v, (int, float, np.floating, np.integer)) and float(v) > 0 for v in settings.values()) \
            or not np.isfinite(bandwidth_factor) or not np.isfinite(tilt_fraction):
        raise PIDError(f"PID tuning settings {settings} are out of range; bandwidth_factor and tilt_fraction must "
                       "be positive and finite, integral_factor and filter_factor positive (inf to disable).")
    A, B = model.linearize()
    nq = model.nq
    lam = float(np.max(np.linalg.eigvals(A).real))
    if not lam > 1e-9:
        raise PIDError(f"The linearisation at upright has no unstable pole (largest real part {lam:.3g} 1/s), so "
                       "there is no bandwidth to scale the PID from; check that the MJCF's upright is inverted.")
    omega = float(bandwidth_factor) * lam
    poles = butterworth_poles(omega)
    import scipy.signal  # seconds at import (it loads scipy.stats): only the PID tuning pays for it

    steps = steps_per_period(period, model.dt)
    T = steps * model.dt
    Ad, Bd = model.hold(steps).linearize() if steps > 1 else (None, None)
    try:
        if steps > 1:
            K = scipy.signal.place_poles(Ad, Bd, np.exp(poles * T)).gain_matrix.reshape(-1)
        else:
            K = scipy.signal.place_poles(A, B, poles).gain_matrix.reshape(-1)
    except (ValueError, np.linalg.LinAlgError) as exc:
        raise PIDError(f"Pole placement failed on this model's linearisation ({exc}); the cart cannot steer the "
                       f"pole here: {_USE_LQR}") from None
    kp = float(K[hinge])
    if abs(kp) < 1e-12:
        raise PIDError("The placed state feedback has no angle gain, so it is not a cascade through the pole "
                       f"angle: {_USE_LQR}")
    ki = 0.0 if np.isinf(integral_factor) else kp * omega / float(integral_factor)
    tau = 0.0 if np.isinf(filter_factor) else 1.0 / (float(filter_factor) * omega)
    u_max = float(min(model.u_eq[0] - model.u_low[0], model.u_high[0] - model.u_eq[0]))
    hold = u_max * abs(float(B[nq + hinge, 0]) / float(A[nq + hinge, hinge])) if A[nq + hinge, hinge] else np.inf
    tilt = float(min(float(tilt_fraction) * hold, MAX_TILT))
    gains = PIDGains(kp=kp, ki=ki, kd=float(K[nq + hinge]), kp_cart=float(K[slide]) / kp,
                     kd_cart=float(K[nq + slide]) / kp, filter_tau=tau, tilt_limit=tilt, bandwidth=omega,
                     poles=poles, closed_loop_poles=np.zeros(0))
    if steps > 1:
        cl = np.linalg.eigvals(sampled_closed_loop_matrix(Ad, Bd, gains, T, slide, hinge))
        cl = cl[np.lexsort((cl.imag, cl.real))]
        if not np.abs(cl).max() < 1:
            raise PIDError(f"The tuned PID does not stabilise the sampled loop at a {T:g} s period once its integrator "
                           f"and filter are included (eigenvalue {cl[np.argmax(np.abs(cl))]:.3g}); raise "
                           "integral_factor or filter_factor, or lower bandwidth_factor.")
        return PIDGains(**{**gains.__dict__, "closed_loop_poles": cl})
    cl = np.linalg.eigvals(closed_loop_matrix(A, B, gains, slide, hinge))
    cl = cl[np.lexsort((cl.imag, cl.real))]
    if not np.max(cl.real) < 0:
        raise PIDError(f"The tuned PID does not stabilise the linearisation once its integrator and filter are "
                       f"included (eigenvalue {cl[np.argmax(cl.real)]:.3g}); raise integral_factor or filter_factor, "
                       "or lower bandwidth_factor.")
    return PIDGains(**{**gains.__dict__, "closed_loop_poles": cl})


class CascadedPID:
    """The cascaded PID ``u = controller(t, x)``: cart-position PD outside, pole-angle PID inside.

    Call it once per control step with increasing ``t``; the time step is taken from successive ``t`` (the first
    call after construction or :meth:`reset` initialises the integrator to 0 and the filter to the measured rate).
    A repeated ``t`` returns the same ctrl without advancing the internal state; a ``t`` that goes back raises
    :class:`PIDError` (call :meth:`reset` to start a new run).

    Parameters
    ----------
    gains : PIDGains
        From :func:`tune_pid`.
    plant : path, CartPoleParams, CartPoleModel or None
        Supplies ``x*``, ``u*``, the hinge to wrap and the ctrl limits.
    anti_windup : bool
        Conditional integration and the ``|ki z|`` clamp (default on; off only to show what windup does).

    Attributes
    ----------
    integral : float
        ``z``, the integrated inner-loop error, rad s.
    rate_filtered : float
        ``y``, the filtered pole rate error, rad/s.
    theta_ref : float
        Last tilt setpoint from the cart loop, rad (relative to ``x*``).
    """

    def __init__(self, gains: PIDGains, plant=None, *, anti_windup: bool = True):
        self.model = plant_model(plant)
        self.slide, self.hinge = check_cascade(self.model)
        self.gains = gains
        self.anti_windup = bool(anti_windup)
        self._nq = self.model.nq
        self._u_eq = float(self.model.u_eq[0])
        self._lo, self._hi = float(self.model.u_low[0]), float(self.model.u_high[0])
        span = self._hi - self._lo
        self._z_max = 0.5 * span / abs(gains.ki) if gains.ki and np.isfinite(span) else np.inf
        self.reset()

    def set_gains(self, gains: PIDGains) -> None:
        """Use ``gains`` from the next call on, keeping the integrator, the filter and the time (a live retune)."""
        self.gains = gains
        span = self._hi - self._lo
        self._z_max = 0.5 * span / abs(gains.ki) if gains.ki and np.isfinite(span) else np.inf

    @classmethod
    def for_model(cls, plant=None, *, anti_windup: bool = True, **tuning) -> "CascadedPID":
        """A cascaded PID tuned for ``plant`` (a path, parameters or model) by :func:`tune_pid` (``tuning`` = its
        keyword settings)."""
        model = plant_model(plant)
        return cls(tune_pid(model, **tuning), model, anti_windup=anti_windup)

    def reset(self) -> None:
        """Forget the integrator, the filter and the previous time (the next call initialises them)."""
        self.integral = 0.0
        self.rate_filtered = 0.0
        self.theta_ref = 0.0
        self._t = None
        self._last = None

    def _law(self, e: np.ndarray, z: float, y: float) -> tuple[float, float, float]:
        g = self.gains
        theta_ref = float(np.clip(-(g.kp_cart * e[self.slide] + g.kd_cart * e[self._nq + self.slide]),
                                  -g.tilt_limit, g.tilt_limit))
        e_i = float(e[self.hinge]) - theta_ref
        u_raw = self._u_eq - (g.kp * e_i + g.ki * z + g.kd * y)
        return u_raw, e_i, theta_ref

    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (1,) at time ``t`` (s) for state ``x`` (4,) ``[cart, angle, cart rate, angle rate]``, clipped to
        the ctrl range."""
        t = float(t)
        e = self.model.state_error(np.asarray(x, dtype=float).reshape(-1))
        rate = float(e[self._nq + self.hinge])
        g = self.gains
        if self._t is None:
            self._t = t
            self.rate_filtered = rate
        elif t < self._t:
            raise PIDError(f"CascadedPID was called at t = {t:g} s after t = {self._t:g} s; time must not go back "
                           "(call reset() before a new run).")
        elif t == self._t and self._last is not None:
            return self._last.copy()
        else:
            dt = t - self._t
            self._t = t
            if g.filter_tau > 0:
                self.rate_filtered += (1.0 - np.exp(-dt / g.filter_tau)) * (rate - self.rate_filtered)
            else:
                self.rate_filtered = rate
            if g.ki:
                u_raw, e_i, _ = self._law(e, self.integral, self.rate_filtered)
                # d(u)/dz = -ki: integrating e_i moves u by -ki e_i dt; skip it when that deepens saturation.
                push = -g.ki * e_i
                frozen = self.anti_windup and ((u_raw > self._hi and push > 0) or (u_raw < self._lo and push < 0))
                if not frozen:
                    self.integral += dt * e_i
                if self.anti_windup:
                    self.integral = float(np.clip(self.integral, -self._z_max, self._z_max))
        u_raw, _, self.theta_ref = self._law(e, self.integral, self.rate_filtered)
        self._last = np.array([np.clip(u_raw, self._lo, self._hi)])
        return self._last.copy()
