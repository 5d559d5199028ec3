"""Infinite-horizon LQR, continuous (CARE) and discrete (DARE), with the checks people forget.

Convention (python-control's): ``K, S, E = lqr(A, B, Q, R)`` with the law ``u = -K x`` (or
``u = u* - K (x - x*)`` about an equilibrium), ``S`` the cost-to-go matrix (``x' S x``), ``E`` the
closed-loop eigenvalues. The result is a named tuple, so it unpacks like python-control's tuple.

Both also take a state-space object (python-control's ``StateSpace``: ``lqr(sys, Q, R)`` on a continuous one,
``dlqr(sys, Q, R)`` on a discrete one, per-sample weights, as python-control reads them), and the plant:
``lqr(plant, Q, R)`` and ``dlqr(plant, Q, R)`` with ``plant`` a path, :class:`~cartpole.models.CartPoleParams` or
:class:`~cartpole.models.CartPoleModel` (:func:`~cartpole.models.plant_model`), designed on its exact linearisation
at the upright equilibrium (dry friction left out: it has no slope at rest), ``Q`` and ``R`` defaulting to
:func:`~cartpole.riccati.weights.default_weights`.

One cost scaling for discrete designs on a plant (**the** convention of the package): ``Q`` and ``R`` are weights
per second, as in the continuous design, so over a control period ``T`` (one physics step unless ``period`` says
more) the stage cost is ``(x'Qx + u'Ru) T``: ``dlqr(plant, Q, R)`` solves ``dlqr(Ad, Bd, Q T, R T)``. Its gain
is the one of ``dlqr(Ad, Bd, Q, R)`` (a common factor on both weights does not move it), and its ``S`` is the
continuous design's to first order in ``T``, so a basin level ``e' S e < rho`` means the same whichever design
built the catch. ``dlqr`` on matrices is python-control's and MATLAB's (per-sample weights, no scaling).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.linalg

from cartpole.errors import CartPoleError
from cartpole.models import is_plant, plant_model, steps_per_period
from cartpole.riccati.weights import default_weights


class LQRError(CartPoleError):
    """Bad weights, mismatched shapes, or a pair (A, B) that cannot be stabilised."""


class LQRResult(NamedTuple):
    """Gain ``K`` (m, n), cost-to-go ``S`` (n, n) and closed-loop eigenvalues ``E`` (n,), for ``n`` states and
    ``m`` inputs."""

    K: np.ndarray
    S: np.ndarray
    E: np.ndarray


def _as2d(name: str, M, shape=None) -> np.ndarray:
    given = np.asarray(M, dtype=float)
    M = np.atleast_2d(given)
    if not np.all(np.isfinite(M)):
        raise LQRError(f"{name} contains NaN or inf; give finite numbers.")
    if shape is not None and M.shape != shape:
        diagonal = given.ndim == 1 and given.size == shape[0]
        hint = f"; for a diagonal of weights give np.diag({name.lower()})" if diagonal else ""
        raise LQRError(f"{name} has shape {given.shape} but must be {shape} to match A and B{hint}.")
    return M


def check_weights(A, B, Q, R):
    """Validate shapes and definiteness for ``n`` states and ``m`` inputs; return float arrays ``(A, B, Q, R)``.

    ``A`` is (n, n); ``B`` (n, m) (a 1-D ``B`` of length n is one input column); ``Q`` (n, n); ``R`` (m, m) or a
    scalar ``r``, meaning ``r I(m)``.

    Raises :class:`LQRError` naming the problem: non-square A, mismatched B/Q/R, Q not symmetric positive
    semidefinite, R not symmetric positive definite.
    """
    A = _as2d("A", A)
    n = A.shape[0]
    if A.shape != (n, n):
        raise LQRError(f"A has shape {A.shape}; it must be square (n, n).")
    B = np.asarray(B, dtype=float)
    # a 1-D B of length n is one input column; _as2d also rejects NaN/inf (the reshape path skipped that)
    B = _as2d("B", B.reshape(n, -1) if B.ndim == 1 and B.size == n else B)
    if B.shape[0] != n:
        raise LQRError(f"B has shape {B.shape} but A is {A.shape}; B must have {n} rows.")
    m = B.shape[1]
    Q = _as2d("Q", Q, (n, n))
    R = _as2d("R", float(R) * np.eye(m) if np.ndim(R) == 0 and np.isfinite(float(R)) else R, (m, m))
    if not np.allclose(Q, Q.T, rtol=1e-10, atol=1e-12):
        raise LQRError("Q is not symmetric; pass (Q + Q.T) / 2 or a diagonal of state weights.")
    if not np.allclose(R, R.T, rtol=1e-10, atol=1e-12):
        raise LQRError("R is not symmetric; pass (R + R.T) / 2 or a diagonal of input weights.")
    qmin = np.linalg.eigvalsh(Q).min()
    if qmin < -1e-10 * max(1.0, np.abs(Q).max()):
        raise LQRError(f"Q is not positive semidefinite (smallest eigenvalue {qmin:.3g}); "
                       "state weights must be >= 0.")
    rmin = np.linalg.eigvalsh(R).min()
    if rmin <= 0:
        raise LQRError(f"R is not positive definite (smallest eigenvalue {rmin:.3g}); "
                       "input weights must be > 0.")
    return A, B, Q, R


def uncontrollable_modes(A, B, *, discrete: bool | None = None) -> np.ndarray:
    """Eigenvalues of ``A`` whose modes the input cannot move (PBH test: rank ``[A - lambda I, B] < n``).

    Parameters
    ----------
    A : (n, n) array
    B : (n, m) array
    discrete : bool, optional
        None: every mode; False: only those with ``Re lambda >= 0`` (the ones continuous LQR must move);
        True: only those with ``|lambda| >= 1`` (discrete).

    Returns
    -------
    (k,) complex array
        Empty when ``(A, B)`` is controllable (``discrete=None``) or stabilisable (otherwise).
    """
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float).reshape(A.shape[0], -1)
    n = A.shape[0]
    out = []
    for lam in np.linalg.eigvals(A):
        if discrete is not None and not (abs(lam) >= 1 - 1e-9 if discrete else lam.real >= -1e-9):
            continue
        s = np.linalg.svd(np.hstack([A - lam * np.eye(n), B]), compute_uv=False)
        if s[-1] < 1e-9 * max(1.0, s[0]):
            out.append(lam)
    return np.array(out, dtype=complex)


def is_controllable(A, B) -> bool:
    """True when every mode of ``A`` can be moved by the input (PBH test on each eigenvalue)."""
    return uncontrollable_modes(A, B).size == 0


def _check_stabilizable(A, B, *, discrete: bool) -> None:
    """PBH test on the unstable modes: rank [A - lambda I, B] = n for every lambda with Re >= 0 (|lambda| >= 1).

    A stable mode the input cannot move is allowed (LQR exists); an unstable one is named in the error.
    """
    bad = uncontrollable_modes(A, B, discrete=discrete)
    if bad.size:
        lam = bad[0]
        lam = lam.real if abs(lam.imag) < 1e-12 else lam
        raise LQRError(f"(A, B) is not stabilisable: the mode with eigenvalue {lam:.4g} cannot be "
                       "moved by the input; check the actuator (gear, joint) or linearisation point.")


def lqr(A, B=None, Q=None, R=None, *, x=None, u=None) -> LQRResult:
    """Continuous-time LQR: minimise ``integral(x'Qx + u'Ru) dt`` for ``x_dot = A x + B u``.

    Called as ``lqr(A, B, Q, R)`` on matrices, or as ``lqr(plant, Q=None, R=None)`` on a plant (python-control's
    two shapes; with a plant the second and third positional arguments are ``Q`` and ``R``).

    Parameters
    ----------
    A : (n, n) array, 1/s, a state-space system, or a plant
        State matrix; a continuous-time state-space object with ``A`` and ``B`` (python-control's ``StateSpace``;
        ``Q`` and ``R`` then given positionally, both required); or the plant (an MJCF path, CartPoleParams or
        CartPoleModel), linearised exactly at ``(x, u)`` without dry friction.
    B : (n, m) array, state-derivative units per unit input (per unit MuJoCo ctrl in this toolkit)
        Input matrix (with a plant: ``Q`` given positionally).
    Q : (n, n) symmetric positive semidefinite array
        State weight (with a plant: default :func:`~cartpole.riccati.weights.default_weights`).
    R : (m, m) symmetric positive definite array (a scalar ``r`` means ``r I(m)``)
        Input weight on MuJoCo ctrl (with a plant: default 0.1 per input).
    x : (n,) array, optional
        Plant only: the state to linearise at (m, rad, m/s, rad/s); default the upright equilibrium ``x_eq``.
    u : (m,) array, optional
        Plant only: the ctrl to linearise at; default ``u_eq``.

    Returns
    -------
    LQRResult
        ``K`` (m, n) for ``u = -K x``, ``S`` (n, n) the CARE solution, ``E`` (n,) eigenvalues of ``A - B K``.

    Raises
    ------
    LQRError
        Bad weights or shapes, an unstabilisable pair, or a Riccati solution that does not check out (closed
        loop not stable, or residual of the Riccati equation above 1e-6 relative to ``S``); with a plant also a
        gain whose loop sampled at the physics step ``dt`` is unstable (design it with :func:`dlqr`).
    """
    if is_plant(A):
        return _plant_lqr(A, *_plant_weights(B, Q, R), x=x, u=u)
    if _is_state_space(A):
        A, B, Q, R = _state_space(A, B, Q, R, discrete=False)
    A, B, Q, R, S = _riccati(A, B, Q, R, discrete=False)
    K = np.linalg.solve(R, B.T @ S)
    E = np.linalg.eigvals(A - B @ K)
    resid = A.T @ S + S @ A - S @ B @ K + Q
    _verify(E.real.max() < 0, resid, S, "continuous")
    return LQRResult(K, S, E)


def dlqr(A, B=None, Q=None, R=None, *, period: float | None = None, x=None, u=None) -> LQRResult:
    """Discrete-time LQR: minimise ``sum(x'Qx + u'Ru)`` for ``x[k+1] = A x[k] + B u[k]``.

    Called as ``dlqr(Ad, Bd, Q, R)`` on matrices (per-sample weights, as python-control and MATLAB), or as
    ``dlqr(plant, Q=None, R=None, period=None)`` on a plant: the exact discrete model of the MJCF's integrator over
    the control period ``T`` (the ctrl held; one physics step by default) at ``(x, u)``, with the package's one
    cost scaling: ``Q``, ``R`` are weights per second and the design is ``dlqr(Ad, Bd, Q T, R T)``, so ``K`` is
    the per-sample design's and ``S`` matches :func:`lqr`'s on the same plant to first order in ``T``.

    Parameters
    ----------
    A : (n, n) array, a state-space system, or a plant
        Discrete state matrix; a discrete-time state-space object with ``A`` and ``B`` (python-control's
        ``StateSpace`` with ``dt > 0``; per-sample ``Q`` and ``R`` given positionally, both required); or the plant
        (an MJCF path, CartPoleParams or CartPoleModel).
    B : (n, m) array
        Discrete input matrix per unit ctrl (with a plant: ``Q`` given positionally).
    Q : (n, n) symmetric positive semidefinite array
        State weight (per sample on matrices, per second on a plant; default there
        :func:`~cartpole.riccati.weights.default_weights`).
    R : (m, m) symmetric positive definite array (a scalar ``r`` means ``r I(m)``)
        Input weight (per sample on matrices, per second on a plant; default there 0.1 per input).
    period : float, optional
        Plant only: control period in s, a whole number of physics steps; default one step.
    x : (n,) array, optional
        Plant only: the state to linearise at; default the upright equilibrium ``x_eq``.
    u : (m,) array, optional
        Plant only: the ctrl to linearise at; default ``u_eq``.

    Returns
    -------
    LQRResult
        ``K`` (m, n) for ``u = -K x``, ``S`` (n, n) the DARE solution, ``E`` (n,) eigenvalues of ``A - B K``
        (inside the unit circle).

    Raises
    ------
    LQRError
        As :func:`lqr`.
    """
    if is_plant(A):
        return _plant_dlqr(A, *_plant_weights(B, Q, R), period=period, x=x, u=u)
    if _is_state_space(A):
        A, B, Q, R = _state_space(A, B, Q, R, discrete=True)
    A, B, Q, R, S = _riccati(A, B, Q, R, discrete=True)
    K = np.linalg.solve(R + B.T @ S @ B, B.T @ S @ A)
    E = np.linalg.eigvals(A - B @ K)
    resid = A.T @ S @ A - S - A.T @ S @ B @ K + Q
    _verify(np.abs(E).max() < 1, resid, S, "discrete")
    return LQRResult(K, S, E)


def _plant_weights(B, Q, R) -> tuple:
    """``(Q, R)`` of a call on a plant, whether they came positionally (in the slots of ``B`` and ``Q``) or by
    keyword: ``lqr(plant, Q, R)``, ``lqr(plant, Q, R=R)``, ``lqr(plant, Q=Q, R=R)``, ``lqr(plant, Q=Q)`` and
    ``lqr(plant, R=R)`` all mean what they say (a lone weight in ``Q``'s slot is ``Q``)."""
    if B is not None and Q is not None and R is not None:
        raise LQRError("A design on a plant takes two weights, Q and R; call lqr(plant, Q, R) (or lqr(A, B, Q, R) "
                       "on matrices).")
    if B is None:
        return Q, R
    return B, (Q if R is None else R)


def _is_state_space(obj) -> bool:
    """A linear system object with ``A`` and ``B`` matrices (python-control's ``StateSpace``, SciPy's ``lti`` in
    state-space form): anything that is not an array and has both."""
    return not isinstance(obj, (np.ndarray, list, tuple)) and hasattr(obj, "A") and hasattr(obj, "B")


def _state_space(sys, B, Q, R, *, discrete: bool) -> tuple:
    """``(A, B, Q, R)`` of ``lqr(sys, Q, R)`` / ``dlqr(sys, Q, R)`` on a state-space object, as python-control
    reads them: the weights in the slots of ``B`` and ``Q`` (or by keyword), no defaults, and the system's time
    base (``dt``: 0 continuous, positive or True discrete, None either) matching the design."""
    Q, R = _plant_weights(B, Q, R)
    name = "dlqr" if discrete else "lqr"
    if Q is None or R is None:
        raise LQRError(f"A design on a state-space system needs both weights; call {name}(sys, Q, R).")
    dt = getattr(sys, "dt", None)
    if dt is not None and discrete and dt is not True and not dt > 0:
        raise LQRError("dlqr was given a continuous-time system (dt = 0); design it with lqr(sys, Q, R), or "
                       "discretise it first (control.c2d(sys, T)).")
    if dt is not None and not discrete and (dt is True or dt > 0):
        raise LQRError(f"lqr was given a discrete-time system (dt = {dt}); design it with dlqr(sys, Q, R).")
    return np.asarray(sys.A, dtype=float), np.asarray(sys.B, dtype=float), Q, R


def _plant_point(plant, Q, R, x, u):
    """The frictionless model of ``plant``, its operating point and the weights (the defaults filled in)."""
    model = plant_model(plant).without_friction()  # dry friction has no slope at rest
    Q0, R0 = default_weights(model)
    x = model.x_eq if x is None else np.asarray(x, dtype=float)
    u = model.u_eq if u is None else np.atleast_1d(np.asarray(u, dtype=float))
    return model, x, u, (Q0 if Q is None else Q), (R0 if R is None else R)


def _plant_lqr(plant, Q, R, *, x, u) -> LQRResult:
    """:func:`lqr` on the exact continuous linearisation of ``plant``; the loop sampled at its physics step must
    be stable too (MuJoCo applies the gain once a step)."""
    model, x, u, Q, R = _plant_point(plant, Q, R, x, u)
    A, B = model.linearize(x, u)
    res = lqr(A, B, Q, R)
    Ad, Bd = model.linearize(x, u, discrete=True)
    radius = float(np.abs(np.linalg.eigvals(Ad - Bd @ res.K)).max())
    if not radius < 1:
        raise LQRError(f"The continuous LQR gain is unstable when applied every {model.dt:g} s physics step "
                       f"(closed-loop spectral radius {radius:.4g}); design it on the exact discrete model "
                       "(dlqr, or discrete=True) or raise R.")
    return res


def _plant_dlqr(plant, Q, R, *, period, x, u) -> LQRResult:
    """:func:`dlqr` on the exact discrete model of ``plant`` over ``period``, weights per second (``Q T, R T``)."""
    model, x, u, Q, R = _plant_point(plant, Q, R, x, u)
    steps = steps_per_period(period, model.dt)
    Ad, Bd = (model.hold(steps).linearize(x, u) if steps > 1 else model.linearize(x, u, discrete=True))
    T = steps * float(model.dt)
    R = np.asarray(R, dtype=float)
    return dlqr(Ad, Bd, np.asarray(Q, dtype=float) * T, R * T)


def _riccati(A, B, Q, R, *, discrete: bool):
    """The checked weights and the stabilising solution ``S`` of the continuous or discrete algebraic Riccati
    equation, or one LQRError sentence."""
    A, B, Q, R = check_weights(A, B, Q, R)
    _check_stabilizable(A, B, discrete=discrete)
    solve = scipy.linalg.solve_discrete_are if discrete else scipy.linalg.solve_continuous_are
    try:
        S = solve(A, B, Q, R)
    except (np.linalg.LinAlgError, ValueError) as exc:
        kind, edge = ("discrete", "the unit circle") if discrete else ("continuous", "the imaginary axis")
        raise LQRError(f"The {kind} Riccati equation has no stabilising solution ({exc}); "
                       f"check that (A, Q) has no unobservable mode on {edge}.") from None
    return A, B, Q, R, S


def _verify(stable: bool, resid: np.ndarray, S: np.ndarray, kind: str) -> None:
    if not stable:
        raise LQRError(f"The {kind} LQR closed loop A - B K is not stable; the pair (A, B) or the weights are "
                       "ill-posed (try a larger Q on the unstable states).")
    rel = np.abs(resid).max() / max(1.0, np.abs(S).max())
    if rel > 1e-6:
        raise LQRError(f"The {kind} Riccati residual is {rel:.2g} relative, too large to trust; "
                       "the problem is badly scaled (rescale states or weights).")
