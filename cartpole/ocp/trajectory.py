"""A planned trajectory, interpolated exactly as Hermite-Simpson collocation defines it.

Hermite-Simpson collocation represents the state on each interval ``[t_k, t_k+1]`` by the cubic Hermite
polynomial through ``(x_k, xdot_k)`` and ``(x_k+1, xdot_k+1)`` (``xdot_k = f(x_k, u_k)``), and the input by a
first-order hold (straight line) between the knot inputs ``u_k`` and ``u_k+1``; the collocation midpoint
state is that cubic evaluated at the interval's middle. :class:`Trajectory` stores the knots and their
derivatives so ``state(t)`` and ``input(t)`` return exactly the functions the optimiser constrained.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cartpole._files import atomic_write, short
from cartpole.errors import CartPoleError


class TrajectoryError(CartPoleError):
    """A trajectory whose arrays are inconsistent, or a file that does not hold one."""


def _ro(a, name: str, shape: tuple) -> np.ndarray:
    """``a`` as a read-only float array of ``shape``; a ``None`` entry of ``shape`` takes any size (the first
    array fixes nx or nu); a 1-D array where a single column is expected becomes that column."""
    arr = np.array(a, dtype=float)
    if arr.ndim == len(shape) - 1 and shape[-1] in (1, None) and len(shape) == 2:
        arr = arr.reshape(*arr.shape, 1)
    if arr.ndim != len(shape) or any(want is not None and got != want for got, want in zip(arr.shape, shape)):
        want = tuple("any" if v is None else v for v in shape)
        raise TrajectoryError(f"Trajectory.{name} has shape {arr.shape} but must be {want}.")
    if not np.all(np.isfinite(arr)):
        raise TrajectoryError(f"Trajectory.{name} contains NaN or inf; a plan must be finite.")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class Trajectory:
    """Knots of a planned motion with cubic-Hermite states and first-order-hold inputs.

    The interpolation is the one Hermite-Simpson collocation defines: on ``[t_k, t_k+1]`` the state is
    the cubic Hermite polynomial matching ``x`` and ``xdot`` at both knots and the input is the straight
    line (first-order hold, FOH) between ``u_k`` and ``u_k+1``. Outside ``[t[0], t[-1]]`` both are clamped
    to the end values.

    Attributes
    ----------
    t : (N+1,) array, s
        Knot times, strictly increasing.
    x : (N+1, nx) array
        Knot states ``[qpos, qvel]`` in MuJoCo's order (m and rad, m/s and rad/s); for one pole
        ``[s, theta, s_dot, theta_dot]``.
    u : (N+1, nu) array
        Knot inputs (MuJoCo ctrl), held first-order between knots (one row per knot, not per interval); a
        1-D array is taken as one input.
    xdot : (N+1, nx) array
        State derivatives ``f(x_k, u_k)`` at the knots (units of ``x`` per s).
    x_mid : (N, nx) array or None
        Collocation midpoint states (equal to ``state((t_k + t_k+1) / 2)`` for a Hermite-Simpson plan).
    u_mid : (N, nu) array or None
        Midpoint inputs (``(u_k + u_k+1) / 2`` under the first-order hold).
    """

    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    xdot: np.ndarray
    x_mid: np.ndarray | None = None
    u_mid: np.ndarray | None = None

    def __post_init__(self):
        t = np.array(self.t, dtype=float).ravel()
        n = t.size
        if n < 2 or not np.all(np.diff(t) > 0):
            raise TrajectoryError("Trajectory.t needs at least two strictly increasing knot times.")
        object.__setattr__(self, "t", _ro(t, "t", (n,)))
        x = _ro(self.x, "x", (n, None))
        u = _ro(self.u, "u", (n, None))
        nx, nu = x.shape[1], u.shape[1]
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "u", u)
        object.__setattr__(self, "xdot", _ro(self.xdot, "xdot", (n, nx)))
        if self.x_mid is not None:
            object.__setattr__(self, "x_mid", _ro(self.x_mid, "x_mid", (n - 1, nx)))
        if self.u_mid is not None:
            object.__setattr__(self, "u_mid", _ro(self.u_mid, "u_mid", (n - 1, nu)))

    # ---- basic facts ---------------------------------------------------------------------------
    @property
    def N(self) -> int:
        """Number of intervals."""
        return self.t.size - 1

    @property
    def nx(self) -> int:
        """State dimension."""
        return self.x.shape[1]

    @property
    def nu(self) -> int:
        """Number of inputs."""
        return self.u.shape[1]

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]`` in s."""
        return float(self.t[-1] - self.t[0])

    @property
    def t_mid(self) -> np.ndarray:
        """(N,) interval midpoints in s."""
        return 0.5 * (self.t[:-1] + self.t[1:])

    # ---- interpolation -------------------------------------------------------------------------
    def _locate(self, t):
        t = np.clip(np.asarray(t, dtype=float), self.t[0], self.t[-1])
        k = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, self.N - 1)
        h = self.t[k + 1] - self.t[k]
        return t, k, h, (t - self.t[k]) / h

    def state(self, t) -> np.ndarray:
        """Cubic-Hermite state at time(s) ``t`` (s): scalar -> (nx,), array (n,) -> (n, nx); clamped outside."""
        scalar = np.ndim(t) == 0
        _, k, h, s = self._locate(np.atleast_1d(t))
        s = s[:, None]
        h = h[:, None]
        h00 = 2 * s**3 - 3 * s**2 + 1
        h10 = s**3 - 2 * s**2 + s
        h01 = -2 * s**3 + 3 * s**2
        h11 = s**3 - s**2
        x = h00 * self.x[k] + h10 * h * self.xdot[k] + h01 * self.x[k + 1] + h11 * h * self.xdot[k + 1]
        return x[0] if scalar else x

    def state_derivative(self, t) -> np.ndarray:
        """Time derivative of the cubic-Hermite state at ``t``: scalar -> (nx,), (n,) -> (n, nx), per s."""
        scalar = np.ndim(t) == 0
        _, k, h, s = self._locate(np.atleast_1d(t))
        s = s[:, None]
        h = h[:, None]
        d00 = (6 * s**2 - 6 * s) / h
        d10 = 3 * s**2 - 4 * s + 1
        d01 = (-6 * s**2 + 6 * s) / h
        d11 = 3 * s**2 - 2 * s
        xd = d00 * self.x[k] + d10 * self.xdot[k] + d01 * self.x[k + 1] + d11 * self.xdot[k + 1]
        return xd[0] if scalar else xd

    def input(self, t) -> np.ndarray:
        """First-order-hold input at ``t`` (s): scalar -> (nu,), array (n,) -> (n, nu); clamped outside."""
        scalar = np.ndim(t) == 0
        _, k, _, s = self._locate(np.atleast_1d(t))
        u = (1 - s)[:, None] * self.u[k] + s[:, None] * self.u[k + 1]
        return u[0] if scalar else u

    def sample(self, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Sample on a uniform grid from ``t[0]`` with step ``dt`` (s) up to and including ``t[-1]``.

        Returns
        -------
        (t (n,), x (n, nx), u (n, nu)), time first.
        """
        if not dt > 0:
            raise TrajectoryError(f"Sampling step {dt} s is not positive; give dt > 0.")
        n = int(np.floor(self.duration / dt + 1e-9))
        t = self.t[0] + dt * np.arange(n + 1)
        return t, self.state(t), self.input(t)

    # ---- files ---------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """JSON-ready dict of lists (``x_mid``/``u_mid`` omitted when absent)."""
        d = {"t": self.t.tolist(), "x": self.x.tolist(), "u": self.u.tolist(), "xdot": self.xdot.tolist()}
        if self.x_mid is not None:
            d["x_mid"] = self.x_mid.tolist()
        if self.u_mid is not None:
            d["u_mid"] = self.u_mid.tolist()
        return d

    def save(self, path: str | Path) -> Path:
        """Write to ``path`` as ``.npz`` (default) or ``.json`` (by suffix), via a temporary file then rename.

        Returns the path written.
        """
        path = Path(path)
        if path.suffix == ".json":
            payload = json.dumps({"format": "cartpole.Trajectory/1", **self.to_dict()}).encode()
            atomic_write(path, lambda fh: fh.write(payload))
        else:
            if path.suffix != ".npz":
                path = path.with_name(path.name + ".npz")
            arrays = {k: np.asarray(v) for k, v in self.to_dict().items()}
            atomic_write(path, lambda fh: np.savez(fh, **arrays))
        return path

    @classmethod
    def load(cls, path: str | Path) -> "Trajectory":
        """Read a trajectory written by :meth:`save` (``.npz`` or ``.json``)."""
        path = Path(path)
        if not path.is_file():
            raise TrajectoryError(f"Trajectory file '{short(path)}' does not exist; give the path save() returned.")
        try:
            if path.suffix == ".json":
                d = json.loads(path.read_text())
            else:
                with np.load(path) as z:
                    d = {k: z[k] for k in z.files}
            return cls(t=d["t"], x=d["x"], u=d["u"], xdot=d["xdot"], x_mid=d.get("x_mid"), u_mid=d.get("u_mid"))
        except (KeyError, ValueError, OSError) as exc:
            raise TrajectoryError(f"'{short(path)}' does not hold a trajectory ({exc}); give a file written by "
                                  "Trajectory.save.") from None


def step_grid_trajectory(f, dt: float, x, u) -> Trajectory:
    """A motion on a uniform step grid (a rollout, a DDP or exact-step plan) as a :class:`Trajectory`.

    Parameters
    ----------
    f : casadi.Function
        The continuous dynamics ``f(x (nx,), u (nu,)) -> xdot (nx,)`` (a model's ``f``).
    dt : float
        s between knots: the knots are at ``dt * k`` s, ``k = 0 .. n``.
    x : (n+1, nx) array
        The states at the knots ``[qpos, qvel]`` (m, rad, m/s, rad/s).
    u : (n, nu) array
        The input (ctrl) held over each step; a 1-D array (n,) is one input.

    Returns
    -------
    Trajectory
        Knot inputs ``u`` with the last one repeated at the end knot ((n+1, nu): step ``k``'s input at knot ``k``),
        ``xdot = f(x_k, u_k)`` at every knot (units of ``x`` per s).
    """
    x = np.asarray(x, dtype=float)
    u = np.asarray(u, dtype=float).reshape(x.shape[0] - 1, -1)
    u_knots = np.vstack([u, u[-1:]])
    xdot = np.asarray(f.map(x.shape[0])(x.T, u_knots.T), dtype=float).T
    return Trajectory(t=float(dt) * np.arange(x.shape[0]), x=x, u=u_knots, xdot=xdot)
