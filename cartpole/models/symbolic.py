"""The cart-pole's equations of motion, derived symbolically in CasADi from :class:`CartPoleParams`.

State ``x = [s, theta, s_dot, theta_dot]`` (MuJoCo's ``[qpos, qvel]``), input ``u`` = MuJoCo ``ctrl``
(slide force ``gear * u``). The Lagrangian is built from the compiled geometry (cart translation along
the slide axis, pole rotation about the hinge axis by Rodrigues' formula), the mass matrix is its Hessian
in the velocities, and every Jacobian is ``casadi.jacobian`` of an SX expression: exact, at any state.

The discrete step reproduces one ``mj_step`` of the integrator the MJCF names:

* ``Euler``: semi-implicit Euler whose joint damping is implicit, ``(M + h D) a = tau - bias``,
  ``v+ = v + h a``, ``q+ = q + h v+`` (damping explicit when the MJCF disables ``eulerdamp``);
* ``implicitfast``: ``(M - h dF/dv) a = F`` with ``dF/dv`` the passive and actuator velocity
  derivatives only (for this system the same as Euler);
* ``implicit``: as implicitfast but ``dF/dv`` includes the Coriolis/centripetal derivative;
* ``RK4``: classical fourth-order Runge-Kutta on ``f(x, u)`` with ``u`` held.

The step assumes ``u`` is inside ``ctrl_range`` (MuJoCo clamps it) and that no joint limit or contact is
active (those are constraint forces, outside a smooth model).
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from cartpole.models.params import CartPoleParams, read_params

NX = 4
NU = 1


def wrap_angle(theta):
    """Wrap an angle (rad, scalar or array) to (-pi, pi]. Use it on errors from upright, not on states."""
    w = np.mod(np.asarray(theta, dtype=float) + np.pi, 2 * np.pi) - np.pi
    w = np.where(w == -np.pi, np.pi, w)
    return w if np.ndim(w) else float(w)


@dataclass(frozen=True)
class CartPoleModel:
    """A compiled symbolic cart-pole: CasADi ``Function`` objects built once, evaluated many times.

    Every Function takes ``x`` (4,) and, where it makes sense, ``u`` (1,), and returns CasADi ``DM``;
    the numpy helpers (:meth:`linearize`, :meth:`dynamics`, :meth:`step_np`) convert.

    Attributes
    ----------
    params : CartPoleParams
    dt : float
        Step of the discrete model in s (the MJCF's ``timestep`` unless built otherwise).
    integrator : str
        Integrator the discrete step reproduces.
    f : casadi.Function
        ``(x, u) -> x_dot`` (4,), continuous dynamics.
    A, B : casadi.Function
        ``(x, u) -> df/dx (4, 4)``, ``(x, u) -> df/du (4, 1)``, exact Jacobians.
    AB : casadi.Function
        ``(x, u) -> (A, B)`` in one call.
    mass_matrix : casadi.Function
        ``x (4,) -> M (2, 2)`` including armature, kg and kg m^2 (only ``q = x[:2]`` matters).
    bias : casadi.Function
        ``x (4,) -> C(q, v) v + g(q)`` (2,), generalized Coriolis, centripetal and gravity forces.
    energy : casadi.Function
        ``x -> total mechanical energy`` in J, zero at upright rest (armature excluded: it is not a body).
    pole_energy : casadi.Function
        ``x -> 0.5 J_h theta_dot^2 + m g l (cos theta - 1)`` in J, the pole's energy about its hinge,
        zero at upright rest and ``-2 m g l`` hanging at rest; what energy shaping regulates.
    step : casadi.Function
        ``(x, u) -> x_next``, one step of ``integrator`` with step ``dt``.
    Ad, Bd : casadi.Function
        ``(x, u) -> d step/dx (4, 4)``, ``d step/du (4, 1)``.
    ABd : casadi.Function
        ``(x, u) -> (Ad, Bd)`` in one call.
    """

    params: CartPoleParams
    dt: float
    integrator: str
    f: ca.Function
    A: ca.Function
    B: ca.Function
    AB: ca.Function
    mass_matrix: ca.Function
    bias: ca.Function
    energy: ca.Function
    pole_energy: ca.Function
    step: ca.Function
    Ad: ca.Function
    Bd: ca.Function
    ABd: ca.Function

    nx: int = NX
    nu: int = NU

    # ---- numpy conveniences ------------------------------------------------------------------
    def dynamics(self, x, u) -> np.ndarray:
        """Continuous dynamics ``x_dot = f(x, u)``; x (4,), u scalar or (1,); returns (4,)."""
        return np.asarray(self.f(np.asarray(x, float), np.atleast_1d(u).astype(float))).ravel()

    def step_np(self, x, u) -> np.ndarray:
        """One discrete step (the MJCF's integrator): x (4,), u scalar or (1,) ctrl; returns (4,)."""
        return np.asarray(self.step(np.asarray(x, float), np.atleast_1d(u).astype(float))).ravel()

    def linearize(self, x=None, u=None, *, discrete: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Exact Jacobians at ``(x, u)`` (default upright rest, zero ctrl).

        Returns ``(A (4, 4), B (4, 1))`` of ``f`` in 1/s and (m/s^2 or rad/s^2) per unit ctrl, or, with
        ``discrete=True``, ``(Ad, Bd)`` of one step of the MJCF's integrator.
        """
        x = np.zeros(NX) if x is None else np.asarray(x, float)
        u = np.zeros(NU) if u is None else np.atleast_1d(u).astype(float)
        fun = self.ABd if discrete else self.AB
        A, B = fun(x, u)
        return np.asarray(A), np.asarray(B)

    def rebuilt(self, *, dt: float | None = None, integrator: str | None = None) -> "CartPoleModel":
        """The same physics with another discrete step (e.g. a control period of several physics steps)."""
        return build_model(self.params, dt=dt or self.dt, integrator=integrator or self.integrator)


def _rodrigues(n: np.ndarray, r: np.ndarray, th):
    """Rotate the constant vector r about the unit axis n by the symbolic angle th (3-vector SX)."""
    n = ca.DM(n)
    r = ca.DM(r)
    return r * ca.cos(th) + ca.cross(n, r) * ca.sin(th) + n * ca.dot(n, r) * (1 - ca.cos(th))


def build_model(params: CartPoleParams | str | None = None, *, dt: float | None = None,
                integrator: str | None = None) -> CartPoleModel:
    """Derive the cart-pole's equations of motion in CasADi and compile its Functions.

    Parameters
    ----------
    params : CartPoleParams or path, optional
        Parameters, or an MJCF path to read them from; default the shipped asset.
    dt : float, optional
        Step in s of the discrete model; default the MJCF's ``timestep``.
    integrator : str, optional
        ``Euler``, ``RK4``, ``implicit`` or ``implicitfast``; default the MJCF's.

    Returns
    -------
    CartPoleModel
    """
    if not isinstance(params, CartPoleParams):
        params = read_params(params)
    p = params
    h = float(p.timestep if dt is None else dt)
    integ = p.integrator if integrator is None else integrator
    from cartpole.models.params import SUPPORTED_INTEGRATORS, MJCFError
    if integ not in SUPPORTED_INTEGRATORS:
        raise MJCFError(f"Integrator '{integ}' is not supported; choose one of {', '.join(SUPPORTED_INTEGRATORS)}.")
    if not h > 0:
        raise MJCFError(f"Time step {h} s is not positive; give a positive dt.")

    x = ca.SX.sym("x", NX)
    u = ca.SX.sym("u", NU)
    q, v = x[:2], x[2:]
    s, th = q[0], q[1]
    sd, thd = v[0], v[1]

    a = ca.DM(p.slide_axis)
    n = np.asarray(p.hinge_axis)
    g = ca.DM(p.gravity)
    mc, mp = p.cart_mass, p.pole_mass

    # Pole centre of mass relative to its position at q = 0 (constants drop out of the Lagrangian).
    com = a * s + _rodrigues(n, p.pole_com, th)
    v_com = ca.jtimes(com, q, v)
    Ic_n = float(n @ p.pole_inertia @ n)  # rotation only about n, so only this inertia component acts
    T = 0.5 * mc * sd**2 + 0.5 * mp * ca.dot(v_com, v_com) + 0.5 * Ic_n * thd**2
    V = -mc * ca.dot(g, a * s) - mp * ca.dot(g, com)
    V0 = -mp * float(np.dot(p.gravity, p.pole_com))  # value of V at q = 0
    M_body = ca.hessian(T, v)[0]
    M = M_body + ca.diag(ca.DM(p.armature))
    Mv = ca.mtimes(M_body, v)
    bias = ca.mtimes(ca.jacobian(Mv, q), v) - ca.gradient(T, q) + ca.gradient(V, q)
    D = ca.DM(p.damping)
    tau = ca.vertcat(p.gear * u[0], 0) - D * v  # actuator and passive (damping) forces
    F = tau - bias  # everything but M qacc

    def solve2(Mat, rhs):
        # explicit 2x2 inverse keeps the SX graph small and branch-free
        det = Mat[0, 0] * Mat[1, 1] - Mat[0, 1] * Mat[1, 0]
        return ca.vertcat(Mat[1, 1] * rhs[0] - Mat[0, 1] * rhs[1],
                          -Mat[1, 0] * rhs[0] + Mat[0, 0] * rhs[1]) / det

    qacc = solve2(M, F)
    xdot = ca.vertcat(v, qacc)
    f = ca.Function("f", [x, u], [xdot], ["x", "u"], ["xdot"])

    # ---- one step of the MJCF's integrator ---------------------------------------------------
    if integ == "RK4":
        k1 = f(x, u)
        k2 = f(x + h / 2 * k1, u)
        k3 = f(x + h / 2 * k2, u)
        k4 = f(x + h * k3, u)
        x_next = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    else:
        if integ == "Euler":
            dFdv = -ca.diag(D) if p.euler_damping_implicit else ca.DM.zeros(2, 2)
        elif integ == "implicitfast":
            dFdv = -ca.diag(D)  # motor actuators have no velocity dependence
        else:  # implicit: full derivative including Coriolis/centripetal terms
            dFdv = ca.jacobian(F, v)
        a_impl = solve2(M - h * dFdv, F)
        v_next = v + h * a_impl
        x_next = ca.vertcat(q + h * v_next, v_next)
    step = ca.Function("step", [x, u], [x_next], ["x", "u"], ["x_next"])

    E = T + V - V0
    Jh = Ic_n + mp * float(np.linalg.norm(p.pole_com - (p.pole_com @ n) * n)) ** 2
    E_pole = 0.5 * Jh * thd**2 - mp * ca.dot(g, _rodrigues(n, p.pole_com, th)) - V0

    Ax, Bu = ca.jacobian(xdot, x), ca.jacobian(xdot, u)
    Adx, Bdu = ca.jacobian(x_next, x), ca.jacobian(x_next, u)
    funcs = dict(
        f=f,
        A=ca.Function("A", [x, u], [Ax], ["x", "u"], ["A"]),
        B=ca.Function("B", [x, u], [Bu], ["x", "u"], ["B"]),
        AB=ca.Function("AB", [x, u], [Ax, Bu], ["x", "u"], ["A", "B"]),
        mass_matrix=ca.Function("mass_matrix", [x], [M], ["x"], ["M"]),
        bias=ca.Function("bias", [x], [bias], ["x"], ["bias"]),
        energy=ca.Function("energy", [x], [E], ["x"], ["E"]),
        pole_energy=ca.Function("pole_energy", [x], [E_pole], ["x"], ["E_pole"]),
        step=step,
        Ad=ca.Function("Ad", [x, u], [Adx], ["x", "u"], ["Ad"]),
        Bd=ca.Function("Bd", [x, u], [Bdu], ["x", "u"], ["Bd"]),
        ABd=ca.Function("ABd", [x, u], [Adx, Bdu], ["x", "u"], ["Ad", "Bd"]),
    )
    return CartPoleModel(params=p, dt=h, integrator=integ, **funcs)


def linearize(model: CartPoleModel, x=None, u=None) -> dict:
    """Continuous and discrete linearisation at ``(x, u)`` (default upright rest, zero ctrl).

    Returns a dict with ``A`` (4, 4), ``B`` (4, 1), ``Ad`` (4, 4), ``Bd`` (4, 1), ``dt`` (s) and ``integrator``.
    """
    A, B = model.linearize(x, u)
    Ad, Bd = model.linearize(x, u, discrete=True)
    return {"A": A, "B": B, "Ad": Ad, "Bd": Bd, "dt": model.dt, "integrator": model.integrator}
