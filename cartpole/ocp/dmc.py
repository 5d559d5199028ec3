"""The dm_control suite's cart-pole, pendulum and acrobot tasks on the toolkit's models: rewards and episodes.

Read from dm_control's source (google-deepmind/dm_control; it cannot be imported beside MuJoCo 4, see the design
notes), each task's reward is written here **once**, as a CasADi SX expression of ``x = [qpos, qvel]`` (nx,) and
``u`` = ctrl (nu,), in two forms of one function (:func:`reward_expression`):

* ``exact=True``: dm_control's reward, sparse indicators included, with ``dm_control/utils/rewards.py``'s
  ``tolerance`` and ``_sigmoids`` transcribed to CasADi (:func:`tolerance`). Scoring evaluates it numerically
  (:func:`reward_function`, built once per model and task and kept).
* ``exact=False``: what the planner optimises. Where dm_control's reward is smooth it is the same reward (the
  cart-pole's quadratic control tolerance unclipped, ``1 - u_0^2``, equal inside ``|u_0| <= 1`` which the OCP's
  ctrl bounds hold on dm_control's files; the acrobot's distance with a ``1e-12 m^2`` floor under its square root
  so its derivative exists at the target; on two or more poles the minimum of the rates' tolerances a
  :func:`smooth_min`). Where it is sparse (``dmc_cartpole_swingup_sparse``,
  ``dmc_pendulum_swingup``) it is a smooth surrogate (:data:`SURROGATE_SIGMOID`): ``tolerance`` toward the centre
  of the task's box with a margin of the box's width, 1 at the centre and decaying smoothly, through the box's edge,
  outside. Both acrobot tasks plan on one surrogate (:data:`ACROBOT_INPUT_WEIGHT`): the smooth task's distance
  tolerance with the ``long_tail`` sigmoid in place of its gaussian, less a small input cost. The smooth task's own
  gaussian is flat from where the acrobot hangs (the tip 3.8 m beyond the target's 0.2 m: ``exp(-33)``, about
  1e-15, gradient alike), so for a planner it is as sparse as the indicator.

The quantities dm_control reads from MuJoCo are computed from the model by name, never by literal index:

* a pole's angle cosine (dm_control: the body's ``xmat`` ``zz``): ``cos phi_i`` with ``phi_i`` the sum of the hinge
  errors from the upright ``x*`` along the chain up to hinge ``i`` (hinge axes parallel, as in dm_control's files,
  where ``x* = 0`` and this is exactly ``zz``);
* the cart position (``qpos['slider']``): the model's slide; the angular velocities (``qvel[1:]``): the hinges'
  rates; the control (``physics.control()[0]``): the first actuator's ctrl;
* the acrobot's tip and target (``site_xpos['tip']``, ``site_xpos['target']``, ``site_size['target', 0]``): the
  MJCF's sites named ``tip`` and ``target``, placed by the model's forward kinematics
  (:func:`cartpole.models.kinematics.forward_kinematics`).

A task on a model that lacks what it needs (a cart-pole task without a cart, the acrobot without its sites) is
refused in one sentence (:class:`DMCError`).

Episodes (:class:`Task`): dm_control's ``control.Environment`` holds each action for ``n_sub_steps`` physics steps
(1 for these tasks: none passes a ``control_timestep``), for ``time_limit / control_timestep`` control steps (1000:
cart-pole and acrobot 10 s at 0.01 s, pendulum 20 s at 0.02 s), and pays after every control step the reward of
the state reached and the action held. Each episode starts from ``mj_resetData`` (``qpos0``, zero velocity) changed
by the task's ``initialize_episode`` with the task's ``numpy.random.RandomState`` (:func:`episode_starts`).
"""
from __future__ import annotations

import functools
import weakref
from dataclasses import dataclass

import casadi as ca
import mujoco
import numpy as np

from cartpole.models import forward_kinematics, load_model
from cartpole.ocp.bounds import OCPError

#: dm_control's ``_DEFAULT_VALUE_AT_MARGIN`` of ``rewards.tolerance``.
VALUE_AT_MARGIN = 0.1

#: The planning surrogates of the sparse rewards: dm_control's ``tolerance`` toward the centre of the task's box
#: (the cart position 0, a cosine's 1), with the ``long_tail`` sigmoid (``1 / (1 + (d s)^2)``: a gradient toward
#: the box from anywhere) and the box's own width as margin (its half-width for the cart, ``1 - lower`` for a
#: cosine), so the surrogate is ``value_at_margin`` (0.1) at the box's edge and 1 only at its centre. A surrogate
#: that is 1 on the whole box (its edges flat) was measured to let the plan rest just outside the cart-pole's
#: narrow angle bound (cos 0.995: 5.7 degrees), where the exact reward is 0; this one pulls it in. The acrobot's tip
#: distance keeps the smooth acrobot task's bounds (within the target's radius) and margin (1 m).
SURROGATE_SIGMOID = "long_tail"
SURROGATE_DISTANCE_MARGIN = 1.0

#: Weight of ``u'u`` (ctrl^2) subtracted from the acrobot's planning surrogate (dm_control's acrobot reward has no
#: input term). Far from the target the reward's curvature is nearly zero, so without it the input Hessian of the
#: plan (DDP's ``Q_uu``) is only the solver's regularisation. It costs at most 1e-3 a step of the return's 1 (the
#: ctrl range is +-1). Chosen among 0, 1e-4, 1e-3 and 1e-2 by the DDP MPC's mean return over dm_control's first 10
#: acrobot episodes of seed 0, then checked on seeds 1 and 2 (the docs' dm_control page).
ACROBOT_INPUT_WEIGHT = 1e-3

#: Floor under the acrobot's squared tip distance in the planning form (m^2): the distance's derivative at the target.
DISTANCE_FLOOR = 1e-12

#: Width of :func:`smooth_min`, the planning form's minimum of the cart-pole's rate tolerances on two or more poles
#: (each in [0, 1]): each pair's is below their minimum by at most half of it, so the planned reward is below the
#: exact one by at most 1.25 % for each pole beyond the first (the minimum enters as ``(1 + m) / 2``). dm_control's ``min`` has a kink wherever two poles' tolerances
#: cross, and a Newton-type solver stalls on it: the SQP on the shipped two-pole cart's running stage (the planner's
#: minimum-time plan, then rest, over ``T_min + 1.5 s``) ended 300 iterations at a stationarity of 1.7e-4 (IPOPT
#: unconverged after 500).
SMOOTH_MIN_WIDTH = 0.05


class DMCError(OCPError):
    """A dm_control task asked of a model that lacks what its reward or its episodes need (one sentence)."""


@dataclass(frozen=True)
class Task:
    """One dm_control suite task as this toolkit runs it.

    Attributes
    ----------
    name : str
        The objective's name, ``dmc_<domain>_<task>``.
    domain, task : str
        dm_control's domain (``cartpole``, ``pendulum``, ``acrobot``) and task (``swingup``, ``swingup_sparse``,
        ``balance``): ``suite.load(domain, task)``.
    sparse : bool
        dm_control's reward is an indicator (the planner optimises a smooth surrogate of it).
    time_limit : float
        dm_control's ``_DEFAULT_TIME_LIMIT`` in s.
    n_sub_steps : int
        Physics steps per control step (dm_control's default 1: no task sets a ``control_timestep``).
    source : str
        Where dm_control defines the reward and the start (file and functions).
    """

    name: str
    domain: str
    task: str
    sparse: bool
    time_limit: float
    n_sub_steps: int
    source: str

    def control_dt(self, timestep: float) -> float:
        """The control step in s on a file whose physics step is ``timestep`` s."""
        return self.n_sub_steps * float(timestep)

    def steps(self, timestep: float) -> int:
        """Control steps of one episode (``time_limit / control_dt``, dm_control's ``_step_limit``): 1000 on
        dm_control's own files."""
        return int(round(self.time_limit / self.control_dt(timestep)))


_CARTPOLE = "dm_control/suite/cartpole.py (Balance._get_reward, Balance.initialize_episode)"
_PENDULUM = "dm_control/suite/pendulum.py (SwingUp.get_reward, SwingUp.initialize_episode)"
_ACROBOT = "dm_control/suite/acrobot.py (Balance._get_reward, Balance.initialize_episode)"

#: The tasks by objective name.
TASKS = {t.name: t for t in (
    Task("dmc_cartpole_swingup", "cartpole", "swingup", False, 10.0, 1, _CARTPOLE),
    Task("dmc_cartpole_swingup_sparse", "cartpole", "swingup_sparse", True, 10.0, 1, _CARTPOLE),
    Task("dmc_cartpole_balance", "cartpole", "balance", False, 10.0, 1, _CARTPOLE),
    Task("dmc_cartpole_balance_sparse", "cartpole", "balance_sparse", True, 10.0, 1, _CARTPOLE),
    Task("dmc_pendulum_swingup", "pendulum", "swingup", True, 20.0, 1, _PENDULUM),
    Task("dmc_acrobot_swingup", "acrobot", "swingup", False, 10.0, 1, _ACROBOT),
    Task("dmc_acrobot_swingup_sparse", "acrobot", "swingup_sparse", True, 10.0, 1, _ACROBOT),
)}

#: Older names kept working: ``dmc_swingup`` is ``dmc_cartpole_swingup``.
ALIASES = {"dmc_swingup": "dmc_cartpole_swingup"}


def task(name: str) -> Task:
    """The :class:`Task` of an objective name (an alias of :data:`ALIASES` resolved).

    Raises
    ------
    DMCError
        Not a dm_control task's name.
    """
    t = TASKS.get(ALIASES.get(name, name))
    if t is None:
        raise DMCError(f"'{name}' is not a dm_control task; choose one of {', '.join(TASKS)}.")
    return t


def is_task(name) -> bool:
    """True when ``name`` (any object) is a dm_control task's objective name or alias."""
    return isinstance(name, str) and ALIASES.get(name, name) in TASKS


def is_sparse_task(name) -> bool:
    """True when ``name`` (any object: an objective's name, an objective, None) is the objective name or alias of a
    dm_control task whose reward is sparse (an indicator, :attr:`Task.sparse`: it pays in the box of
    :func:`sparse_box`, which the planners enter by :mod:`cartpole.planning.box_entry`); False for anything else."""
    return is_task(name) and task(name).sparse


# ---- dm_control/utils/rewards.py, transcribed to CasADi ----------------------------------------------------
def _sigmoids(x, value_at_1: float, sigmoid: str):
    """``rewards._sigmoids``: 1 at ``x = 0``, ``value_at_1`` at ``x = 1``, in [0, 1] (``x`` a CasADi expression)."""
    if sigmoid in ("cosine", "linear", "quadratic"):
        if not 0 <= value_at_1 < 1:
            raise ValueError(f"value_at_1 must be nonnegative and smaller than 1, got {value_at_1}.")
    elif not 0 < value_at_1 < 1:
        raise ValueError(f"value_at_1 must be strictly between 0 and 1, got {value_at_1}.")
    if sigmoid == "gaussian":
        scale = np.sqrt(-2 * np.log(value_at_1))
        return ca.exp(-0.5 * (x * scale) ** 2)
    if sigmoid == "hyperbolic":
        scale = np.arccosh(1 / value_at_1)
        return 1 / ca.cosh(x * scale)
    if sigmoid == "long_tail":
        scale = np.sqrt(1 / value_at_1 - 1)
        return 1 / ((x * scale) ** 2 + 1)
    if sigmoid == "reciprocal":
        scale = 1 / value_at_1 - 1
        return 1 / (ca.fabs(x) * scale + 1)
    if sigmoid == "cosine":
        s = x * (np.arccos(2 * value_at_1 - 1) / np.pi)
        return ca.if_else(ca.fabs(s) < 1, (1 + ca.cos(np.pi * s)) / 2, 0.0)
    if sigmoid == "linear":
        s = x * (1 - value_at_1)
        return ca.if_else(ca.fabs(s) < 1, 1 - s, 0.0)
    if sigmoid == "quadratic":
        s = x * np.sqrt(1 - value_at_1)
        return ca.if_else(ca.fabs(s) < 1, 1 - s**2, 0.0)
    if sigmoid == "tanh_squared":
        scale = np.arctanh(np.sqrt(1 - value_at_1))
        return 1 - ca.tanh(x * scale) ** 2
    raise ValueError(f"Unknown sigmoid type {sigmoid!r}.")


def tolerance(x, bounds=(0.0, 0.0), margin: float = 0.0, sigmoid: str = "gaussian",
              value_at_margin: float = VALUE_AT_MARGIN):
    """dm_control's ``rewards.tolerance`` on a CasADi expression ``x`` (scalar): 1 inside ``bounds`` (inclusive,
    may be infinite), outside it ``0`` when ``margin == 0``, else ``_sigmoids(distance / margin, value_at_margin,
    sigmoid)`` (``value_at_margin`` at ``margin`` from the nearest bound). Same checks and sentences as
    dm_control's (``ValueError``); the result is a CasADi expression in [0, 1].

    Bounds that are one point (``lower == upper``, e.g. dm_control's default ``(0, 0)``) with a margin: the same
    values, written as the sigmoid of the signed distance, with no "in bounds" branch. dm_control's branch is the
    point itself, whose constant 1 has no derivatives, so a planner's Hessian at an iterate exactly there (a guess with
    the cart at 0, rates at rest) would miss the sigmoid's curvature; the even sigmoids take the signed distance (the
    same value, smooth through the point), ``linear`` and ``reciprocal`` its magnitude (their kink is dm_control's)."""
    lower, upper = bounds
    if lower > upper:
        raise ValueError("Lower bound must be <= upper bound.")
    if margin < 0:
        raise ValueError("`margin` must be non-negative.")
    in_bounds = ca.logic_and(x >= lower, x <= upper)
    if margin == 0:
        return ca.if_else(in_bounds, 1.0, 0.0)
    if lower == upper and np.isfinite(lower):
        d = (x - lower) / margin
        return _sigmoids(ca.fabs(d) if sigmoid in ("linear", "reciprocal") else d, value_at_margin, sigmoid)
    d = ca.if_else(x < lower, lower - x, x - upper) / margin
    return ca.if_else(in_bounds, 1.0, _sigmoids(d, value_at_margin, sigmoid))


# ---- what each domain reads from MuJoCo, from the model by name ---------------------------------------------
def _pole_cosines(model, x) -> list:
    """Each hinge body's angle cosine from upright (dm_control's ``xmat[pole, 'zz']``), chain order."""
    x_eq = np.asarray(model.x_eq, float)
    phi, out = 0, []
    for h in model.hinges:
        phi = phi + (x[h] - x_eq[h])
        out.append(ca.cos(phi))
    return out


def site(params, name: str):
    """The MJCF's site ``name`` as the task's expressions use it.

    Parameters
    ----------
    params : CartPoleParams
        The model read from the MJCF (or URDF) that has the site.
    name : str
        The site's name (e.g. ``"tip"``, ``"target"``).

    Returns
    -------
    tuple or None
        ``(body index or -1, position (3,) in m in that body's frame (in the world for -1), size (3,) in m)``, or None
        when the file has no such site.
    """
    mjcf = params.mjcf if params.urdf is None else ""  # a URDF's params: their MJCF text
    return _sites(mjcf, params.xml, tuple(b.name for b in params.bodies)).get(name)


@functools.lru_cache(maxsize=32)
def _sites(mjcf: str, xml: str, bodies: tuple) -> dict:
    """Every named site of the MJCF (compiled once per file and text) as :func:`site` describes it."""
    m, _, _ = load_model(mjcf or None, xml=None if mjcf else xml)
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)  # a site on the world or on a body welded to it: its world position at qpos0
    out = {}
    for sid in range(m.nsite):
        name = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_SITE, sid)
        if not name:
            continue
        b = int(m.site_bodyid[sid])
        bname = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b) or ""
        if bname in bodies and m.body_weldid[b] != 0:
            out[name] = (bodies.index(bname), np.array(m.site_pos[sid], float), np.array(m.site_size[sid], float))
        else:
            out[name] = (-1, np.array(d.site_xpos[sid], float), np.array(m.site_size[sid], float))
    return out


def site_world(params, where, q):
    """A site's world position as a CasADi expression of the configuration.

    Parameters
    ----------
    params : CartPoleParams
    where : tuple
        The site, as :func:`site` returns it.
    q : SX or DM (nq,)
        The configuration (qpos).

    Returns
    -------
    SX or DM (3, 1)
        The site's world position in m.
    """
    body, pos, _ = where
    if body < 0:
        return ca.DM(pos.reshape(3, 1))
    k = forward_kinematics(params, q)
    R = k.rotation[body]
    origin = k.com[body] - ca.mtimes(R, ca.DM(np.reshape(params.bodies[body].ipos, (3, 1))))
    return origin + ca.mtimes(R, ca.DM(pos.reshape(3, 1)))


def check_model(model, name: str) -> Task:
    """The :class:`Task` ``name`` after checking that ``model`` has what its reward and its starts need.

    Cart-pole tasks: a cart (a slide joint) carrying at least one hinge, and an actuator. Pendulum: one hinge
    and no cart. Acrobot: at least two hinges, no cart, and sites named ``tip`` and ``target`` (dm_control's
    ``acrobot.xml``; ``cartpole/assets/dmc_acrobot.xml`` has both).

    Raises
    ------
    DMCError
        One sentence naming what is missing.
    """
    t = task(name)
    p = model.params
    what = f"The {t.name} objective (dm_control's {t.domain} {t.task})"
    if model.nu < 1:
        raise DMCError(f"{what} needs an actuator; the MJCF has none.")
    if t.domain == "cartpole" and (model.slide is None or not model.hinges):
        raise DMCError(f"{what} needs a cart (a slide joint) carrying at least one pole hinge; the MJCF has "
                       f"{len(model.slides)} slide and {len(model.hinges)} hinge joints.")
    if t.domain == "pendulum" and (model.slides or len(model.hinges) != 1):
        raise DMCError(f"{what} needs a single hinge without a cart; the MJCF has {len(model.slides)} slide and "
                       f"{len(model.hinges)} hinge joints.")
    if t.domain == "acrobot":
        if model.slides or len(model.hinges) < 2:
            raise DMCError(f"{what} needs a chain of at least two hinges without a cart; the MJCF has "
                           f"{len(model.slides)} slide and {len(model.hinges)} hinge joints.")
        missing = [s for s in ("tip", "target") if site(p, s) is None]
        if missing:
            raise DMCError(f"{what} measures the distance from the site 'tip' to the site 'target' (as dm_control's "
                           f"acrobot.xml); the MJCF has no site named {' or '.join(repr(s) for s in missing)}.")
    return t


def smooth_min(a, b, width: float = SMOOTH_MIN_WIDTH):
    """``(a + b - sqrt((a - b)^2 + width^2)) / 2``: smooth, below ``min(a, b)`` by at most ``width / 2`` (at
    ``a = b``) and by less than ``width^2 / (4 |a - b|)`` away from it; CasADi expressions or floats."""
    symbolic = any(isinstance(v, (ca.SX, ca.MX, ca.DM)) for v in (a, b))
    return (a + b - (ca.sqrt if symbolic else np.sqrt)((a - b) ** 2 + width**2)) / 2


def reward_expression(model, name: str, x, u, *, exact: bool = True):
    """The reward of dm_control task ``name`` as a CasADi expression of ``x`` (nx,) and ``u`` (nu,) SX symbols.

    ``exact=True``: dm_control's reward, in [0, 1]; ``exact=False``: the planner's form (the same reward where it
    is smooth, the surrogate of the module notes where it is sparse, and for both acrobot tasks). Units: m, rad,
    m/s, rad/s, ctrl.

    * cartpole ``swingup``, ``balance`` (``Balance._get_reward(sparse=False)``): ``mean_i (cos phi_i + 1) / 2 *
      (4 + tolerance(u_0, margin=1, value_at_margin=0, 'quadratic')) / 5 * (1 + min_i tolerance(rate_i,
      margin=5)) / 2 * (1 + tolerance(cart, margin=2)) / 2`` (planned with :func:`smooth_min` for the ``min``);
    * cartpole ``swingup_sparse`` (``sparse=True``): ``tolerance(cart, (-0.25, 0.25)) * prod_i tolerance(cos
      phi_i, (0.995, 1))``;
    * pendulum ``swingup`` (``SwingUp.get_reward``, sparse): ``tolerance(cos phi, (cos 8 deg, 1))``;
    * acrobot ``swingup`` / ``swingup_sparse`` (``Balance._get_reward``): ``tolerance(|target - tip|, (0, r),
      margin=1 / 0)`` with ``r`` the target site's radius (0.2 m); planned on ``tolerance(|target - tip|, (0, r),
      margin=1, 'long_tail') - ACROBOT_INPUT_WEIGHT u'u``.

    Raises
    ------
    DMCError
        As :func:`check_model`.
    """
    t = check_model(model, name)
    surrogate = t.sparse and not exact

    def box(v, lower: float, upper: float, centre: float, width: float):
        """``tolerance(v, (lower, upper))``, or its surrogate: toward ``centre`` with margin ``width``."""
        if not surrogate:
            return tolerance(v, (lower, upper))
        return tolerance(v, (centre, centre), margin=width, sigmoid=SURROGATE_SIGMOID)
    if t.domain == "cartpole":
        cosines = _pole_cosines(model, x)
        cart = x[model.slide]
        if t.sparse:
            r = box(cart, -0.25, 0.25, 0.0, 0.25)
            for c in cosines:
                r = r * box(c, 0.995, 1.0, 1.0, 1 - 0.995)
            return r
        upright = sum((c + 1) / 2 for c in cosines) / len(cosines)
        centered = (1 + tolerance(cart, margin=2.0)) / 2
        quadratic = (tolerance(u[0], margin=1.0, value_at_margin=0.0, sigmoid="quadratic") if exact
                     else 1 - u[0] ** 2)
        small_control = (4 + quadratic) / 5
        rates = [tolerance(x[model.nq + h], margin=5.0) for h in model.hinges]
        m = rates[0]
        for r in rates[1:]:
            m = ca.fmin(m, r) if exact else smooth_min(m, r)
        small_velocity = (1 + m) / 2
        return upright * small_control * small_velocity * centered
    if t.domain == "pendulum":
        (c,) = _pole_cosines(model, x)
        lower = float(np.cos(np.deg2rad(8)))
        return box(c, lower, 1.0, 1.0, 1 - lower)
    params = model.params
    tip, target = site(params, "tip"), site(params, "target")
    q = x[:model.nq]
    gap = site_world(params, target, q) - site_world(params, tip, q)
    d2 = ca.sumsqr(gap)
    radius = float(target[2][0])
    if exact:
        return tolerance(ca.sqrt(d2), (0.0, radius), margin=0.0 if t.sparse else 1.0)
    # both tasks' planning surrogate (module notes): long-tailed, so it has a gradient from anywhere
    dist = ca.sqrt(d2 + DISTANCE_FLOOR)
    return (tolerance(dist, (0.0, radius), margin=SURROGATE_DISTANCE_MARGIN, sigmoid=SURROGATE_SIGMOID)
            - ACROBOT_INPUT_WEIGHT * ca.sumsqr(u))


def sparse_box(model, name: str, x) -> tuple:
    """Where a sparse task pays: its reward is 1 exactly when ``lower <= g(x) <= upper`` (every entry), else 0.

    ``g`` is a CasADi expression (m,) of the state ``x`` (nx,) SX: cartpole ``swingup_sparse`` the cart position and
    every pole's cosine (``[-0.25, 0.25]``, ``[0.995, 1]``); pendulum ``swingup`` the pole's cosine (``[cos 8 deg,
    1]``); acrobot ``swingup_sparse`` the squared tip-to-target distance (``[0, r^2]``, ``r`` the target's radius).
    These are the bounds of :func:`reward_expression`'s exact form (dm_control's ``tolerance`` with no margin is the
    indicator of its closed bounds); a bound that always holds (a cosine's 1, a squared distance's 0) is returned
    as infinite, so that a margin kept inside the box never excludes upright itself.

    Returns
    -------
    (g, lower (m,), upper (m,))

    Raises
    ------
    DMCError
        Not a sparse task, or a model that lacks what it needs (:func:`check_model`).
    """
    t = check_model(model, name)
    if not t.sparse:
        raise DMCError(f"'{t.name}' pays a smooth reward, not a box; its reward has no sparse box.")
    if t.domain == "cartpole":
        cosines = _pole_cosines(model, x)
        g = ca.vertcat(x[model.slide], *cosines)
        return g, np.r_[-0.25, [0.995] * len(cosines)], np.r_[0.25, [np.inf] * len(cosines)]
    if t.domain == "pendulum":
        (c,) = _pole_cosines(model, x)
        return ca.vertcat(c), np.array([float(np.cos(np.deg2rad(8)))]), np.array([np.inf])
    params = model.params
    tip, target = site(params, "tip"), site(params, "target")
    q = x[:model.nq]
    gap = site_world(params, target, q) - site_world(params, tip, q)
    r = float(target[2][0])
    return ca.vertcat(ca.sumsqr(gap)), np.array([-np.inf]), np.array([r * r])


_FUNCTIONS: dict = {}


def reward_function(model, name: str, *, exact: bool = True) -> ca.Function:
    """:func:`reward_expression` as a CasADi Function of SX symbols ``(x (nx,), u (nu,)) -> reward`` (scalar),
    inputs named ``x``, ``u``, output ``reward``; built once per model, task and form and kept while the model
    lives (scoring a rollout does not rebuild it). ``F.map(n)`` evaluates ``n`` columns at once.

    Raises
    ------
    DMCError
        As :func:`check_model`.
    """
    t = task(name)
    key = (id(model), t.name, bool(exact))
    hit = _FUNCTIONS.get(key)
    if hit is not None and hit[0]() is model:
        return hit[1]
    x, u = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu)
    f = ca.Function(f"{t.name}_reward{'' if exact else '_plan'}", [x, u],
                    [reward_expression(model, t.name, x, u, exact=exact)], ["x", "u"], ["reward"])
    _FUNCTIONS[key] = (weakref.ref(model, lambda _ref, key=key: _FUNCTIONS.pop(key, None)), f)
    return f


def rewards(model, name: str, x, u) -> np.ndarray:
    """dm_control's exact reward of task ``name`` at states ``x`` (..., nx) and ctrl ``u`` (..., nu),
    broadcast together: (...,), each in [0, 1] (:func:`reward_function` mapped over the rows)."""
    x = np.asarray(x, float)
    u = np.asarray(u, float)
    batch = np.broadcast_shapes(x.shape[:-1], u.shape[:-1])
    X = np.broadcast_to(x, (*batch, x.shape[-1])).reshape(-1, x.shape[-1])
    U = np.broadcast_to(u, (*batch, u.shape[-1])).reshape(-1, u.shape[-1])
    if X.shape[0] == 0:
        return np.zeros(batch)
    f = reward_function(model, name, exact=True)
    return np.asarray(f.map(X.shape[0])(X.T, U.T), float).reshape(batch)


def episode_starts(model, name: str, n: int, seed: int | None = 0) -> np.ndarray:
    """The start states ``[qpos, qvel]`` (n, nx) of dm_control's first ``n`` episodes of task ``name`` with
    ``task_kwargs={'random': seed}``: one ``numpy.random.RandomState(seed)`` drawn in the order of the task's
    ``initialize_episode``, each episode from ``qpos0`` at rest (``mj_resetData``):

    * cartpole swingup (both): ``slider = .01 randn``, ``hinge_1 = pi + .01 randn``, the further hinges
      ``.1 randn(nv - 2)``, every rate ``.01 randn(nv)``;
    * cartpole balance: ``slider = uniform(-.1, .1)``, every hinge ``uniform(-.034, .034, nv - 1)``, every rate
      ``.01 randn(nv)``;
    * pendulum: ``hinge = uniform(-pi, pi)``; acrobot: ``[shoulder, elbow] = uniform(-pi, pi, 2)``, at rest.

    dm_control's angles are from its files' upright ``qpos = 0``: here they are offsets from the model's upright
    ``x*`` (the same on those files). Units m, rad, m/s, rad/s.

    Raises
    ------
    DMCError
        As :func:`check_model`; ``n`` below 1.
    """
    t = check_model(model, name)
    if int(n) < 1:
        raise DMCError(f"The number of {t.name} episodes must be at least 1; got {n}.")
    rng = np.random.RandomState(seed)
    nq = model.nq
    x_eq = np.asarray(model.x_eq, float)
    q0 = np.array([j.qpos0 for j in model.params.joints], float)
    hinges = list(model.hinges)
    out = np.empty((int(n), model.nx))
    for k in range(int(n)):
        q, v = q0.copy(), np.zeros(nq)
        if t.domain == "cartpole" and t.task.startswith("swingup"):
            q[model.slide] = 0.01 * rng.randn()
            q[hinges[0]] = x_eq[hinges[0]] + np.pi + 0.01 * rng.randn()
            q[hinges[1:]] = x_eq[hinges[1:]] + 0.1 * rng.randn(nq - 2)
            v[:] = 0.01 * rng.randn(nq)
        elif t.domain == "cartpole":
            q[model.slide] = rng.uniform(-0.1, 0.1)
            q[hinges] = x_eq[hinges] + rng.uniform(-0.034, 0.034, nq - 1)
            v[:] = 0.01 * rng.randn(nq)
        else:
            q[hinges] = x_eq[hinges] + rng.uniform(-np.pi, np.pi, len(hinges))
        out[k] = np.r_[q, v]
    return out
