"""Replay metrics: small pure functions of a logged run's arrays (``t`` (n+1,), ``x`` (n+1, 2 nq), ``ctrl`` (n, nu)).

Pass a :class:`~cartpole.sim.rollout.Rollout` as ``run.t``, ``run.x``, ``run.ctrl``; :func:`summarize`
does that for every metric of the lab at once, :func:`swingup_metrics` for a swing-up.

Every function takes the model's layout by name, never by column literal: ``hinges`` (qpos indices of the pole
angles), ``slide`` (qpos index of the cart, or None) and ``x_eq`` (the upright equilibrium, (2 nq,)). Pass a
:class:`~cartpole.models.CartPoleModel` to :func:`summarize` (or a model or parameters to the swing-up
functions) and they are read from it. Without them the cart-first layout is assumed: qpos 0 the cart's slide,
every other qpos a hinge, upright at the origin (the single-pole cart ``[s, theta, s_dot, theta_dot]``).
Angle *errors* from ``x_eq`` are wrapped to (-pi, pi]; states are never wrapped.

Two settling times, because they answer different questions:

* :func:`settling_time_seed` is the balance lab's definition, computed exactly as its ``settling_time``
  does, applied to every pole angle: find every sample where some ``|theta_i - theta_i*| > 0.05 rad``; none ->
  ``0.0``; otherwise the time of the sample *after* the last exceedance. For one pole this is the lab's
  function. It looks at the pole angles only, so a cart still rolling back to the middle (or a pole still
  swinging inside the band) counts as settled. One deviation: when the very last sample still exceeds the
  band the lab's code returns the final time stamp, which reads as "settled at the end"; we return ``inf`` (never
  settled). The lab's code logged the state *before* each of its 1200 steps (t = 0 .. 5.995 s); a
  :class:`Rollout` also holds the final state (t = 6.0 s), which changes nothing unless the run never settles.
* :func:`settling_time_strict` asks for the whole state: the first time after which every entry of the state
  error ``x - x*`` (angle entries wrapped) stays within :data:`STRICT_TOLERANCE` (0.01 m, rad, m/s or rad/s)
  at every later sample up to the end of the run (``inf`` if the last sample is outside that box).

The swing-up's metrics use the same functions (all on the logged physics steps):

* *upright*: every wrapped ``|theta_i - theta_i*| < UPRIGHT_TOL`` (0.05 rad, the lab's settling band);
* *at rest*: additionally every ``|theta_i_dot| < REST_RATE_TOL`` (0.1 rad/s) and ``|s_dot| < REST_SPEED_TOL``
  (0.1 m/s) when the controller read MuJoCo's exact state; when it read quantised sensors (a rig's encoders),
  each bound is widened by the rate those sensors cannot resolve within one control period
  (:func:`rest_tolerance`, below);
* *time to upright*: :func:`settling_time_seed` of the run, the first logged time after which every pole stays
  within the band until the end of the log (``None`` in :func:`swingup_metrics` when it never does);
* *cart clearance*: :func:`track_margin`, the smallest distance to a cart joint limit over the run;
* *success*: upright and at rest over the last ``hold`` seconds, the cart never within ``limit_tol`` of its joint
  limit (where MuJoCo's limit constraint would push it), and every ctrl inside its actuator's ctrl range.

At rest from quantised sensors. A controller that reads an encoder of resolution ``q`` once every period ``T``
cannot tell a rate below ``q / T`` from standing still within one period: a joint turning that slowly moves less than
one count between two readings. A loop closed through such sensors cannot converge to the equilibrium (no
quantised feedback of an unstable plant can); it holds the state in a neighbourhood whose size scales with ``q``,
moving as the counts change. So for a run on a rig, :func:`rest_tolerance` gives each velocity its exact-state bound
plus the sensors' rate resolution, computed from the rig's sensors and period and the model, never from a run:

* a joint measured by a quantised ``jointpos`` sensor (an encoder) adds ``q / T``; by a quantised ``jointvel``
  sensor, its quantum; by several, the finest; unmeasured joints and unquantised (only noisy) sensors add nothing;
* a slide (the cart) adds, besides its own encoder's, the speed at which the chain's centre of mass moves relative
  to the cart when every hinge turns at its unresolved rate: ``sum_i (m_i / M) d_i rho_i`` over the hinges, with
  ``m_i`` the mass hinge ``i`` carries, ``d_i`` the distance of its centre of mass from the axis
  (:meth:`~cartpole.models.CartPoleParams.carried_by`), ``M`` the mass the first hinge carries and ``rho_i`` the
  hinge's rate resolution. Balancing keeps the cart under that centre of mass, so the cart moves as fast as the
  centre of mass does unseen.

The angle band is not widened, a run with exact state keeps the bounds above, and a loop that oscillates (past a
gain or delay margin) or drifts still fails: its rates and its angles grow far past what the counts hide
(``tests/validation/test_metrics_rest.py``, ``tests/apps/test_swingup_ctrl_noise.py``; docs/margins.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cartpole.models import CartPoleParams, plant_model, plant_params, state_error, wrap_angle
from cartpole.ocp import dmc
from cartpole.sim.disturbance import UPRIGHT_BAND

#: Upright band on every wrapped |theta_i - theta_i*| in rad: the balance lab's settling band, the swing-up's
#: upright test and the catch basin's final-state test.
UPRIGHT_TOL = 0.05

#: "At rest" besides upright: every |theta_i_dot| (rad/s) and |s_dot| (m/s) below these.
REST_RATE_TOL = 0.1
REST_SPEED_TOL = 0.1

#: Half-width of the strict settling box on every entry of the state error (m, rad, m/s, rad/s).
STRICT_TOLERANCE = 0.01


def _times_states(t, x) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t, dtype=float).ravel()
    x = np.asarray(x, dtype=float)
    if x.ndim != 2 or x.shape[0] != t.shape[0] or x.shape[1] < 2 or x.shape[1] % 2:
        raise ValueError(f"Need t (n+1,) and x (n+1, 2 nq) = [qpos, qvel]; got t {t.shape} and x {x.shape}.")
    return t, x


def _hinges(hinges, nq: int) -> tuple:
    """The hinge qpos indices given, or the cart-first default ``1 .. nq-1``."""
    return tuple(range(1, nq)) if hinges is None else tuple(int(h) for h in hinges)


def _x_eq(x_eq, nx: int) -> np.ndarray:
    x_eq = np.zeros(nx) if x_eq is None else np.asarray(x_eq, dtype=float).ravel()
    if x_eq.shape != (nx,):
        raise ValueError(f"x_eq has {x_eq.size} entries but the states have {nx}.")
    return x_eq


def _as_model(source):
    """A model (anything with ``params`` and ``x_eq``) as it is; parameters or an MJCF path built into one
    (:func:`~cartpole.models.plant_model`), so that the upright is computed, not assumed at qpos 0: a file built
    hanging has its upright half a turn away."""
    return source if hasattr(source, "params") and hasattr(source, "x_eq") else plant_model(source)


def _layout(source):
    """``(params, x_eq)`` of a plant (:func:`_as_model`)."""
    model = _as_model(source)
    return model.params, np.asarray(model.x_eq, dtype=float)


def _params(source) -> CartPoleParams:
    """The parameters of a plant (a model, parameters or an MJCF path), without building a model."""
    return source.params if hasattr(source, "params") else plant_params(source)


def pole_angle_errors(x, *, x_eq=None, hinges=None) -> np.ndarray:
    """Wrapped angle errors from upright of every pole, (n+1, n_hinges) rad.

    Parameters
    ----------
    x : (n+1, 2 nq) array
        States ``[qpos, qvel]``.
    x_eq : (2 nq,) array, optional
        Upright equilibrium (default the origin).
    hinges : sequence of int, optional
        qpos indices of the pole angles (default ``1 .. nq-1``).
    """
    x = np.atleast_2d(np.asarray(x, dtype=float))
    nq = x.shape[1] // 2
    idx = list(_hinges(hinges, nq))
    return wrap_angle(x[:, idx] - _x_eq(x_eq, x.shape[1])[idx])


def settling_time_seed(t, x, *, band: float = UPRIGHT_TOL, x_eq=None, hinges=None) -> float:
    """The balance lab's settling time: the time after which every ``|theta_i - theta_i*|`` stays within ``band``.

    Parameters
    ----------
    t : (n+1,) array, s
    x : (n+1, 2 nq) array
        States ``[qpos, qvel]``; only the pole angles (rad) are used.
    band : float, rad
        The lab's threshold, :data:`UPRIGHT_TOL` (0.05 rad).
    x_eq : (2 nq,) array, optional
        Upright equilibrium (default the origin); the wrapped errors ``theta_i - theta_i*`` are tested.
    hinges : sequence of int, optional
        qpos indices of the pole angles (default ``1 .. nq-1``: one pole -> column 1, the lab's).

    Returns
    -------
    float, s
        ``t[0]`` (the lab's ``0.0`` for a run from t = 0) if no angle error ever exceeds ``band``; otherwise
        ``t`` of the sample after the last sample where one does; ``inf`` when that last exceedance is the
        final sample. For a swing-up this is the time to upright.
    """
    t, x = _times_states(t, x)
    err = pole_angle_errors(x, x_eq=x_eq, hinges=hinges)
    above = np.flatnonzero(np.any(np.abs(err) > band, axis=1))
    if above.size == 0:
        return float(t[0])
    k = int(above[-1]) + 1
    return float(t[k]) if k < t.size else float("inf")


def settling_time_strict(t, x, x_eq=None, *, tol=STRICT_TOLERANCE, hinges=None) -> float:
    """First time after which the whole state stays inside a box around the equilibrium until the end.

    Parameters
    ----------
    t : (n+1,) array, s
    x : (n+1, 2 nq) array
        States ``[qpos, qvel]``.
    x_eq : (2 nq,) array, optional
        Equilibrium ``x*`` (default the origin); the angle errors are wrapped.
    tol : float or (2 nq,) sequence
        Half-widths of the box, in m, rad, m/s, rad/s (default :data:`STRICT_TOLERANCE` on every entry).
    hinges : sequence of int, optional
        qpos indices whose error is wrapped (default ``1 .. nq-1``).

    Returns
    -------
    float, s
        ``t[k]`` for the smallest ``k`` such that every sample ``k..n`` is inside the box; ``inf`` if the final
        sample is outside (the run never settled).
    """
    t, x = _times_states(t, x)
    e = state_error(x, _x_eq(x_eq, x.shape[1]), _hinges(hinges, x.shape[1] // 2))
    inside = np.all(np.abs(e) <= np.asarray(tol, dtype=float), axis=1)
    if not inside[-1]:
        return float("inf")
    outside = np.flatnonzero(~inside)
    return float(t[outside[-1] + 1]) if outside.size else float(t[0])


def _ctrl2d(ctrl) -> np.ndarray:
    ctrl = np.asarray(ctrl, dtype=float)
    return ctrl.reshape(-1, 1) if ctrl.ndim < 2 else ctrl


def residual_error(t, x, x_eq, *, hinges, window: float = 1.0) -> np.ndarray:
    """Largest ``|x - x*|`` per state over the last ``window`` seconds of a run (hinge errors wrapped): what is left
    of the error once the transient is over (a limit cycle's amplitude, a cart stuck off centre by friction).

    Parameters
    ----------
    t : (N+1,) array, s
    x : (N+1, nx) array
        States ``[qpos, qvel]``.
    x_eq : (nx,) array
        The equilibrium the run holds.
    hinges : sequence of int
        qpos indices of the hinges (their errors are wrapped).
    window : float
        Seconds at the end of the run, > 0 (the whole run when it is shorter).

    Returns
    -------
    (nx,) array
        m, rad, m/s, rad/s in state order.
    """
    t, x = _times_states(t, x)
    tail = t >= t[-1] - float(window) - 1e-12
    return np.abs(state_error(x[tail], x_eq, hinges)).max(axis=0)


def peak_ctrl_per_actuator(ctrl) -> np.ndarray:
    """Largest ``|ctrl|`` of each actuator, (nu,) in MuJoCo ctrl units (zeros for an empty log).

    ``ctrl`` is (n, nu) as a :class:`Rollout` logs it ((n,) is one actuator).
    """
    ctrl = _ctrl2d(ctrl)
    return np.abs(ctrl).max(axis=0) if ctrl.shape[0] else np.zeros(ctrl.shape[1])


def peak_ctrl(ctrl) -> float:
    """Largest ``|ctrl|`` applied by any actuator: the max over actuators of :func:`peak_ctrl_per_actuator`
    (MuJoCo ctrl units; force is ``gear`` times this), 0 for an empty log."""
    peaks = peak_ctrl_per_actuator(ctrl)
    return float(peaks.max()) if peaks.size else 0.0


def saturation_fraction(ctrl, ctrl_range, *, atol: float = 1e-12) -> float:
    """Fraction (0..1) of physics steps in which some actuator's ctrl sits at a bound of its range (within ``atol``).

    Parameters
    ----------
    ctrl : (n, nu) or (n,) array
        ctrl applied during each step (already clipped, as a :class:`Rollout` logs it).
    ctrl_range : (nu, 2) or (2,) array
        ``[low, high]`` per actuator (as ``CartPoleParams.ctrl_range``; one row is shared by all); infinite
        bounds never saturate.
    """
    u = _ctrl2d(ctrl)
    if u.shape[0] == 0:
        return 0.0
    rng = np.asarray(ctrl_range, dtype=float).reshape(-1, 2)
    lo, hi = rng[:, 0], rng[:, 1]
    at_bound = np.any((u <= lo + atol) | (u >= hi - atol), axis=1)
    return float(np.mean(at_bound))


def track_margin(x, cart_range, *, slide: int | None = 0) -> float:
    """Smallest distance in m of the cart to either end of its slide range over the run.

    Parameters
    ----------
    x : (n+1, 2 nq) or (n+1, nq) array
        States or ``qpos``; column ``slide`` is the cart position in m.
    cart_range : (2,) array
        Slide joint range ``[low, high]`` in m (``inf`` when unlimited).
    slide : int or None
        qpos index of the cart's slide (``model.slide``; default 0); None (no cart) gives ``inf``.

    Returns
    -------
    float, m
        ``min_k min(s_k - low, high - s_k)``: ``inf`` for an unlimited rail or no cart, ``<= 0`` when the cart
        reached (or, through MuJoCo's soft limit, passed) a joint limit.
    """
    if slide is None:
        return float("inf")
    s = np.asarray(x, dtype=float)[:, slide]
    lo, hi = (float(v) for v in np.ravel(cart_range))
    return float(np.min(np.minimum(s - lo, hi - s)))


@dataclass(frozen=True)
class RunMetrics:
    """Every metric of one run (see the module docstring for the definitions).

    Attributes
    ----------
    settling_time_seed : float, s (``inf`` if never)
    settling_time_strict : float, s (``inf`` if never)
    peak_ctrl : float, ctrl units (max over actuators)
    saturation_fraction : float, 0..1
    track_margin : float, m
    diverged : bool
        MuJoCo warned that the simulation blew up (a bad position, velocity, acceleration or ctrl) and reset the state
        during the run (``info["diverged"]``): the run is never settled, whatever its last states look like.
    diverged_at : float or None
        s: when it did (:func:`diverged_at`), None when it did not.
    """

    settling_time_seed: float
    settling_time_strict: float
    peak_ctrl: float
    saturation_fraction: float
    track_margin: float
    diverged: bool = False
    diverged_at: float | None = None

    @property
    def hit_limit(self) -> bool:
        """True when the cart reached a joint limit (``track_margin <= 0``)."""
        return self.track_margin <= 0.0

    @property
    def settled(self) -> bool:
        """Strict settling time finite, the cart never reached its limit, and the run did not diverge."""
        return bool(np.isfinite(self.settling_time_strict) and not self.hit_limit and not self.diverged)


def summarize(run, model=None, *, x_eq=None, hinges=None, slide: int | None = 0, ctrl_range=None,
              cart_range=None, tol=STRICT_TOLERANCE) -> RunMetrics:
    """All metrics of a :class:`~cartpole.sim.rollout.Rollout` (anything with ``t``, ``x``, ``ctrl``).

    Parameters
    ----------
    run : Rollout
    model : CartPoleModel, optional
        Supplies ``x_eq``, ``hinges``, ``slide``, the ctrl ranges and the cart range; keywords given override it.
    x_eq : (2 nq,) array, optional
        Equilibrium (default ``model.x_eq``, else the origin).
    hinges : sequence of int, optional
        Pole-angle qpos indices (default ``model.hinges``, else ``1 .. nq-1``).
    slide : int or None
        The cart's qpos index (used without ``model``; default 0).
    ctrl_range : (nu, 2) or (2,) array, optional
        Default ``model.params.ctrl_range``, else unbounded.
    cart_range : (2,) array, optional
        Default ``model.params.cart_range``, else unbounded.
    tol : float or (2 nq,) sequence
        Strict settling box (m, rad, m/s, rad/s).
    """
    if model is not None:
        x_eq = model.x_eq if x_eq is None else x_eq
        hinges = model.hinges if hinges is None else hinges
        slide = model.slide
        ctrl_range = model.params.ctrl_range if ctrl_range is None else ctrl_range
        cart_range = model.params.cart_range if cart_range is None else cart_range
    ctrl_range = (-np.inf, np.inf) if ctrl_range is None else ctrl_range
    cart_range = (-np.inf, np.inf) if cart_range is None else cart_range
    return RunMetrics(
        settling_time_seed=settling_time_seed(run.t, run.x, x_eq=x_eq, hinges=hinges),
        settling_time_strict=settling_time_strict(run.t, run.x, x_eq, tol=tol, hinges=hinges),
        peak_ctrl=peak_ctrl(run.ctrl),
        saturation_fraction=saturation_fraction(run.ctrl, ctrl_range),
        track_margin=track_margin(run.x, cart_range, slide=slide),
        diverged=diverged(run),
        diverged_at=diverged_at(run),
    )


def diverged(run) -> bool:
    """True when MuJoCo reset a blown-up run (the rollout's ``info["diverged"]`` holds the time): such a run's last
    states are MuJoCo's reset, not the controller's work, so no success test may count it."""
    return diverged_at(run) is not None


def touched(run) -> dict | None:
    """The first contact MuJoCo found in ``run`` (its ``info["contact"]``: ``t`` s, ``geom1``, ``geom2``, ``dist`` m,
    ``steps`` in contact), or None for a run that never touched: the symbolic model has no contacts, so a run that
    touched is not the controller's clean work."""
    info = getattr(run, "info", None)
    return info.get("contact") if isinstance(info, dict) else None


def diverged_at(run) -> float | None:
    """The time in s at which MuJoCo warned that ``run`` (a :class:`~cartpole.sim.rollout.Rollout`) blew up and reset
    it (its ``info["diverged"]``), or None when it did not."""
    info = getattr(run, "info", None)
    t = info.get("diverged") if isinstance(info, dict) else None
    return None if t is None else float(t)


def cart_range_used(rollout, *, slide: int | None = 0) -> tuple[float, float]:
    """``(min, max)`` cart position in m over a :class:`~cartpole.sim.rollout.Rollout` (``(0, 0)`` without a
    cart, ``slide=None``)."""
    if slide is None:
        return 0.0, 0.0
    s = rollout.qpos[:, slide]
    return float(s.min()), float(s.max())


def ctrl_within_range(rollout, params: CartPoleParams) -> bool:
    """Whether every applied ctrl of ``rollout`` lies inside its actuator's row of ``params.ctrl_range``."""
    rng = np.asarray(params.ctrl_range, dtype=float).reshape(-1, 2)
    u = _ctrl2d(rollout.ctrl)
    return bool(np.all((u >= rng[:, 0]) & (u <= rng[:, 1])))


def _rate_resolution(params: CartPoleParams, spec, period: float) -> np.ndarray:
    """(nq,) rate in m/s or rad/s that the quantised joint sensors of ``spec`` cannot resolve within ``period`` s, per
    joint (0 for a joint no quantised joint sensor measures); see the module docstring."""
    nq = len(params.joints)
    rho = np.full(nq, np.inf)
    for s in getattr(spec, "sensors", ()):
        if s.resolution > 0 and s.kind in ("jointpos", "jointvel") and 0 <= s.target < nq:
            rate = s.resolution / period if s.kind == "jointpos" else s.resolution
            rho[s.target] = min(rho[s.target], rate)
    return np.where(np.isfinite(rho), rho, 0.0)


def rest_tolerance(source, rig=None) -> np.ndarray:
    """The "at rest" bound on each velocity, (nq,) in qvel order (m/s on slides, rad/s on hinges).

    Parameters
    ----------
    source : CartPoleModel, CartPoleParams or path
        The cart-pole (its joints, and the masses and geometry the cart's bound uses).
    rig : Rig, optional
        The run's rig (anything with ``spec``, a :class:`~cartpole.estimation.sensors.SensorSpec` or None, and
        ``period`` in s): None, or a rig whose controller reads MuJoCo's exact state (``spec`` None), gives
        :data:`REST_RATE_TOL` on every hinge and :data:`REST_SPEED_TOL` on every slide.

    Returns
    -------
    (nq,) array
        Those bounds, each widened by the rate the rig's quantised sensors cannot resolve within one period (the
        module docstring: ``q / T`` per encoder; on the cart also the chain's centre of mass moving that unseen).
    """
    params = _params(source)
    nq = len(params.joints)
    tol = np.full(nq, REST_RATE_TOL)
    tol[list(params.slides)] = REST_SPEED_TOL
    spec = getattr(rig, "spec", None)
    if spec is None:
        return tol
    rho = _rate_resolution(params, spec, float(rig.period))
    if params.hinges and params.slides:
        carried = params.pole_mass
        lever = []
        for h in params.hinges:
            m, d, _ = params.carried_by(h)
            lever.append(m * d / carried if carried > 0 else 0.0)
        chain = float(np.dot(lever, rho[list(params.hinges)]))
        rho[list(params.slides)] += chain
    return tol + rho


def held_upright(rollout, *, hold: float = 1.0, x_eq=None, hinges=None, slide: int | None = 0,
                 tolerance=None) -> bool:
    """Whether the last ``hold`` seconds (and at least the final state) of ``rollout`` are upright and at rest.

    Every wrapped pole-angle error from ``x_eq`` must stay below :data:`UPRIGHT_TOL`, every hinge rate below
    :data:`REST_RATE_TOL` and the cart speed (qvel ``slide``; skipped when None) below :data:`REST_SPEED_TOL`, or
    below ``tolerance`` (nq,) per qvel (m/s, rad/s; :func:`rest_tolerance` of a run on a rig) when given.
    ``hinges`` defaults to ``1 .. nq-1``, ``x_eq`` (nx,) to the origin.
    """
    if rollout.t[-1] - rollout.t[0] < hold:
        return False
    last = rollout.t >= rollout.t[-1] - hold - 1e-12
    x = rollout.x[last]
    nq = x.shape[1] // 2
    idx = list(_hinges(hinges, nq))
    if tolerance is None:
        tolerance = np.full(nq, REST_RATE_TOL)
        if slide is not None:
            tolerance[slide] = REST_SPEED_TOL
    tolerance = np.asarray(tolerance, dtype=float)
    up = np.all(np.abs(pole_angle_errors(x, x_eq=x_eq, hinges=idx)) < UPRIGHT_TOL)
    still = np.all(np.abs(x[:, [nq + h for h in idx]]) < tolerance[idx])
    cart = slide is None or np.all(np.abs(x[:, nq + slide]) < tolerance[slide])
    return bool(up and still and cart)


def swingup_success(rollout, source, *, hold: float = 1.0, limit_tol: float = 1e-3, rig=None) -> bool:
    """The swing-up succeeded: held upright at rest for the last ``hold`` s, cart never at its limit, ctrl in range,
    no contact on the way (:func:`touched`).

    Parameters
    ----------
    rollout : Rollout
    source : CartPoleModel, CartPoleParams or path
        The plant; its upright ``x_eq`` is the reference (computed from parameters or a path, so a file built
        hanging is judged against its true upright), with its hinges, slide, cart and ctrl ranges.
    hold : float
        Seconds at the end that must be upright and at rest.
    limit_tol : float
        m: coming closer than this to a cart limit (:func:`track_margin`) counts as hitting it.
    rig : Rig, optional
        The rig the run had (:class:`~cartpole.sim.rig.Rig`): with quantised sensors "at rest" is
        :func:`rest_tolerance`'s; None (or a rig reading the exact state) keeps the exact-state bounds.

    Returns
    -------
    bool
    """
    params, x_eq = _layout(source)
    return bool(not diverged(rollout) and touched(rollout) is None
                and held_upright(rollout, hold=hold, x_eq=x_eq, hinges=params.hinges, slide=params.slide,
                                 tolerance=rest_tolerance(params, rig))
                and track_margin(rollout.qpos, params.cart_range, slide=params.slide) > limit_tol
                and ctrl_within_range(rollout, params))


def catch_held(rollout, source, handover_at: float | None, *, hold: float = 1.0, rig=None) -> bool:
    """Whether the catch that took over at ``handover_at`` held: the run reached the hand-over, did not diverge, and
    ends upright and at rest (:func:`held_upright`: every pole inside :data:`UPRIGHT_TOL` of upright and still over
    the last ``hold`` s), the part of :func:`swingup_success` that is the catch's.

    Parameters
    ----------
    rollout : Rollout
    source : CartPoleModel, CartPoleParams or path
        As :func:`swingup_success`.
    handover_at : float or None
        s: when the controller handed over to the catch (None: it never did, so nothing was caught).
    hold : float
        Seconds at the end that must be upright and at rest.
    rig : Rig, optional
        As :func:`swingup_success`.

    Returns
    -------
    bool
        False without a hand-over, after a divergence, or when the run does not end upright at rest.
    """
    if handover_at is None or diverged(rollout) or rollout.t[-1] < handover_at:
        return False
    params, x_eq = _layout(source)
    return held_upright(rollout, hold=hold, x_eq=x_eq, hinges=params.hinges, slide=params.slide,
                        tolerance=rest_tolerance(params, rig))


def failure_reason(metrics: dict, *, limit_tol: float = 1e-3) -> str:
    """Why a swing-up failed, in a few words, from its :func:`swingup_metrics` (or any dict with ``success``,
    ``diverged`` and ``cart_clearance`` (m)); ``""`` for a success.

    Returns
    -------
    str
        ``"diverged"`` (MuJoCo blew up and reset the run), ``"cart reached its limit"`` (closer than ``limit_tol``
        m to a cart limit) or ``"not upright at rest over the last second"``.
    """
    if metrics["success"]:
        return ""
    if metrics.get("diverged"):
        return "diverged"
    clearance = metrics.get("cart_clearance")
    if clearance is not None and clearance <= limit_tol:
        return "cart reached its limit"
    return "not upright at rest over the last second"


def swingup_metrics(rollout, source, *, hold: float = 1.0, rig=None) -> dict:
    """All swing-up metrics of a :class:`~cartpole.sim.rollout.Rollout` in one JSON-ready dict.

    Parameters
    ----------
    rollout : Rollout
    source : CartPoleModel, CartPoleParams or path
        As :func:`swingup_success`.
    hold : float
        Seconds at the end that must be upright and at rest.
    rig : Rig, optional
        As :func:`swingup_success`.

    Returns
    -------
    dict
        ``success`` (bool, :func:`swingup_success`), ``rest_tolerance`` (the bound on each velocity, qvel order,
        m/s and rad/s, :func:`rest_tolerance`), ``time_to_upright`` (s, :func:`settling_time_seed` over every
        pole; None if not every pole is upright at the end, or the run diverged), ``peak_ctrl`` (ctrl units, max over
        actuators), ``cart_min``, ``cart_max``, ``cart_clearance`` (m, :func:`track_margin`), ``duration`` (s),
        ``diverged`` (bool: MuJoCo reset the run as blown up, :func:`diverged`), ``diverged_at`` (s or None) and
        ``diverged_warning`` (MuJoCo's warning, e.g. ``"BADQACC"``, or None), ``contact`` (:func:`touched`: the first
        contact, or None).
    """
    source = _as_model(source)  # built once for the metrics below
    params, x_eq = _layout(source)
    lo, hi = cart_range_used(rollout, slide=params.slide)
    t_up = settling_time_seed(rollout.t, rollout.x, x_eq=x_eq, hinges=params.hinges)
    t_div = diverged_at(rollout)
    info = rollout.info if isinstance(getattr(rollout, "info", None), dict) else {}
    return {"success": swingup_success(rollout, source, hold=hold, rig=rig),
            "rest_tolerance": rest_tolerance(params, rig).tolist(),
            "time_to_upright": t_up if (np.isfinite(t_up) and t_div is None) else None,
            "peak_ctrl": peak_ctrl(rollout.ctrl), "cart_min": lo, "cart_max": hi,
            "cart_clearance": track_margin(rollout.qpos, params.cart_range, slide=params.slide),
            "duration": float(rollout.t[-1] - rollout.t[0]),
            "diverged": t_div is not None, "diverged_at": t_div,
            "diverged_warning": info.get("diverged_warning") if t_div is not None else None,
            "contact": touched(rollout)}


#: Seconds a pole must stay in the upright band after entering it for :func:`uptime_metrics` to count a swing-up.
SWINGUP_HOLD = 1.0


def _upright_mask(rollout, source, band: float) -> np.ndarray:
    params, x_eq = _layout(source)
    return np.all(np.abs(pole_angle_errors(rollout.x, x_eq=x_eq, hinges=params.hinges)) < band, axis=1)


def upright_segments(rollout, source, *, band: float = UPRIGHT_BAND) -> list[tuple[float, float]]:
    """The spans ``(start, end)`` in s during which every pole is within ``band`` rad of upright (angle errors
    wrapped), in time order.

    Parameters
    ----------
    rollout : Rollout
    source : CartPoleModel, CartPoleParams or path
        As :func:`swingup_success`.
    band : float
        rad; default :data:`cartpole.sim.disturbance.UPRIGHT_BAND`.
    """
    up = _upright_mask(rollout, source, band)
    t = np.asarray(rollout.t, dtype=float)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], up.astype(int), [0]])))
    return [(float(t[a]), float(t[b - 1])) for a, b in zip(edges[::2], edges[1::2])]


def uptime_metrics(rollout, source, *, band: float = UPRIGHT_BAND, hold: float = SWINGUP_HOLD, events=(),
                   duration: float | None = None) -> dict:
    """How much of a long, disturbed run was spent upright, and how often it swung up again.

    Parameters
    ----------
    rollout : Rollout
    source : CartPoleModel, CartPoleParams or path
        As :func:`swingup_success`.
    band : float
        rad: every pole's wrapped angle error below this counts as upright.
    hold : float
        s: an entry into the band counts as a swing-up only when it stays upright at least this long, also at the
        run's end (an entry with less than ``hold`` s of run left is not counted: a chain spinning through the band
        at the run's last steps has not swung up); a run that starts upright has not swung up at its start.
    events : sequence of (float, float)
        The disturbances' ``(start, end)`` times in s (e.g. :attr:`cartpole.sim.disturbance.KnockdownForce.events`).
    duration : float, optional
        s the run was asked to last; uptime is a fraction of it, so a run that stopped early (diverged) counts the
        rest as down. Default the logged length.

    Returns
    -------
    dict
        ``uptime`` (fraction of ``duration`` upright; 0 for a diverged run from its divergence on), ``upright_band``
        (rad), ``knockdowns`` (number of events), ``swingups`` (entries into the band held ``hold`` s),
        ``swingup_times`` (s, each counted entry), ``recoveries`` (events followed by a counted swing-up before the
        next event or the end), ``unrecovered_at`` (s, start of each other event: the last one may simply have had
        too little run left).
    """
    t = np.asarray(rollout.t, dtype=float)
    total = float(t[-1] - t[0]) if duration is None else float(duration)
    source = _as_model(source)  # built once for the segments and the mask
    segments = upright_segments(rollout, source, band=band)
    up_time = float(np.sum(np.diff(t)[_upright_mask(rollout, source, band)[:-1]]))  # each step upright at its start
    counted = [a for a, b in segments if a > t[0] and b - a >= hold - 1e-9]
    events = [(float(a), float(b)) for a, b in events]
    ends = [a for a, _ in events[1:]] + [np.inf]
    missed = [a for (a, _), nxt in zip(events, ends) if not any(a < s < nxt for s in counted)]
    return {"uptime": up_time / total if total > 0 else 0.0, "upright_band": float(band), "knockdowns": len(events),
            "swingups": len(counted), "swingup_times": counted, "recoveries": len(events) - len(missed),
            "unrecovered_at": missed}


#: dm_control's episode of every task here: 1000 control steps (:meth:`cartpole.ocp.dmc.Task.steps` on its files).
DMC_STEPS = 1000

#: ``steps`` of :func:`dmc_rewards` meaning "the task's episode length".
EPISODE = "episode"


def dmc_reward(model, x, u, objective: str = "dmc_cartpole_swingup") -> np.ndarray:
    """dm_control's exact reward of the task ``objective`` (:data:`cartpole.ocp.objectives.DMC`) for states ``x``
    (..., 2 nq) and ctrl ``u`` (..., nu), broadcast: (...,), each in [0, 1].

    The task's one definition (:func:`cartpole.ocp.dmc.reward_expression` with ``exact=True``: sparse indicators
    as dm_control computes them), as a CasADi Function built once per model (:func:`cartpole.ocp.dmc.reward_function`)
    and evaluated on every row at once (``Function.map``). States in m, rad, m/s, rad/s.
    """
    return dmc.rewards(model, objective, x, u)


def dmc_swingup_reward(model, x, u) -> np.ndarray:
    """:func:`dmc_reward` of ``dmc_cartpole_swingup`` (``dm_control/suite/cartpole.py``,
    ``Balance._get_reward(sparse=False)``): states ``x`` (..., 2 nq), ctrl ``u`` (..., nu) -> (...,) in [0, 1]."""
    return dmc_reward(model, x, u, "dmc_cartpole_swingup")


def dmc_rewards(rollout, model, control_dt: float | None = None, *, objective: str = "dmc_cartpole_swingup",
                steps: int | str | None = DMC_STEPS) -> np.ndarray:
    """The reward dm_control would pay at each control step of a logged rollout, (n_steps,).

    dm_control applies the action for one control step (``control_dt``, a whole number of physics steps), then
    pays the reward of the state reached and that action: reward ``j`` is :func:`dmc_reward` of the state logged at
    ``(j + 1) control_dt`` and the ctrl of the last physics step before it. ``control_dt`` defaults to the task's
    (:meth:`cartpole.ocp.dmc.Task.control_dt`: one MJCF step for every task here); at most ``steps`` control steps
    are counted (default 1000; :data:`EPISODE`: the task's episode, :meth:`~cartpole.ocp.dmc.Task.steps`; None:
    as many as the log holds).
    """
    dt = float(model.params.timestep)
    task = dmc.task(objective)
    control_dt = task.control_dt(dt) if control_dt is None else float(control_dt)
    m = int(round(control_dt / dt))
    if m < 1 or abs(m * dt - control_dt) > 1e-9 * max(1.0, control_dt):
        raise ValueError(f"control_dt = {control_dt} s must be a whole number of MJCF steps of {dt} s.")
    ctrl = np.asarray(rollout.ctrl, float).reshape(len(rollout.ctrl), -1)
    n = ctrl.shape[0] // m
    if steps == EPISODE:
        steps = task.steps(dt)
    if steps is not None:
        n = min(n, int(steps))
    idx = m * np.arange(1, n + 1)
    return dmc_reward(model, np.asarray(rollout.x, float)[idx], ctrl[idx - 1], objective)


def dmc_swingup_rewards(rollout, model, control_dt: float | None = None, *, steps: int | None = DMC_STEPS) -> np.ndarray:
    """:func:`dmc_rewards` of ``dmc_cartpole_swingup`` (n_steps,)."""
    return dmc_rewards(rollout, model, control_dt, steps=steps)


def dmc_return(rollout, model, control_dt: float | None = None, *, objective: str = "dmc_cartpole_swingup",
               steps: int | str | None = DMC_STEPS) -> float:
    """dm_control's return of a logged rollout: the sum of :func:`dmc_rewards` (1000 is the most an episode of
    1000 control steps can earn)."""
    return float(np.sum(dmc_rewards(rollout, model, control_dt, objective=objective, steps=steps)))


def dmc_swingup_return(rollout, model, control_dt: float | None = None, *, steps: int | None = DMC_STEPS) -> float:
    """:func:`dmc_return` of ``dmc_cartpole_swingup``."""
    return dmc_return(rollout, model, control_dt, steps=steps)
