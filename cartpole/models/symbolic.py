"""Equations of motion of a tree of slide and hinge joints, derived symbolically in CasADi from its params.

State ``x = [qpos, qvel]`` in MuJoCo's order (for a cart with n poles: cart position, hinge angles 1..n,
cart velocity, hinge rates), input ``u`` = MuJoCo ``ctrl`` (generalized force ``gear * u`` on each actuated
joint). The Lagrangian is built from the compiled geometry (:mod:`cartpole.models.kinematics`): the mass
matrix is ``sum_b m_b Jv_b' Jv_b + Jw_b' I_b Jw_b`` plus armature, the Coriolis and centripetal forces
``d(M v)/dq v - 1/2 d(v' M v)/dq``, gravity and springs the gradient of the potential. ``M qacc = F`` is
solved by CasADi's symbolic ``solve`` (no hand-written inverse), and every Jacobian is
``casadi.jacobian`` of an SX expression: exact, at any state.

Actuators are MuJoCo's affine ones with a joint transmission (:class:`~cartpole.models.params.ActuatorParams`):
the generalized force of actuator ``a`` on its joint is ``gear u + r (b0 + b1 r q + b2 r v)`` (``r`` its
transmission), modelled exactly; MuJoCo's actuator damping and armature enter as joint damping and armature. A
joint's ``frictionloss`` enters as the smooth ``-frictionloss tanh(v / friction_width)``
(:mod:`cartpole.models.friction`), while MuJoCo keeps its true friction constraint.

The discrete step reproduces one ``mj_step`` of the integrator the MJCF names:

* ``Euler``: semi-implicit Euler whose damping is implicit, ``(M + h D) a = F``, ``v+ = v + h a``,
  ``q+ = q + h v+`` (damping explicit when the MJCF disables ``eulerdamp``); as in MuJoCo, an actuator's
  velocity bias ``b2`` stays explicit;
* ``implicitfast``: ``(M - h dF/dv) a = F`` with ``dF/dv`` the damping and the actuators' velocity derivative
  (``r**2 b2`` on the actuated joint);
* ``implicit``: as implicitfast but ``dF/dv`` includes the Coriolis/centripetal derivative;
* ``RK4``: classical fourth-order Runge-Kutta on ``f(x, u)`` with ``u`` held.

With frictionloss the step is not ``mj_step`` exactly: MuJoCo solves its friction constraint, the model has the
smooth force. Where MuJoCo's friction slides (its force at the bound, opposing the motion: on the shipped cart
whenever the joints move faster than about 0.3 m/s or rad/s) and ``|v|`` is above about 20 widths, the two forces
are equal and the steps agree to round-off; near rest MuJoCo sticks and the model creeps. The smooth friction's
derivative ``-frictionloss / width sech^2(v / width)`` joins ``dF/dv`` in the Euler (with ``eulerdamp``),
implicitfast and implicit steps: MuJoCo's constraint acts in the same step as the velocity it opposes, and an
explicit treatment of a slope as steep as ``frictionloss / width`` makes the step chatter about rest for narrow
widths (:mod:`cartpole.models.friction`); while sliding the derivative is zero, so the sliding-regime agreement is
unchanged.

:func:`equations` with a :class:`~cartpole.models.friction.FrictionConstraint` solves MuJoCo's friction
constraint exactly instead (:func:`~cartpole.models.friction.constraint_friction_force`, a box QP over the friction
joints, outside every ``dF/dv``): then the step equals ``mj_step`` sticking or sliding (system identification
uses it; its Jacobians are piecewise, so planners keep the smooth force).

The step assumes ``u`` is inside ``ctrl_range`` (MuJoCo clamps it) and that no joint limit is active
(limits are constraint forces, outside a smooth model; contacts the reader refuses).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

from cartpole._arrays import readonly
from cartpole.models.discretize import hold_model, steps_per_period
from cartpole.models.contacts import ContactReport, check_equilibrium_contacts, contact_report
from cartpole.models.equilibrium import find_equilibrium
from cartpole.models.friction import (DEFAULT_FRICTION_WIDTH, FrictionConstraint, check_width,
                                      constraint_friction_force, smooth_friction)
from cartpole.models.kinematics import forward_kinematics, forward_kinematics_np
from cartpole.models.params import SUPPORTED_INTEGRATORS, CartPoleParams, MJCFError, read_params


#: Common-subexpression elimination shrinks the Jacobians' virtual-machine programs by about 30 % from two poles
#: on (three poles: A, B 60 -> 50 us); on the single pole it only adds build time.
_CSE_FROM_NQ = 3


def wrap_angle(theta):
    """Wrap an angle (rad, scalar or array) to (-pi, pi]. Use it on errors from upright, not on states."""
    w = np.mod(np.asarray(theta, dtype=float) + np.pi, 2 * np.pi) - np.pi
    w = np.where(w == -np.pi, np.pi, w)
    return w if np.ndim(w) else float(w)


def state_error(x, x_ref, hinges) -> np.ndarray:
    """``x - x_ref`` (..., nx) with the hinge-angle entries (qpos indices ``hinges``) wrapped to (-pi, pi].

    Hinge angles never wrap in MuJoCo; errors fed to a controller, a catch test or a metric do.
    """
    e = np.array(np.asarray(x, dtype=float) - np.asarray(x_ref, dtype=float), copy=True)
    idx = list(hinges)
    if idx:
        e[..., idx] = wrap_angle(e[..., idx])
    return e


@dataclass(frozen=True)
class CartPoleModel:
    """A compiled symbolic cart-pole: CasADi ``Function`` objects built once, evaluated many times.

    Every Function takes ``x`` (nx,) and, where it makes sense, ``u`` (nu,), and returns CasADi ``DM``;
    the numpy helpers (:meth:`linearize`, :meth:`dynamics`, :meth:`step_np`) convert. ``nx = 2 nq``.

    Attributes
    ----------
    params : CartPoleParams
    dt : float
        Step of the discrete model in s (the MJCF's ``timestep`` unless built otherwise).
    integrator : str
        Integrator the discrete step reproduces.
    f : casadi.Function
        ``(x, u) -> x_dot`` (nx,), continuous dynamics.
    A, B : casadi.Function
        ``(x, u) -> df/dx (nx, nx)``, ``(x, u) -> df/du (nx, nu)``, exact Jacobians.
    AB : casadi.Function
        ``(x, u) -> (A, B)`` in one call.
    mass_matrix : casadi.Function
        ``x (nx,) -> M (nq, nq)`` including armature, kg, kg m, kg m^2 (only ``q`` matters).
    bias : casadi.Function
        ``x (nx,) -> C(q, v) v + g(q)`` (nq,), Coriolis, centripetal, gravity and spring forces.
    energy : casadi.Function
        ``x -> total mechanical energy`` in J (kinetic, gravity, springs), zero at upright rest ``x_eq``
        (armature excluded: it is not a body).
    pole_energy : casadi.Function or None
        For a model with one hinge: ``x -> 1/2 J_h theta_dot^2 + (potential of the pole about its hinge)``,
        zero at upright rest and ``-2 m g l`` hanging at rest; what energy shaping regulates. None otherwise.
    step : casadi.Function
        ``(x, u) -> x_next``, one step of ``integrator`` with step ``dt``.
    Ad, Bd, ABd : casadi.Function
        ``(x, u) -> d step/dx (nx, nx)``, ``d step/du (nx, nu)``, both in one call.
    x_eq, u_eq : arrays (nx,), (nu,)
        The upright equilibrium (every pole's centre of mass above its hinge), ``f(x_eq, u_eq) = 0``.
    potential : casadi.Function
        ``q -> (dV/dq, d2V/dq2, dVg/dq, d2Vg/dq2)``, the potential's gradient and Hessian (all, gravity alone).
    actuation : (nq, nu) array
        Generalized force per unit ctrl.
    friction : casadi.Function
        ``x (nx,) -> F_friction (nq,)``: the smooth generalized friction force ``-frictionloss tanh(v / width)``,
        N on slides, N m on hinges (zeros without frictionloss); it is part of ``f`` and ``step``.
    friction_width : float
        The smooth friction's velocity scale ``width``, m/s on slides, rad/s on hinges.
    actuator_bias : casadi.Function
        ``x (nx,) -> F_bias (nq,)``: the actuators' state-dependent generalized force
        ``sum_a r_a (b0 + b1 r_a q + b2 r_a v)`` on their joints (zeros for plain motors); part of ``f``.
    rest_potential : casadi.Function
        As ``potential`` with the actuators' position-dependent force (``b0``, ``b1``) added as the potential
        ``-integral F_bias dq``: what a rest balances (the same Function as ``potential`` without a bias).
    x_hanging, u_hanging : arrays (nx,), (nu,)
        Hanging rest (every pole's centre of mass below its hinge), computed on first use.
    """

    params: CartPoleParams
    dt: float
    integrator: str
    f: ca.Function
    AB: ca.Function
    mass_matrix: ca.Function
    bias: ca.Function
    energy: ca.Function
    pole_energy: ca.Function | None
    step: ca.Function
    ABd: ca.Function
    x_eq: np.ndarray
    u_eq: np.ndarray
    potential: ca.Function
    actuation: np.ndarray
    friction: ca.Function
    friction_width: float
    actuator_bias: ca.Function
    rest_potential: ca.Function

    @functools.cached_property
    def _hanging(self) -> tuple:
        x, u = find_equilibrium(self.params, self.rest_potential, self.actuation, upright=False)
        return readonly(x), readonly(u)

    @functools.cached_property
    def contacts(self) -> ContactReport:
        """The file's geom pairs by whether they can touch (:func:`cartpole.models.contacts.contact_report`: cart over
        its range, every hinge over its range or a full turn), angles in words from hanging."""
        try:
            hanging = self.x_hanging
        except MJCFError:
            hanging = None
        return contact_report(self.params, self.x_eq, x_hanging=hanging)

    @property
    def x_hanging(self) -> np.ndarray:
        """(nx,) hanging rest: every pole's centre of mass below its hinge."""
        return self._hanging[0]

    @property
    def u_hanging(self) -> np.ndarray:
        """(nu,) ctrl that holds :attr:`x_hanging`."""
        return self._hanging[1]

    # ---- single Jacobians, built on first use (AB and ABd serve every caller in the package) --------------
    def _part(self, fun: ca.Function, k: int, name: str) -> ca.Function:
        x, u = ca.SX.sym("x", self.nx), ca.SX.sym("u", self.nu)
        return ca.Function(name, [x, u], [fun(x, u)[k]], ["x", "u"], [name], {"cse": self.nq >= _CSE_FROM_NQ})

    @functools.cached_property
    def A(self) -> ca.Function:
        """``(x, u) -> df/dx`` (nx, nx)."""
        return self._part(self.AB, 0, "A")

    @functools.cached_property
    def B(self) -> ca.Function:
        """``(x, u) -> df/du`` (nx, nu)."""
        return self._part(self.AB, 1, "B")

    @functools.cached_property
    def Ad(self) -> ca.Function:
        """``(x, u) -> d step/dx`` (nx, nx)."""
        return self._part(self.ABd, 0, "Ad")

    @functools.cached_property
    def Bd(self) -> ca.Function:
        """``(x, u) -> d step/du`` (nx, nu)."""
        return self._part(self.ABd, 1, "Bd")

    # ---- sizes and named indices ------------------------------------------------------------
    @property
    def nq(self) -> int:
        """Number of joint coordinates."""
        return self.params.nq

    @property
    def nv(self) -> int:
        """Number of joint velocities (= nq)."""
        return self.params.nq

    @property
    def nx(self) -> int:
        """State dimension ``nq + nv``."""
        return 2 * self.params.nq

    @property
    def nu(self) -> int:
        """Number of inputs (actuators)."""
        return self.params.nu

    @property
    def slide(self) -> int | None:
        """qpos index of the cart's slide, or None."""
        return self.params.slide

    @property
    def slides(self) -> tuple:
        """qpos indices of every slide joint."""
        return self.params.slides

    @property
    def hinges(self) -> tuple:
        """qpos indices of the hinges (poles), in tree order."""
        return self.params.hinges

    @property
    def u_low(self) -> np.ndarray:
        """(nu,) lower ctrl bounds."""
        return readonly(self.params.ctrl_range[:, 0])

    @property
    def u_high(self) -> np.ndarray:
        """(nu,) upper ctrl bounds."""
        return readonly(self.params.ctrl_range[:, 1])

    def state_error(self, x, x_ref=None) -> np.ndarray:
        """``x - x_ref`` (..., nx) with hinge-angle errors wrapped; ``x_ref`` defaults to ``x_eq``."""
        return state_error(x, self.x_eq if x_ref is None else x_ref, self.hinges)

    # ---- numpy conveniences ------------------------------------------------------------------
    def dynamics(self, x, u) -> np.ndarray:
        """Continuous dynamics ``x_dot = f(x, u)``; x (nx,), u (nu,) or scalar; returns (nx,)."""
        return np.asarray(self.f(np.asarray(x, float), np.atleast_1d(u).astype(float))).ravel()

    def step_np(self, x, u) -> np.ndarray:
        """One discrete step (the MJCF's integrator): x (nx,), u (nu,) ctrl; returns (nx,)."""
        return np.asarray(self.step(np.asarray(x, float), np.atleast_1d(u).astype(float))).ravel()

    def linearize(self, x=None, u=None, *, discrete: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Exact Jacobians at the state ``x`` (nx,) ``[qpos, qvel]`` (SI: m, rad, m/s, rad/s) and the ctrl ``u``
        (nu,) (default the upright equilibrium ``x_eq``, ``u_eq``).

        Returns ``(A (nx, nx), B (nx, nu))`` of ``f`` (B per unit ctrl), or, with ``discrete=True``,
        ``(Ad, Bd)`` of one step of the MJCF's integrator.
        """
        x = self.x_eq if x is None else np.asarray(x, float)
        u = self.u_eq if u is None else np.atleast_1d(u).astype(float)
        A, B = (self.ABd if discrete else self.AB)(x, u)
        return np.asarray(A), np.asarray(B)

    def statespace(self, x=None, u=None, *, dt: float | None = None, C=None, outputs=None, name: str | None = None):
        """The linearisation at ``(x, u)`` as a python-control ``StateSpace`` with the MJCF's signal names.

        States are named after the joints, ``[<joint>..., <joint>_vel...]`` (MuJoCo's order), inputs after the
        actuators, outputs after the states (the full state, ``C = I``) unless ``C`` and ``outputs`` are given.

        Parameters
        ----------
        x : (nx,) array, optional
            Operating state (m, rad, m/s, rad/s); default the upright equilibrium ``x_eq``.
        u : (nu,) array, optional
            Operating ctrl; default ``u_eq``.
        dt : float, optional
            None: the continuous ``(A, B)``. A control period in s (a whole number of physics steps, one step
            included): the exact discrete model over that hold (:meth:`hold`), with ``dt`` the system's sample time.
        C : (ny, nx) array, optional
            Measured outputs ``y = C x`` (no feedthrough); default the identity.
        outputs : sequence of str, optional
            One name per row of ``C`` (default ``y0 ..``; with ``C`` unset, the state names).
        name : str, optional
            The system's name (default the MJCF file's stem).

        Returns
        -------
        control.StateSpace
            Continuous (``dt = 0``) or discrete (``dt`` the period in s); ``B`` per unit ctrl.

        Raises
        ------
        PeriodError
            ``dt`` not a positive whole number of the MJCF's physics steps.
        MJCFError
            ``C`` or ``outputs`` whose shapes do not match the model.
        """
        import control  # python-control takes seconds to import: only this method's callers pay for it

        if dt is None:
            A, B = self.linearize(x, u)
        else:
            A, B = self.hold(steps_per_period(dt, float(self.dt))).linearize(x, u)
        joints = [j.name for j in self.params.joints]
        states = joints + [f"{j}_vel" for j in joints]
        inputs = [a.name for a in self.params.actuators]
        if C is None:
            C = np.eye(self.nx)
            outputs = states if outputs is None else list(outputs)
        C = np.atleast_2d(np.asarray(C, dtype=float))
        if C.shape[1] != self.nx:
            raise MJCFError(f"C has shape {C.shape}; it must have one column per state ({self.nx}: "
                            f"{', '.join(states)}).")
        outputs = [f"y{i}" for i in range(C.shape[0])] if outputs is None else [str(o) for o in outputs]
        if len(outputs) != C.shape[0]:
            raise MJCFError(f"outputs names {len(outputs)} signals but C has {C.shape[0]} rows; give one per row.")
        D = np.zeros((C.shape[0], self.nu))
        return control.ss(A, B, C, D, 0 if dt is None else float(dt), states=states, inputs=inputs,
                          outputs=outputs, name=name or Path(self.params.mjcf).stem)

    def hold(self, steps: int):
        """The exact discrete model over ``steps`` physics steps with the ctrl held
        (:class:`~cartpole.models.discretize.HoldModel`), built on first use and kept with this model."""
        holds = self.__dict__.setdefault("_holds", {})  # a frozen dataclass still has a __dict__ for caches
        if steps not in holds:
            holds[steps] = hold_model(self, steps)
        return holds[steps]

    def without_friction(self, joints=None) -> "CartPoleModel":
        """The same model (step, integrator, friction width) with the ``frictionloss`` of ``joints`` (qpos indices;
        default all) removed (:meth:`CartPoleParams.without_friction`); ``self`` when none of them has any.

        Linear designs at rest use ``without_friction()``: there the smooth friction's slope ``frictionloss / width``
        would be a viscous damping (50 N s/m for 0.5 N at the default width) that the joint, stuck or sliding at the
        Coulomb level, does not have."""
        drop = tuple(range(self.nq) if joints is None else sorted({int(j) for j in joints}))
        if not any(self.params.joints[j].frictionloss != 0 for j in drop):
            return self
        built = self.__dict__.setdefault("_without_friction", {})  # a cache, like hold()'s
        if drop not in built:
            built[drop] = build_model(self.params.without_friction(drop), dt=self.dt, integrator=self.integrator,
                                      friction_width=self.friction_width)
        return built[drop]

    def rebuilt(self, *, dt: float | None = None, integrator: str | None = None) -> "CartPoleModel":
        """The same physics (and friction width) with another discrete step (e.g. a control period of several
        physics steps)."""
        return build_model(self.params, dt=dt or self.dt, integrator=integrator or self.integrator,
                           friction_width=self.friction_width)


def _lagrangian(p: CartPoleParams, q, v):
    """(M_body (nq, nq) without armature, potential V) as SX in ``q``, ``v``."""
    kin = forward_kinematics(p, q)
    g = ca.DM(p.gravity)
    M = ca.SX.zeros(p.nq, p.nq)
    V = 0
    for b, body in enumerate(p.bodies):
        if not (_is_symbol(body.mass) or _is_symbol(body.inertia)) and body.mass == 0 and not np.any(body.inertia):
            continue
        Jv = ca.jacobian(kin.com[b], q)
        Jw = kin.angular_jacobian[b]
        M += body.mass * ca.mtimes(Jv.T, Jv) + ca.mtimes([Jw.T, kin.inertia[b], Jw])
        V -= body.mass * ca.dot(g, kin.com[b])
    for i, j in enumerate(p.joints):
        if j.stiffness:
            V += 0.5 * j.stiffness * (q[i] - j.springref) ** 2
    return M, V, kin


def _pole_energy(p: CartPoleParams, kin, v, inertia: float):
    """The single pole's energy about its hinge (SX or float) for kinematics ``kin``, rates ``v`` and the pole's
    inertia about the hinge ``inertia`` (kg m^2)."""
    h = p.hinges[0]
    V = 0
    for b in p.pole_bodies:
        V = V - p.bodies[b].mass * (p.gravity @ (kin.com[b] - kin.joint_anchor[h]) if isinstance(kin.com[b], np.ndarray)
                                    else ca.dot(ca.DM(p.gravity), kin.com[b] - kin.joint_anchor[h]))
    return 0.5 * inertia * v[h] ** 2 + V


def _potential_np(p: CartPoleParams, q) -> float:
    """Potential energy (gravity and springs, J) at numeric ``q``, the same sum as in :func:`_lagrangian`."""
    kin = forward_kinematics_np(p, q)
    V = -sum(b.mass * (p.gravity @ kin.com[i]) for i, b in enumerate(p.bodies))
    return float(V + sum(0.5 * j.stiffness * (q[i] - j.springref) ** 2 for i, j in enumerate(p.joints)))


def build_model(plant: CartPoleParams | str | None = None, *, dt: float | None = None,
                integrator: str | None = None, friction_width: float = DEFAULT_FRICTION_WIDTH) -> CartPoleModel:
    """Derive the equations of motion in CasADi, compile their Functions and find the equilibria.

    Parameters
    ----------
    plant : CartPoleParams, CartPoleModel or path, optional
        Parameters, a model (rebuilt from its parameters), or an MJCF or URDF path to read them from; default the
        shipped asset.
    dt : float, optional
        Step in s of the discrete model; default the MJCF's ``timestep``.
    integrator : str, optional
        ``Euler``, ``RK4``, ``implicit`` or ``implicitfast``; default the MJCF's.
    friction_width : float
        Velocity scale of the smooth friction ``-frictionloss tanh(v / friction_width)``, m/s on slides and
        rad/s on hinges (default :data:`~cartpole.models.friction.DEFAULT_FRICTION_WIDTH`, 0.01, justified there).
        Without frictionloss it changes nothing.

    Returns
    -------
    CartPoleModel

    Raises
    ------
    MJCFError
        For an unsupported integrator, a non-positive step, or a model without an upright equilibrium.
    FrictionWidthError
        For a friction width that is not a finite positive velocity.
    """
    params = plant.params if isinstance(plant, CartPoleModel) else plant
    if not isinstance(params, CartPoleParams):
        params = read_params(params)
    p = params
    h = float(p.timestep if dt is None else dt)
    integ = p.integrator if integrator is None else integrator
    if integ not in SUPPORTED_INTEGRATORS:
        raise MJCFError(f"Integrator '{integ}' is not supported; choose one of {', '.join(SUPPORTED_INTEGRATORS)}.")
    if not h > 0:
        raise MJCFError(f"Time step {h} s is not positive; give a positive dt.")
    width = check_width(friction_width)

    nq, nu = p.nq, p.nu
    opts = {"cse": nq >= _CSE_FROM_NQ}
    x = ca.SX.sym("x", 2 * nq)
    u = ca.SX.sym("u", nu)
    q, v = x[:nq], x[nq:]
    eq = equations(p, x, u, dt=h, integrator=integ, friction_width=width)
    M, M_body, V, kin, bias, Bmat = eq.M, eq.M_body, eq.V, eq.kin, eq.bias, eq.actuation  # noqa: N806
    F_fric, F_act, V_act, xdot, x_next = eq.F_friction, eq.F_actuator, eq.V_actuator, eq.xdot, eq.x_next
    T = 0.5 * ca.dot(v, ca.mtimes(M_body, v))
    f = ca.Function("f", [x, u], [xdot], ["x", "u"], ["xdot"], opts)
    step = ca.Function("step", [x, u], [x_next], ["x", "u"], ["x_next"], opts)

    # ---- equilibria: upright (every COM above its hinge) and hanging ------------------------------
    Vg = V - sum(0.5 * j.stiffness * (q[i] - j.springref) ** 2 for i, j in enumerate(p.joints) if j.stiffness)
    H, dV = ca.hessian(V, q)
    Hg, dVg = ca.hessian(Vg, q)
    potential = ca.Function("potential", [q], [dV, H, dVg, Hg])
    if p.has_actuator_bias:
        H_rest, dV_rest = ca.hessian(V + V_act, q)
        rest_potential = ca.Function("rest_potential", [q], [dV_rest, H_rest, dVg, Hg])
    else:
        rest_potential = potential
    x_eq, u_eq = find_equilibrium(p, rest_potential, Bmat, upright=True)
    check_equilibrium_contacts(p, x_eq)  # a pair touching at upright: nothing the model computes would hold there
    V0 = _potential_np(p, x_eq[:nq])

    E = T + V - V0
    pole_energy = None
    if len(p.hinges) == 1:
        J = p.pole_inertia_about_hinge
        Ep = _pole_energy(p, kin, v, J) - _pole_energy(p, forward_kinematics_np(p, x_eq[:nq]), np.zeros(nq), J)
        pole_energy = ca.Function("pole_energy", [x], [Ep], ["x"], ["E_pole"])

    Ax, Bu = ca.jacobian(xdot, x), ca.jacobian(xdot, u)
    Adx, Bdu = ca.jacobian(x_next, x), ca.jacobian(x_next, u)
    fn = lambda name, i, o, names_in, names_out: ca.Function(name, i, o, names_in, names_out, opts)  # noqa: E731
    funcs = dict(
        f=f,
        AB=fn("AB", [x, u], [Ax, Bu], ["x", "u"], ["A", "B"]),
        mass_matrix=fn("mass_matrix", [x], [M], ["x"], ["M"]),
        bias=fn("bias", [x], [bias], ["x"], ["bias"]),
        energy=fn("energy", [x], [E], ["x"], ["E"]),
        pole_energy=pole_energy,
        step=step,
        ABd=fn("ABd", [x, u], [Adx, Bdu], ["x", "u"], ["Ad", "Bd"]),
        friction=fn("friction", [x], [F_fric], ["x"], ["F_friction"]),
        actuator_bias=fn("actuator_bias", [x], [F_act], ["x"], ["F_bias"]),
    )
    return CartPoleModel(params=p, dt=h, integrator=integ, x_eq=readonly(x_eq), u_eq=readonly(u_eq),
                         potential=potential, actuation=readonly(Bmat), friction_width=width,
                         rest_potential=rest_potential, **funcs)


@dataclass(frozen=True)
class Equations:
    """The SX expressions of one model in the symbols ``x`` (nx,) and ``u`` (nu,) (and of any parameter symbols
    the params carry), what :func:`build_model` compiles and a parametric model (system identification) reuses.

    Attributes
    ----------
    xdot : SX (nx,)
        ``f(x, u)``.
    x_next : SX (nx,)
        One step of the integrator.
    M : SX (nq, nq)
        Mass matrix with armature.
    M_body : SX (nq, nq)
        Mass matrix without armature, kg, kg m, kg m^2.
    V : SX
        Potential energy (gravity and springs), J.
    kin : Kinematics
        Forward kinematics at ``q``.
    bias : SX (nq,)
        ``C(q, v) v + g(q)``.
    F_friction, F_actuator : SX (nq,)
        Smooth friction and actuator bias forces (zeros when absent).
    V_actuator : SX
        Potential of the actuators' position-dependent force.
    actuation : (nq, nu) array or SX
        Generalized force per unit ctrl (SX when a gear is a symbol).
    """

    xdot: object
    x_next: object
    M: object
    M_body: object
    V: object
    kin: object
    bias: object
    F_friction: object
    F_actuator: object
    V_actuator: object
    actuation: object


def _is_symbol(value) -> bool:
    return isinstance(value, (ca.SX, ca.MX))


def _symbolic_params(p: CartPoleParams) -> bool:
    """True when any parameter the equations read is a CasADi symbol (a parametric model)."""
    vals = [v for b in p.bodies for v in (b.mass, b.ipos, b.inertia)]
    vals += [v for j in p.joints for v in (j.damping, j.armature, j.frictionloss)]
    vals += [v for a in p.actuators for v in (a.gear, a.transmission, a.damping, a.armature)]
    return any(_is_symbol(v) for v in vals)


def _joint_vector(p: CartPoleParams, field: str):
    """(nq,) SX of a joint field (``damping``, ``armature``, ``frictionloss``) with the actuators' share added as
    :attr:`CartPoleParams.damping` and :attr:`CartPoleParams.armature` add it, for params holding symbols."""
    vals = [getattr(j, field) for j in p.joints]
    if field != "frictionloss":
        for a in p.actuators:
            extra = getattr(a, field)
            if _is_symbol(extra) or extra:
                vals[a.joint] = vals[a.joint] + a.transmission ** 2 * extra
    return ca.vertcat(*[ca.SX(v) if not _is_symbol(v) else v for v in vals])


def equations(p: CartPoleParams, x, u, *, dt: float, integrator: str, friction_width: float,
              friction_constraint: FrictionConstraint | None = None) -> Equations:
    """Derive the equations of motion and one integrator step as SX in ``x`` and ``u``.

    The parameters may hold CasADi SX symbols instead of numbers (a body's ``mass``, ``ipos`` (3,), ``inertia``
    (3,); a joint's ``damping``, ``armature``, ``frictionloss``; an actuator's ``gear`` with its ``transmission``):
    then the expressions are functions of those symbols too, the same derivation (what system identification
    fits). With numbers only, this is exactly what :func:`build_model` compiles.

    Parameters
    ----------
    p : CartPoleParams
    x : SX (nx,)
        State symbol ``[qpos, qvel]``.
    u : SX (nu,)
        Ctrl symbol.
    dt : float
        Step in s.
    integrator : str
        One of ``SUPPORTED_INTEGRATORS``.
    friction_width : float
        Velocity scale of the smooth friction, m/s or rad/s.
    friction_constraint : FrictionConstraint, optional
        Given, ``frictionloss`` is MuJoCo's friction constraint solved exactly
        (:func:`~cartpole.models.friction.constraint_friction_force`: the joint sticks as in ``mj_step``), not the
        smooth force; ``friction_width`` is then unused and ``F_friction`` is the constraint force.

    Returns
    -------
    Equations
    """
    nq, nu = p.nq, p.nu
    h, integ = float(dt), integrator
    q, v = x[:nq], x[nq:]
    symbolic = _symbolic_params(p)
    M_body, V, kin = _lagrangian(p, q, v)  # noqa: N806
    M = M_body + ca.diag(_joint_vector(p, "armature") if symbolic else ca.DM(p.armature))
    T = 0.5 * ca.dot(v, ca.mtimes(M_body, v))
    bias = ca.mtimes(ca.jacobian(ca.mtimes(M_body, v), q), v) - ca.gradient(T, q) + ca.gradient(V, q)
    if symbolic:
        Bmat = ca.SX.zeros(nq, nu)
        for i, a in enumerate(p.actuators):
            Bmat[a.joint, i] = a.gear
    else:
        Bmat = np.zeros((nq, nu))
        for i, a in enumerate(p.actuators):
            Bmat[a.joint, i] = a.gear
    D = _joint_vector(p, "damping") if symbolic else ca.DM(p.damping)
    F = ca.mtimes(Bmat if symbolic else ca.DM(Bmat), u) - D * v - bias  # everything but M qacc
    # Friction and actuator bias are added only where present, so a model without them is the one it always was,
    # bit for bit.
    has_friction = p.has_friction if not symbolic else any(
        _is_symbol(j.frictionloss) or j.frictionloss for j in p.joints)
    fl = _joint_vector(p, "frictionloss") if symbolic else p.frictionloss
    exact = friction_constraint is not None and has_friction
    F_act, V_act = _actuator_bias(p, q, v)
    if p.has_actuator_bias:
        F = F + F_act
    if exact:  # MuJoCo's constraint, on the acceleration everything else gives (it acts on no dF/dv below)
        fl = ca.DM(fl) if not _is_symbol(fl) else fl
        dofs = [i for i, j in enumerate(p.joints) if _is_symbol(j.frictionloss) or j.frictionloss]
        M0 = ca.substitute(M, q, ca.DM(friction_constraint.qpos0))
        F_fric = constraint_friction_force(M, M0, ca.solve(M, F), v, fl, dofs, friction_constraint)
        F = F + F_fric
    else:
        F_fric = smooth_friction(fl, v, friction_width) if has_friction else ca.SX.zeros(nq)
        if has_friction:
            F = F + F_fric
    qacc = ca.solve(M, F)
    xdot = ca.vertcat(v, qacc)

    # ---- one step of the MJCF's integrator ---------------------------------------------------
    if integ == "RK4":
        f = None if symbolic else ca.Function("f", [x, u], [xdot], ["x", "u"], ["xdot"], {"cse": nq >= _CSE_FROM_NQ})
        fx = (lambda xx: f(xx, u)) if f is not None else (lambda xx: ca.substitute(xdot, x, xx))
        k1 = fx(x)
        k2 = fx(x + h / 2 * k1)
        k3 = fx(x + h / 2 * k2)
        k4 = fx(x + h * k3)
        x_next = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    else:
        if integ == "Euler":
            dFdv = -ca.diag(D) if p.euler_damping_implicit else ca.DM.zeros(nq, nq)
            if has_friction and p.euler_damping_implicit and not exact:
                dFdv = dFdv + ca.jacobian(F_fric, v)
        elif integ == "implicitfast":
            dFdv = -ca.diag(D)  # plus the actuators' velocity derivative, without Coriolis/centripetal terms
            if has_friction and not exact:
                dFdv = dFdv + ca.jacobian(F_fric, v)
            if p.has_actuator_bias:
                dFdv = dFdv + ca.jacobian(F_act, v)
        else:  # implicit: full derivative including Coriolis/centripetal terms, friction and actuator bias
            dFdv = ca.jacobian(F - F_fric if exact else F, v)
        a_impl = ca.solve(M - h * dFdv, F)
        v_next = v + h * a_impl
        x_next = ca.vertcat(q + h * v_next, v_next)
    return Equations(xdot=xdot, x_next=x_next, M=M, M_body=M_body, V=V, kin=kin, bias=bias, F_friction=F_fric,
                     F_actuator=F_act, V_actuator=V_act, actuation=Bmat)


def _actuator_bias(p: CartPoleParams, q, v):
    """The actuators' state-dependent generalized force (nq,) SX and the potential (SX scalar) of its
    position-dependent part: actuator ``a`` on joint ``j`` with transmission ``r`` and bias ``(b0, b1, b2)`` adds
    ``r (b0 + b1 r q_j + b2 r v_j)`` to joint ``j`` (MuJoCo: length ``r q_j``, velocity ``r v_j``, joint force ``r``
    times the actuator force), whose ``b0, b1`` part is ``-d/dq_j`` of ``-(r b0 q_j + 1/2 r^2 b1 q_j^2)``."""
    F = ca.SX.zeros(p.nq)
    V = 0
    for a in p.actuators:
        if not a.biased:
            continue
        r, (b0, b1, b2) = a.transmission, (float(b) for b in a.bias)
        j = a.joint
        F[j] = F[j] + r * (b0 + b1 * r * q[j] + b2 * r * v[j])
        V = V - (r * b0 * q[j] + 0.5 * r * r * b1 * q[j] ** 2)
    return F, V
