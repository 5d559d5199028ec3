"""Energy-shaping swing-up by collocated partial feedback linearisation (Spong's cart-pole swing-up).

The controller chooses a desired cart acceleration

    a_d = guard( sat(k_E (E_ref - E) w + a_D)  -  phi(E) (k_x s + k_v s_dot) ),   w = -theta_dot M21(theta) / (m l)

and turns it into ctrl *exactly* with the model's mass matrix ``M``, bias ``b``, joint damping ``D`` and gear:
the pole row of ``M qacc + b = tau - D v`` gives ``theta_ddot(a)`` for a cart acceleration ``a``, and the cart row
then gives the slide force, hence ``ctrl = (M11 a + M12 theta_ddot(a) + b1 + D1 s_dot) / gear``.

Why the sign is right for any hinge-axis sign: the pole's energy about its hinge ``E`` (zero at upright rest, see
:attr:`CartPoleModel.pole_energy`) changes as ``dE/dt = -D2 theta_dot^2 - (J_h / M22) theta_dot M21 a`` (no
armature: ``J_h = M22``), so ``dE/dt`` is affine in the cart acceleration ``a`` with slope ``(J_h m l / M22) w``.
With ``w`` computed from the model's own ``M21`` (which carries the hinge axis sign and offset), choosing
``a = k_E (E_ref - E) w`` makes the pumped power ``k_E (J_h m l / M22) (E_ref - E) w^2`` push ``E`` towards ``E_ref``
whatever the axis convention. For a plain pole ``w = -sigma theta_dot cos(theta)`` (``sigma = +1`` for the
shipped asset), i.e. the textbook ``a = k_E (E - E_up) theta_dot cos(theta)``.

Why damping compensation and a small overshoot: the hinge damping drains ``D2 theta_dot^2`` every instant; with
``E_ref = E_up`` and a timid gain the pumping vanishes as ``E -> E_up`` and the pole settles where pumping balances
damping, short of the top (``tests/control/test_energy.py`` measures the deficit in MuJoCo). The law therefore puts
the drained power back through the cart (``a_D``, softened where the pole cannot be pumped), aims slightly above
the top (``E_ref = overshoot * 2 m g l``, 0.5 % by default) so the pole passes the top slowly instead of stalling
just below it, and uses a strong, saturated energy gain. Cart centring is weighted down while the energy is far from
its target (it would eat the pumping) and a control-barrier guard keeps the cart ``track_margin`` inside its joint
range. The LQR catch (:mod:`cartpole.control.switching`) takes over once the state is in its verified basin.

The energy regulated is the pole subsystem's own, ``E = pole_energy + 0.5 armature theta_dot^2`` (the hinge
armature's kinetic energy belongs to what the pole's equation of motion conserves).

The law is for one pole on a cart whose only actuator drives the cart's slide (any joint order: the slide and the
hinge are ``model.slide`` and ``model.hinges[0]``); the cart position is measured from the computed upright
equilibrium ``model.x_eq`` (the pole energy is zero there, so a pole built off vertical is handled). Anything else
(two or more poles, a motor on a hinge) is refused with :class:`EnergyShapingModelError`: swing such a chain up by
trajectory optimisation (``--method trajopt``).

Units: ``s`` m, ``theta`` rad, ``E`` J, ``a`` m/s^2, ``ctrl`` MuJoCo ctrl (slide force = ``gear * ctrl`` N).
"""
from __future__ import annotations

import dataclasses
import math
import types
from dataclasses import dataclass, replace
from typing import ClassVar

import casadi as ca
import numpy as np

from cartpole.control.model_rollout import model_rollout
from cartpole.errors import CartPoleError
from cartpole.models import CartPoleModel, plant_model
from cartpole.options import StageOptions


class EnergyShapingError(CartPoleError):
    """Bad gains or a model the energy-shaping controller cannot drive (no ctrl limit, no track limit...)."""


class EnergyShapingModelError(EnergyShapingError):
    """The model is not one pole on a cart driven through the cart's slide, which is all energy shaping drives."""


def check_single_pole(model: CartPoleModel) -> tuple[int, int]:
    """``(slide, hinge)`` qpos indices of a model energy shaping can drive: one slide, one hinge, one actuator on
    the slide.

    Raises
    ------
    EnergyShapingModelError
        With one sentence naming what the model has instead and pointing to ``method='trajopt'``.
    """
    p = model.params
    if len(p.hinges) != 1:
        what = f"this model has {len(p.hinges)} hinges"
    elif len(p.slides) != 1:
        what = "this model has no slide for a cart" if not p.slides else f"this model has {len(p.slides)} slides"
    elif p.nu != 1:
        what = f"this model has {p.nu} actuators"
    elif p.actuated[0] != p.slide:
        what = f"its actuator drives joint '{p.joints[p.actuated[0]].name}', not the cart's slide"
    elif not p.gear > 0:
        raise EnergyShapingModelError(f"Energy shaping needs the motor to push the cart along +x as ctrl grows, and "
                                      f"this model's gear is {p.gear:g}; give the actuator a positive gear (flip "
                                      "its sign) or use `method='trajopt'` instead.")
    elif not p.g > 0 or not p.pole_com_distance > 0:
        raise EnergyShapingModelError("Energy shaping pumps the pole's energy against gravity and this model has "
                                      + ("no gravity" if not p.g > 0 else "its pole's centre of mass on the hinge axis")
                                      + "; use `method='trajopt'` instead.")
    else:
        return p.slide, p.hinges[0]
    raise EnergyShapingModelError(f"Energy shaping is for one pole driven by the cart and {what}; "
                                  "use `method='trajopt'` instead.")


@dataclass(frozen=True)
class EnergyGains:
    """The gains and limits an :class:`EnergyShapingController` actually uses, in SI units.

    Attributes
    ----------
    k_energy : float
        Energy gain ``k_E`` in (m/s^2) / (J rad/s): ``a_E = k_E (E_ref - E) w``.
    k_x : float
        Cart centring stiffness in 1/s^2 (m/s^2 per m).
    k_v : float
        Cart centring damping in 1/s (m/s^2 per m/s).
    a_energy_max : float
        Saturation of the energy part of the cart acceleration, m/s^2.
    energy_target : float
        ``E_ref`` in J (pole energy; 0 = upright rest).
    kick_rate : float
        Pole rates below this (rad/s) count as ``+-kick_rate`` in the pumping direction, so a pole at rest
        is set swinging; 0 disables the kick.
    track_margin : float
        m: the track guard keeps the cart this far inside its joint range.
    a_brake : float
        m/s^2: deceleration the track guard plans to stop the cart with (below the available ``a_max`` so the
        pole's reaction force and damping can still be overcome at full ctrl).
    barrier_rate : float
        1/s: how fast the guard lets the cart use up its stopping margin (control-barrier-function rate).
    damping_softening : float
        rad/s, ``eps`` of the hinge-damping compensation ``a_D = D2 theta_dot^2 w / (m l (w^2 + eps^2))``, which
        replaces the power the hinge damping drains wherever pumping is effective (``|w| >> eps``); ``inf``
        disables the compensation.
    centring_band : float
        J: the cart centring acts with weight ``1 / (1 + ((E_ref - E) / centring_band)^2)``, full strength once the
        energy is right, fading while the pole is still being pumped (when it would eat the pumping).
    """

    k_energy: float
    k_x: float
    k_v: float
    a_energy_max: float
    energy_target: float
    kick_rate: float
    track_margin: float
    a_brake: float
    barrier_rate: float
    damping_softening: float
    centring_band: float


def model_scales(model: CartPoleModel) -> dict:
    """Physical scales the default gains are built from.

    Parameters
    ----------
    model : CartPoleModel

    Returns
    -------
    dict
        ``g`` (m/s^2), ``mgl`` (J, pole weight times COM distance: the swing-up needs ``2 mgl``),
        ``omega0`` (rad/s, small-swing pendulum frequency ``sqrt(mgl / M22)``), ``a_max`` (m/s^2, the cart
        acceleration full ctrl gives at upright rest with the pole's reaction, ``gear u_max / (M11 - M12^2 / M22)``),
        ``half_track`` (m, half the cart joint range, inf when unlimited). The mass matrix is taken at ``x_eq``.

    Raises
    ------
    EnergyShapingModelError
        For a model that is not one pole driven by the cart (:func:`check_single_pole`).
    """
    si, hi = check_single_pole(model)
    p = model.params
    M = np.asarray(model.mass_matrix(model.x_eq))
    mgl = p.pole_mass * p.g * p.pole_com_distance
    m_eff = M[si, si] - M[si, hi] ** 2 / M[hi, hi]
    return {"g": p.g, "mgl": mgl, "omega0": float(np.sqrt(mgl / M[hi, hi])),
            "a_max": float(p.gear * p.u_max / m_eff),
            "half_track": float(0.5 * (p.cart_range[1] - p.cart_range[0]))}


#: How far (a factor) an energy-shaping setting may go beyond its default (or beyond 1 for a small default).
MAX_SCALING = 1000.0
#: The explicit SI gains an :class:`EnergyOptions` may set, overriding the scaled ones.
SI_GAINS = ("k_energy", "k_x", "k_v", "a_energy_max", "energy_target")


@dataclasses.dataclass(frozen=True, eq=False)
class EnergyOptions(StageOptions):
    """The energy-shaping swing-up's settings as one value (what :class:`EnergyShapingController` and
    :func:`cartpole.apps.swingup.run_swingup` take; ``replace``, ``as_dict`` and by-name variation from
    :class:`cartpole.options.StageOptions`: a sweep's ``setting:<name>`` axis varies a scaling by its name),
    validated on creation. The scalings are dimensionless: :func:`default_gains` turns them into SI gains with the
    model's own pole energy ``2 mgl``, natural rate ``omega0`` and largest cart acceleration ``a_max``, so one set
    fits every cart-pole; the SI fields, when set, override the scaled gains.

    Attributes
    ----------
    energy_gain : float
        ``kappa`` > 0: ``k_E = kappa a_max / (2 mgl omega0)``, ``kappa`` times the gain at which a full energy
        deficit ``2 mgl`` at pole rate ``omega0`` asks for the full acceleration ``a_max``.
    overshoot : float
        >= 0: ``E_ref = overshoot * 2 mgl`` J above upright rest (beats the hinge damping; the catch takes over at
        the top).
    energy_accel : float
        In (0, 1]: the fraction of ``a_max`` the energy term may use.
    centring_frequency : float
        >= 0: cart centring natural frequency as a fraction of ``omega0``.
    centring_damping : float
        >= 0: its damping ratio.
    kick : float
        >= 0: kick rate (leaving rest at the bottom) as a fraction of ``omega0``.
    track_margin : float
        >= 0: m kept from each cart limit.
    brake_accel : float
        In (0, 1]: the rail guard's deceleration as a fraction of ``a_max``.
    barrier_rate : float
        > 0: the guard's rate as a multiple of ``omega0``.
    damping_softening : float
        > 0: ``eps`` of the damping compensation as a fraction of ``omega0`` (``inf``: no compensation).
    centring_band : float
        > 0: energy band of the centring weight as a fraction of ``2 mgl``.
    k_energy, k_x, k_v, a_energy_max, energy_target : float or None
        Explicit SI gains overriding the scaled ones (``k_E`` in (m/s^2)/(J rad/s), centring stiffness 1/s^2 and
        damping 1/s, acceleration limit m/s^2, energy target J); None: scaled from the model.

    Each scaling may go at most :data:`MAX_SCALING` times beyond its default (or beyond 1 for a small default):
    farther it only overflows the law.
    """

    error: ClassVar[type] = EnergyShapingError

    energy_gain: float = 15.0
    overshoot: float = 0.005
    energy_accel: float = 1.0
    centring_frequency: float = 0.6
    centring_damping: float = 1.0
    kick: float = 0.05
    track_margin: float = 0.2
    brake_accel: float = 0.5
    barrier_rate: float = 2.0
    damping_softening: float = 0.3
    centring_band: float = 0.05
    k_energy: float | None = None
    k_x: float | None = None
    k_v: float | None = None
    a_energy_max: float | None = None
    energy_target: float | None = None

    def __post_init__(self):
        ok = {"energy_gain": lambda v: v > 0, "overshoot": lambda v: v >= 0, "energy_accel": lambda v: 0 < v <= 1,
              "centring_frequency": lambda v: v >= 0, "centring_damping": lambda v: v >= 0,
              "kick": lambda v: v >= 0, "track_margin": lambda v: v >= 0, "brake_accel": lambda v: 0 < v <= 1,
              "barrier_rate": lambda v: v > 0, "damping_softening": lambda v: v > 0, "centring_band": lambda v: v > 0}
        defaults = {f.name: f.default for f in dataclasses.fields(self)}
        bad = []
        for k, test in ok.items():
            v = getattr(self, k)
            try:
                f = float(v)
            except (TypeError, ValueError, OverflowError):
                f = math.nan
            # damping_softening = inf is documented: no damping compensation
            if k == "damping_softening" and f == math.inf:
                self.set_field(k, f)
                continue
            if isinstance(v, bool) or not (math.isfinite(f) and test(f)
                                           and abs(f) <= MAX_SCALING * max(defaults[k], 1.0)):
                bad.append(f"{k} = {v!r}")
            else:
                self.set_field(k, f)
        if bad:
            raise EnergyShapingError(f"Energy-shaping setting(s) {', '.join(bad)} out of range: gains must be "
                                     "positive, overshoot and margins non-negative, fractions in (0, 1], none more "
                                     f"than {MAX_SCALING:g} times its default.")
        for k in SI_GAINS:
            v = getattr(self, k)
            if v is not None:
                try:
                    self.set_field(k, float(v))
                except (TypeError, ValueError, OverflowError):
                    raise EnergyShapingError(f"The energy-shaping gain {k} = {v!r} is not a number.") from None

    SCALARS: ClassVar[tuple] = ("energy_gain", "overshoot", "energy_accel", "centring_frequency",
                                "centring_damping", "kick", "track_margin", "brake_accel", "barrier_rate",
                                "damping_softening", "centring_band")

    @property
    def scaling(self) -> dict:
        """The dimensionless scalings (name -> value), as :func:`default_gains` takes them."""
        return {k: getattr(self, k) for k in self.SCALARS}

    @property
    def explicit(self) -> dict:
        """The SI gains set explicitly (name -> value), None ones left out."""
        return {k: getattr(self, k) for k in SI_GAINS if getattr(self, k) is not None}


def energy_options(value=None) -> EnergyOptions:
    """``value`` as :class:`EnergyOptions`: itself, the defaults for None, or a mapping of field names (scalings
    and SI gains) applied to the defaults.

    Raises
    ------
    EnergyShapingError
        An unknown name (the sentence lists the fields) or a value out of range.
    """
    if value is None:
        return EnergyOptions()
    if isinstance(value, EnergyOptions):
        return value
    if not isinstance(value, (dict, types.MappingProxyType)):
        raise EnergyShapingError(f"Energy-shaping settings must be EnergyOptions or a dict; got {value!r}.")
    return EnergyOptions().replace(**dict(value))


#: Dimensionless defaults of :func:`default_gains` (tuned on the shipped asset and checked on the test variants):
#: :class:`EnergyOptions`' scalings.
DEFAULT_SCALING = types.MappingProxyType(EnergyOptions().scaling)


def default_gains(model: CartPoleModel, options: EnergyOptions | None = None, **scaling) -> EnergyGains:
    """Gains scaled by the model's own parameters, so one set of dimensionless numbers fits every cart-pole.

    Parameters
    ----------
    model : CartPoleModel
    options : EnergyOptions, optional
        The scalings (default :class:`EnergyOptions`' defaults; its SI fields are not used here).
    **scaling
        Scalings replacing those of ``options`` by name (any :attr:`EnergyOptions.SCALARS`).

    Returns
    -------
    EnergyGains

    Raises
    ------
    EnergyShapingError
        An unknown or out-of-range setting, or a model whose actuator has no ctrlrange.
    """
    unknown = set(scaling) - set(EnergyOptions.SCALARS)
    if unknown:
        raise EnergyShapingError(f"Unknown energy-shaping setting(s) {sorted(unknown)}; use "
                                 f"{', '.join(EnergyOptions.SCALARS)}.")
    c = energy_options(options).replace(**scaling).scaling
    sc = model_scales(model)
    if not np.isfinite(sc["a_max"]):
        raise EnergyShapingError("The MJCF's actuator has no ctrlrange, so default energy gains cannot be scaled; "
                                 "design on cartpole.models.planning_limits(params) (a stated default bound, or one "
                                 "given as its `u_max`), set ctrlrange on the motor, or pass every gain.")
    wx = c["centring_frequency"] * sc["omega0"]
    return EnergyGains(k_energy=c["energy_gain"] * sc["a_max"] / (2 * sc["mgl"] * sc["omega0"]),
                       k_x=wx**2, k_v=2 * c["centring_damping"] * wx,
                       a_energy_max=c["energy_accel"] * sc["a_max"],
                       energy_target=c["overshoot"] * 2 * sc["mgl"], kick_rate=c["kick"] * sc["omega0"],
                       track_margin=float(c["track_margin"]), a_brake=c["brake_accel"] * sc["a_max"],
                       barrier_rate=c["barrier_rate"] * sc["omega0"],
                       damping_softening=c["damping_softening"] * sc["omega0"],
                       centring_band=c["centring_band"] * 2 * sc["mgl"])


_PRM = ("k_energy", "k_x", "k_v", "a_energy_max", "energy_target", "kick_rate", "track_margin", "a_brake",
        "barrier_rate", "damping_softening", "centring_band")


def _law(model: CartPoleModel) -> ca.Function:
    """CasADi Function ``(x, [EnergyGains fields..., u_lo, u_hi]) -> (ctrl, a_d, E, w)``, built once."""
    si, hi = check_single_pole(model)
    p = model.params
    nq = p.nq
    si_v, hi_v = nq + si, nq + hi  # state indices of the cart velocity and the pole rate
    x = ca.SX.sym("x", 2 * nq)
    prm = ca.SX.sym("prm", len(_PRM) + 2)
    kE, kx, kv, aEmax, Eref, kick, margin, abrake, gamma, eps, band, ulo, uhi = (prm[i] for i in range(len(_PRM) + 2))
    M = model.mass_matrix(x)
    b = model.bias(x)
    # The pole subsystem's energy as its own equation of motion conserves it: the hinge armature's kinetic energy
    # belongs to it (pole_energy counts bodies only), so dE/dt = -D2 theta_dot^2 + m l w a exactly.
    E = model.pole_energy(x) + 0.5 * float(p.armature[hi]) * x[hi_v] ** 2
    D1, D2 = float(p.damping[si]), float(p.damping[hi])
    ml = p.pole_mass * p.pole_com_distance
    s_eq = float(model.x_eq[si])  # centring is towards the equilibrium's cart position
    s_abs, sd, thd_raw = x[si], x[si_v], x[hi_v]
    s = s_abs - s_eq if s_eq else s_abs
    # A pole at rest gives no pumping direction (the hanging state is an equilibrium of the law): replace a pole
    # rate smaller than `kick` by +-kick so the law starts the swing itself instead of waiting for numerical noise.
    thd = ca.if_else(ca.fabs(thd_raw) < kick, ca.if_else(thd_raw < 0, -kick, kick), thd_raw)
    w = -thd * M[hi, si] / ml  # rad/s; direction in which cart acceleration pumps pole energy (hinge sign included)
    w_true = -thd_raw * M[hi, si] / ml
    # Hinge-damping compensation: the power D2 theta_dot^2 put back through the cart, softened where the pole
    # cannot be pumped (w ~ 0) so it stays bounded (at most D2 theta_dot^2 / (2 m l eps)).
    aD = D2 * thd_raw ** 2 * w_true / (ml * (w_true**2 + eps**2))
    aE = ca.fmin(ca.fmax(kE * (Eref - E) * w + aD, -aEmax), aEmax)
    # Cart centring fights the pumping while the energy is far from its target (it needs large cart velocities);
    # weight it by how close the energy is: full strength within ~centring_band of E_ref, fading outside.
    phi = 1 / (1 + ((Eref - E) / band) ** 2)
    a = aE - phi * (kx * s + kv * sd)
    # Track guard, a control barrier function on h = (distance to the limit minus margin) - (stopping distance at
    # a_brake): dh/dt >= -gamma h gives, while moving towards that limit, a <= a_brake (gamma h / |s_dot| - 1).
    big = 1e9
    s_lo = float(p.cart_range[0]) if np.isfinite(p.cart_range[0]) else -big
    s_hi = float(p.cart_range[1]) if np.isfinite(p.cart_range[1]) else big
    h_hi = (s_hi - margin - s_abs) - ca.fmax(sd, 0) ** 2 / (2 * abrake)
    h_lo = (s_abs - s_lo - margin) - ca.fmin(sd, 0) ** 2 / (2 * abrake)
    eps = 1e-9
    a_up = ca.if_else(sd > eps, abrake * (gamma * h_hi / ca.fmax(sd, eps) - 1), big)
    a_dn = ca.if_else(sd < -eps, -abrake * (gamma * h_lo / ca.fmax(-sd, eps) - 1), -big)
    a = ca.fmin(ca.fmax(a, a_dn), a_up)
    # Collocated partial feedback linearisation: the force that gives the cart exactly the acceleration a.
    thdd = (-D2 * thd_raw - b[hi] - M[hi, si] * a) / M[hi, hi]
    force = M[si, si] * a + M[si, hi] * thdd + b[si] + D1 * sd
    u = ca.fmin(ca.fmax(force / p.gear, ulo), uhi)
    return ca.Function("energy_law", [x, prm], [u, a, E, w], ["x", "prm"], ["u", "a", "E", "w"])


class EnergyShapingController:
    """Swing the pole up by pumping its energy to ``E_ref`` through the cart acceleration; ``u = c(t, x)``.

    Parameters
    ----------
    plant : path, CartPoleParams, CartPoleModel or None
        The symbolic model the law inverts (None = shipped asset).
    options : EnergyOptions or dict, optional
        The settings (dimensionless scalings of :func:`default_gains`, optional explicit SI gains ``k_energy``
        (m/s^2)/(J rad/s), ``k_x`` 1/s^2, ``k_v`` 1/s, ``a_energy_max`` m/s^2, ``energy_target`` J), or a dict of
        those fields applied to the defaults (:func:`energy_options`); default :class:`EnergyOptions`' defaults.
    gains : EnergyGains, optional
        Every gain at once (the SI fields of ``options`` still override its fields).

    Attributes
    ----------
    gains : EnergyGains
        The gains in use (SI).
    options : EnergyOptions
        The settings they came from.
    model : CartPoleModel

    Raises
    ------
    EnergyShapingModelError
        For a model that is not one pole on a cart driven by the cart's slide (use ``method='trajopt'``).
    EnergyShapingError
        For bad gains or settings.
    """

    def __init__(self, plant=None, options: EnergyOptions | dict | None = None, *, gains: EnergyGains | None = None):
        self.model = plant_model(plant)
        check_single_pole(self.model)
        self.options = opts = energy_options(options)
        g = gains if gains is not None else default_gains(self.model, opts)
        g = replace(g, **opts.explicit)
        vals = np.array([getattr(g, k) for k in _PRM], dtype=float)
        if np.any(np.isnan(vals)) or g.k_energy <= 0 or g.a_energy_max <= 0 or g.a_brake <= 0 \
                or g.barrier_rate <= 0 or min(g.k_x, g.k_v, g.kick_rate, g.track_margin) < 0:
            bad = [k for k in _PRM if not np.isfinite(getattr(g, k))
                   or (getattr(g, k) <= 0 if k in ("k_energy", "a_energy_max", "a_brake", "barrier_rate")
                       else getattr(g, k) < 0 and k in ("k_x", "k_v", "kick_rate", "track_margin"))]
            raise EnergyShapingError(f"Energy-shaping gain(s) {', '.join(bad) or 'given'} out of range; k_energy, "
                                     "a_energy_max, a_brake and barrier_rate must be positive, k_x, k_v, kick_rate "
                                     "and track_margin non-negative.")
        self.gains = g
        lo, hi = self.model.params.ctrl_range[0]
        self._prm = np.array([*vals, lo, hi], dtype=float)
        self._fun = _law(self.model)

    def __call__(self, t: float, x) -> np.ndarray:
        """ctrl (1,) (clipped to the ctrl range) at time ``t`` (s, unused) for state ``x`` (nx,)."""
        return np.array([float(self._fun(np.asarray(x, dtype=float), self._prm)[0])])

    @property
    def law(self) -> tuple:
        """``(Function, prm)``: the law as a CasADi Function ``(x (nx,), prm) -> (ctrl, a, E, w)`` and its parameter
        vector (gains, then the ctrl range), so ``ctrl = law[0](x, law[1])[0]``; for code generation
        (:mod:`cartpole.export`)."""
        return self._fun, self._prm.copy()

    def evaluate(self, x) -> dict:
        """The law's internals at state ``x`` (nx,): ``ctrl``, desired cart acceleration ``a`` (m/s^2), pole energy
        ``E`` (J) and pumping direction ``w`` (rad/s)."""
        u, a, E, w = self._fun(np.asarray(x, dtype=float), self._prm)
        return {"ctrl": float(u), "a": float(a), "E": float(E), "w": float(w)}

    def pole_energy(self, x) -> float:
        """Pole energy about the hinge in J (0 = upright rest) at state ``x`` (nx,)."""
        return float(self.model.pole_energy(np.asarray(x, dtype=float)))


def energy_rollout(model: CartPoleModel, controller, x0, steps: int, *, u_limits) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~cartpole.control.model_rollout.model_rollout` for a one-input model, its ctrl clipped to ``u_limits``:
    the rollout behind every energy guess.

    Parameters
    ----------
    model : CartPoleModel
        A model with one input (what energy shaping drives).
    controller : callable
        ``(t (s), x (nx,)) -> ctrl`` (scalar or (1,)), e.g. :class:`EnergyShapingController`.
    x0 : (nx,) array
        Start state.
    steps : int
        Number of steps of ``model.dt`` s.
    u_limits : (2,) or (1, 2) array
        ``[low, high]`` ctrl clip.

    Returns
    -------
    x : (steps+1, nx) array
        States, row 0 the start (NaN/inf are not caught: check them where it matters).
    u : (steps,) array
        ctrl applied during each step.
    """
    if model.nu != 1:
        raise EnergyShapingModelError(f"Energy shaping is for one pole driven by the cart and this model has "
                                      f"{model.nu} actuators; use `method='trajopt'` instead.")
    x, u = model_rollout(model, controller, x0, steps, u_limits=np.asarray(u_limits, dtype=float).reshape(1, 2))
    return x, u[:, 0]
