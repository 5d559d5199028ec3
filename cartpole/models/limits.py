"""Bounds a swing-up plans within, for files that leave the motor or the rail unlimited, and starts on a range's edge.

Balancing (LQR, PID, linearisation) needs no bound: a file without ``ctrlrange`` or with an unlimited slide runs
as written. Everything that *plans* a swing-up (energy shaping's gains, trajectory optimisation, NMPC, DDP) needs
a largest force and a longest track: with neither, the optimal swing-up is an infinitely hard kick on an
infinitely long rail. :func:`planning_limits` fills in what the file leaves open with one stated default each,
or with what the caller gives (``u_max``, ``cart_max``; ``--u-max``, ``--cart-max`` on the command line):

* **Force (an actuator without ctrlrange):** ``|ctrl| <= F / |gear|`` where ``F`` is

  - on a slide: the force that accelerates everything the slide moves at one standard gravity,
    ``F = M g0`` (:data:`DEFAULT_FORCE_G` g0; for the lab's cart, 1.1 kg: 10.8 N, about half its motor's 20 N);
  - on a hinge: the torque that holds everything the hinge carries horizontal, ``F = m g0 l`` times
    :data:`DEFAULT_TORQUE_FACTOR` (gravity's largest pull on it: the planners pump a weaker motor's chain up over
    several swings, a much stronger one makes the swing-up trivial).

  ``g0 = 9.80665 m/s^2`` (standard gravity, also under a file whose gravity is off or unusual), so the default is a
  physical force of the model's own scale.
* **Rail (an unlimited cart slide):** ``|s - centre| <= cart_max`` with ``cart_max`` = :data:`DEFAULT_RAIL_LENGTHS`
  times the chain's length ``L`` (twice the distance from the first hinge to the centre of mass of everything it
  carries: the length of a uniform pole with the same mass moment; exact for one or several equal uniform poles).
  The lab's 0.6 m pole on its +-1.5 m rail has 2.5 L; 3 L is a little more room than that, enough for energy
  shaping and the planners at the default force, without licensing an unbounded sprint.

The bounds are applied to the *planning* parameters only: MuJoCo keeps running the file as written, the
controllers clip their ctrl to the bound (so the logged ctrl replays unchanged on the file), and the success check
holds the run to the same bound. Every default used is said in a sentence (:attr:`PlanningLimits.notes`) and in the
JSON (:meth:`PlanningLimits.to_dict`).

:func:`start_on_range` moves a default start that lies just outside a joint range (a hinge limited to +-3.14159
hanging at pi) onto the range's edge and says so.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from cartpole._arrays import readonly
from cartpole.errors import CartPoleError
from cartpole.models.params import CartPoleParams
from cartpole.models.symbolic import build_model

#: Standard gravity g0 in m/s^2: the unit of the default force.
STANDARD_GRAVITY = 9.80665
#: Default force limit of an actuator on a slide without ctrlrange: this many g0 for everything the slide moves.
DEFAULT_FORCE_G = 1.0
#: Default torque limit of an actuator on a hinge without ctrlrange: this factor times the torque ``m g0 l`` that
#: holds everything the hinge carries horizontal.
DEFAULT_TORQUE_FACTOR = 1.0
#: Default half-length of an unlimited cart rail: this many chain lengths either side of the centre.
DEFAULT_RAIL_LENGTHS = 3.0
#: Farthest a default start may lie outside a joint's range and still be moved onto its edge (rad or m).
START_SNAP = 1e-3


class LimitsError(CartPoleError, ValueError):
    """A bound given for the plan that MuJoCo would not honour (wider than the file's own) or that is not a
    positive finite number."""


@dataclass(frozen=True)
class PlanningLimits:
    """The ctrl and rail bounds a swing-up plans within, and where each came from.

    Attributes
    ----------
    u_low, u_high : (nu,) arrays
        ``u_low <= ctrl <= u_high`` per actuator (MuJoCo ctrl), finite.
    u_source : tuple of str
        Per actuator: ``"file"`` (its ctrlrange), ``"default"`` (no ctrlrange: :func:`default_u_max`) or
        ``"u_max"`` (given).
    actuator_names : tuple of str
    cart_range : (2,) array or None
        ``[low, high]`` in m of the cart's slide the plan and the success check keep to; None without a cart.
    cart_source : str or None
        ``"file"``, ``"default"`` (unlimited in the file: :func:`default_cart_max`) or ``"cart_max"`` (given).
    chain_length : float
        ``L`` in m, the chain length the default rail is measured in (0 without a hinge).
    basis : tuple of str
        Per actuator, what a default bound is (e.g. ``"10.79 N: 1 g0 on the 1.1 kg the slide moves, through gear
        20"``); "" where the bound is not a default.
    """

    u_low: np.ndarray
    u_high: np.ndarray
    u_source: tuple
    actuator_names: tuple
    cart_range: np.ndarray | None
    cart_source: str | None
    chain_length: float = 0.0
    basis: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "u_low", readonly(np.atleast_1d(self.u_low)))
        object.__setattr__(self, "u_high", readonly(np.atleast_1d(self.u_high)))
        if self.cart_range is not None:
            object.__setattr__(self, "cart_range", readonly(self.cart_range))

    @property
    def defaulted(self) -> bool:
        """True when any bound is a default rather than the file's or the caller's."""
        return "default" in self.u_source or self.cart_source == "default"

    @property
    def notes(self) -> tuple:
        """One sentence per default used (empty when every bound is the file's or given)."""
        out = []
        for i, src in enumerate(self.u_source):
            if src == "default":
                out.append(f"Actuator '{self.actuator_names[i]}' has no ctrlrange in the MJCF, so the swing-up plans "
                           f"within the default |ctrl| <= {self.u_high[i]:.4g} ({self.basis[i]}); give --u-max "
                           "(u_max in Python) to choose another bound.")
        if self.cart_source == "default":
            half = 0.5 * float(self.cart_range[1] - self.cart_range[0])
            out.append(f"The cart's slide is unlimited in the MJCF, so the swing-up keeps the cart within the default "
                       f"+-{half:.4g} m ({DEFAULT_RAIL_LENGTHS:g} chain lengths of {self.chain_length:.4g} m); give "
                       "--cart-max (cart_max in Python) to choose another rail.")
        return tuple(out)

    def to_dict(self) -> dict:
        """JSON form: ``u_low``, ``u_high``, ``u_source``, ``cart_range``, ``cart_source``, ``defaulted``,
        ``notes``."""
        return {"u_low": self.u_low.tolist(), "u_high": self.u_high.tolist(), "u_source": list(self.u_source),
                "cart_range": None if self.cart_range is None else self.cart_range.tolist(),
                "cart_source": self.cart_source, "chain_length": self.chain_length, "defaulted": self.defaulted,
                "notes": list(self.notes)}


def chain_length(params: CartPoleParams) -> float:
    """Length ``L`` in m of the chain on the first hinge: twice the distance from its axis to the centre of mass of
    everything it carries (a uniform pole's length; 0 without a hinge or mass).

    Parameters
    ----------
    params : CartPoleParams

    Returns
    -------
    float
    """
    if not params.hinges:
        return 0.0
    return 2.0 * float(params.carried_by(params.hinges[0])[1])


def default_u_max(params: CartPoleParams) -> np.ndarray:
    """Default ``|ctrl|`` bound per actuator (nu,): force ``DEFAULT_FORCE_G g0 M`` on a slide (``M`` the mass the
    slide moves), torque ``DEFAULT_TORQUE_FACTOR m g0 l`` on a hinge (``m``, ``l`` what it carries and its centre of
    mass's distance from the axis), divided by ``|gear|`` (N or N m per unit ctrl). 1 where that is zero.

    Parameters
    ----------
    params : CartPoleParams

    Returns
    -------
    (nu,) float array
    """
    return _default_u_max(params)[0]


def _default_u_max(params: CartPoleParams) -> tuple[np.ndarray, tuple]:
    """:func:`default_u_max` and, per actuator, the sentence fragment saying what it is."""
    out, words = np.ones(params.nu), []
    for k, a in enumerate(params.actuators):
        joint = params.joints[a.joint]
        if joint.kind == "slide":
            mass = sum(params.bodies[b].mass for b in params.subtree(joint.body))
            force = DEFAULT_FORCE_G * STANDARD_GRAVITY * mass
            what = (f"{force:.4g} N: {DEFAULT_FORCE_G:g} g0 on the {mass:.4g} kg slide '{joint.name}' moves, "
                    f"through gear {a.gear:g}")
        else:
            m, l, _ = params.carried_by(a.joint)
            force = DEFAULT_TORQUE_FACTOR * m * STANDARD_GRAVITY * l
            what = (f"{force:.4g} N m: {DEFAULT_TORQUE_FACTOR:g} x the torque holding the {m:.4g} kg hinge "
                    f"'{joint.name}' carries horizontal at {l:.4g} m, through gear {a.gear:g}")
        if force > 0 and abs(a.gear) > 0:
            out[k] = _stated(force / abs(a.gear))
        else:
            what = "ctrl 1: the actuator has no gear or carries no mass"
        words.append(what)
    return out, tuple(words)


def _stated(value: float) -> float:
    """``value`` rounded to the 4 significant digits the sentence states, then to a float32 number (so a float32
    controller's clip lands exactly on the bound a double check holds it to)."""
    return float(np.float32(float(f"{value:.4g}")))


def default_cart_max(params: CartPoleParams) -> float:
    """Default half-length in m of an unlimited cart rail: ``DEFAULT_RAIL_LENGTHS`` x :func:`chain_length` (1 m
    when the chain has no length).

    Parameters
    ----------
    params : CartPoleParams

    Returns
    -------
    float
    """
    L = chain_length(params)
    return _stated(DEFAULT_RAIL_LENGTHS * L) if L > 0 else 1.0


def _positive(value, name: str, unit: str) -> np.ndarray:
    v = np.asarray(value, float)
    if not (v.size and np.all(np.isfinite(v)) and np.all(v > 0)):
        raise LimitsError(f"{name} = {np.ravel(v).tolist()} {unit} is not a positive finite bound; give `{name}` a "
                          "positive number.")
    return v


def planning_limits(params: CartPoleParams, *, u_max=None, cart_max: float | None = None
                    ) -> tuple[CartPoleParams, PlanningLimits]:
    """The parameters a swing-up plans with: every unlimited actuator and an unlimited cart rail bounded.

    Parameters
    ----------
    params : CartPoleParams
        As read from the file (MuJoCo keeps running the file itself).
    u_max : float or (nu,) array, optional
        ``|ctrl| <= u_max`` for every actuator (replacing the file's ctrlrange, which must contain it: MuJoCo clamps
        to the file's); default the file's ctrlrange, or :func:`default_u_max` where it has none.
    cart_max : float, optional
        m: the cart keeps ``|s - centre| <= cart_max`` (centre: the middle of the file's slide range, 0 when
        unlimited; inside the file's range); default the file's range, or :func:`default_cart_max` when unlimited.

    Returns
    -------
    params : CartPoleParams
        ``params`` with finite ``ctrl_range`` on every actuator and a finite range on the cart's slide (the same
        object when nothing changed).
    limits : PlanningLimits
        The bounds and their sources (its :attr:`~PlanningLimits.notes` say every default used).

    Raises
    ------
    LimitsError
        ``u_max`` or ``cart_max`` not positive and finite, ``u_max`` of the wrong size, or wider than the file's own
        ctrlrange or slide range; ``cart_max`` for a model without a cart.
    """
    names = tuple(a.name or f"#{i}" for i, a in enumerate(params.actuators))
    rng = np.asarray(params.ctrl_range, float).reshape(params.nu, 2).copy()
    source = []
    if u_max is not None:
        u = _positive(u_max, "u_max", "(ctrl)")
        if u.size not in (1, params.nu):
            raise LimitsError(f"u_max has {u.size} values and the model has {params.nu} actuator(s); give `u_max` one "
                              f"number or one per actuator ({', '.join(names)}).")
        u = np.broadcast_to(u.ravel(), (params.nu,))
        for i in range(params.nu):
            if -u[i] < rng[i, 0] or u[i] > rng[i, 1]:
                raise LimitsError(f"u_max = {u[i]:g} is wider than actuator '{names[i]}''s ctrlrange "
                                  f"[{rng[i, 0]:g}, {rng[i, 1]:g}] in the MJCF, where MuJoCo clamps the ctrl; give "
                                  f"`u_max` at most {min(-rng[i, 0], rng[i, 1]):g} or widen the ctrlrange.")
            rng[i] = (-u[i], u[i])
        source = ["u_max"] * params.nu
    basis = [""] * params.nu
    if u_max is None:
        dflt = None
        for i in range(params.nu):
            if np.all(np.isfinite(rng[i])):
                source.append("file")
                continue
            dflt = _default_u_max(params) if dflt is None else dflt
            basis[i] = dflt[1][i]
            dflt_u = dflt[0]
            lo, hi = rng[i]
            rng[i] = (lo if np.isfinite(lo) else -dflt_u[i], hi if np.isfinite(hi) else dflt_u[i])
            source.append("default")
    joints = list(params.joints)
    cart_range, cart_source = None, None
    if params.slide is None and cart_max is not None:
        raise LimitsError("`cart_max` bounds the cart's travel and this model has no slide joint; drop it.")
    if params.slide is not None:
        lo, hi = (float(v) for v in params.cart_range)
        limited = np.isfinite(lo) and np.isfinite(hi)
        centre = 0.5 * (lo + hi) if limited else 0.0
        if cart_max is not None:
            c = float(_positive(cart_max, "cart_max", "m").ravel()[0])
            if centre - c < lo or centre + c > hi:
                raise LimitsError(f"cart_max = {c:g} m is wider than the cart's slide range [{lo:g}, {hi:g}] m in the "
                                  f"MJCF, where MuJoCo stops the cart; give `cart_max` at most {0.5 * (hi - lo):g} "
                                  "or widen the range.")
            cart_range, cart_source = np.array([centre - c, centre + c]), "cart_max"
        elif limited:
            cart_range, cart_source = np.array([lo, hi]), "file"
        else:
            c = default_cart_max(params)
            cart_range = np.array([lo if np.isfinite(lo) else centre - c, hi if np.isfinite(hi) else centre + c])
            cart_source = "default"
        joints[params.slide] = dataclasses.replace(joints[params.slide], range=readonly(cart_range))
    limits = PlanningLimits(u_low=rng[:, 0], u_high=rng[:, 1], u_source=tuple(source), actuator_names=names,
                            cart_range=cart_range, cart_source=cart_source, chain_length=chain_length(params),
                            basis=tuple(basis))
    changed = not np.array_equal(rng, np.asarray(params.ctrl_range, float).reshape(params.nu, 2)) or (
        params.slide is not None and not np.array_equal(cart_range, np.asarray(params.cart_range, float)))
    if not changed:
        return params, limits
    actuators = tuple(dataclasses.replace(a, ctrl_range=readonly(rng[i])) for i, a in enumerate(params.actuators))
    return dataclasses.replace(params, actuators=actuators, joints=tuple(joints)), limits


def bounded_model(model, limits: PlanningLimits):
    """``model`` (a :class:`~cartpole.models.CartPoleModel`, e.g. a planning model read from another file) with the
    ctrl and cart bounds of ``limits`` (same actuators and cart), rebuilt only where they differ.

    Parameters
    ----------
    model : CartPoleModel
    limits : PlanningLimits

    Returns
    -------
    CartPoleModel
    """
    p = model.params
    rng = np.column_stack([limits.u_low, limits.u_high])
    same_u = p.nu == rng.shape[0] and np.array_equal(np.asarray(p.ctrl_range, float).reshape(p.nu, 2), rng)
    same_cart = p.slide is None or limits.cart_range is None or np.array_equal(p.cart_range, limits.cart_range)
    if same_u and same_cart:
        return model
    actuators = tuple(dataclasses.replace(a, ctrl_range=readonly(rng[i])) if i < rng.shape[0] else a
                      for i, a in enumerate(p.actuators))
    joints = list(p.joints)
    if not same_cart:
        joints[p.slide] = dataclasses.replace(joints[p.slide], range=readonly(limits.cart_range))
    return build_model(dataclasses.replace(p, actuators=actuators, joints=tuple(joints)))


@dataclass(frozen=True)
class MotorDrive:
    """One actuator as a law that pushes its joint one way or the other sees it (:func:`motor_drive`).

    Attributes
    ----------
    joint : int
        qpos index of the joint it drives.
    sign : float
        +1 or -1: the sign of the ctrl that pushes that joint forward (its gear's; +1 for a zero gear).
    low, high : float
        Its ctrl range (MuJoCo ctrl; ``-inf``, ``inf`` when unlimited).
    """

    joint: int
    sign: float
    low: float
    high: float

    @property
    def mid(self) -> float:
        """The ctrl range's middle, ``(low + high) / 2``."""
        return 0.5 * (self.low + self.high)

    @property
    def half(self) -> float:
        """The ctrl range's half-width, ``(high - low) / 2``."""
        return 0.5 * (self.high - self.low)

    @property
    def limited(self) -> bool:
        """True when both ends of the ctrl range are finite."""
        return bool(np.isfinite(self.low) and np.isfinite(self.high))


def motor_drive(params: CartPoleParams, u_limits=None, *, actuator: int = 0) -> MotorDrive:
    """The joint actuator ``actuator`` drives, the ctrl sign that pushes it forward and the ctrl range to push within.

    Parameters
    ----------
    params : CartPoleParams
    u_limits : (nu, 2) array, optional
        ``[low, high]`` ctrl per actuator a law clips to (e.g. a catch's ``u_limits``, or :func:`planning_limits`');
        default the file's ``ctrl_range``.
    actuator : int
        Which actuator (ctrl index); default the first.

    Returns
    -------
    MotorDrive

    Raises
    ------
    LimitsError
        ``actuator`` not one of the model's, or ``u_limits`` not one ``[low, high]`` pair per actuator.
    """
    if not (isinstance(actuator, (int, np.integer)) and 0 <= actuator < params.nu):
        raise LimitsError(f"actuator = {actuator!r} is not one of this model's {params.nu} actuator(s); give "
                          f"`actuator` a ctrl index from 0 to {params.nu - 1}.")
    lims = np.asarray(params.ctrl_range if u_limits is None else u_limits, dtype=float)
    if lims.size != 2 * params.nu:
        raise LimitsError(f"u_limits has {lims.size} values and the model has {params.nu} actuator(s); give "
                          "`u_limits` one [low, high] pair of ctrl per actuator.")
    low, high = (float(v) for v in lims.reshape(params.nu, 2)[actuator])
    gear = float(params.actuators[actuator].gear)
    return MotorDrive(joint=int(params.actuated[actuator]), sign=float(np.sign(gear) or 1.0), low=low, high=high)


@dataclass(frozen=True)
class StartMove:
    """A default start moved onto a joint range's edge: ``joint`` (name), ``index`` (qpos), ``before`` and
    ``after`` (rad or m), ``unit``."""

    joint: str
    index: int
    before: float
    after: float
    unit: str

    def sentence(self) -> str:
        """The note said in prose and JSON."""
        return (f"The default start {self.before:.9g} {self.unit} of joint '{self.joint}' lies "
                f"{abs(self.after - self.before):.2g} {self.unit} outside its range in the MJCF, so it starts on the "
                f"range's edge, {self.after:.9g} {self.unit}; give --x0 to start elsewhere.")

    def to_dict(self) -> dict:
        """JSON form (``joint``, ``index``, ``before``, ``after``, ``unit``, ``note``)."""
        return {"joint": self.joint, "index": self.index, "before": self.before, "after": self.after,
                "unit": self.unit, "note": self.sentence()}


def start_on_range(x0, params: CartPoleParams, *, tol: float = START_SNAP) -> tuple[np.ndarray, tuple]:
    """A default start with each joint position that lies outside its range by at most ``tol`` moved onto the
    range's edge (a slide strictly inside: ``tol / 10`` in from its end, as starts must be).

    Parameters
    ----------
    x0 : (2 nq,) array
        ``[qpos, qvel]``.
    params : CartPoleParams
    tol : float
        rad (hinges) or m (slides), default :data:`START_SNAP`.

    Returns
    -------
    x : (2 nq,) float array
        The start, moved where needed (farther out positions are left as they are, for the start check to refuse).
    moves : tuple of StartMove
    """
    x = np.array(x0, float).ravel()
    moves = []
    for i, j in enumerate(params.joints):
        lo, hi = (float(v) for v in j.range)
        inset = tol / 10 if j.kind == "slide" else 0.0
        unit = "m" if j.kind == "slide" else "rad"
        slide = j.kind == "slide"  # a slide's start must lie strictly inside its range, a hinge's may be on its end
        after = None
        if np.isfinite(lo) and lo - tol <= x[i] and (x[i] < lo or (slide and x[i] == lo)):
            after = lo + inset
        elif np.isfinite(hi) and x[i] <= hi + tol and (x[i] > hi or (slide and x[i] == hi)):
            after = hi - inset
        if after is not None:
            moves.append(StartMove(joint=j.name, index=i, before=float(x[i]), after=float(after), unit=unit))
            x[i] = after
    return x, tuple(moves)
