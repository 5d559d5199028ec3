"""Infinite-horizon LQR, continuous (CARE) and discrete (DARE), with the checks people forget.

Convention (python-control's): ``K, S, E = lqr(A, B, Q, R)`` with the law ``u = -K x`` (or
``u = u* - K (x - x*)`` about an equilibrium), ``S`` the cost-to-go matrix (``x' S x``), ``E`` the
closed-loop eigenvalues. The result is a named tuple, so it unpacks like python-control's tuple.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.linalg

from cartpole.errors import CartPoleError


class LQRError(CartPoleError):
    """Bad weights, mismatched shapes, or a pair (A, B) that cannot be stabilised."""


class LQRResult(NamedTuple):
    """Gain ``K`` (m, n), cost-to-go ``S`` (n, n) and closed-loop eigenvalues ``E`` (n,), for ``n`` states and
    ``m`` inputs."""

    K: np.ndarray
    S: np.ndarray
    E: np.ndarray


def _as2d(name: str, M, shape=None) -> np.ndarray:
    M = np.atleast_2d(np.asarray(M, dtype=float))
    if not np.all(np.isfinite(M)):
        raise LQRError(f"{name} contains NaN or inf; give finite numbers.")
    if shape is not None and M.shape != shape:
        raise LQRError(f"{name} has shape {M.shape} but must be {shape} to match A and B.")
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


def lqr(A, B, Q, R) -> LQRResult:
    """Continuous-time LQR: minimise ``integral(x'Qx + u'Ru) dt`` for ``x_dot = A x + B u``.

    Parameters
    ----------
    A : (n, n) array, 1/s
    B : (n, m) array, state-derivative units per unit input (per unit MuJoCo ctrl in this toolkit)
    Q : (n, n) symmetric positive semidefinite array
    R : (m, m) symmetric positive definite array (a scalar ``r`` means ``r I(m)``)

    Returns
    -------
    LQRResult
        ``K`` (m, n) for ``u = -K x``, ``S`` (n, n) the CARE solution, ``E`` (n,) eigenvalues of ``A - B K``.

    Raises
    ------
    LQRError
        Bad weights or shapes, an unstabilisable pair, or a Riccati solution that does not check out (closed
        loop not stable, or residual of the Riccati equation above 1e-6 relative to ``S``).
    """
    A, B, Q, R, S = _riccati(A, B, Q, R, discrete=False)
    K = np.linalg.solve(R, B.T @ S)
    E = np.linalg.eigvals(A - B @ K)
    resid = A.T @ S + S @ A - S @ B @ K + Q
    _verify(E.real.max() < 0, resid, S, "continuous")
    return LQRResult(K, S, E)


def dlqr(A, B, Q, R) -> LQRResult:
    """Discrete-time LQR: minimise ``sum(x'Qx + u'Ru)`` for ``x[k+1] = A x[k] + B u[k]``.

    Parameters and returns as :func:`lqr`; ``E`` are eigenvalues of ``A - B K`` (inside the unit circle).
    """
    A, B, Q, R, S = _riccati(A, B, Q, R, discrete=True)
    K = np.linalg.solve(R + B.T @ S @ B, B.T @ S @ A)
    E = np.linalg.eigvals(A - B @ K)
    resid = A.T @ S @ A - S - A.T @ S @ B @ K + Q
    _verify(np.abs(E).max() < 1, resid, S, "discrete")
    return LQRResult(K, S, E)


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
