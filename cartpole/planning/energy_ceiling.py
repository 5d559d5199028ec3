"""A proof that a swing-up is impossible: the most energy a bounded actuator can pump into the pole against the
joint damping (``docs/swingup.md``, "When the planner says infeasible", derives it).

For one hinge on a cart driven by a force ``|F| <= F_max`` (or one hinge driven by a torque ``|tau| <= tau_max``),
the pole's energy in the frame of the system's horizontal momentum,

    E = 1/2 I(theta) theta_dot^2 + V(theta),    I = M_hh - M_sh^2 / M_ss   (M the mass matrix, V the potential),

obeys, off the cart's end stops,

    dE/dt = -(F + f - b_s v_p) r(theta) theta_dot - (b + b_s r^2) theta_dot^2,   r = M_sh / M_ss,

where ``b``, ``b_s`` are the hinge and slide damping, ``f`` the slide's dry friction (at most its frictionloss) and
``v_p = p / M_ss`` the velocity of the momentum ``p``; hinge friction only takes energy out. So along the hinge angle
travelled ``lambda``, ``dE/dlambda <= a(theta) - beta(theta) |theta_dot|`` with ``a = F_eff |r|`` (``F_eff = F_max +
f + b_s V_p``, ``V_p`` a bound on ``|v_p|``) and ``beta = b + b_s r^2``; for a driven hinge ``a = tau_max``,
``beta = b``. Between two turning points (``theta_dot = 0``, ``E = V``) the hinge turns one way, and the solution of
``dW/dlambda = a - beta sqrt(2 (W - V) / I)`` from ``W = E`` bounds ``E`` (comparison: the right side decreases in
``W``). :func:`energy_ceiling` propagates that bound over a grid of angles in both directions, restarting at every
angle a turn can reach with ``E = V`` there (each step and each restart rounded up, so the grid only loosens it),
until nothing grows: every state the pole can reach lies under it. When upright is not under it, no swing-up exists,
for any duration.

``V_p``: ``X = s + R(theta)`` (``R`` the integral of ``r``) stays within the cart's range widened by ``R``'s, and
``|dv_p/dt| <= (F_max + f + b_s (|v_p| + |r| |theta_dot|)) / M_ss``; a swing-up starts and ends at rest, so speed
``v`` at any instant needs a monotone run of ``X`` of at least ``v^2 / A`` (accelerating from the last rest, braking
to the next): ``V_p^2 <= A * width``. With ``|theta_dot|`` bounded by the energy bound, the bounds are solved
together and every larger ``V_p`` shown inconsistent (see :func:`energy_ceiling`).
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import mujoco
import numpy as np

from cartpole.models import CartPoleParams, build_model
from cartpole.sim.rollout import make_mujoco

#: Grid points over one turn of the hinge.
GRID = 1000
#: Normalised energy (hanging rest -1, upright 1) the ceiling must stay below for the proof to be claimed: a margin for
#: MuJoCo's discrete step, which the continuous bound does not cover.
CLAIM_BELOW = 0.9


@dataclass(frozen=True)
class EnergyCeiling:
    """The outcome of :func:`energy_ceiling`.

    Attributes
    ----------
    proven : bool
        Upright is provably out of reach from the start at rest, for any duration.
    ceiling : float or None
        The bound on the pole's energy over every reachable state, normalised (hanging rest -1, upright 1); None when
        no bound applies (see ``reason``).
    kind : str
        ``"cart"`` (a force on the slide), ``"hinge"`` (a torque on the hinge) or ``""``.
    force : float
        The actuator's largest force (N) or torque (N m): ``|gear| * min(|gain| max|ctrl|, forcerange)``.
    force_bound : float
        ``F_eff``: the force with the slide's friction and its damper's largest push added (N), or the torque.
    hinge_damping, slide_damping : float
        N m s/rad and N s/m.
    speed_bound : float or None
        ``V_p`` in m/s (cart only, with slide damping).
    cart_range : (float, float) or None
        m: the slide range the cart stays in (the bound's assumption).
    reason : str or None
        Why no bound applies to this model or start (e.g. two hinges), else None.
    """

    proven: bool
    ceiling: float | None
    kind: str = ""
    force: float = 0.0
    force_bound: float = 0.0
    hinge_damping: float = 0.0
    slide_damping: float = 0.0
    speed_bound: float | None = None
    cart_range: tuple | None = None
    reason: str | None = None

    def sentence(self) -> str:
        """The proof in one short sentence with its numbers (no final full stop), e.g. for the planner's refusal."""
        if not self.proven:
            return f"no energy bound proves it ({self.reason or 'the bound reaches upright'})"
        lift = f"lifts the pole's energy only to {self.ceiling:.2f} (hanging -1, upright 1)"
        if self.kind == "cart":
            extra = self.force_bound - self.force
            via = f" (+{extra:.2g} N via the slide's damper)" if extra > 0 else ""
            lo, hi = self.cart_range
            return (f"against hinge damping {self.hinge_damping:g} and slide damping {self.slide_damping:g}, at most "
                    f"{self.force:.3g} N{via} {lift} with the cart in [{lo:.3g}, {hi:.3g}] m; see docs/swingup.md")
        return (f"against hinge damping {self.hinge_damping:g} N m s/rad, at most {self.force:.3g} N m {lift} at any "
                "duration; see docs/swingup.md")

    def as_dict(self) -> dict:
        """JSON-ready fields."""
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def _no(reason: str) -> EnergyCeiling:
    return EnergyCeiling(proven=False, ceiling=None, reason=reason)


def _interval_bounds(f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Upper and lower bounds of a smooth periodic table ``f`` (n,) over each grid interval ``[i, i+1]``: the ends'
    max (min) widened by ``max|f''| h^2 / 8`` (from second differences, with 50 % to spare)."""
    nxt = np.roll(f, -1)
    c = 1.5 * float(np.max(np.abs(nxt - 2 * f + np.roll(f, 1)))) / 8.0
    return np.maximum(f, nxt) + c, np.minimum(f, nxt) - c


def reachable_energy(V, a, beta, inertia, *, start: int = 0, max_sweeps: int = 100000) -> np.ndarray:
    """Upper bounds (2, n) of the pole energy reachable at each grid angle moving forward (row 0) and backward (row 1).

    Parameters
    ----------
    V, a, beta, inertia : (n,) arrays
        Over one turn of the hinge on a uniform grid (index 0 the start): potential (J), energy input per radian
        travelled (J/rad), damping (N m s/rad) and inertia (kg m^2) of the bound (module notes).
    start : int
        Grid index of the start, at rest (energy ``V[start]``, either direction).
    max_sweeps : int
        Safety cap on the sweeps.

    Returns
    -------
    (2, n) array
        ``-inf`` where the angle is out of reach in that direction.
    """
    n = V.size
    h = 2 * np.pi / n
    amax, _ = _interval_bounds(a)
    _, bmin = _interval_bounds(beta)
    bmax, _ = _interval_bounds(beta)
    Vmax, Vmin = _interval_bounds(V)
    Imax, Imin = _interval_bounds(inertia)
    Imin = np.maximum(Imin, 1e-15)
    bmin = np.maximum(bmin, 0.0)
    up = np.full((2, n), -np.inf)
    up[:, start] = V[start]
    for _ in range(max_sweeps):
        changed = False
        for row, step in ((0, 1), (1, -1)):
            U = up[row]
            for k in range(2 * n):
                i = (start + step * k) % n
                j = (i + step) % n
                q = i if step == 1 else j  # the interval [q, q + 1] crossed
                W = U[i]
                if not W >= V[i]:
                    continue
                w_up = W + h * amax[q]  # no more than this anywhere on the interval
                v_hi = np.sqrt(2.0 * max(0.0, w_up - Vmin[q]) / Imin[q])
                w_lo = W - h * bmax[q] * v_hi  # no less than this
                v_lo = np.sqrt(2.0 * max(0.0, w_lo - Vmax[q]) / Imax[q])
                w = W + h * (amax[q] - bmin[q] * v_lo)
                if w >= V[j] and w > U[j] + 1e-14:
                    U[j] = w
                    changed = True
        for row, step in ((0, 1), (1, -1)):  # a turn inside the next interval, then back through this angle
            other = up[1 - row]
            for i in np.nonzero(up[row] >= V)[0]:
                q = i if step == 1 else (i - 1) % n
                w = min(Vmax[q], up[row][i] + h * amax[q]) + h * amax[q]
                if w > other[i] + 1e-14:
                    other[i] = w
                    changed = True
        if not changed:
            break
    return up


def _tables(m, d, x0, slide, hinge, n):
    """Potential, mass-matrix entries over one turn of the hinge from the start's angle, the cart where it starts."""
    th = float(x0[hinge]) + 2 * np.pi * np.arange(n) / n
    V = np.empty(n)
    Mss, Msh, Mhh = np.empty(n), np.empty(n), np.empty(n)
    M = np.zeros((m.nv, m.nv))
    for i, t in enumerate(th):
        d.qpos[:] = x0[:m.nq]
        d.qpos[hinge] = t
        d.qvel[:] = 0.0
        mujoco.mj_forward(m, d)
        mujoco.mj_fullM(m, d, M)
        V[i] = d.energy[0]
        Mhh[i] = M[hinge, hinge]
        if slide is not None:
            Mss[i], Msh[i] = M[slide, slide], M[slide, hinge]
    return th, V, Mss, Msh, Mhh


def energy_ceiling(params: CartPoleParams, x0=None, *, cart_range=None, grid: int = GRID) -> EnergyCeiling:
    """Whether the actuator can pump the pole from ``x0`` (at rest) up to upright against the damping, and the bound.

    Parameters
    ----------
    params : CartPoleParams
        One hinge, alone or on one slide (the cart), one actuator on the cart's slide (or on the hinge without a
        cart): a ``<motor>``-like actuator (no bias, no dynamics) with a ctrlrange; no springs, no hinge limit, the
        slide horizontal. Anything else gets ``proven=False`` and a ``reason``.
    x0 : (nx,) array, optional
        The start; default hanging at rest. It must be at rest (zero velocities).
    cart_range : (float, float), optional
        m: the slide range the motion stays in (default the slide's joint range; the planner's bounds shrink it by
        its margin). Needed, finite, when the slide is damped.
    grid : int
        Angles over one turn.

    Returns
    -------
    EnergyCeiling
        ``proven`` when upright lies above the bound with a margin (:data:`CLAIM_BELOW`).
    """
    m, d = make_mujoco(params)
    m.opt.enableflags |= int(mujoco.mjtEnableBit.mjENBL_ENERGY)
    found = _one_hinge_and_motor(m)
    if isinstance(found, str):
        return _no(found)
    hinge, slide = found
    if x0 is None:
        x0 = build_model(params).x_hanging
    x0 = np.asarray(x0, float).ravel()
    if x0.size != m.nq + m.nv or np.any(x0[m.nq:] != 0.0):
        return _no("the energy bound starts at rest")
    force = _actuator_force(m)
    b = float(m.dof_damping[hinge])
    th, V, Mss, Msh, Mhh = _tables(m, d, x0, slide, hinge, int(grid))
    if slide is not None:
        d.qpos[:] = x0[:m.nq]
        d.qpos[slide] += 0.37
        mujoco.mj_forward(m, d)
        V_shift = float(d.energy[0])
        if abs(V_shift - V[0]) > 1e-9 * max(1.0, abs(V[0])):
            return _no("the slide is not horizontal, so gravity pushes the cart")
    Vh, Vu = float(V.min()), float(V.max())
    if not Vu - Vh > 0:
        return _no("gravity does not lift the pole")
    if slide is None:
        a, beta, inertia = np.full(th.size, force), np.full(th.size, b), Mhh
        up = reachable_energy(V, a, beta, inertia, start=0)
        return _verdict(up, V, EnergyCeiling(proven=False, ceiling=None, kind="hinge", force=float(force),
                                              force_bound=float(force), hinge_damping=b, slide_damping=0.0))
    bs = float(m.dof_damping[slide])
    fs = float(m.dof_frictionloss[slide])
    if np.ptp(Mss) > 1e-9 * Mss.max():
        return _no("the cart's inertia changes with the angle")
    M = float(Mss.mean())
    lo, hi = (tuple(float(v) for v in params.cart_range) if cart_range is None else
              (float(cart_range[0]), float(cart_range[1])))
    cart = EnergyCeiling(proven=False, ceiling=None, kind="cart", force=float(force), force_bound=float(force + fs),
                         hinge_damping=b, slide_damping=bs, cart_range=(lo, hi))
    return _cart_ceiling(V, Msh / M, Mhh - Msh**2 / M, M, cart)


def _one_hinge_and_motor(m):
    """``(hinge dof, slide dof or None)`` of a MuJoCo model the bound covers, else the reason it does not (a
    sentence's part)."""
    hinges = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE]
    slides = [j for j in range(m.njnt) if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_SLIDE]
    if len(hinges) != 1 or len(slides) > 1 or m.njnt != len(hinges) + len(slides):
        return "the energy bound covers one hinge, alone or on one cart"
    if m.nu != 1:
        return "the energy bound covers one actuator"
    hinge = int(m.jnt_dofadr[hinges[0]])
    slide = int(m.jnt_dofadr[slides[0]]) if slides else None
    driven = int(m.actuator_trnid[0, 0])
    if m.actuator_trntype[0] != mujoco.mjtTrn.mjTRN_JOINT or driven != (slides[0] if slides else hinges[0]):
        return "the energy bound needs the actuator on the cart's slide, or on the hinge without a cart"
    if (m.actuator_dyntype[0] != mujoco.mjtDyn.mjDYN_NONE or m.actuator_biastype[0] != mujoco.mjtBias.mjBIAS_NONE
            or m.actuator_gaintype[0] != mujoco.mjtGain.mjGAIN_FIXED):
        return "the energy bound needs a plain motor (no bias, gain or activation dynamics)"
    if not m.actuator_ctrllimited[0]:
        return "the actuator has no ctrlrange, so its force is unbounded"
    if np.any(np.asarray(m.jnt_stiffness) != 0.0) or m.jnt_limited[hinges[0]]:
        return "a joint spring or a hinge limit can store energy the bound does not count"
    return hinge, slide


def _actuator_force(m) -> float:
    """The actuator's largest force (N) or torque (N m): ``|gear| * min(|gain| max|ctrl|, forcerange)``."""
    u = float(np.max(np.abs(m.actuator_ctrlrange[0])))
    force = abs(float(m.actuator_gainprm[0, 0])) * u
    if m.actuator_forcelimited[0]:
        force = min(force, float(np.max(np.abs(m.actuator_forcerange[0]))))
    return force * abs(float(m.actuator_gear[0, 0]))


def _cart_ceiling(V, r, inertia, M: float, cart: EnergyCeiling) -> EnergyCeiling:
    """The verdict for a hinge on a cart (module doc): potential ``V``, ``r = M_sh / M_ss`` and the reduced inertia
    over the grid, the cart's mass ``M`` (kg), and ``cart`` the bound's force, damping and cart range (its
    ``force_bound`` the force with the slide's friction, without the damper's push)."""
    b, bs = cart.hinge_damping, cart.slide_damping
    F0 = cart.force_bound  # the force with the slide's friction
    lo, hi = cart.cart_range
    beta = b + bs * r**2
    Vh, Vu = float(V.min()), float(V.max())

    def bound(F_eff):
        up = reachable_energy(V, F_eff * np.abs(r), beta, inertia, start=0)
        best = up.max(axis=0)
        seen = best >= V
        Imin = max(float(inertia.min()), 1e-15)
        omega = float(np.sqrt(2.0 * max(0.0, float(np.max(best[seen] - V[seen]))) / Imin)) * 1.01
        return up, omega

    if bs == 0.0:
        up, _ = bound(F0)
        return _verdict(up, V, cart)
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return _no("a damped slide without a finite range lets the damper push without bound")
    h = 2 * np.pi / V.size
    R = np.cumsum(r) * h
    width = (hi - lo) + float(np.ptp(R)) + 2 * h * float(np.abs(r).max())
    r_max = float(np.abs(r).max())

    def speed(omega):
        """The V_p that V_p^2 = width (F + f + bs (V_p + r_max omega)) / M solves (the largest root)."""
        k = width * bs / M
        c = width * (F0 + bs * r_max * omega) / M
        return 0.5 * (k + np.sqrt(k * k + 4 * c))

    # Far out, a crude |theta_dot| bound (E grows only while |theta_dot| < a / beta, so E <= max(V) + 1/2 I_max
    # (F_eff max|r| / beta)^2) is linear in V_p, and V_p^2 <= width A / M then fails beyond the larger root of a
    # quadratic; in between, the energy bound's own |theta_dot| at the top of each of a few intervals.
    Imin, Imax = max(float(inertia.min()), 1e-15), float(inertia.max())
    rb = float(np.max(np.abs(r) / beta)) if np.all(beta > 0) else np.inf
    if not np.isfinite(rb):
        return _no("an undamped hinge leaves the slide damper's push unbounded")
    om0 = float(np.sqrt(2.0 * (Vu - Vh) / Imin))
    kap = float(np.sqrt(Imax / Imin)) * rb
    B = width / M * (bs + bs * r_max * kap * bs)
    C = width / M * (F0 + bs * r_max * (om0 + kap * F0))
    v_far = 0.5 * (B + np.sqrt(B * B + 4 * C))
    # the least consistent (V_p, omega) by iteration from zero
    vp = 0.0
    for _ in range(30):
        _, omega = bound(F0 + bs * vp)
        nxt = speed(omega)
        if nxt <= vp * (1 + 1e-4) + 1e-9:
            break
        vp = nxt
    vp_claim = 1.02 * vp + 1e-3
    grid_v = np.linspace(vp_claim, max(v_far, vp_claim), 7)
    for v1, v2 in itertools.pairwise(grid_v):
        if v1 >= v2:
            break
        _, om2 = bound(F0 + bs * v2)
        if not v1 * v1 - width * (F0 + bs * v2 + bs * r_max * om2) / M > 0.0:
            return _no("the slide damper's push could not be bounded")
    up, _ = bound(F0 + bs * vp_claim)
    return _verdict(up, V, replace(cart, force_bound=float(F0 + bs * vp_claim), speed_bound=vp_claim))


def _verdict(up, V, bound: EnergyCeiling) -> EnergyCeiling:
    """``bound`` (its force, damping and ranges) with the ceiling of the reachable energy ``up`` (2, n) over the
    potential ``V`` (n,), normalised (hanging -1, upright 1), and whether it proves upright out of reach."""
    Vh, Vu = float(V.min()), float(V.max())
    best = up.max(axis=0)
    seen = best >= V
    ceiling = float(2.0 * (np.max(best[seen]) - Vh) / (Vu - Vh) - 1.0)
    proven = bool(not seen[int(np.argmax(V))] and ceiling < CLAIM_BELOW)
    return replace(bound, proven=proven, ceiling=ceiling, reason=None if proven else "the bound reaches upright")
